"""Flights whose IMU sits away from the centre of gravity, and what the main job makes of
them with and without its position.

:func:`imu_away_from_cg` moves a simulated flight's accelerometers to a body point ``r``:
they read ``w_dot x r + w x (w x r)`` more (from the true rates and their rate of change).
:func:`imu_offset_run` flies one such flight and runs the job on its measured channels
alone, once as an autopilot log without the IMU position and once with it
(``identify(..., imu_position=r)``, as a log's ``INS_POS<n>_*`` or ``EKF2_IMU_POS_*`` give
it). ``benchmarks/bench_imu_position.py`` runs it over seeds; docs/main_job.md ("The IMU
position") reads the rates.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from drake_uav.diagrams import fly
from drake_uav.estimation.imu_position import ACCELEROMETERS
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.isolation import lever_arm_specific_force
from drake_uav.testing.discovery_cases import FLIGHT_DURATION, SUITES, measured_only
from drake_uav.vehicles.loading import load_fixed_wing

__all__ = ["OFFSET", "imu_away_from_cg", "imu_offset_run"]

OFFSET = (0.2, -0.05, 0.1)
"""[m] body axes FRD: 20 cm ahead of the centre of gravity, 5 cm left, 10 cm below."""

def imu_away_from_cg(flight: FlightLog, position: Sequence[float]) -> FlightLog:
    """``flight`` (of :func:`~drake_uav.diagrams.fly`, with its true rates ``p, q, r``)
    with its accelerometers read at ``position`` [m] instead of the centre of gravity."""
    w = flight.stack(("p", "q", "r"))
    extra = np.asarray(position, float) @ lever_arm_specific_force(
        np.gradient(w, flight.time, axis=0), w)
    return flight.with_measured({c: flight[c] + extra[:, i]
                                 for i, c in enumerate(ACCELEROMETERS)})


def imu_offset_run(seed: int, turbulence: str = "light", suite: str = "default",
                   position: Sequence[float] = OFFSET) -> dict:
    """The job's findings on one flight with its IMU at ``position`` [m], without and with
    the position: ``found_without``, ``found_with`` (comma-separated) and
    ``skew_without``, ``skew_with`` [s] (the air-data time skew the compatibility check
    applied, 0 when none)."""
    params = load_fixed_wing("aerosonde")
    flight = fly(params, turbulence, seed=seed, duration=FLIGHT_DURATION,
                 sensors=SUITES[suite](params.rho))
    log = measured_only(imu_away_from_cg(flight, position))
    out = {}
    for key, given in (("without", None), ("with", tuple(position))):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = identify(log, params, seed=seed, imu_position=given)
        skew = next((e.estimate for e in (run.compatibility.applied if run.compatibility
                                          else ()) if e.name == "air_data_time_skew"), 0.0)
        out[f"found_{key}"] = ",".join(run.findings)
        out[f"skew_{key}"] = float(skew)
    return out
