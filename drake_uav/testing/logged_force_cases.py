"""Scenario ``logged_force``: a tether whose tension a separate logger records.

One identification flight (:func:`drake_uav.diagrams.fly`, the aerosonde, 120 s, the
default multisine) pulled by a tether towards a ground point (:data:`ANCHOR`: on the
ground 400 m east of the track's middle, the aircraft 100 m up), with the tether's
tension (:func:`~drake_uav.testing.discovery_cases.tether_tension`, mean 3 and standard
deviation 1 at strength 1, slow: 0.02-0.5 Hz) acting at the centre of gravity. A load
cell logs the tension with noise on a logger of its own (:data:`LOGGER_RATE`) whose clock
is off by a constant offset; its samples are written onto the autopilot's time base by
their own stamps, so that the channel ``tension`` [N] lags the force the aircraft felt by
that offset. Then the main job (:func:`~drake_uav.identification.pipeline.identify`) with
the catalog model on the measured channels alone.

The strength is set by ``size``, the share of ``C_Y``'s variation the pull adds (as in
the ``discovery`` scenario, :mod:`~drake_uav.testing.discovery_cases`), calibrated once
per turbulence level on clean flights of :data:`~drake_uav.testing.discovery_cases.
CALIBRATION_SEEDS`. With ``effect="none"`` the same logger records a tension that does
not act on the aircraft (a load cell on the ground): an unrelated logged channel.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from drake_uav.campaigns.registry import register_scenario
from drake_uav.diagrams import fly
from drake_uav.identification.assessment.noise_floor import held_out_noise_floor
from drake_uav.identification.discovery.fitted_point import unit_vectors_towards
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.rotations import euler_to_rotmat
from drake_uav.testing.discovery_cases import (
    CALIBRATION_SEEDS,
    FLIGHT_DURATION,
    SUITES,
    aero_condition,
    measured_only,
    pull_towards_point,
    qbar_s,
    tether_tension,
    true_coefficients,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.loading import load_fixed_wing

__all__ = ["ANCHOR", "LOGGER_RATE", "TENSION_NOISE", "OFFSET_RANGE", "EXPECTED",
           "EXPECTED_OFF_CG", "HOOK", "MOVED", "MOVED_OFF_CG", "clock_offset",
           "separate_logger", "expected_finding", "tethered_flight", "logged_force"]

ANCHOR = (1500.0, 400.0, 0.0)
"""NED point [m] of the tether's anchor: on the ground, 400 m east of the middle of the
track (which runs north from the origin, 100 m up)."""
LOGGER_RATE = 20.0
"""[Hz] of the load cell's logger."""
TENSION_NOISE = 0.05
"""Standard deviation of the logged tension's noise at strength 1 [N]."""
OFFSET_RANGE = (0.3, 2.0)
"""[s]: the logger's clock offset, drawn per flight uniformly in this range with a random
sign (:func:`clock_offset`)."""
EXPECTED = "force_towards_point_logged:tension"
"""The finding that names the tether: a force proportional to the logged tension towards
a point the data locate."""
MOVED = ("CL", "CD", "CY")
"""The coefficients the tether moves (it acts at the centre of gravity)."""
HOOK = (0.15, 0.0, 0.10)
"""[m] FRD body point of a tow hook: 0.15 m ahead of and 0.10 m below the centre of
gravity, under the fuselage (``attachment="hook"``)."""
EXPECTED_OFF_CG = "force_towards_point_logged:tension_off_cg"
"""The finding that names a tether pulling at :data:`HOOK`: the same force, with its
moment."""
MOVED_OFF_CG = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
"""The coefficients a tether pulling at :data:`HOOK` moves."""


def clock_offset(seed: int) -> float:
    """The logger's clock offset [s] of flight ``seed`` (:data:`OFFSET_RANGE`)."""
    rng = np.random.default_rng([seed, 77])
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(*OFFSET_RANGE))


