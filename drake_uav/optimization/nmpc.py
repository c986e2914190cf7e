"""Tracking NMPC of a multirotor with a time-varying terminal set (Argyropoulos 2020, ch. 3-4).

The optimal control problem (eq. 4.4) over ``T_p`` with ``N`` shooting intervals
of ``h = T_p / N``, states ``X_0..X_N`` (13 each) and motor thrusts
``U_0..U_{N-1}`` as decision variables (multiple shooting)::

    minimise    sum_j h [e_j^T Q_F e_j + (U_j - u_r,j)^T R_F (U_j - u_r,j)],  j = 1..N / 0..N-1
    subject to  X_0 = x(t_k),  X_{j+1} = RK4_h(X_j, U_j),  0 <= U_j <= f_max (failed: 0)
                |theta_e,j| <= bound, |v_j| <= v_max, |omega_j| <= omega_max  (the box of
                the terminal set's ErrorBounds, eq. 4.4d)
                e_N^T (P(t_k + T_p) + I) e_N <= pi~(t_k + T_p)^2                   (eq. 4.4e)

The OCP is general: the terminal set may be left out (``terminal=None``, a reference
table given instead), the state weight ``Q_F`` may be positive semi-definite (zero on
the yaw error and the yaw rate: yaw free, as after a motor failure), the box may bound
each rate axis separately (``bounds``, 12 entries), the reference and the weights can be
replaced between solves (:meth:`TrackingNmpc.set_objective`: a reference that starts at
a fault, a hover point, an escape attitude), and motor health ``h`` scales the
thrusts in the prediction model (``f(x, h u)``, failed motors held at 0).

with ``e_j = state_error(X_j, x_r(t_k + j h))`` (linear in ``X_j``: the attitude
error ``2 vec(q_r* (x) q)`` is linear in ``q``), so the cost is a convex quadratic
and the terminal constraint a second-order cone. The RK4 step is built on
:func:`~drake_uav.model.multirotor.multirotor_dynamics` (compiled, with exact
Jacobians by the chain rule through the four stages). The terminal penalty of
eq. 4.29 depends on time only and is left out (Argyropoulos 2020, sec. 4.4).

Two modes share one program built once (only coefficients change per step):

* ``"nlp"``: the full nonlinear program, warm-started from the shifted solution:
  by default the same SQP step iterated to convergence (Gauss-Newton Hessian,
  which is exact for the cost; its fixed points are KKT points of the NLP), or the
  dynamics as nonlinear constraints with compiled Jacobians for SNOPT or IPOPT;
* ``"rti"``: one SQP step per period (real-time iteration): the dynamics are
  linearised about the shifted previous solution, and the sparse convex QP
  (quadratic cost, linear dynamics, bounds, cone) is solved.

Each QP of the SQP is first solved by a Riccati recursion over the horizon
(:mod:`drake_uav.optimization.riccati_lq`) without its bounds; when that solution
leaves the terminal cone, the cone's multiplier is found from the end-state
sensitivity (the QP's KKT conditions with the cone active). A solution that meets
every thrust bound and state-box row is the QP's unique optimum; otherwise the
QP goes to Clarabel through the ``MathematicalProgram``, whose coefficients are
then updated. Along a reference the bounds are rarely active, so most steps cost
one linearisation and one or two Riccati sweeps.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import (
    ClarabelSolver,
    IpoptSolver,
    MathematicalProgram,
    SnoptSolver,
    SolverOptions,
)
from scipy.optimize import brentq

from drake_uav.model.attitude_error import ERROR_SIZE
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.multirotor import STATE_SIZE, motor_wrench, multirotor_dynamics
from drake_uav.model.rotations import quat_conjugate
from drake_uav.optimization.riccati_lq import solve_lq, terminal_sensitivity
from drake_uav.optimization.terminal_set import (
    ErrorBounds,
    ReferenceTable,
    TerminalSet,
)
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "NmpcSettings",
    "NmpcResult",
    "TrackingNmpc",
    "default_waypoints",
    "rk4_step",
    "positive_semidefinite",
    "SublevelTerminal",
]


def positive_semidefinite(name: str, value, size: int) -> np.ndarray:
    """``value`` as a symmetric positive semi-definite (size, size) matrix (a vector =
    diagonal); raises ``ValueError`` naming ``name`` when it is not (zero weights allowed:
    an error component left free, e.g. yaw after a motor failure)."""
    M = np.asarray(value, dtype=float)
    M = np.diag(M) if M.ndim == 1 else M
    if M.shape != (size, size) or not np.all(np.isfinite(M)):
        raise ValueError(f"{name} must be a finite ({size}, {size}) matrix or {size} "
                         f"diagonal entries, got shape {M.shape}")
    if not np.allclose(M, M.T, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise ValueError(f"{name} must be symmetric")
    smallest = np.linalg.eigvalsh(M).min()
    if smallest < -1e-12 * max(1.0, np.abs(M).max()):
        raise ValueError(f"{name} must be positive semi-definite (smallest eigenvalue "
                         f"{smallest:.3g})")
    return M


def default_waypoints() -> tuple[np.ndarray, float]:
    """A 6-waypoint NED mission [m] (take off to 2 m, a loop, back) and its duration [s]."""
    return np.array([[0, 0, -2], [3, 1, -3], [7, 3, -4], [8, 8, -4], [3, 10, -3],
                     [0, 5, -2]], dtype=float), 20.0


@dataclasses.dataclass(frozen=True)
class NmpcSettings:
    """OCP and solver settings; weights act on the error state of
    :mod:`drake_uav.model.attitude_error` and on the motor thrusts [N]."""

    horizon: float = 1.0
    """Prediction horizon ``T_p`` [s]."""
    nodes: int = 40
    """Shooting intervals ``N``."""
    period: float = 0.025
    """Control period [s]; ``horizon`` must be a multiple of it."""
    state_weight: tuple = (20.0,) * 3 + (5.0,) * 3 + (2.0,) * 3 + (0.2,) * 3
    """``Q_F`` diagonal (12): position [1/m^2], attitude [1/rad^2], velocity, rates;
    positive semi-definite (a zero leaves that error component free)."""
    input_weight: float = 0.05
    """``R_F = input_weight I`` [1/N^2]."""
    mode: str = "rti"
    """``"rti"`` (one SQP step, Clarabel) or ``"nlp"`` (full NLP)."""
    nlp_solver: str = "sqp"
    """Full-NLP solver: ``"sqp"`` (Gauss-Newton SQP iterated to convergence, QPs with
    Clarabel), ``"snopt"`` or ``"ipopt"`` (through ``MathematicalProgram``)."""
    qp_solver: str = "riccati"
    """QPs of the SQP (both modes): ``"riccati"`` solves each by the Riccati recursion
    (:mod:`drake_uav.optimization.riccati_lq`), exact when no thrust bound or state-box
    row is active (the terminal cone may be), and hands the others to Clarabel;
    ``"clarabel"`` gives every QP to Clarabel."""
    max_iterations: int = 20
    """Iteration limit of the full NLP (SQP iterations, SNOPT major iterations)."""
    tolerance: float = 1e-4
    """SQP convergence: largest state / input step and dynamics defect [SI]."""
    relax_terminal: bool = True
    """When the OCP is infeasible, solve it again without the terminal constraint
    (status ``"relaxed"``): far from the reference the local law behind the fallback
    is not stabilising."""

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        if not (self.horizon > 0 and self.period > 0 and self.nodes >= 2):
            raise ValueError("NmpcSettings.horizon, period must be positive and nodes >= 2")
        ratio = self.horizon / self.period
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f"NmpcSettings.horizon = {self.horizon} s is not a multiple of "
                             f"the period {self.period} s")
        positive_semidefinite("NmpcSettings.state_weight", self.state_weight, ERROR_SIZE)
        if not self.input_weight > 0:
            raise ValueError(f"NmpcSettings.input_weight must be positive, got "
                             f"{self.input_weight}")
        if self.mode not in ("rti", "nlp"):
            raise ValueError(f"NmpcSettings.mode must be 'rti' or 'nlp', got {self.mode!r}")
        if self.nlp_solver not in ("sqp", "snopt", "ipopt"):
            raise ValueError(f"NmpcSettings.nlp_solver must be 'sqp', 'snopt' or 'ipopt', "
                             f"got {self.nlp_solver!r}")
        if self.qp_solver not in ("riccati", "clarabel"):
            raise ValueError(f"NmpcSettings.qp_solver must be 'riccati' or 'clarabel', "
                             f"got {self.qp_solver!r}")
        if not (self.max_iterations >= 1 and self.tolerance > 0):
            raise ValueError("NmpcSettings.max_iterations must be >= 1 and tolerance > 0")


@dataclasses.dataclass(frozen=True)
class SublevelTerminal:
    """Terminal region ``{x : value(x) <= level}`` of a scalar function of the state (13),
    e.g. a recovery tube's value (Argyropoulos 2020, sec. 5.3, category IV).

    Each step linearises it at the end state of the warm start (central differences of
    ``step`` per state): the OCP's terminal constraint is the half-space
    ``value(x_g) + grad^T (x_N - x_g) <= level``; where the gradient vanishes (deep
    inside or outside a flat region) no constraint is added.
    """

    value: Callable[[np.ndarray], float]
    level: float = 0.0
    step: float = 1e-4

    def linearise(self, x) -> tuple[np.ndarray, float] | None:
        """``(a, b)`` of the half-space ``a^T x_N <= b`` at ``x``, or None (flat)."""
        x = np.asarray(x, dtype=float)
        v = float(self.value(x))
        grad = np.empty(STATE_SIZE)
        for i in range(STATE_SIZE):
            e = np.zeros(STATE_SIZE)
            e[i] = self.step
            grad[i] = (float(self.value(x + e)) - float(self.value(x - e))) / (2 * self.step)
        if not (np.isfinite(v) and np.all(np.isfinite(grad))) or not grad.any():
            return None
        return grad, float(self.level - v + grad @ x)


@dataclasses.dataclass(frozen=True)
class NmpcResult:
    """Outcome of one solve; ``status`` is ``"solved"``, ``"relaxed"`` (solved without the
    terminal constraint, which was infeasible), ``"infeasible"`` or ``"failed"``."""

    thrusts: np.ndarray
    """First input [N] (n); the reference input when the solve failed."""
    status: str
    solver_status: str
    iterations: int
    solve_time: float
    """Wall time of the whole step [s] (linearisation, update, solve)."""
    terminal_ratio: float
    """``e_N^T P~ e_N / pi~^2`` of the predicted end state (<= 1 inside the set); with a
    :class:`SublevelTerminal`, ``value(x_N) - level`` (<= 0 inside); nan without a
    terminal constraint."""
    states: np.ndarray
    inputs: np.ndarray

    @property
    def success(self) -> bool:
        return self.status == "solved"


def rk4_step(x, u, h: float, params: MultirotorParams):
    """One RK4 step of the rigid body (13) under motor thrusts ``u`` (no saturation)."""
    def f(s):
        return multirotor_dynamics(s, motor_wrench(u, params), params)
    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


@functools.cache
def _dynamics(params: MultirotorParams) -> CompiledFunction:
    n = params.num_motors
    return CompiledFunction(lambda x, u: multirotor_dynamics(x, motor_wrench(u, params), params),
                            [STATE_SIZE, n], wrt={0: None, 1: None}, name="multirotor_rhs")


def _rk4_batch(fn: CompiledFunction, X, U, h):
    """RK4 steps of a batch (B, 13), (B, n) with Jacobians (B, 13, 13), (B, 13, n).

    The chain rule runs through the four stages on the joint Jacobian with respect
    to ``(X, U)``: stage ``s`` is evaluated at ``x_s = X + c_s h k_{s-1}``, so
    ``dk_s = J_s [[I + c_s h dk_{s-1}/dX, c_s h dk_{s-1}/dU], [0, I]]``.
    """
    B, n = len(X), U.shape[1]
    m = STATE_SIZE + n
    eye = np.zeros((B, m, m))
    eye[:, np.arange(m), np.arange(m)] = 1.0
    Xn, total = X.copy(), eye[:, :STATE_SIZE].copy()
    k = dk = None
    for c, w in ((0.0, 1.0), (0.5, 2.0), (0.5, 2.0), (1.0, 1.0)):
        if k is None:
            k, dk = fn.batch_value_and_jacobian(X, U)
        else:
            D = eye.copy()
            D[:, :STATE_SIZE] += c * h * dk
            k, J = fn.batch_value_and_jacobian(X + c * h * k, U)
            dk = J @ D
        Xn += h * w / 6.0 * k
        total += h * w / 6.0 * dk
    return Xn, total[:, :, :STATE_SIZE], total[:, :, STATE_SIZE:]


def _box_upper(bounds) -> np.ndarray:
    """Upper bounds (12, error layout) from ``ErrorBounds``, an array or ``None``."""
    if bounds is None:
        return ErrorBounds().upper()
    if isinstance(bounds, ErrorBounds):
        return bounds.upper()
    upper = np.asarray(bounds, dtype=float)
    if upper.shape != (ERROR_SIZE,) or np.any(np.isnan(upper)) or np.any(upper <= 0) \
            or np.any(np.isfinite(upper[:3])):
        raise ValueError(f"bounds must be ErrorBounds or {ERROR_SIZE} positive upper bounds "
                         f"(inf = none; the position unbounded), got {bounds}")
    return upper


def _error_maps(x_ref) -> tuple[np.ndarray, np.ndarray]:
    """``L`` (M, 12, 13), ``l`` (M, 12) with ``state_error(x, x_ref[k]) = L[k] x + l[k]``
    for reference states ``x_ref`` (M, 13)."""
    M = len(x_ref)
    L = np.zeros((M, ERROR_SIZE, STATE_SIZE))
    L[:, 0:3, 0:3] = np.eye(3)
    L[:, 6:12, 7:13] = np.eye(6)
    c = quat_conjugate(x_ref[:, 3:7].T).T
    w, v = c[:, 0], c[:, 1:]
    # vec(c (x) q) = w q_v + q_w v + v x q_v
    L[:, 3:6, 3] = 2 * v
    L[:, 3:6, 4:7] = 2 * w[:, None, None] * np.eye(3)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # the cross-product matrix of v
        L[:, 3 + i, 4 + j] -= 2 * v[:, k]
        L[:, 3 + j, 4 + i] += 2 * v[:, k]
    l = np.zeros((M, ERROR_SIZE))
    l[:, 0:3], l[:, 6:12] = -x_ref[:, 0:3], -x_ref[:, 7:13]
    return L, l


_ACTIVE_SET_ITERATIONS = 12
"""Riccati solves of one QP before it goes to Clarabel."""
_KKT_TOLERANCE = 1e-9
"""A fixed thrust's multiplier of the wrong sign beyond this [cost/N] releases it."""


