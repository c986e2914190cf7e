"""Tracking NMPC as a periodic Drake controller, with the local LTV law as fallback."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_uav.model.multirotor import STATE_SIZE
from drake_uav.optimization.nmpc import NmpcSettings, TrackingNmpc
from drake_uav.optimization.terminal_set import TerminalSet
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["NmpcController", "STATUS_SOLVED", "STATUS_FALLBACK_INFEASIBLE",
           "STATUS_FALLBACK_FAILED"]

STATUS_SOLVED = 0.0
"""The NMPC solved; its first input is applied."""
STATUS_FALLBACK_INFEASIBLE = 1.0
"""The OCP was infeasible; the saturated local law ``u = K(t) e + u_r`` is applied."""
STATUS_FALLBACK_FAILED = 2.0
"""The solver failed otherwise (or raised); the saturated local law is applied."""


class NmpcController(LeafSystem):
    """Periodic tracking NMPC (Argyropoulos 2020, ch. 4).

    ==================  ====  ==============================================
    Input port          Size  Content [unit]
    ==================  ====  ==============================================
    ``state``           13    plant state (or its estimate): p NED [m],
                              q (w, x, y, z), v NED [m/s], omega FRD [rad/s]
    ==================  ====  ==============================================

    ==================  ====  ==============================================
    Output port         Size  Content [unit]
    ==================  ====  ==============================================
    ``motor_thrusts``   n     thrust commands [N], within [0, f_max]
    ``status``          1     0 solved, 1 fallback (infeasible), 2 fallback
                              (solver failure)
    ``solve_time``      1     wall time of the step [s]
    ==================  ====  ==============================================

    Every ``settings.period`` [s] (40 Hz by default) the OCP is solved from the
    state; the outputs hold until the next period. On infeasibility or failure
    the controller applies ``u = K(t) e + u_r(t)`` saturated to the thrust bounds,
    with the position error limited to ``fallback_position_limit`` [m] (the law is
    local; far from the reference an unlimited error would command full tilt).
    It never raises inside a simulation.
    """

    def __init__(self, params: MultirotorParams, terminal: TerminalSet,
                 settings: NmpcSettings | None = None, fallback_position_limit: float = 1.0):
        super().__init__()
        self.mpc = TrackingNmpc(params, terminal, settings)
        self.terminal = terminal
        self.fallback_position_limit = float(fallback_position_limit)
        n = params.num_motors
        self._f_max = params.f_max * (terminal.health > 0)
        _, u0 = terminal.reference.at(0.0)
        self._state = self.DeclareVectorInputPort("state", STATE_SIZE)
        self._memory = self.DeclareDiscreteState(BasicVector(np.concatenate([u0, [0.0, 0.0, 0.0]])))
        self.DeclarePeriodicDiscreteUpdateEvent(self.mpc.settings.period, 0.0, self._update)
        # thrusts, status, solve time, terminal ratio e_N^T P~ e_N / pi~^2 (inf: no solution)
        self.DeclareStateOutputPort("all", self._memory)
        self.DeclareVectorOutputPort("motor_thrusts", n, self._thrusts,
                                     prerequisites_of_calc={self.xd_ticket()})
        self.DeclareVectorOutputPort("status", 1, lambda c, o: o.SetAtIndex(
            0, c.get_discrete_state_vector().GetAtIndex(n)),
            prerequisites_of_calc={self.xd_ticket()})
        self.DeclareVectorOutputPort("solve_time", 1, lambda c, o: o.SetAtIndex(
            0, c.get_discrete_state_vector().GetAtIndex(n + 1)),
            prerequisites_of_calc={self.xd_ticket()})
        self.n = n

    def _thrusts(self, context, output):
        output.SetFromVector(context.get_discrete_state_vector().value()[:self.n])

    def fallback(self, t: float, x) -> np.ndarray:
        """The saturated local law ``K(t) e + u_r`` with the limited position error."""
        xr, _ = self.terminal.reference.at(t)
        x = np.array(x, dtype=float)
        d = x[:3] - xr[:3]
        norm = np.linalg.norm(d)
        if norm > self.fallback_position_limit:
            x[:3] = xr[:3] + d * (self.fallback_position_limit / norm)
        return np.clip(self.terminal.feedback(t, x), 0.0, self._f_max)

    def _update(self, context, discrete_state):
        t = context.get_time()
        x = self._state.Eval(context)
        try:
            result = self.mpc.solve(t, x)
            if result.success:
                values = np.concatenate([result.thrusts, [STATUS_SOLVED, result.solve_time,
                                                            result.terminal_ratio]])
            else:
                code = STATUS_FALLBACK_INFEASIBLE if result.status == "infeasible" \
                    else STATUS_FALLBACK_FAILED
                values = np.concatenate([self.fallback(t, x), [code, result.solve_time, np.inf]])
        except Exception:  # noqa: BLE001 - a controller never raises inside a simulation
            try:
                u = self.fallback(t, x)
            except Exception:  # noqa: BLE001
                u = np.clip(self.terminal.reference.at(t)[1], 0.0, self._f_max)
            values = np.concatenate([u, [STATUS_FALLBACK_FAILED, 0.0, np.inf]])
        if not np.all(np.isfinite(values[:self.n])):
            values[:self.n] = np.clip(self.terminal.reference.at(t)[1], 0.0, self._f_max)
            values[self.n] = STATUS_FALLBACK_FAILED
        discrete_state.get_mutable_vector().SetFromVector(values)
