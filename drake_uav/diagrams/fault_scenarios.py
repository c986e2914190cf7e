"""The seven motor-failure scenarios of Argyropoulos 2020, ch. 6, and their vehicle.

The source gives the failed motors, the fault times, the unsafe discs and the safe
point, nothing else (no vehicle, no trajectories). Coordinates: the source's x, y
axes are mapped to NED with north = x and east = -y (its z points up), so its disc
centre (5, 7) is (north 5, east -7) here. Motors are 0-based as in the source's
allocation (eq. 1.3).

The vehicle is :func:`fault_vehicle`: the catalog hexacopter with ``f_max = 10 N`` per
motor (thrust/weight 3.06). With the catalog's 7 N (thrust/weight 2.14) the two
motors left to hold the attitude in category I give at most 14 N against a weight of
19.6 N, so the vertical impact speed cannot drop below about 0.54 of free fall, and
the one-apart pairs barely hover.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.diagrams.faults import fly_fault
from drake_uav.optimization.fault_response import Category, UnsafeDisc
from drake_uav.optimization.flatness import flat_reference, velocity_heading
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.systems.faults import MotorFailure
from drake_uav.vehicles.multirotor import MultirotorParams, hexacopter

__all__ = ["FAULT_VEHICLE_F_MAX", "fault_vehicle", "FaultScenario", "SCENARIOS",
           "scenario", "scenario_reference", "scenario_tubes", "fly_scenario"]

FAULT_VEHICLE_F_MAX = 10.0
"""Per-motor thrust of the fault vehicle [N]."""


def fault_vehicle(**overrides) -> MultirotorParams:
    """The catalog hexacopter (2 kg, 550 mm) with ``f_max = 10 N`` (thrust/weight 3.06), the
    vehicle of the ch. 6 scenarios (module docstring)."""
    return hexacopter(**{"f_max": FAULT_VEHICLE_F_MAX, **overrides})


@dataclasses.dataclass(frozen=True)
class FaultScenario:
    """One scenario: the mission, the failure, the areas, and the source's category."""

    name: str
    description: str
    failed_motors: tuple[int, ...]
    fault_time: float
    """[s]"""
    waypoints: tuple
    """Mission waypoints NED [m]."""
    mission_time: float
    """[s]"""
    expected: Category
    """The category the source reports."""
    unsafe_disc: UnsafeDisc | None = None
    safe_point: tuple[float, float] = (0.0, 0.0)
    duration: float = 40.0
    """Longest simulated time [s] (a landing ends it earlier)."""
    waypoint_times: tuple | None = None
    """Times of the waypoints [s] (default: equal segments over ``mission_time``)."""
    stops: tuple[int, ...] = ()
    """Waypoints (indices) where the mission stops at rest: the minimum-snap pieces
    between stops are solved apart, so an aggressive piece does not shake the others."""
    upset: tuple | None = None
    """``(start [s], duration [s], torque FRD (3) [N m])``: a torque pulse (a gust or a
    collision) just before the failure that leaves the vehicle outside its recovery tube."""

    def external_wrench(self) -> PiecewisePolynomial | None:
        """The upset as a 6-vector wrench trajectory (force NED, torque FRD), or None."""
        if self.upset is None:
            return None
        start, length, torque = self.upset
        pulse = np.concatenate([np.zeros(3), torque])
        times = [0.0, start, start + 1e-3, start + length, start + length + 1e-3,
                 start + length + 1.0]
        values = np.array([0 * pulse, 0 * pulse, pulse, pulse, 0 * pulse, 0 * pulse])
        return PiecewisePolynomial.FirstOrderHold(times, values.T)

    def failures(self) -> tuple[MotorFailure, ...]:
        """The total failure of :attr:`failed_motors` at :attr:`fault_time`."""
        return (MotorFailure(self.fault_time, self.failed_motors, 0.0),)


def scenario_reference(sc: FaultScenario, params: MultirotorParams,
                       dt: float = 0.005) -> ReferenceTable:
    """Minimum-snap mission through the scenario's waypoints with the velocity heading,
    sampled every ``dt`` [s] by flatness (all motors healthy)."""
    w = np.asarray(sc.waypoints, dtype=float)
    times = np.linspace(0.0, sc.mission_time, len(w)) if sc.waypoint_times is None \
        else np.asarray(sc.waypoint_times, dtype=float)
    bounds = [0, *sc.stops, len(w) - 1]
    states, thrusts = [], []
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        traj = minimum_snap(w[a:b + 1], times[a:b + 1])
        t = np.arange(times[a], times[b] + dt / 2, dt)[0 if k == 0 else 1:]
        ref = flat_reference(traj, params, t, yaw=velocity_heading(traj))
        states.append(ref.state)
        thrusts.append(ref.motor_thrusts)
    state = np.vstack(states)
    return ReferenceTable(dt * np.arange(len(state)), state, np.vstack(thrusts))


_LOOP_8M = ((0.0, 0.0, -8.0), (4.0, 2.0, -8.0), (8.0, 0.0, -8.0), (4.0, -3.0, -8.0),
            (0.0, 0.0, -8.0))