@dataclasses.dataclass(frozen=True)
class _QpSolution:
    """One QP of the SQP: success, solver name and iterations, states and inputs."""

    success: bool
    name: str
    iterations: int
    X: np.ndarray
    U: np.ndarray


class TrackingNmpc:
    """The OCP of the module docstring, built once for a terminal set and settings.

    :meth:`solve` takes the time [s] and the measured plant state (13) and returns an
    :class:`NmpcResult`; it never raises for a failed solve (the status says so).

    Parameters
    ----------
    params : MultirotorParams
        The vehicle (the prediction model).
    terminal : TerminalSet or None
        The time-varying terminal set (eq. 4.4e) with its reference, health and box; or
        ``None``: no terminal constraint, and ``reference`` (required), ``health`` and
        ``bounds`` give the rest.
    settings : NmpcSettings, optional
    reference : ReferenceTable, optional
        Reference state and thrusts when ``terminal`` is ``None``.
    health : array (n), optional
        Motor health in [0, 1] when ``terminal`` is ``None`` (default all ones).
    bounds : ErrorBounds or array (12), optional
        Box of eq. 4.4d in error layout (upper bounds, ``inf`` = none; per axis when an
        array) when ``terminal`` is ``None`` (default ``ErrorBounds()``).
    terminal_region : SublevelTerminal, optional
        Terminal region of a value function (e.g. a recovery tube) when ``terminal`` is
        ``None``.

    Raises
    ------
    ValueError
        A setting, weight, health or bound that is invalid, or no reference.
    """

    def __init__(self, params: MultirotorParams, terminal: TerminalSet | None,
                 settings: NmpcSettings | None = None, *,
                 reference: ReferenceTable | None = None, health=None, bounds=None,
                 terminal_region: SublevelTerminal | None = None):
        settings = settings or NmpcSettings()
        settings.validate()
        self.params, self.terminal, self.settings = params, terminal, settings
        self.N, self.h = settings.nodes, settings.horizon / settings.nodes
        self.Q = positive_semidefinite("NmpcSettings.state_weight", settings.state_weight,
                                       ERROR_SIZE)
        n = self.n = params.num_motors
        if terminal is not None:
            reference, health, upper = terminal.reference, terminal.health, terminal.upper
        else:
            if reference is None:
                raise ValueError("reference is required when terminal is None")
            health = np.ones(n) if health is None else np.asarray(health, dtype=float)
            params.effective_allocation(health)  # validates the health
            upper = _box_upper(bounds)
        self.reference, self.health, self.upper = reference, health, upper
        self.terminal_region = terminal_region if terminal is None else None
        self._half = None
        self._reference_start = 0.0
        self._scaled = bool(np.any(health != 1.0))
        self.R = settings.input_weight * np.eye(n)
        self.f_max = params.f_max * (health > 0)
        self._fn = _dynamics(params)
        self._input_R = np.broadcast_to(2 * self.h * self.R, (self.N, n, n))
        self._build()
        self._guess = None

    def _build(self) -> None:
        N, n = self.N, self.n
        prog = self.prog = MathematicalProgram()
        self.X = prog.NewContinuousVariables(N + 1, STATE_SIZE, "x")
        self.U = prog.NewContinuousVariables(N, n, "u")
        self._x0 = prog.AddBoundingBoxConstraint(np.zeros(13), np.zeros(13), self.X[0])
        for j in range(N):
            prog.AddBoundingBoxConstraint(np.zeros(n), self.f_max, self.U[j])
        self._state_costs = [prog.AddQuadraticCost(np.eye(13), np.zeros(13), self.X[j])
                             for j in range(1, N + 1)]
        self._input_costs = [prog.AddQuadraticCost(np.eye(n), np.zeros(n), self.U[j])
                             for j in range(N)]
        self._x_index = np.array(prog.FindDecisionVariableIndices(self.X.ravel())).reshape(
            N + 1, STATE_SIZE)
        self._u_index = np.array(prog.FindDecisionVariableIndices(self.U.ravel())).reshape(N, n)
        self._cone = prog.AddLorentzConeConstraint(np.zeros((13, 13)), np.ones(13), self.X[N])
        self._halfspace = prog.AddLinearConstraint(np.zeros((1, 13)), [-np.inf], [np.inf],
                                                   self.X[N])
        # state box of eq. 4.4d: attitude error (changes with q_r), velocity, rates
        upper = self.upper
        self._box_rows = [i for i in range(3, 12) if np.isfinite(upper[i])]
        self._box = [prog.AddLinearConstraint(np.zeros((len(self._box_rows), 13)),
                                              -upper[self._box_rows], upper[self._box_rows],
                                              self.X[j]) for j in range(1, N + 1)]
        self._qp = self.settings.mode == "rti" or self.settings.nlp_solver == "sqp"
        if self._qp:
            self._dyn = [prog.AddLinearEqualityConstraint(
                np.zeros((13, 26 + n)), np.zeros(13),
                np.concatenate([self.X[j], self.U[j], self.X[j + 1]])) for j in range(N)]
            self._solver = ClarabelSolver()
        else:
            for j in range(N):
                prog.AddConstraint(self._defect, np.zeros(13), np.zeros(13),
                                   np.concatenate([self.X[j], self.U[j], self.X[j + 1]]))
            self._solver = SnoptSolver() if self.settings.nlp_solver == "snopt" \
                else IpoptSolver()
        self._options = SolverOptions()
        if self._qp:  # QP accuracy well below the tracking errors of interest
            for name, value in (("tol_gap_abs", 1e-5), ("tol_gap_rel", 1e-5),
                                ("tol_feas", 1e-6)):
                self._options.SetOption(ClarabelSolver.id(), name, value)
        elif self.settings.nlp_solver == "snopt":
            self._options.SetOption(SnoptSolver.id(), "Major iterations limit",
                                    self.settings.max_iterations)
        else:
            self._options.SetOption(IpoptSolver.id(), "max_iter", self.settings.max_iterations)
            self._options.SetOption(IpoptSolver.id(), "print_level", 0)

    def set_objective(self, reference: ReferenceTable | None = None,
                      start_time: float | None = None, state_weight=None) -> None:
        """Replaces the stage cost's reference and weights for the next solves.

        ``reference`` is read at ``t - start_time`` (a reference that starts at a fault
        or a switch, time [s]); ``state_weight`` is ``Q_F`` (12 diagonal entries or a
        matrix, positive semi-definite). The terminal set, if any, keeps its own
        reference. The warm start is kept (the shifted solution is still a trajectory of
        the model). Raises ``ValueError`` for an invalid weight.
        """
        if reference is not None:
            self.reference = reference
        if start_time is not None:
            self._reference_start = float(start_time)
        if state_weight is not None:
            self.Q = positive_semidefinite("state_weight", state_weight, ERROR_SIZE)
        self._program_current = False

    def _model_batch(self, X, U):
        """RK4 steps and Jacobians of the model with the motor health applied."""
        if not self._scaled:
            return _rk4_batch(self._fn, X, U, self.h)
        Xn, Ax, Bu = _rk4_batch(self._fn, X, U * self.health, self.h)
        return Xn, Ax, Bu * self.health

    def _defect(self, z):
        """``RK4(x_j, u_j) - x_{j+1}`` with the compiled Jacobian (AutoDiffXd or float)."""
        n = self.n
        if z.dtype != object:
            x, u = z[:13], z[13:13 + n]
            Xn, _, _ = self._model_batch(x[None], u[None])
            return Xn[0] - z[13 + n:]
        values, grads = ExtractValue(z)[:, 0], ExtractGradient(z)
        Xn, Ax, Bu = self._model_batch(values[None, :13], values[None, 13:13 + n])
        J = np.hstack([Ax[0], Bu[0], -np.eye(13)])
        return InitializeAutoDiff(Xn[0] - values[13 + n:], J @ grads)[:, 0]

    # ------------------------------------------------------------------ per step
    def _update(self, t: float, x: np.ndarray) -> None:
        """The step's QP data as arrays (every node at once); the program's coefficients
        follow only when the QP goes to Clarabel (:meth:`_update_program`)."""
        N, h = self.N, self.h
        xr, ur = self.reference.at(t - self._reference_start + h * np.arange(N + 1))
        if x[3:7] @ xr[0, 3:7] < 0:
            x = np.concatenate([x[:3], -x[3:7], x[7:]])
        L, l = _error_maps(xr)
        LQ = np.swapaxes(L[1:], 1, 2) @ (2 * h * self.Q)
        self._stage_Q = LQ @ L[1:] + 1e-9 * np.eye(13)  # nodes 1..N
        self._stage_q = (LQ @ l[1:, :, None])[:, :, 0]
        self._input_r = -2 * h * (ur[:-1] * (self.f_max > 0)) @ self.R
        rows = self._box_rows
        self._box_L = L[1:, rows]  # attitude rows are errors; the others bound x itself
        self._box_offset = np.where(np.array(rows) < 6, l[1:, rows], 0.0)
        if self.terminal is not None:
            Pt, _, level = self.terminal.matrices_at(t + self.settings.horizon)
            S = np.linalg.cholesky(Pt).T  # e^T Pt e = |S e|^2
            self._terminal = (Pt, level, L[N], l[N], S)
        self._cone_on, self._program_current = self.terminal is not None, False
        self._region_on, self._half = True, None
        self._xr, self._ur, self._x = xr, ur, x

    def _update_program(self) -> None:
        """Copies the step's data into the ``MathematicalProgram`` (Clarabel, SNOPT, IPOPT)."""
        if self._program_current:
            return
        self._x0.evaluator().UpdateLowerBound(self._x)
        self._x0.evaluator().UpdateUpperBound(self._x)
        upper = self.upper[self._box_rows]
        for j in range(self.N):
            off = self._box_offset[j]
            self._box[j].evaluator().UpdateCoefficients(self._box_L[j], -upper - off,
                                                        upper - off)
            self._state_costs[j].evaluator().UpdateCoefficients(
                self._stage_Q[j], self._stage_q[j], 0.0, True)
            self._input_costs[j].evaluator().UpdateCoefficients(
                2 * self.h * self.R, self._input_r[j], 0.0, True)
        self._set_cone(self._cone_on)
        self._set_halfspace()
        self._program_current = True

    def _set_halfspace(self) -> None:
        """The linearised terminal region ``a^T x_N <= b``, or no constraint."""
        if self._half is None:
            self._halfspace.evaluator().UpdateCoefficients(np.zeros((1, 13)), [-np.inf],
                                                           [np.inf])
        else:
            a, b = self._half
            self._halfspace.evaluator().UpdateCoefficients(a[None], [-np.inf], [b])

    def _set_cone(self, on: bool) -> None:
        """The terminal cone ``|S (L x_N + l)| <= pi~``, or (off) ``1 >= |0|``."""
        self._cone_on = on = on and self.terminal is not None
        if on:
            _, level, L, l, S = self._terminal
            A = np.vstack([np.zeros((1, 13)), S @ L])
            b = np.concatenate([[level], S @ l])
        else:
            A, b = np.zeros((13, 13)), np.zeros(13)
            b[0] = 1.0
        self._cone.evaluator().UpdateCoefficients(A, b)

    def _initial_guess(self) -> tuple[np.ndarray, np.ndarray]:
        """Shifted previous solution, or the reference (first step / after a failure)."""
        if self._guess is None:
            X = self._xr.copy()
            X[0] = self._x
            return X, self._ur[:-1] * (self.f_max > 0)
        X, U = self._guess
        X = np.vstack([X, rk4_step(X[-1], U[-1] * self.health, self.h, self.params)])
        U = np.vstack([U, U[-1:], U[-1:]])
        # one control period later: the nodes move by period / h intervals (one when the
        # period is the shooting interval, the default)
        s = self.settings.period / self.h
        nodes = np.arange(len(X) - 1) + s
        k = np.minimum(nodes.astype(int), len(X) - 2)
        w = (nodes - k)[:, None]
        X = X[k] * (1.0 - w) + X[k + 1] * w
        U = U[k[:-1]] * (1.0 - w[:-1]) + U[k[:-1] + 1] * w[:-1]
        X[0] = self._x
        return X, U

    def solve(self, t: float, x) -> NmpcResult:
        """One step at time ``t`` [s] from the measured state ``x`` (13)."""
        start = time.perf_counter()
        x = np.asarray(x, dtype=float)[:STATE_SIZE]
        if not np.all(np.isfinite(x)) or not np.isfinite(t):
            self._guess = None
            return self._failure("failed", "non-finite state or time", start)
        try:
            self._update(t, x)
            out = self._solve_ocp(start)
            if out.status == "infeasible" and self.settings.relax_terminal:
                self._cone_on, self._region_on = False, False
                if self._program_current:
                    self._set_cone(False)
                relaxed = self._solve_ocp(start)
                if relaxed.success:
                    return dataclasses.replace(relaxed, status="relaxed")
            return out
        except (RuntimeError, ValueError, np.linalg.LinAlgError) as err:
            self._guess = None
            return self._failure("failed", str(err), start)

    def _solve_ocp(self, start: float) -> NmpcResult:
        """One RTI step, the SQP to convergence, or the NLP solver, from the warm start."""
        Xg, Ug = self._initial_guess()
        half = self.terminal_region.linearise(Xg[-1]) \
            if self.terminal_region is not None and self._region_on else None
        if (half is None) != (self._half is None) or half is not None:
            self._half, self._program_current = half, False
        if not self._qp:
            self._update_program()
            result = self._solve_once(Xg, Ug)
            details = result.get_solver_details()
            iterations = int(getattr(details, "iterations", getattr(details, "info", 0)))
            return self._result(self._program_solution(result, iterations), start)
        sweeps = 1 if self.settings.mode == "rti" else self.settings.max_iterations
        total, converged = 0, self.settings.mode == "rti"
        lin = self._linearise(Xg, Ug)
        for _ in range(sweeps):
            sol = self._sqp_step(Xg, Ug, lin)
            total += sol.iterations
            if not sol.success or self.settings.mode == "rti":
                break
            step = max(np.abs(sol.X - Xg).max(), np.abs(sol.U - Ug).max())
            Xg, Ug = sol.X, sol.U
            lin = self._linearise(Xg, Ug)
            if step <= self.settings.tolerance and \
                    np.abs(lin[0] - Xg[1:]).max() <= self.settings.tolerance:
                converged = True
                break
        out = self._result(dataclasses.replace(sol, iterations=total), start)
        if out.success and not converged:
            return dataclasses.replace(out, solver_status="IterationLimit")
        return out

    def _solve_once(self, Xg, Ug):
        guess = np.zeros(self.prog.num_vars())
        self.prog.SetDecisionVariableValueInVector(self.X, Xg, guess)
        self.prog.SetDecisionVariableValueInVector(self.U, Ug, guess)
        return self._solver.Solve(self.prog, guess, self._options)

    def _program_solution(self, result, iterations: int) -> _QpSolution:
        z = result.get_x_val()
        return _QpSolution(result.is_success(), result.get_solution_result().name, iterations,
                           z[self._x_index], z[self._u_index])

    def _linearise(self, Xg, Ug):
        """RK4 steps and their exact Jacobians about ``(Xg, Ug)``; raises on a diverged
        prediction."""
        lin = self._model_batch(Xg[:-1], Ug)
        if not all(np.all(np.isfinite(a)) for a in lin):
            raise ValueError("non-finite linearisation (the prediction diverged)")
        return lin

    def _sqp_step(self, Xg, Ug, lin) -> _QpSolution:
        """The QP of the dynamics linearised about ``(Xg, Ug)`` (exact Jacobians): by
        Riccati recursions (:meth:`_riccati`, KKT conditions checked) when
        ``qp_solver="riccati"`` and they reach its optimum, otherwise by Clarabel."""
        Xn, Ax, Bu = lin
        c = Xn - (Ax @ Xg[:-1, :, None])[:, :, 0] - (Bu @ Ug[:, :, None])[:, :, 0]
        fast = None
        if self.settings.qp_solver == "riccati":
            try:
                fast = self._riccati(Ax, Bu, c)
            except (np.linalg.LinAlgError, ValueError):  # a singular stage: Clarabel decides
                fast = None
        if fast is not None:
            return fast
        self._update_program()
        for j, binding in enumerate(self._dyn):
            binding.evaluator().UpdateCoefficients(
                np.hstack([Ax[j], Bu[j], -np.eye(13)]), -c[j])
        result = self._solver.Solve(self.prog, None, self._options)
        return self._program_solution(
            result, int(getattr(result.get_solver_details(), "iterations", 0)))

    def _riccati(self, Ax, Bu, c) -> _QpSolution | None:
        """The QP by Riccati recursions with a primal-dual active set on the thrust bounds
        (Hintermueller, Ito & Kunisch 2002): thrusts at a bound in the working set are
        fixed, the others free; bounds the solution violates join the set, fixed thrusts
        whose multiplier has the wrong sign leave it. Failed motors stay fixed at 0.

        Returns the solution once it meets the QP's KKT conditions (every bound and
        state-box row met, multipliers of the fixed thrusts of the right sign, the cone
        met or active with ``mu >= 0``), else ``None`` (a state-box row is violated, the
        cone was not met this way, or no convergence in ``_ACTIVE_SET_ITERATIONS``).
        """
        healthy = np.broadcast_to(self.f_max > 0, Bu.shape[::2])
        upper = np.broadcast_to(self.f_max, healthy.shape)
        fixed, value = ~healthy, np.zeros(healthy.shape)
        iteration = 0
        while True:
            iteration += 1
            if iteration > _ACTIVE_SET_ITERATIONS:
                return None
            if fixed.any():
                lq = self._lq_with_cone(Ax, Bu * ~fixed[:, None, :],
                                        c + (Bu @ (value * fixed)[:, :, None])[:, :, 0])
            else:
                lq = self._lq_with_cone(Ax, Bu, c)
            if lq is None:
                return None
            sol, w = lq
            U = np.where(fixed, value, sol.U)
            low, high = ~fixed & (U < 0.0), ~fixed & (U > upper)
            release = fixed & healthy
            if release.any():
                g = self._input_gradient(Ax, Bu, sol.X, U, w)
                release &= (((value == 0.0) & (g < -_KKT_TOLERANCE))
                            | ((value == upper) & (g > _KKT_TOLERANCE)))
            if not (low.any() or high.any() or release.any()):
                break
            fixed = (fixed | low | high) & ~release
            value = np.where(low, 0.0, np.where(high, upper, value))
        box = (self._box_L @ sol.X[1:, :, None])[:, :, 0] + self._box_offset
        if np.any(np.abs(box) > self.upper[self._box_rows]):
            return None
        active = ", cone active" if self._half is None else ", region active"
        name = "Riccati" + (active if w is not None else "") + \
            (", bounds active" if (fixed & healthy).any() else "")
        return _QpSolution(True, name, iteration, sol.X, U)

    def _lq_with_cone(self, Ax, Bu, c):
        """The equality-constrained QP ``(solution, w)``, with the cone made active by the
        end-state term ``w`` when the solution without it leaves the cone (``w = None``
        when it does not); ``None`` when the cone cannot be met."""
        data = (Ax, Bu, c, self._stage_Q, self._stage_q, self._input_R, self._input_r)
        sol = solve_lq(self._x, *data)
        if self._half is not None:
            return self._lq_with_halfspace(sol, data, Ax, Bu)
        if not self._cone_on or self._cone_ratio(sol.X[-1]) <= 1.0:
            return sol, None
        w = self._cone_multiplier(sol, Ax, Bu)
        if w is None:
            return None
        sol = solve_lq(self._x, *data, terminal=(0.0, w))
        return (sol, w) if self._cone_ratio(sol.X[-1]) <= 1.0 + 1e-6 else None

    def _lq_with_halfspace(self, sol, data, Ax, Bu):
        """The QP with the linearised terminal region ``a^T x_N <= b``: active when the
        solution without it leaves it; then ``w = mu a`` with ``x_N(w) = x_N(0) + G w``
        (:func:`~drake_uav.optimization.riccati_lq.terminal_sensitivity`) on the plane,
        ``mu = (b - a^T x_N(0)) / (a^T G a) >= 0``."""
        a, b = self._half
        if a @ sol.X[-1] <= b:
            return sol, None
        curvature = float(a @ terminal_sensitivity(sol, Ax, Bu) @ a)
        if not curvature < 0:
            return None
        w = (b - a @ sol.X[-1]) / curvature * a
        sol = solve_lq(self._x, *data, terminal=(0.0, w))
        scale = max(1.0, abs(b))
        return (sol, w) if a @ sol.X[-1] <= b + 1e-6 * scale else None

    def _input_gradient(self, Ax, Bu, X, U, w) -> np.ndarray:
        """``dL/du_j = R_j u_j + r_j + B_j^T lambda_{j+1}`` (N, n): the Lagrangian's
        gradient in the thrusts, with the costates of the adjoint recursion
        ``lambda_j = Q_j x_j + q_j + A_j^T lambda_{j+1}``, ``lambda_N = Q_N x_N + q_N + w``;
        zero for free thrusts, the bound multiplier for fixed ones."""
        N, Q, q = self.N, self._stage_Q, self._stage_q
        lam = np.empty((N + 1, STATE_SIZE))
        lam[N] = Q[N - 1] @ X[N] + q[N - 1] + (0.0 if w is None else w)
        for j in range(N - 1, 0, -1):
            lam[j] = Q[j - 1] @ X[j] + q[j - 1] + Ax[j].T @ lam[j + 1]
        BtL = (np.swapaxes(Bu, 1, 2) @ lam[1:, :, None])[:, :, 0]
        return U @ self._input_R[0] + self._input_r + BtL

    def _cone_ratio(self, xN) -> float:
        """``e_N^T P~ e_N / pi~^2`` of the end state ``xN``."""
        Pt, level, L, l, _ = self._terminal
        e = L @ xN + l
        return float(e @ Pt @ e) / level**2

    def _cone_multiplier(self, sol, Ax, Bu) -> np.ndarray | None:
        """The linear term ``w = mu grad g(x_N)`` on ``x_N`` with which the equality-
        constrained QP ends on the cone, ``g = e_N^T P~ e_N``; ``None`` if none is found.

        With ``G = dx_N/dw`` (:func:`~drake_uav.optimization.riccati_lq.terminal_sensitivity`)
        the end state for a multiplier ``mu >= 0`` solves the 13 x 13 system
        ``(I - 2 mu G L^T P~ L) x_N = x_N(0) + 2 mu G L^T P~ l``; ``g(x_N(mu))`` decreases
        in ``mu`` and its root ``g = pi~^2`` is bracketed and found by Brent's method.
        Those are the KKT conditions of the QP with the cone (multiplier ``mu``).
        """
        Pt, level, L, l, _ = self._terminal
        GM = terminal_sensitivity(sol, Ax, Bu) @ (2.0 * L.T @ Pt)
        GML, GMl, x0N, eye = GM @ L, GM @ l, sol.X[-1], np.eye(STATE_SIZE)

        def end(mu):
            return np.linalg.solve(eye - mu * GML, x0N + mu * GMl)

        def excess(mu):
            return self._cone_ratio(end(mu)) - 1.0

        high = 1.0
        while (value := excess(high)) > 0.0:
            high *= 8.0
            if high > 1e15:
                return None
        if not np.isfinite(value):
            return None
        mu = brentq(excess, 0.0, high, xtol=1e-12 * high, rtol=1e-14, maxiter=200)
        return 2.0 * mu * L.T @ Pt @ (L @ end(mu) + l)

    def _failure(self, status, solver_status, start) -> NmpcResult:
        ur = self._ur[0] if hasattr(self, "_ur") else np.zeros(self.n)
        return NmpcResult(thrusts=np.clip(ur, 0.0, self.f_max), status=status,
                          solver_status=solver_status, iterations=0,
                          solve_time=time.perf_counter() - start, terminal_ratio=np.inf,
                          states=np.empty((0, 13)), inputs=np.empty((0, self.n)))

    def _result(self, sol: _QpSolution, start) -> NmpcResult:
        """``sol.iterations``: QP solver iterations summed over the SQP steps (1 for a
        Riccati solve), or the NLP solver's own count (SNOPT's exit code when it reports
        none)."""
        X, U = sol.X, sol.U
        if not sol.success or not np.all(np.isfinite(U)):
            self._guess = None
            status = "infeasible" if "Infeasible" in sol.name else "failed"
            return dataclasses.replace(self._failure(status, sol.name, start),
                                       iterations=sol.iterations)
        self._guess = (X, U)
        if self.terminal is not None:
            ratio = self._cone_ratio(X[-1])
        elif self.terminal_region is not None:
            ratio = float(self.terminal_region.value(X[-1])) - self.terminal_region.level
        else:
            ratio = np.nan
        return NmpcResult(thrusts=np.clip(U[0], 0.0, self.f_max), status="solved",
                          solver_status=sol.name, iterations=sol.iterations,
                          solve_time=time.perf_counter() - start,
                          terminal_ratio=ratio, states=X, inputs=U)

    def reset(self) -> None:
        """Forget the warm start (e.g. after a jump of the state)."""
        self._guess = None

