"""Tracking NMPC of a multirotor with a time-varying terminal set (Argyropoulos 2020, ch. 3-4).

The optimal control problem (eq. 4.4) over ``T_p`` with ``N`` shooting intervals
of ``h = T_p / N``, states ``X_0..X_N`` (13 each) and motor thrusts
``U_0..U_{N-1}`` as decision variables (multiple shooting)::

    minimise    sum_j h [e_j^T Q_F e_j + (U_j - u_r,j)^T R_F (U_j - u_r,j)],  j = 1..N / 0..N-1
    subject to  X_0 = x(t_k),  X_{j+1} = RK4_h(X_j, U_j),  0 <= U_j <= f_max (failed: 0)
                |theta_e,j| <= bound, |v_j| <= v_max, |omega_j| <= omega_max  (the box of
                the terminal set's ErrorBounds, eq. 4.4d)
                e_N^T (P(t_k + T_p) + I) e_N <= pi~(t_k + T_p)^2                   (eq. 4.4e)

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
  (quadratic cost, linear dynamics, bounds, cone) goes to Clarabel.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import (
    ClarabelSolver,
    IpoptSolver,
    MathematicalProgram,
    SnoptSolver,
    SolverOptions,
)

from drake_uav.model.attitude_error import ERROR_SIZE
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.multirotor import STATE_SIZE, motor_wrench, multirotor_dynamics
from drake_uav.model.rotations import quat_conjugate
from drake_uav.optimization.terminal_set import TerminalSet, positive_definite
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "NmpcSettings",
    "NmpcResult",
    "TrackingNmpc",
    "default_waypoints",
    "rk4_step",
]


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
    """``Q_F`` diagonal (12): position [1/m^2], attitude [1/rad^2], velocity, rates."""
    input_weight: float = 0.05
    """``R_F = input_weight I`` [1/N^2]."""
    mode: str = "rti"
    """``"rti"`` (one SQP step, Clarabel) or ``"nlp"`` (full NLP)."""
    nlp_solver: str = "sqp"
    """Full-NLP solver: ``"sqp"`` (Gauss-Newton SQP iterated to convergence, QPs with
    Clarabel), ``"snopt"`` or ``"ipopt"`` (through ``MathematicalProgram``)."""
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
        positive_definite("NmpcSettings.state_weight", self.state_weight, ERROR_SIZE)
        if not self.input_weight > 0:
            raise ValueError(f"NmpcSettings.input_weight must be positive, got "
                             f"{self.input_weight}")
        if self.mode not in ("rti", "nlp"):
            raise ValueError(f"NmpcSettings.mode must be 'rti' or 'nlp', got {self.mode!r}")
        if self.nlp_solver not in ("sqp", "snopt", "ipopt"):
            raise ValueError(f"NmpcSettings.nlp_solver must be 'sqp', 'snopt' or 'ipopt', "
                             f"got {self.nlp_solver!r}")
        if not (self.max_iterations >= 1 and self.tolerance > 0):
            raise ValueError("NmpcSettings.max_iterations must be >= 1 and tolerance > 0")


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
    """``e_N^T P~ e_N / pi~^2`` of the predicted end state (<= 1 inside the set)."""
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
    """RK4 steps of a batch (B, 13), (B, n) with Jacobians (B, 13, 13), (B, 13, n)."""
    B, n = len(X), U.shape[1]
    eye = np.eye(STATE_SIZE)
    ks, dkx, dku = [], [], []
    for c, prev in ((0.0, None), (0.5, 0), (0.5, 1), (1.0, 2)):
        if prev is None:
            xs, dxs, dus = X, np.broadcast_to(eye, (B, 13, 13)), np.zeros((B, 13, n))
        else:
            xs = X + c * h * ks[prev]
            dxs, dus = eye + c * h * dkx[prev], c * h * dku[prev]
        k, (Jx, Ju) = fn.batch_jacobians(xs, U)
        ks.append(k)
        dkx.append(Jx @ dxs)
        dku.append(Jx @ dus + Ju)
    w = (1.0, 2.0, 2.0, 1.0)
    Xn = X + h / 6.0 * sum(wi * k for wi, k in zip(w, ks, strict=True))
    Ax = eye + h / 6.0 * sum(wi * d for wi, d in zip(w, dkx, strict=True))
    Bu = h / 6.0 * sum(wi * d for wi, d in zip(w, dku, strict=True))
    return Xn, Ax, Bu


def _error_map(x_ref) -> tuple[np.ndarray, np.ndarray]:
    """``L`` (12, 13), ``l`` (12) with ``state_error(x, x_ref) = L x + l``."""
    L = np.zeros((ERROR_SIZE, STATE_SIZE))
    L[0:3, 0:3] = np.eye(3)
    L[6:12, 7:13] = np.eye(6)
    c = quat_conjugate(x_ref[3:7])
    w, v = c[0], c[1:]
    # vec(c (x) q) = w q_v + q_w v + v x q_v
    L[3:6, 3] = 2 * v
    L[3:6, 4:7] = 2 * (w * np.eye(3) + np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]],
                                                  [-v[1], v[0], 0]]))
    l = np.zeros(ERROR_SIZE)
    l[0:3], l[6:12] = -x_ref[0:3], -x_ref[7:13]
    return L, l


class TrackingNmpc:
    """The OCP of the module docstring, built once for a terminal set and settings.

    :meth:`solve` takes the time [s] and the measured plant state (13) and returns an
    :class:`NmpcResult`; it never raises for a failed solve (the status says so).
    """

    def __init__(self, params: MultirotorParams, terminal: TerminalSet,
                 settings: NmpcSettings | None = None):
        settings = settings or NmpcSettings()
        settings.validate()
        self.params, self.terminal, self.settings = params, terminal, settings
        self.N, self.h = settings.nodes, settings.horizon / settings.nodes
        self.Q = positive_definite("NmpcSettings.state_weight", settings.state_weight,
                                   ERROR_SIZE)
        n = self.n = params.num_motors
        self.R = settings.input_weight * np.eye(n)
        self.f_max = params.f_max * (terminal.health > 0)
        self._fn = _dynamics(params)
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
        self._cone = prog.AddLorentzConeConstraint(np.zeros((13, 13)), np.ones(13), self.X[N])
        # state box of eq. 4.4d: attitude error (changes with q_r), velocity, rates
        upper = self.terminal.upper
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

    def _defect(self, z):
        """``RK4(x_j, u_j) - x_{j+1}`` with the compiled Jacobian (AutoDiffXd or float)."""
        n = self.n
        if z.dtype != object:
            x, u = z[:13], z[13:13 + n]
            Xn, _, _ = _rk4_batch(self._fn, x[None], u[None], self.h)
            return Xn[0] - z[13 + n:]
        values, grads = ExtractValue(z)[:, 0], ExtractGradient(z)
        Xn, Ax, Bu = _rk4_batch(self._fn, values[None, :13], values[None, 13:13 + n], self.h)
        J = np.hstack([Ax[0], Bu[0], -np.eye(13)])
        return InitializeAutoDiff(Xn[0] - values[13 + n:], J @ grads)[:, 0]

    # ------------------------------------------------------------------ per step
    def _update(self, t: float, x: np.ndarray) -> None:
        N, h = self.N, self.h
        xr, ur = self.terminal.reference.at(t + h * np.arange(N + 1))
        if x[3:7] @ xr[0, 3:7] < 0:
            x = np.concatenate([x[:3], -x[3:7], x[7:]])
        self._x0.evaluator().UpdateLowerBound(x)
        self._x0.evaluator().UpdateUpperBound(x)
        rows, upper = self._box_rows, self.terminal.upper[self._box_rows]
        for j in range(1, N + 1):
            L, l = _error_map(xr[j])
            Lb = L[rows]
            keep = np.array(rows) < 6  # attitude rows are errors; the others bound x itself
            offset = np.where(keep, l[rows], 0.0)
            self._box[j - 1].evaluator().UpdateCoefficients(Lb, -upper - offset, upper - offset)
            H = 2 * h * L.T @ self.Q @ L
            self._state_costs[j - 1].evaluator().UpdateCoefficients(
                H + 1e-9 * np.eye(13), 2 * h * L.T @ self.Q @ l)
        for j in range(N):
            self._input_costs[j].evaluator().UpdateCoefficients(
                2 * h * self.R, -2 * h * self.R @ (ur[j] * (self.f_max > 0)))
        Pt, _, level = self.terminal.matrices_at(t + self.settings.horizon)
        L, l = _error_map(xr[N])
        S = np.linalg.cholesky(Pt).T  # e^T Pt e = |S e|^2
        A = np.vstack([np.zeros((1, 13)), S @ L])
        b = np.concatenate([[level], S @ l])
        self._cone.evaluator().UpdateCoefficients(A, b)
        self._terminal = (Pt, level, L, l)
        self._xr, self._ur, self._x = xr, ur, x

    def _initial_guess(self) -> tuple[np.ndarray, np.ndarray]:
        """Shifted previous solution, or the reference (first step / after a failure)."""
        if self._guess is None:
            X = self._xr.copy()
            X[0] = self._x
            return X, self._ur[:-1] * (self.f_max > 0)
        X, U = self._guess
        U = np.vstack([U[1:], U[-1:]])
        Xn, _, _ = _rk4_batch(self._fn, X[-1:], U[-1:], self.h)
        X = np.vstack([X[1:], Xn])
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
                Pt, level, L, l = self._terminal
                unbounded = np.zeros(13)
                unbounded[0] = 1.0  # 1 >= |0|: the cone constraint always holds
                self._cone.evaluator().UpdateCoefficients(np.zeros((13, 13)), unbounded)
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
        if not self._qp:
            return self._result(self._solve_once(Xg, Ug), start)
        sweeps = 1 if self.settings.mode == "rti" else self.settings.max_iterations
        total, converged = 0, self.settings.mode == "rti"
        for _ in range(sweeps):
            result = self._sqp_step(Xg, Ug)
            total += int(getattr(result.get_solver_details(), "iterations", 0))
            if not result.is_success():
                break
            X, U = result.GetSolution(self.X), result.GetSolution(self.U)
            step = max(np.abs(X - Xg).max(), np.abs(U - Ug).max())
            Xg, Ug = X, U
            if step <= self.settings.tolerance and self._defect_max(X, U) <= \
                    self.settings.tolerance:
                converged = True
                break
        out = self._result(result, start, total)
        if out.success and not converged:
            return dataclasses.replace(out, solver_status="IterationLimit")
        return out

    def _solve_once(self, Xg, Ug):
        guess = np.zeros(self.prog.num_vars())
        self.prog.SetDecisionVariableValueInVector(self.X, Xg, guess)
        self.prog.SetDecisionVariableValueInVector(self.U, Ug, guess)
        return self._solver.Solve(self.prog, guess, self._options)

    def _sqp_step(self, Xg, Ug):
        """The QP of the dynamics linearised about ``(Xg, Ug)`` (exact Jacobians)."""
        Xn, Ax, Bu = _rk4_batch(self._fn, Xg[:-1], Ug, self.h)
        if not (np.all(np.isfinite(Xn)) and np.all(np.isfinite(Ax)) and np.all(np.isfinite(Bu))):
            raise ValueError("non-finite linearisation (the prediction diverged)")
        for j, binding in enumerate(self._dyn):
            c = Xn[j] - Ax[j] @ Xg[j] - Bu[j] @ Ug[j]
            binding.evaluator().UpdateCoefficients(np.hstack([Ax[j], Bu[j], -np.eye(13)]), -c)
        return self._solve_once(Xg, Ug)

    def _defect_max(self, X, U) -> float:
        Xn, _, _ = _rk4_batch(self._fn, X[:-1], U, self.h)
        return float(np.abs(Xn - X[1:]).max())

    def _failure(self, status, solver_status, start) -> NmpcResult:
        ur = self._ur[0] if hasattr(self, "_ur") else np.zeros(self.n)
        return NmpcResult(thrusts=np.clip(ur, 0.0, self.f_max), status=status,
                          solver_status=solver_status, iterations=0,
                          solve_time=time.perf_counter() - start, terminal_ratio=np.inf,
                          states=np.empty((0, 13)), inputs=np.empty((0, self.n)))

    def _result(self, result, start, iterations: int | None = None) -> NmpcResult:
        """``iterations``: QP solver iterations summed over the SQP steps (None: the
        NLP solver's own count, or SNOPT's exit code when it reports none)."""
        name = result.get_solution_result().name
        details = result.get_solver_details()
        if iterations is None:
            iterations = int(getattr(details, "iterations", getattr(details, "info", 0)))
        X, U = result.GetSolution(self.X), result.GetSolution(self.U)
        if not result.is_success() or not np.all(np.isfinite(U)):
            self._guess = None
            status = "infeasible" if "Infeasible" in name else "failed"
            return dataclasses.replace(self._failure(status, name, start),
                                       iterations=iterations)
        self._guess = (X, U)
        Pt, level, L, l = self._terminal
        e = L @ X[-1] + l
        return NmpcResult(thrusts=np.clip(U[0], 0.0, self.f_max), status="solved",
                          solver_status=name, iterations=iterations,
                          solve_time=time.perf_counter() - start,
                          terminal_ratio=float(e @ Pt @ e) / level**2, states=X, inputs=U)

    def reset(self) -> None:
        """Forget the warm start (e.g. after a jump of the state)."""
        self._guess = None