"""A gentle 8 m high loop (20 s): the missions of the scenarios that keep tracking."""

_DASH = ((0.0, 0.0, -8.0), (2.0, 1.0, -8.0), (4.0, 0.0, -8.0), (10.0, 4.0, -8.0),
         (4.0, 8.0, -8.0), (0.0, 0.0, -8.0))
_DASH_TIMES = (0.0, 4.0, 8.0, 9.6, 11.2, 13.5)
"""A gentle start to a stop at 8 s, then a fast loop (banks to 59 deg, 8.6 m/s): the
remaining mission of the category-III scenarios."""

SCENARIOS: dict[str, FaultScenario] = {sc.name: sc for sc in (
    FaultScenario("I", "motors 3 and 4 (adjacent: no closure) at 10 s, 10 m up",
                  (3, 4), 10.0, ((0.0, 0.0, -10.0), (4.0, 2.0, -10.0), (8.0, 0.0, -10.0),
                                 (4.0, -3.0, -10.0), (0.0, 0.0, -10.0)), 20.0, Category.I),
    FaultScenario("IIa", "motors 0 and 3 at 3 s, just after an upset (a roll torque of 4.25 N m "
                  "for 0.22 s) in a dash towards the unsafe disc (10, 0) R 6; free fall "
                  "would land inside", (0, 3), 3.0, ((0.0, 0.0, -8.0), (12.0, 0.0, -8.0)),
                  8.0, Category.II, UnsafeDisc((10.0, 0.0), 6.0),
                  upset=(2.78, 0.22, (4.25, 0.0, 0.0))),
    FaultScenario("IIb", "motors 1 and 5 at 3 s, just after an upset (a roll torque of 4.25 N m "
                  "for 0.22 s); unsafe disc (5, 7) R 5 (NED (5, -7)); free fall would land "
                  "outside", (1, 5), 3.0, ((0.0, 0.0, -8.0), (12.0, 4.0, -8.0)), 8.0,
                  Category.II, UnsafeDisc((5.0, -7.0), 5.0), upset=(2.78, 0.22, (4.25, 0.0, 0.0))),
    FaultScenario("IIIa", "motors 0 and 3 at 7 s, before a fast loop (banks to 59 deg) that "
                  "comes too close to the recovery tube's boundary; land at (0, 0)", (0, 3),
                  7.0, _DASH, 13.5, Category.III, waypoint_times=_DASH_TIMES, stops=(2,)),
    FaultScenario("IIIb", "motors 3 and 5 at 7 s, before the same fast loop; land at (0, 0)",
                  (3, 5), 7.0, _DASH, 13.5, Category.III, waypoint_times=_DASH_TIMES,
                  stops=(2,)),
    FaultScenario("IVa", "motor 2 at 4 s; keep tracking", (2,), 4.0, _LOOP_8M, 20.0,
                  Category.IV, duration=22.0),
    FaultScenario("IVb", "motors 2 and 4 at 4 s; keep tracking (yaw rate sacrificed)",
                  (2, 4), 4.0, _LOOP_8M, 20.0, Category.IV, duration=22.0),
)}
"""The seven scenarios of Argyropoulos 2020, ch. 6, by name."""


def scenario(name: str) -> FaultScenario:
    """The scenario called ``name`` (``"I"``, ``"IIa"``, ... ``"IVb"``); raises
    ``ValueError`` listing the names for an unknown one."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown fault scenario {name!r}; choose one of "
                         f"{', '.join(SCENARIOS)}") from None


def scenario_tubes(params: MultirotorParams, settings=None, cache_dir=None):
    """``tube_for(failed_motors) -> value function`` of the recovery tubes of ``params``
    (:func:`~drake_uav.optimization.reachability.recovery_tube`, cached on disk and in
    memory), as :func:`~drake_uav.diagrams.faults.fly_fault` takes it."""
    from drake_uav.optimization.reachability import recovery_tube

    tubes: dict = {}

    def tube_for(failed):
        key = tuple(sorted(failed))
        if key not in tubes:
            tubes[key] = recovery_tube(params, key, settings, cache_dir=cache_dir).value
        return tubes[key]

    return tube_for


def fly_scenario(sc: FaultScenario | str, params: MultirotorParams | None = None, *,
                 tube_for=None, duration: float | None = None, **kwargs):
    """Flies scenario ``sc`` (or its name) with :func:`~drake_uav.diagrams.faults.fly_fault`
    on :func:`fault_vehicle` (or ``params``) for ``duration`` [s] (default the
    scenario's); ``tube_for`` defaults to :func:`scenario_tubes`; other keyword
    arguments go to ``fly_fault``."""
    sc = scenario(sc) if isinstance(sc, str) else sc
    params = params or fault_vehicle()
    tube_for = tube_for or scenario_tubes(params)
    return fly_fault(params, scenario_reference(sc, params), sc.failures(),
                     duration or sc.duration,
                     tube_for=tube_for, unsafe_disc=sc.unsafe_disc, safe_point=sc.safe_point,
                     external_wrench=sc.external_wrench(), **kwargs)