def separate_logger(log: FlightLog, channel: str, value, noise_std: float, offset: float,
                    seed: int, unit: str = "N") -> FlightLog:
    """``log`` with ``channel`` recorded by a logger of its own clock.

    The logger samples ``value(t)`` (a function of the true time [s]) at
    :data:`LOGGER_RATE` on its clock, which reads ``offset`` [s] ahead of the autopilot's,
    adds white noise of ``noise_std``, and its samples are written onto the log's time base
    by their stamps (each row holds the last sample stamped at or before it): the channel
    lags the true value by ``offset``.

    Parameters
    ----------
    log : FlightLog
        The autopilot's log.
    channel : str
        The new channel's name.
    value : callable
        ``value(t)`` [unit] at true times ``t`` (array).
    noise_std : float
        The logged noise [unit].
    offset : float
        [s] the logger's clock ahead of the autopilot's.
    seed : int
        Seed of the noise.
    unit : str
        The channel's unit.

    Returns
    -------
    FlightLog
        The log with the channel.
    """
    stamps = np.arange(log.time[0], log.time[-1] + 1.0 / LOGGER_RATE, 1.0 / LOGGER_RATE)
    rng = np.random.default_rng([seed, 78])
    samples = np.asarray(value(stamps - offset)) + noise_std * rng.standard_normal(len(stamps))
    row = np.clip(np.searchsorted(stamps, log.time, side="right") - 1, 0, len(stamps) - 1)
    return log.with_measured({channel: samples[row]}, {channel: unit})


def _side_force(flight: FlightLog, params: FixedWingParams) -> np.ndarray:
    """C_Y change of the tether at strength 1 along a flight's truth."""
    path = np.column_stack([flight["pn"], flight["pe"], flight["pd"]])
    towards = unit_vectors_towards(path, np.array([ANCHOR]))[:, 0, :]
    rotation = euler_to_rotmat(np.array([flight["roll"], flight["pitch"], flight["yaw"]]))
    body = np.einsum("ijn,in->jn", rotation, towards)
    condition = aero_condition(flight, params)
    return tether_tension(flight.time) * body[1] / qbar_s(condition.airspeed, params)


@functools.cache
def _unit_strength(turbulence: str) -> float:
    """Median over the calibration flights of ``std(C_Y) / std(tether's C_Y at strength
    1)``: the strength of size 1."""
    params = load_fixed_wing("aerosonde")
    ratios = []
    for seed in CALIBRATION_SEEDS:
        flight = fly(params, turbulence=turbulence, seed=seed, duration=FLIGHT_DURATION)
        cy = true_coefficients(flight, aero_condition(flight, params))["CY"]
        ratios.append(np.std(cy) / np.std(_side_force(flight, params)))
    return float(np.median(ratios))


def expected_finding(attachment: str) -> tuple[str, tuple[str, ...]]:
    """The finding that names a tether pulling at ``attachment`` ("cg" or "hook") and the
    coefficients it moves: :data:`EXPECTED` and :data:`MOVED`, or :data:`EXPECTED_OFF_CG`
    and :data:`MOVED_OFF_CG`."""
    return (EXPECTED_OFF_CG, MOVED_OFF_CG) if attachment == "hook" else (EXPECTED, MOVED)


def tethered_flight(seed: int, *, effect: str = "tether", size: float = 0.3,
                    suite: str = "default", turbulence: str = "light",
                    offset: float | None = None, attachment: str = "cg"
                    ) -> tuple[FlightLog, float, float]:
    """One flight of the :func:`logged_force` scenario: the aerosonde pulled by a tether
    (or not) whose tension a separate logger records.

    Parameters
    ----------
    seed : int
        Seed of the turbulence, the sensors' and the logger's noise (and of the clock
        offset when ``offset`` is None).
    effect : str
        "tether", or "none" (the logger records a tension that does not act).
    size : float
        The tether's share of C_Y's variation.
    suite, turbulence : str
        Sensor suite (:data:`~drake_uav.testing.discovery_cases.SUITES`) and turbulence.
    offset : float or None
        The logger's clock offset [s]; None: :func:`clock_offset` of the seed.
    attachment : str
        "cg", or "hook" (the tether pulls at :data:`HOOK`).

    Returns
    -------
    log : FlightLog
        The flight's log with the ``tension`` channel [N], truth channels included
        (:func:`~drake_uav.testing.discovery_cases.measured_only` strips them).
    strength : float
        The tension's scale (1: mean 3 N, standard deviation 1 N).
    offset : float
        The logger's clock offset [s].

    Raises
    ------
    ValueError
        Naming an unknown effect, suite or attachment.
    """
    if effect not in ("tether", "none"):
        raise ValueError(f"logged_force: effect {effect!r} unknown (known: tether, none)")
    if suite not in SUITES:
        raise ValueError(f"logged_force: suite {suite!r} unknown (known: {', '.join(SUITES)})")
    if attachment not in ("cg", "hook"):
        raise ValueError(f"logged_force: attachment {attachment!r} unknown (known: cg, hook)")
    offset = clock_offset(seed) if offset is None else float(offset)
    catalog = load_fixed_wing("aerosonde")
    strength = float(size) * _unit_strength(turbulence)
    options = {"aircraft": catalog, "turbulence": turbulence, "seed": seed,
               "duration": FLIGHT_DURATION, "sensors": SUITES[suite](catalog.rho)}

    def tension(t):
        return strength * tether_tension(t)

    if effect == "tether":
        options |= pull_towards_point(lambda t: float(tension(t)[0]), ANCHOR,
                                      HOOK if attachment == "hook" else (0.0, 0.0, 0.0))
    log = separate_logger(fly(**options), "tension", tension, strength * TENSION_NOISE,
                          offset, seed)
    return log, strength, offset


