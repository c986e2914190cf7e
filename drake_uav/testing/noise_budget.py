"""Which sensor limits each measured coefficient: the error budget of a simulated flight.

The job measures each aerodynamic coefficient from the accelerometers, gyros, attitude,
pitot and vanes (:func:`~drake_uav.identification.pipeline.select_samples`). For a flight of
:func:`~drake_uav.diagrams.fly`, which logs each sensor beside its truth,
:func:`noise_budget` isolates the coefficients once from the true signals and once for
each sensor group with that group's logged channels and every other channel true; the RMS
difference is that group's share of the coefficient's error per sample (noise, bias and
lag alike), as the job sees it (after the isolation's smoothing, at its sample rate).
Independent sensor errors add in quadrature, so the groups' shares, squared, add up to the
error with every sensor logged (``ALL``) when the isolation is close to linear in them.

The thrust is the catalog's model at the logged airspeed (``propulsion="catalog"``), so
that a group's share does not include a different thrust fit. GPS does not enter the
coefficients.

``benchmarks/bench_noise_budget.py`` prints the budget for the campaign's flights;
docs/main_job.md ("What keeps the drag-axis effects from the targets") reads it.
"""

from __future__ import annotations

import numpy as np

from drake_uav.estimation.signals import AIR_DATA, ATTITUDE, IMU, LOG_CHANNELS
from drake_uav.identification.pipeline import select_samples
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.testing.discovery_cases import measured_only
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["SENSOR_GROUPS", "ALL", "noise_budget"]

_GROUPS = {"accelerometer": IMU[:3], "gyro": IMU[3:], "attitude": ATTITUDE,
           "pitot": AIR_DATA[:1], "vanes": AIR_DATA[1:]}
SENSOR_GROUPS: dict[str, dict[str, str]] = {
    group: {LOG_CHANNELS[name]: name for name in names} for group, names in _GROUPS.items()}
"""Sensor group -> its logged channels -> their truth channels in a simulated flight."""

ALL = "all sensors"
"""The key of the error with every sensor logged."""


def _with_truth(flight: FlightLog, logged: tuple[str, ...], rho: float) -> FlightLog:
    """The measured channels of ``flight``, those of the groups not in ``logged`` replaced
    by their truth (the dynamic pressure follows the true airspeed)."""
    true = {channel: flight[truth] for group, pairs in SENSOR_GROUPS.items()
            if group not in logged for channel, truth in pairs.items()}
    if "pitot" not in logged:
        true["pitot_qbar"] = dynamic_pressure(flight["airspeed"], rho)
    return measured_only(flight).with_measured(true)


def _coefficients(log: FlightLog, params: FixedWingParams, rate_hz: float):
    samples = select_samples(log, params, rate_hz=rate_hz, air_data="vanes",
                             propulsion="catalog")[0]
    return samples.time, {c: np.asarray(samples.coefficients[c]) for c in COEFFICIENTS}


def noise_budget(flight: FlightLog, params: FixedWingParams,
                 rate_hz: float = 50.0) -> dict[str, dict[str, float]]:
    """Sensor group (and :data:`ALL`) -> coefficient -> RMS error of the coefficient's
    samples [-] when only that group's channels are the logged ones (module docstring).

    ``flight`` needs the truth channels of :data:`SENSOR_GROUPS` (a flight of
    :func:`~drake_uav.diagrams.fly`); ``rate_hz`` is the isolation's sample rate [Hz].
    """
    missing = sorted({t for pairs in SENSOR_GROUPS.values() for t in pairs.values()}
                     - set(flight.names))
    if missing:
        raise ValueError(f"noise_budget: the flight has no truth channel {', '.join(missing)}; "
                         "the budget needs a simulated flight (drake_uav.diagrams.fly)")
    time, reference = _coefficients(_with_truth(flight, (), params.rho), params, rate_hz)
    out = {}
    for name, logged in [*((g, (g,)) for g in SENSOR_GROUPS), (ALL, tuple(SENSOR_GROUPS))]:
        t, measured = _coefficients(_with_truth(flight, logged, params.rho), params, rate_hz)
        _, i, j = np.intersect1d(t, time, return_indices=True)
        out[name] = {c: float(np.sqrt(np.mean((measured[c][i] - reference[c][j]) ** 2)))
                     for c in COEFFICIENTS}
    return out
