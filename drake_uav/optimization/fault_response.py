"""Motor-failure categories I-IV and the controller of each (Argyropoulos 2020, sec. 5.3).

At the fault time the failure is classified (:func:`classify_fault`):

* I: the healthy motors lose closure (:func:`~drake_uav.optimization.allocation.
  closure_holds`): the attitude cannot be held, impact is unavoidable; minimise the
  vertical impact speed;
* II also escapes when the free-fall point is outside the disc but the landing ahead
  along the direction of motion would end inside it (the source lands keeping the
  direction, which may lead into the disc);
* II also when closure holds but the healthy motors cannot carry the weight with zero yaw
  torque (the hexacopter's alternating triples, whose motors all turn the same way): the
  vehicle hovers only spinning faster and faster (the model has no yaw damping), so it
  lands at once; this case is not in the source;
* II: closure holds but the state is outside the recovery tube (hover cannot be reached
  in time): escape logic (eq. 5.17-5.25, :mod:`drake_uav.optimization.escape`);
* III: inside the tube, but the remaining reference leaves it by more than a margin:
  stop, hover-move to a safe point, land there;
* IV: otherwise keep tracking the reference.

The priority of outcomes (ch. 7) is track > land safely > avoid the unsafe area >
minimise the impact speed: each category aims at the highest outcome its state allows.

:class:`FaultResponse` is the controller of every phase, one NMPC
(:class:`~drake_uav.optimization.nmpc.TrackingNmpc`, no terminal set, yaw free after
the fault) whose reference and weights change with the phase:

=====  ==================  ==========================================================
phase  name                objective
=====  ==================  ==========================================================
0      ``tracking``        the mission reference (before the fault; IV after it,
                           optionally with the recovery tube as terminal region)
1      ``impact``          I: vertical descent reference, weights on the vertical
                           position and speed and on the tilt only
2      ``escape``          II: attitude ``q_d`` of eq. 5.23-5.24 (weights on
                           ``q_e,x``, ``q_e,y`` and the roll/pitch rates only) at the
                           maximum thrust of LP 5.22, until outside the disc with an
                           outward velocity
3      ``landing``         II: land ahead along the horizontal velocity (direction kept)
4      ``safe_landing``    III: stop, move to the safe point, land there
=====  ==================  ==========================================================

It never raises from :meth:`FaultResponse.step`: a failed NMPC solve applies the
NMPC's own fallback (the reference thrusts on the healthy motors); an exception while
switching or planning keeps the previous objective and, failing that, applies the
hover thrusts of the healthy motors (:meth:`FaultResponse.fallback_thrusts`).
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable

import numpy as np

from drake_uav.optimization.allocation import (
    canonical_failed_motors,
    closure_holds,
    max_thrust,
    max_thrust_allocation,
)
from drake_uav.optimization.escape import (
    altitude_hold_thrust,
    escape_attitude,
    free_fall_impact,
    outward_direction,
)
from drake_uav.optimization.fault_plans import (
    LandingSettings,
    landing_waypoints,
    moving_landing_waypoints,
    plan_reference,
    stop_point,
)
from drake_uav.optimization.nmpc import NmpcSettings, SublevelTerminal, TrackingNmpc
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["REFERENCE_MARGIN", "Category", "Phase", "UnsafeDisc", "FaultClassification",
           "classify_fault", "failed_from_health", "FaultResponseSettings", "FaultResponse"]


REFERENCE_MARGIN = -0.9
"""Default category-III margin on the tube value: every remaining reference state must
have a tube value at most this. The value ``V(x) = min_t l(x(t))`` (best control, worst
yaw rate) with ``l = max(tilt / theta_th, rate / omega_th) - 1`` near the target, so
``V <= -0.9`` says the failed vehicle can bring that state to within a tenth of the
target's tilt and rate bounds within the horizon. A
reference merely inside the tube (``V <= 0``) may be one the vehicle only just
recovers from; tracking errors after a failure add to it."""


class Category(enum.IntEnum):
    """Fault category of Argyropoulos 2020, sec. 5.3 (0: no fault yet)."""

    NONE = 0
    I = 1  # noqa: E741 - the source's name
    II = 2
    III = 3
    IV = 4


class Phase(enum.IntEnum):
    """Objective of :class:`FaultResponse` (module docstring)."""

    TRACKING = 0
    IMPACT = 1
    ESCAPE = 2
    LANDING = 3
    SAFE_LANDING = 4


@dataclasses.dataclass(frozen=True)
class UnsafeDisc:
    """A circular area on the ground to avoid: ``center`` (north, east) [m], ``radius`` [m]."""

    center: tuple[float, float]
    radius: float

    def __post_init__(self):
        c = np.asarray(self.center, dtype=float)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise ValueError(f"unsafe_disc.center must be (north, east) [m], got {self.center}")
        if not (np.isfinite(self.radius) and self.radius >= 0):
            raise ValueError(f"unsafe_disc.radius must be a non-negative length [m], got "
                             f"{self.radius}")

    def contains(self, point) -> bool:
        """True when the horizontal ``point`` (north, east) [m] is inside the disc."""
        return bool(np.linalg.norm(np.asarray(point, float)[:2] - self.center) < self.radius)


def failed_from_health(health) -> tuple[int, ...]:
    """Motors counted as failed for the classification: health below 0.5 (a motor at half
    its thrust or more still helps closure; the replay draws the same threshold)."""
    return tuple(int(i) for i in np.flatnonzero(np.asarray(health, dtype=float) < 0.5))


@dataclasses.dataclass(frozen=True)
class FaultClassification:
    """Outcome of :func:`classify_fault`."""

    category: Category
    closure: bool
    state_value: float
    """Tube value at the fault state (<= 0 inside; nan when closure fails)."""
    reference_value: float
    """Largest tube value along the remaining reference (nan when not evaluated)."""


def classify_fault(params: MultirotorParams, failed_motors, state,
                   remaining_reference, tube_value: Callable[[np.ndarray], float] | None,
                   margin: float = REFERENCE_MARGIN) -> FaultClassification:
    """Category of a failure at ``state`` (13) (Argyropoulos 2020, sec. 5.3).

    Parameters
    ----------
    params : MultirotorParams
    failed_motors : iterable of int
        0-based failed motors (the supervisor is told them at the fault time).
    state : array (13)
        Plant state at the fault.
    remaining_reference : array (k, 13)
        Reference states from the fault time to the end.
    tube_value : callable or None
        Value of the recovery tube of this failure set at a state (<= 0 inside), e.g.
        ``RecoveryTube.value``; needed unless closure fails.
    margin : float
        Category III when the largest tube value along the remaining reference exceeds
        this (the tube's value units; :data:`REFERENCE_MARGIN` by default, negative: the
        reference must stay that deep inside).

    Raises
    ------
    ValueError
        Unknown motor index, or no tube where closure holds.
    """
    failed = canonical_failed_motors(params, failed_motors)
    if not closure_holds(params, failed):
        return FaultClassification(Category.I, False, np.nan, np.nan)
    if max_thrust(params, failed, yaw_free=False) < params.weight:
        # hover only spinning, faster and faster (no yaw damping): land at once
        return FaultClassification(Category.II, True, np.nan, np.nan)
    if tube_value is None:
        raise ValueError(f"tube is required to classify a failure of motors {list(failed)} "
                         "with closure (categories II-IV)")
    value = float(tube_value(np.asarray(state, dtype=float)))
    if value > 0:
        return FaultClassification(Category.II, True, value, np.nan)
    ref = np.atleast_2d(np.asarray(remaining_reference, dtype=float))
    worst = max(float(tube_value(x)) for x in ref) if len(ref) else -np.inf
    category = Category.III if worst > margin else Category.IV
    return FaultClassification(category, True, value, worst)


@dataclasses.dataclass(frozen=True)
class FaultResponseSettings:
    """Weights and gains of :class:`FaultResponse` (error layout of the NMPC: position,
    attitude, velocity, rates; the source gives none)."""

    nmpc: NmpcSettings = NmpcSettings(period=0.0125)
    """Horizon, nodes, period and the nominal (pre-fault) weights. The period is half the
    shooting interval (80 Hz, 40 nodes over 1 s): after an unbalanced failure the vehicle
    spins (5-6 rad/s within 18 s for motors 2 and 4), and at 40 Hz the body turns 8 deg
    between two commands, which doubles the position error; fault-free tracking is the same
    at both rates (its error is the state noise's)."""
    tracking_weight: tuple = (20.0,) * 3 + (5.0, 5.0, 0.0) + (2.0,) * 3 + (0.2, 0.2, 0.02)
    """IV (and the landing phases): the nominal weights with the yaw free (no weight on
    the yaw error) and a light weight on the yaw rate. An unbalanced failure (motors 2
    and 4) leaves a yaw torque to be traded against the position: with the yaw rate
    weighed like the roll and pitch rates the controller lets the vehicle sink rather
    than spin (about 4x the fault-free position error); with no weight the spin of a
    long flight has no bound (the model has no yaw damping)."""
    impact_weight: tuple = (0.0, 0.0, 20.0) + (5.0, 5.0, 0.0) + (0.0, 0.0, 10.0) \
        + (0.2, 0.2, 0.0)
    """I: altitude, tilt, vertical speed and roll/pitch rates only."""
    escape_weight: tuple = (0.0,) * 3 + (10.0, 10.0, 0.0) + (0.0,) * 3 + (0.2, 0.2, 0.0)
    """II escape: ``q_e,x``, ``q_e,y`` and the roll/pitch rates only (eq. 5.25)."""
    bounds: tuple = (np.inf,) * 12
    """State box of the OCP after the failure (error layout, upper bounds): none by
    default. The nominal box bounds the yaw error, which is free after a failure, and a
    box the state already violates at the fault makes every OCP infeasible."""
    altitude_gains: tuple[float, float] = (1.0, 2.0)
    """``k1`` [1/s^2], ``k2`` [1/s] of the escape's altitude hold (eq. 5.21): poles at
    -1, -1."""
    landing: LandingSettings = LandingSettings()
    tube_terminal: bool = False
    """Category IV with the recovery tube as terminal region (the source's choice). Off by
    default: the tube's value grows with a yaw rate beyond its limit, which the failures
    that must spin exceed, so the region fights the spin they need (motors 2 and 4 failed
    then leave the mission and touch the ground; docs/faults.md)."""
    yaw_allocation_weight: float = 0.1
    """Weight of the yaw-torque row when the mission's wrench is allocated on the healthy
    motors and they cannot produce all of it (thrust and roll/pitch torques weigh 1): the
    yaw is the axis given up after a failure."""
    escape_max_tilt: float = np.radians(35.0)
    """Largest escape tilt [rad]: eq. 5.23 gives ``cos phi = F_z / F_max``, 60 deg for an
    opposite pair of this vehicle; above the cap the thrust is lowered to ``F_z / cos
    phi_max`` instead (a deviation: the source has no cap)."""
    escape_time_limit: float = 10.0
    """Longest escape [s]; then the vehicle lands where it goes."""

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        self.nmpc.validate()
        self.landing.validate()
        if len(self.altitude_gains) != 2 or min(self.altitude_gains) <= 0:
            raise ValueError(f"FaultResponseSettings.altitude_gains must be two positive "
                             f"gains, got {self.altitude_gains}")
        if not 0 < self.escape_max_tilt < np.pi / 2:
            raise ValueError("FaultResponseSettings.escape_max_tilt must be in (0, pi/2) rad")
        if not self.escape_time_limit > 0:
            raise ValueError("FaultResponseSettings.escape_time_limit must be positive")


class FaultResponse:
    """The controller of the module docstring.

    Parameters
    ----------
    params : MultirotorParams
    reference : ReferenceTable
        The mission (time from 0 at the start of the flight).
    settings : FaultResponseSettings, optional
    unsafe_disc : UnsafeDisc, optional
        The area category II avoids.
    safe_point : (north, east), optional
        Where category III lands [m] (default the origin).
    tube_for : callable, optional
        ``tube_for(failed_motors) -> value function`` of the recovery tube: with
        ``settings.tube_terminal``, category IV keeps tracking with the tube as terminal
        region (:class:`~drake_uav.optimization.nmpc.SublevelTerminal`).
    """

    def __init__(self, params: MultirotorParams, reference: ReferenceTable,
                 settings: FaultResponseSettings | None = None,
                 unsafe_disc: UnsafeDisc | None = None, safe_point=(0.0, 0.0),
                 tube_for: Callable | None = None):
        self.settings = settings or FaultResponseSettings()
        self.settings.validate()
        self.params, self.reference = params, reference
        self.unsafe_disc, self.safe_point = unsafe_disc, np.asarray(safe_point, dtype=float)
        self.tube_for = tube_for
        self.mpc = TrackingNmpc(params, None, self.settings.nmpc, reference=reference)
        self.phase, self.category = Phase.TRACKING, Category.NONE
        self.health = np.ones(params.num_motors)
        self.failed: tuple[int, ...] = ()
        self.last_thrusts = reference.at(0.0)[1]
        self._escape: dict = {}

    # ------------------------------------------------------------------ switching
    def switch(self, t: float, x, health, category: Category) -> None:
        """Takes the objective of ``category`` at time ``t`` [s] from state ``x`` (13)
        with motor ``health`` (n); never raises (keeps the previous objective on error)."""
        try:
            self._switch(t, np.asarray(x, dtype=float), np.asarray(health, dtype=float),
                         Category(int(category)))
        except (ValueError, RuntimeError, ArithmeticError, OSError, np.linalg.LinAlgError):
            self.category = Category(int(category))  # not tried again at every step

    def _switch(self, t, x, health, category):
        s = self.settings
        self.category, self.health = category, health
        self.failed = failed_from_health(health)
        weight = s.tracking_weight
        region = None
        if category == Category.IV and self.tube_for is not None and s.tube_terminal:
            region = SublevelTerminal(self.tube_for(self.failed))
        self.mpc = TrackingNmpc(self.params, None, dataclasses.replace(
            s.nmpc, state_weight=weight), reference=self._healthy_reference(health),
            health=health,
            bounds=np.asarray(s.bounds, dtype=float), terminal_region=region)
        if category == Category.IV:
            self.phase = Phase.TRACKING
        elif category == Category.I:
            self._plan(t, x, *self._impact_waypoints(x), s.impact_weight, Phase.IMPACT,
                       max_thrust_allocation(self.params, self.failed) * (health > 0))
        elif category == Category.III:
            self._plan(t, x, *landing_waypoints(x[:3], x[7:10], self.safe_point, s.landing),
                       weight, Phase.SAFE_LANDING)
        elif category == Category.II:
            impact = free_fall_impact(x[:3], x[7:10], self.params.gravity)
            ahead = moving_landing_waypoints(x[:3], x[7:10], s.landing)[0][0]
            if self.unsafe_disc is not None and (self.unsafe_disc.contains(impact.point)
                                                 or self.unsafe_disc.contains(ahead)):
                self._escape = dict(start=t, altitude=-x[2], allocation=max_thrust_allocation(
                    self.params, self.failed) * (health > 0))
                self.phase = Phase.ESCAPE
                self.mpc.set_objective(state_weight=s.escape_weight)
            else:
                self._land_ahead(t, x)

    def _healthy_reference(self, health) -> ReferenceTable:
        """The mission with its reference wrench (thrust and torques) allocated anew on the
        healthy motors: its thrusts are the NMPC's input reference, so thrusts left on the
        failed motors' share would pull every step towards an unbalanced yaw torque. Where
        the healthy motors cannot produce the wrench, the yaw torque gives way first
        (:attr:`FaultResponseSettings.yaw_allocation_weight`)."""
        wrench = self.reference.thrusts @ self.params.allocation_matrix.T
        thrusts = self.params.thrusts_for_wrench(
            wrench, health, yaw_weight=self.settings.yaw_allocation_weight)
        return ReferenceTable(self.reference.time, self.reference.state, thrusts)

    def _impact_waypoints(self, x):
        """Stop the horizontal motion and descend straight down."""
        s = self.settings.landing
        stop, t_stop = stop_point(x[:3], np.array([x[7], x[8], 0.0]), s)
        height = max(-x[2], 0.0) + s.touchdown_depth
        ground = np.array([stop[0], stop[1], s.touchdown_depth])
        return np.array([ground]), np.array([max(t_stop, s.final_descent_time,
                                                 height / s.descent_speed)])

    def _land_ahead(self, t, x):
        self._plan(t, x, *moving_landing_waypoints(x[:3], x[7:10], self.settings.landing),
                   self.settings.tracking_weight, Phase.LANDING)

    def _plan(self, t, x, waypoints, durations, weight, phase, allocation=None):
        """Flies a plan; with ``allocation`` (n) [N] the reference thrusts are that
        allocation scaled to the plan's total thrust (category I: the only thrusts that
        leave the attitude alone, e.g. the pair opposite each other)."""
        # The plan starts at zero acceleration: the acceleration under the thrust just lost
        # would make it fall with the vehicle, and the one the current attitude gives at
        # hover thrust (up to g tan 35 deg after an escape) would make it keep accelerating;
        # the NMPC's attitude error absorbs the jump instead.
        ref = plan_reference(self.params, x, np.zeros(3), waypoints, durations, self.health,
                             self.settings.landing)
        if allocation is not None and allocation.sum() > 0:
            total = ref.thrusts.sum(axis=1, keepdims=True)
            ref = ReferenceTable(ref.time, ref.state, allocation * np.clip(
                total / allocation.sum(), 0.0, 1.0))
        self.mpc.set_objective(reference=ref, start_time=t, state_weight=weight)
        self.phase = phase

    # ------------------------------------------------------------------ per step
    def step(self, t: float, x) -> tuple[np.ndarray, str, float]:
        """Thrusts [N] (n), the NMPC status and its solve time [s] at time ``t`` [s] from
        state ``x`` (13)."""
        x = np.asarray(x, dtype=float)
        solve_time = 0.0
        try:
            if self.phase == Phase.ESCAPE:
                self._escape_objective(t, x)
            result = self.mpc.solve(t, x)
            u, status, solve_time = result.thrusts, result.status, result.solve_time
        except (ValueError, RuntimeError, np.linalg.LinAlgError, ArithmeticError):
            u, status = self.fallback_thrusts(), "failed"
        if not np.all(np.isfinite(u)):
            u, status = self.fallback_thrusts(), "failed"
        self.last_thrusts = u
        return u, status, solve_time

    def _escape_objective(self, t, x):
        """Eq. 5.19-5.25 at the current state; leaves for the landing once outside the disc
        with an outward velocity (or after ``escape_time_limit``)."""
        s, e, disc = self.settings, self._escape, self.unsafe_disc
        d = outward_direction(x[:3], disc.center)
        outside = not disc.contains(x[:2]) and float(x[7:9] @ d) > 0
        if outside or t - e["start"] > s.escape_time_limit:
            self._land_ahead(t, x)
            return
        F_max = float(e["allocation"].sum())
        Fz = altitude_hold_thrust(-x[2], -x[9], e["altitude"], self.params.mass,
                                  self.params.gravity, s.altitude_gains)
        F = min(F_max, Fz / np.cos(s.escape_max_tilt))
        q_d, _ = escape_attitude(x[:3], disc.center, Fz, F)
        target = np.concatenate([x[:3], q_d, x[7:10], np.zeros(3)])
        dt = s.nmpc.horizon + s.nmpc.period
        thrusts = e["allocation"] * (F / F_max if F_max > 0 else 0.0)
        ref = ReferenceTable([0.0, dt], np.vstack([target, target]),
                             np.vstack([thrusts, thrusts]))
        self.mpc.set_objective(reference=ref, start_time=t)

    def fallback_thrusts(self) -> np.ndarray:
        """Equal thrusts on the healthy motors that sum to the weight, within bounds."""
        healthy = self.health > 0
        share = self.params.weight / max(float(self.health[healthy].sum()), 1e-9)
        return np.where(healthy, min(share, self.params.f_max), 0.0)
