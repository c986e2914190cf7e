"""Reference trajectories flown after a motor failure: stop, move, land (Argyropoulos 2020,
sec. 5.3).

A plan is a chain of single-segment minimum-snap pieces (:func:`minimum_snap` with
its initial derivatives given for the first piece, so the plan starts from the
vehicle's moving state), each sampled by differential flatness on the healthy motors,
joined into one :class:`~drake_uav.optimization.terminal_set.ReferenceTable` whose time
starts at the switch. The last piece ends ``touchdown_depth`` below the ground so
that the vehicle meets the ground while still descending slowly (a reference that
ends on the ground is approached asymptotically and never touches it).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_uav.model.rotations import quat_to_euler
from drake_uav.optimization.flatness import flat_reference
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["LandingSettings", "plan_reference", "stop_point", "landing_waypoints",
           "moving_landing_waypoints"]


@dataclasses.dataclass(frozen=True)
class LandingSettings:
    """Speeds and margins of the post-failure plans (the source gives none)."""

    cruise_speed: float = 1.0
    """Mean speed of a horizontal move [m/s]."""
    braking: float = 1.5
    """Mean deceleration when stopping from a moving state [m/s^2]."""
    approach_altitude: float = 2.0
    """Altitude of the hover point above the landing point [m]."""
    final_descent_time: float = 8.0
    """Duration of the last descent from the approach altitude [s]."""
    descent_speed: float = 1.0
    """Mean vertical speed of a longer descent [m/s]."""
    touchdown_depth: float = 0.2
    """How far below the ground the last piece ends [m]; sets the touchdown speed
    (about 0.5 m/s with the defaults)."""
    min_piece_time: float = 2.0
    """Shortest piece [s]."""
    sample_time: float = 0.01
    """Grid of the reference table [s]."""

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first field that is not positive."""
        for field in dataclasses.fields(self):
            if not getattr(self, field.name) > 0:
                raise ValueError(f"LandingSettings.{field.name} must be positive, got "
                                 f"{getattr(self, field.name)}")


def stop_point(position, velocity, settings: LandingSettings) -> tuple[np.ndarray, float]:
    """Where [m] and after how long [s] a vehicle moving at ``velocity`` [m/s] stops with
    the mean deceleration ``settings.braking`` (no reversal: half the initial speed
    times the time)."""
    p, v = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
    T = max(settings.min_piece_time, 2.0 * np.linalg.norm(v) / settings.braking)
    return p + 0.5 * v * T, float(T)


def landing_waypoints(position, velocity, target, settings: LandingSettings):
    """Stop, hover-move to ``settings.approach_altitude`` above ``target`` (north, east) [m],
    descend: the waypoints (k, 3) NED and piece durations (k,) of Argyropoulos 2020's
    category-III landing (hover, then land at a safe point)."""
    stop, t_stop = stop_point(position, velocity, settings)
    above = np.array([target[0], target[1], -settings.approach_altitude])
    move = max(settings.min_piece_time, np.linalg.norm(above - stop) / settings.cruise_speed)
    ground = np.array([target[0], target[1], settings.touchdown_depth])
    return np.array([stop, above, ground]), np.array([t_stop, move,
                                                       settings.final_descent_time])


def moving_landing_waypoints(position, velocity, settings: LandingSettings):
    """One piece from a moving state to the ground, ahead along the horizontal velocity
    (the direction of motion is kept: the horizontal displacement is half the initial
    horizontal velocity times the duration); the duration follows the descent speed and
    the braking."""
    p, v = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
    height = max(-p[2], 0.0) + settings.touchdown_depth
    T = max(settings.final_descent_time, height / settings.descent_speed,
            2.0 * np.linalg.norm(v[:2]) / settings.braking)
    ground = np.array([p[0] + 0.5 * v[0] * T, p[1] + 0.5 * v[1] * T,
                       settings.touchdown_depth])
    return ground[None], np.array([T])


def plan_reference(params: MultirotorParams, state, acceleration, waypoints, durations,
                   health=None, settings: LandingSettings | None = None) -> ReferenceTable:
    """Reference table (time from 0) through ``waypoints`` (k, 3) NED [m] with piece
    ``durations`` (k,) [s], starting at ``state`` (13) with ``acceleration`` (3) [m/s^2]
    and at rest at every waypoint; constant yaw (the current one); thrusts on the
    motors of ``health`` (n, in [0, 1]).

    Raises ``ValueError`` for non-finite input or durations that are not positive.
    """
    settings = settings or LandingSettings()
    x = np.asarray(state, dtype=float)
    w = np.atleast_2d(np.asarray(waypoints, dtype=float))
    T = np.atleast_1d(np.asarray(durations, dtype=float))
    if len(w) != len(T) or not (np.all(np.isfinite(x)) and np.all(np.isfinite(w))
                                and np.all(T > 0)):
        raise ValueError("plan_reference: state and waypoints must be finite, with one "
                         "positive duration per waypoint")
    yaw = float(quat_to_euler(x[3:7] / np.linalg.norm(x[3:7]))[2])
    dt = settings.sample_time
    start, derivatives = x[:3], np.vstack([x[7:10], np.asarray(acceleration, dtype=float)])
    states, thrusts = [], []
    for k, (goal, duration) in enumerate(zip(w, T, strict=True)):
        duration = dt * max(np.ceil(duration / dt), 2)
        traj = minimum_snap(np.vstack([start, goal]), [0.0, duration],
                            initial_derivatives=derivatives if k == 0 else None)
        t = np.arange(0.0, duration + dt / 2, dt)[0 if k == 0 else 1:]
        ref = flat_reference(traj, params, t, yaw=yaw, health=health)
        states.append(ref.state)
        thrusts.append(ref.motor_thrusts)
        start = goal
    state_table = np.vstack(states)
    for k in range(1, len(state_table)):  # one quaternion sign along the table
        if state_table[k, 3:7] @ state_table[k - 1, 3:7] < 0:
            state_table[k, 3:7] *= -1
    return ReferenceTable(dt * np.arange(len(state_table)), state_table, np.vstack(thrusts))
