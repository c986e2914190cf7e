"""Campaign scenario ``motor_fault``: a random motor failure at a random time on one of the
ch. 6 missions (Argyropoulos 2020), classified and flown by the fault-tolerant controller.

The outcome of a run is ranked as the source's priority (ch. 7): 4 tracked (no
touchdown and the position within ``TRACKED_RMSE`` of the reference after the fault),
3 landed safely (touchdown at most ``SAFE_SPEED`` down, outside the unsafe disc), 2 the
unsafe area avoided (touchdown outside the disc), 1 impact. The category says which
outcome the tube judged feasible: IV tracking, III a safe landing, II avoiding the
disc, I none (only the impact speed). A run violates the priority when its outcome
ranks below what its category promised.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math

import numpy as np

from drake_uav.campaigns.registry import register_scenario
from drake_uav.diagrams.fault_scenarios import (
    fault_vehicle,
    fly_scenario,
    scenario,
    scenario_tubes,
)
from drake_uav.diagrams.faults import FaultRun
from drake_uav.optimization.allocation import closure_holds
from drake_uav.optimization.fault_response import Category

__all__ = ["motor_fault", "outcome", "TRACKED_RMSE", "SAFE_SPEED", "LANDING_TIME",
           "TRACKING_END", "MISSIONS"]

TRACKED_RMSE = 1.0
"""Position RMSE [m] after the fault below which a run still tracks."""
SAFE_SPEED = 1.0
"""Largest downward touchdown speed [m/s] of a safe landing."""
LANDING_TIME = 120.0
"""Simulated time after the fault [s] by default, room for a landing from anywhere on the
missions: a stop from their top speed of about 8 m/s at the plans' mean braking carries the
vehicle up to about 50 m from the safe point, which it then crosses at the 1 m/s mean
cruise speed before an 8 m descent at 1 m/s (about 75 s in all)."""
TRACKING_END = 2.0
"""A run still tracking its mission (category IV) ends this long after the mission [s]
(the landings fly on, up to :data:`LANDING_TIME` after the fault)."""
MISSIONS = {"I": "I", "II": "IIa", "III": "IIIa", "IV": "IVa"}
"""Target -> the scenario whose mission (and disc) the campaign flies."""
_REQUIRED = {Category.I: 1, Category.II: 2, Category.III: 3, Category.IV: 4}


def outcome(run: FaultRun) -> int:
    """Rank of the run's outcome (module docstring)."""
    td = run.touchdown
    if td is None:
        return 4 if run.position_rmse(run.fault_time) <= TRACKED_RMSE else 1
    inside = run.unsafe_disc is not None and run.unsafe_disc.contains(td.position)
    if inside:
        return 1
    return 3 if td.vertical_speed <= SAFE_SPEED else 2


@functools.cache
def _failure_sets(closure: bool) -> tuple[tuple[int, ...], ...]:
    params = fault_vehicle()
    n = params.num_motors
    sets = [s for k in range(1, n + 1) for s in itertools.combinations(range(n), k)]
    return tuple(s for s in sets if closure_holds(params, s) == closure)


@functools.cache
def _tubes(coarse: bool):
    from drake_uav.optimization.reachability import TubeSettings

    return scenario_tubes(fault_vehicle(), TubeSettings.coarse() if coarse else None)


@register_scenario("motor_fault")
def motor_fault(seed: int, params: dict) -> dict:
    """A random failure at a random time on a ch. 6 mission.

    Parameters (defaults): ``target`` ("IV": "I" draws a failure set without closure on
    the category-I mission; "II", "III", "IV" a set with closure on the missions of
    scenarios IIa (with its disc and its upset, moved to end at the drawn fault time), IIIa
    and IVa), ``coarse_tube`` (False), ``duration``
    [s] (default: the scenario's, and at least :data:`LANDING_TIME` after the fault; the
    fault time is drawn in [1 s, the shorter of the mission and the duration less 1 s]).

    Metrics: ``category`` (1-4; 0 if not classified), ``failed`` (the set, e.g. "0,3"),
    ``fault_time`` [s], ``outcome`` (rank 1-4), ``priority_violated``, ``touchdown``,
    ``impact_speed`` and ``free_fall_speed`` [m/s] (nan without touchdown),
    ``rmse_after`` [m].
    """
    target = str(params.get("target", "IV"))
    if target not in MISSIONS:
        raise ValueError(f"motor_fault: target {target!r} unknown ({', '.join(MISSIONS)})")
    rng = np.random.default_rng([seed, 3200])
    sets = _failure_sets(target != "I")
    failed = sets[int(rng.integers(len(sets)))]
    base = scenario(MISSIONS[target])
    duration = params.get("duration")
    end = min(base.mission_time, float(duration or math.inf)) - 1.0
    fault_time = round(round(float(rng.uniform(1.0, end)) / 0.025) * 0.025, 3)
    # room for a landing from anywhere on the mission (a touchdown ends the flight)
    duration = float(duration or max(base.duration, fault_time + LANDING_TIME))
    sc = dataclasses.replace(base, failed_motors=failed, fault_time=fault_time)
    if base.upset is not None:  # the upset ends at the failure, as in the scenario
        start, length, torque = base.upset
        sc = dataclasses.replace(sc, upset=(fault_time - length, length, torque))
    run = fly_scenario(sc, tube_for=_tubes(bool(params.get("coarse_tube", False))),
                       duration=duration, end_after_mission=TRACKING_END)
    rank = outcome(run)
    td, ff = run.touchdown, run.free_fall
    return {
        "category": int(run.category),
        "failed": ",".join(map(str, failed)),
        "fault_time": fault_time,
        "outcome": rank,
        "priority_violated": bool(rank < _REQUIRED.get(run.category, 5)),
        "touchdown": td is not None,
        "impact_speed": td.vertical_speed if td else math.nan,
        "free_fall_speed": ff.vertical_speed if ff else math.nan,
        "rmse_after": run.position_rmse(run.fault_time),
    }
