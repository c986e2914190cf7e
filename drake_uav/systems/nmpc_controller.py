"""Tracking NMPC as a periodic Drake controller, with the local LTV law as fallback."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_uav.model.attitude_error import state_error
from drake_uav.model.multirotor import STATE_SIZE
from drake_uav.optimization.nmpc import NmpcSettings, TrackingNmpc
from drake_uav.optimization.terminal_set import TerminalSet
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["NmpcController", "STATUS_SOLVED", "STATUS_FALLBACK_INFEASIBLE",
           "STATUS_FALLBACK_FAILED"]

STATUS_SOLVED = 0.0
"""The NMPC solved; its first input is applied."""
STATUS_FALLBACK_INFEASIBLE = 1.0
"""The OCP was infeasible: the first input of the OCP without the terminal constraint
is applied (``NmpcSettings.relax_terminal``), or, when that fails too or relaxing is
off, the saturated local law ``u = K(t) e + u_r``."""
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
    ``status``          1     0 solved, 1 terminal set unreachable (relaxed
                              OCP or local law), 2 solver failure (local law)
    ``solve_time``      1     wall time of the step [s]
    ==================  ====  ==============================================

    Every ``settings.period`` [s] (40 Hz by default) the OCP is solved from the
    state; the outputs hold until the next period. An infeasible OCP is solved
    again without its terminal constraint (``settings.relax_terminal``); if that
    fails too, or on any other failure, the controller applies ``u = K(t) e + u_r(t)``
    saturated to the thrust bounds; with ``scale_error`` the error is first scaled
    onto the terminal level set (the law is certified there only; far outside it
    destabilises the vehicle within seconds). It never raises inside a simulation.
    """

    def __init__(self, params: MultirotorParams, terminal: TerminalSet,
                 settings: NmpcSettings | None = None, scale_error: bool = False):
        super().__init__()
        self.mpc = TrackingNmpc(params, terminal, settings)
        self.terminal = terminal
        self.scale_error = bool(scale_error)
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
        """The saturated local law ``K(t) e + u_r`` on the error scaled into the terminal
        level set (``e sqrt(min(1, pi~^2 / V(t, e)))``, the region where the law is
        certified) when ``scale_error`` is set; otherwise on the error itself."""
        xr, ur = self.terminal.reference.at(t)
        x = np.asarray(x, dtype=float)
        if x[3:7] @ xr[3:7] < 0:
            x = np.concatenate([x[:3], -x[3:7], x[7:]])
        e = state_error(x, xr)
        Pt, K, level = self.terminal.matrices_at(t)
        V = float(e @ Pt @ e)
        if self.scale_error and V > level**2:
            e = e * (level / np.sqrt(V))
        return np.clip(K @ e + ur, 0.0, self._f_max)

    def _update(self, context, discrete_state):
        t = context.get_time()
        x = self._state.Eval(context)
        try:
            result = self.mpc.solve(t, x)
            if result.success or result.status == "relaxed":
                code = STATUS_SOLVED if result.success else STATUS_FALLBACK_INFEASIBLE
                values = np.concatenate([result.thrusts, [code, result.solve_time,
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