@register_scenario("logged_force")
def logged_force(seed: int, params: dict) -> dict:
    """One tethered flight (or a clean one with an unrelated tension channel), then the
    main job.

    Parameters (defaults): ``effect`` ("tether" or "none"), ``size`` (0.3, share of
    ``C_Y``'s variation), ``suite`` ("default" or "research"), ``turbulence`` ("light"),
    ``offset`` (the logger's clock offset [s]; None: :func:`clock_offset` of the seed),
    ``attachment`` ("cg", or "hook": the tether pulls at :data:`HOOK`, so its moment moves
    C_l, C_m and C_n too).

    Metrics: ``found`` (comma-separated findings), ``named`` (the discovery's findings are
    exactly :data:`EXPECTED`, or :data:`EXPECTED_OFF_CG` at the hook), ``exact`` (that, and
    no calibration finding but the channel's clock offset), ``any_finding`` (on a clean
    flight), ``offset`` (the true one), ``offset_estimate``, ``offset_sigma``,
    ``offset_applied``, ``strength``; per coefficient of :data:`MOVED` (at the hook
    :data:`MOVED_OFF_CG`), ``excess_explained_<k>`` (NaN at the floor) and
    ``kept_<k>`` (the finding was kept on it); ``point_error`` [m] and ``point_sigma`` [m].
    """
    effect = params.get("effect", "tether")
    expected, moved = expected_finding(params.get("attachment", "cg"))
    log, strength, offset = tethered_flight(
        seed, effect=effect, size=float(params.get("size", 0.3)),
        suite=params.get("suite", "default"), turbulence=params.get("turbulence", "light"),
        offset=params.get("offset"), attachment=params.get("attachment", "cg"))
    catalog = load_fixed_wing("aerosonde")
    run = identify(measured_only(log), catalog, seed=seed)
    found = list(run.findings)
    discovered = [f.name for f in run.discovery.found]
    shift = next((e for e in run.compatibility.effects
                  if e.name == "tension_clock_offset"), None) if run.compatibility else None
    calibration = [n for n in found if n not in discovered]
    metrics = {"found": ",".join(found), "any_finding": bool(found), "strength": strength,
               "offset": offset,
               "offset_estimate": math.nan if shift is None else shift.estimate,
               "offset_sigma": math.nan if shift is None else shift.sigma,
               "offset_applied": bool(shift is not None and shift.applied)}
    if effect == "none":
        return metrics
    named = discovered == [expected]
    metrics |= {"named": named,
                "exact": named and set(calibration) <= {"tension_clock_offset"}}
    floors = held_out_noise_floor(run.samples, run.discovery, catalog)
    finding = next((f for f in run.discovery.found if f.name == expected), None)
    for k in moved:
        explained = floors[k].excess_explained
        metrics[f"excess_explained_{k}"] = math.nan if explained is None else explained
        metrics[f"kept_{k}"] = finding is not None and k in finding.coefficients
    located = finding is not None and "p_n" in finding.parameters
    metrics["point_error"] = (float(np.linalg.norm(np.subtract(
        [finding.parameters[f"p_{a}"][0] for a in "ned"], ANCHOR))) if located else math.nan)
    metrics["point_sigma"] = (max(finding.parameters[f"p_{a}"][1] for a in "ned")
                              if located else math.nan)
    return metrics
