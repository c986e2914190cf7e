"""Motor failures in a diagram: injection, classification, fault-tolerant control
(Argyropoulos 2020, sec. 5.3).

``FaultInjector`` -> plant ``motor_health``; ``FaultSupervisor`` reads the health and the
state and classifies the failure at the fault time; ``FaultTolerantController`` takes
the category and flies its objective (:mod:`drake_uav.optimization.fault_response`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_uav.model.multirotor import STATE_SIZE
from drake_uav.optimization.fault_response import (
    REFERENCE_MARGIN,
    Category,
    FaultResponse,
    classify_fault,
    failed_from_health,
)
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["MotorFailure", "FaultInjector", "FaultSupervisor", "FaultTolerantController",
           "SUPERVISOR_SIZE", "CONTROLLER_STATUS"]


@dataclasses.dataclass(frozen=True)
class MotorFailure:
    """Motors that lose thrust at ``time`` [s]: ``health`` 0 is a total failure, between 0
    and 1 a partial one (the fraction of the commanded thrust they still produce)."""

    time: float
    motors: tuple[int, ...]
    health: float = 0.0

    def validate(self, num_motors: int, name: str = "failure") -> None:
        """Raises ``ValueError`` naming the field (``name.motors``, ``name.health``,
        ``name.time``)."""
        if not (np.isfinite(self.time) and self.time >= 0):
            raise ValueError(f"{name}.time must be a non-negative time [s], got {self.time}")
        if len(self.motors) == 0:
            raise ValueError(f"{name}.motors must name at least one motor")
        for m in self.motors:
            if int(m) != m or not 0 <= m < num_motors:
                raise ValueError(f"{name}.motors: unknown motor index {m} (the vehicle has "
                                 f"motors 0..{num_motors - 1})")
        if not (np.isfinite(self.health) and 0.0 <= self.health <= 1.0):
            raise ValueError(f"{name}.health must be in [0, 1], got {self.health}")


class FaultInjector(LeafSystem):
    """Motor health over time from a schedule of :class:`MotorFailure` (the lowest health
    of every failure in effect; a failure acts from its time on).

    ================  ====  ==============================================
    Output port       Size  Content [unit]
    ================  ====  ==============================================
    ``motor_health``  n     1 healthy, 0 failed, between: partial [-]
    ================  ====  ==============================================

    Raises ``ValueError`` naming the failure and field for an unknown motor, a health
    outside [0, 1] or a negative time.
    """

    def __init__(self, num_motors: int, failures: Sequence[MotorFailure]):
        super().__init__()
        self.failures = tuple(failures)
        for k, f in enumerate(self.failures):
            f.validate(num_motors, f"failures[{k}]")
        self.num_motors = num_motors
        self.DeclareVectorOutputPort("motor_health", num_motors, self._calc,
                                     prerequisites_of_calc={self.time_ticket()})

    def health_at(self, t: float) -> np.ndarray:
        """Motor health (n) at time ``t`` [s]."""
        h = np.ones(self.num_motors)
        for f in self.failures:
            if t >= f.time:
                h[list(f.motors)] = np.minimum(h[list(f.motors)], f.health)
        return h

    def _calc(self, context, output):
        output.SetFromVector(self.health_at(context.get_time()))


SUPERVISOR_SIZE = 5
"""``all`` output of :class:`FaultSupervisor`: category, switch time [s], fault time [s],
tube value at the fault state, largest tube value along the remaining reference."""


class FaultSupervisor(LeafSystem):
    """Classifies a motor failure at the fault time (Argyropoulos 2020, sec. 5.3).

    ==================  ====  ==============================================
    Input port          Size  Content [unit]
    ==================  ====  ==============================================
    ``state``           13    vehicle state
    ``motor_health``    n     health of each motor (the supervisor is told the
                              failure at the fault time)
    ==================  ====  ==============================================

    ==================  ====  ==============================================
    Output port         Size  Content [unit]
    ==================  ====  ==============================================
    ``category``        1     0 before a failure, then 1..4 (I..IV)
    ``switch_time``     1     when the controller takes the category's
                              objective [s] (nan before a failure)
    ``all``             5     :data:`SUPERVISOR_SIZE`
    ==================  ====  ==============================================

    At every ``period`` [s] it compares the health with all ones; at the first period at
    or after a failure it classifies once (:func:`~drake_uav.optimization.fault_response.
    classify_fault`) and holds the category. The ``category`` output already gives the
    new category at that instant (it classifies from its inputs until the update has
    stored the result), so a controller updated at the same instants switches at the
    fault time: the switch time is the first period at or after the failure.

    Parameters
    ----------
    params : MultirotorParams
    reference : ReferenceTable
        The mission, for the category-III test on the remaining reference.
    tube_for : callable or None
        ``tube_for(failed_motors) -> value function`` (state (13) -> float, <= 0 inside
        the recovery tube), e.g. ``lambda f: recovery_tube(params, f).value``.
    period : float
        Update period [s] (the controller's).
    margin : float
        Category-III margin on the tube value (:data:`~drake_uav.optimization.
        fault_response.REFERENCE_MARGIN`).
    category : Category or None
        Forces the category instead of classifying (to fly one category's controller
        whatever the tube says); the classification figures are still computed when a
        tube is given.
    reference_stride : float
        Spacing [s] of the remaining-reference states tested against the tube.
    """

    def __init__(self, params: MultirotorParams, reference: ReferenceTable,
                 tube_for: Callable | None, period: float = 0.025,
                 margin: float = REFERENCE_MARGIN,
                 category: Category | None = None, reference_stride: float = 0.1):
        super().__init__()
        self.params, self.reference, self.tube_for = params, reference, tube_for
        self.margin, self.forced = float(margin), category
        self.reference_stride, self.period = float(reference_stride), float(period)
        self._state = self.DeclareVectorInputPort("state", STATE_SIZE)
        self._health = self.DeclareVectorInputPort("motor_health", params.num_motors)
        self._memory = self.DeclareDiscreteState(
            BasicVector([0.0, np.nan, np.nan, np.nan, np.nan]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._cache: dict = {}
        ticket = {self.xd_ticket(), self.time_ticket(), self._state.ticket(),
                  self._health.ticket()}
        self.DeclareVectorOutputPort("all", SUPERVISOR_SIZE, lambda c, o: o.SetFromVector(
            self._current(c)), prerequisites_of_calc=ticket)
        self.DeclareVectorOutputPort("category", 1, lambda c, o: o.SetAtIndex(
            0, self._current(c)[0]), prerequisites_of_calc=ticket)
        self.DeclareVectorOutputPort("switch_time", 1, lambda c, o: o.SetAtIndex(
            0, self._current(c)[1]), prerequisites_of_calc=ticket)

    def classify(self, t: float, x, health) -> tuple[Category, float, float]:
        """Category, tube value at ``x`` and largest one along the remaining reference for
        a failure seen at ``t`` [s] (the forced category when one was given). A tube
        that cannot be built or evaluated classifies as II (outside: the conservative
        answer), with nan values."""
        failed = failed_from_health(health)
        ref = self.reference
        times = np.arange(max(t, 0.0), ref.end_time + 1e-9, self.reference_stride)
        remaining = ref.at(times)[0] if len(times) else np.empty((0, STATE_SIZE))
        tube = None
        if self.tube_for is not None:
            try:
                tube = self.tube_for(failed)
            except (ValueError, RuntimeError, OSError):
                tube = None
        try:
            result = classify_fault(self.params, failed, x, remaining, tube, self.margin)
            category, sv, rv = result.category, result.state_value, result.reference_value
        except (ValueError, RuntimeError, ArithmeticError):
            category, sv, rv = Category.II, np.nan, np.nan
        if self.forced is not None:
            category = Category(int(self.forced))
        return category, sv, rv

    def _current(self, context) -> np.ndarray:
        """The stored classification, or the one the next update will store (a failure
        seen now), or no failure."""
        memory = context.get_discrete_state_vector().CopyToVector()
        if memory[0] != 0:
            return memory
        health = self._health.Eval(context)
        if np.all(health >= 1.0):
            return memory
        t = context.get_time()
        key = (t, health.tobytes())
        if key not in self._cache:  # the output and the update classify the same instant
            category, sv, rv = self.classify(t, self._state.Eval(context), health)
            self._cache = {key: np.array([float(category), t, t, sv, rv])}
        return self._cache[key]

    def _update(self, context, discrete_state):
        memory = self._current(context)
        discrete_state.get_mutable_vector().SetFromVector(memory)


CONTROLLER_STATUS = {"solved": 0.0, "relaxed": 1.0, "infeasible": 1.0, "failed": 2.0}
"""Status codes of :class:`FaultTolerantController` (as the NMPC controller's)."""


class FaultTolerantController(LeafSystem):
    """Periodic NMPC that flies the mission and, after a failure, its category's
    objective (:class:`~drake_uav.optimization.fault_response.FaultResponse`).

    ==================  ====  ==============================================
    Input port          Size  Content [unit]
    ==================  ====  ==============================================
    ``state``           13    vehicle state
    ``motor_health``    n     motor health (the model's thrust scaling)
    ``category``        1     from :class:`FaultSupervisor` (0: no failure)
    ==================  ====  ==============================================

    ==================  =====  =============================================
    Output port         Size   Content [unit]
    ==================  =====  =============================================
    ``motor_thrusts``   n      commands [N] in [0, f_max], 0 on failed motors
    ``all``             n + 3  thrusts, phase (:class:`Phase`), status (0
                               solved, 1 relaxed, 2 fallback), solve time [s]
    ==================  =====  =============================================

    It never raises inside a simulation (the response's fallbacks, then equal thrusts
    on the healthy motors).
    """

    def __init__(self, response: FaultResponse):
        super().__init__()
        self.response = response
        n = self.n = response.params.num_motors
        self._state = self.DeclareVectorInputPort("state", STATE_SIZE)
        self._health = self.DeclareVectorInputPort("motor_health", n)
        self._category = self.DeclareVectorInputPort("category", 1)
        u0 = response.reference.at(0.0)[1]
        self._memory = self.DeclareDiscreteState(BasicVector(np.concatenate([u0, [0, 0, 0]])))
        self.DeclarePeriodicDiscreteUpdateEvent(response.settings.nmpc.period, 0.0,
                                                self._update)
        self.DeclareStateOutputPort("all", self._memory)
        self.DeclareVectorOutputPort("motor_thrusts", n, self._thrusts,
                                     prerequisites_of_calc={self.xd_ticket()})

    def _thrusts(self, context, output):
        output.SetFromVector(context.get_discrete_state_vector().CopyToVector()[:self.n])

    def _update(self, context, discrete_state):
        t, r = context.get_time(), self.response
        x = self._state.Eval(context)
        category = int(self._category.Eval(context)[0])
        try:
            if category != int(r.category) and category != 0:
                r.switch(t, x, self._health.Eval(context), category)
            u, status, solve_time = r.step(t, x)
            code = CONTROLLER_STATUS.get(status, 2.0)
        except Exception:  # noqa: BLE001 - a controller never raises inside a simulation
            u, code, solve_time = r.fallback_thrusts(), 2.0, 0.0
        discrete_state.get_mutable_vector().SetFromVector(
            np.concatenate([u, [float(r.phase), code, solve_time]]))
