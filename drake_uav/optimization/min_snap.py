"""Minimum-snap piecewise-polynomial trajectories and optimal segment times (Argyropoulos 2020,
sec. 2.1).

A trajectory through keyframes ``sigma_0 .. sigma_m`` at times ``t_0 < .. < t_m``
is one polynomial of degree ``n`` per segment and axis. Its coefficients solve
the QP of Argyropoulos 2020, eq. 2.2-2.3::

    minimise    integral ||d^k sigma / dt^k||^2 dt          (k = order, 4 = snap)
    subject to  sigma(t_i) = sigma_i,                        i = 0..m
                d^p sigma / dt^p = 0 at t_0 and t_m,          p = 1..k
                    (or the given initial derivatives at t_0: a start from a moving
                    state, e.g. landing after a motor failure)
                d^p sigma / dt^p continuous at t_1..t_{m-1},  p = 1..continuity
                |d sigma_a / dt| <= v_max_a, |d^2 sigma_a / dt^2| <= a_max_a (optional,
                enforced at sample times on each axis a)

Each segment uses the normalised time ``s = (t - t_j) / T_j`` in [0, 1], which
keeps the program well conditioned; the axes decouple, so one program (built
once per segment count and options) is solved per axis with updated
coefficients. Without bounds every constraint is an equality and the KKT system
is solved directly (Drake's equality-constrained QP solver); with bounds the
program goes to Clarabel. :func:`optimize_segment_times` distributes a fixed
total time by the constrained gradient descent of Argyropoulos 2020, eq. 2.4-2.5.
Positions are in m and times in s (NED, so altitude is ``-sigma_z``).
"""

from __future__ import annotations

import dataclasses
from math import factorial

import numpy as np
from pydrake.polynomial import Polynomial
from pydrake.solvers import (
    ChooseBestSolver,
    ClarabelSolver,
    MakeSolver,
    MathematicalProgram,
    SolutionResult,
    SolverOptions,
)
from pydrake.trajectories import PiecewisePolynomial

__all__ = [
    "TrajectoryInfeasibleError",
    "PolynomialTrajectory",
    "MinimumSnap",
    "minimum_snap",
    "TimeAllocationResult",
    "optimize_segment_times",
]


_AUGMENTATION = 0.01
"""Weight of the penalty ``|A_eq c - b_eq|^2`` added to the (normalised) cost."""


class TrajectoryInfeasibleError(ValueError):
    """The minimum-snap QP has no solution; ``solution_result`` holds the solver status."""

    def __init__(self, message: str, solution_result: SolutionResult):
        super().__init__(message)
        self.solution_result = solution_result


def _derivative_factors(degree: int, d: int) -> np.ndarray:
    """``i! / (i - d)!`` for i = 0..degree (zero for i < d)."""
    return np.array([factorial(i) / factorial(i - d) if i >= d else 0.0
                     for i in range(degree + 1)])


def _derivative_rows(degree: int, d: int, s) -> np.ndarray:
    """Rows mapping coefficients to ``d^d p / ds^d`` at normalised times ``s`` (len(s), n+1)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    powers = np.arange(degree + 1) - d
    with np.errstate(divide="ignore", invalid="ignore"):
        basis = np.where(powers >= 0, s[:, None] ** np.maximum(powers, 0), 0.0)
    return basis * _derivative_factors(degree, d)


def _cost_matrix(degree: int, k: int) -> np.ndarray:
    """``integral_0^1 (d^k p / ds^k)^2 ds = c^T Q c`` for one segment."""
    f = _derivative_factors(degree, k)
    i = np.arange(degree + 1)
    expo = i[:, None] + i[None, :] - 2 * k + 1
    with np.errstate(divide="ignore"):
        Q = np.where(expo > 0, np.outer(f, f) / np.maximum(expo, 1), 0.0)
    return Q


@dataclasses.dataclass(frozen=True, eq=False)
class PolynomialTrajectory:
    """Piecewise polynomial ``sigma(t)``; segment j is ``sum_i c[j, a, i] s^i``.

    ``breaks`` (m+1,) [s]; ``coefficients`` (m, dim, n+1) in the normalised time
    ``s = (t - breaks[j]) / (breaks[j+1] - breaks[j])`` [m]. Before the first and
    after the last break the trajectory holds its end position with zero
    derivatives.
    """

    breaks: np.ndarray
    coefficients: np.ndarray

    @property
    def num_segments(self) -> int:
        return self.coefficients.shape[0]

    @property
    def dim(self) -> int:
        return self.coefficients.shape[1]

    @property
    def degree(self) -> int:
        return self.coefficients.shape[2] - 1

    @property
    def segment_times(self) -> np.ndarray:
        """Segment durations ``T_j`` [s]."""
        return np.diff(self.breaks)

    def start_time(self) -> float:
        return float(self.breaks[0])

    def end_time(self) -> float:
        return float(self.breaks[-1])

    def value(self, t, derivative: int = 0) -> np.ndarray:
        """``d^derivative sigma / dt^derivative`` at ``t``: (dim,) for a scalar, else (N, dim)."""
        scalar = np.ndim(t) == 0
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(t, self.breaks[0], self.breaks[-1])
        j = np.clip(np.searchsorted(self.breaks, tc, side="right") - 1, 0, self.num_segments - 1)
        T = self.segment_times[j]
        s = (tc - self.breaks[j]) / T
        powers = np.arange(self.degree + 1) - derivative
        basis = np.where(powers >= 0, s[:, None] ** np.maximum(powers, 0), 0.0)
        basis *= _derivative_factors(self.degree, derivative)
        out = np.einsum("ni,nai->na", basis, self.coefficients[j]) / T[:, None] ** derivative
        if derivative > 0:
            out[(t < self.breaks[0]) | (t > self.breaks[-1])] = 0.0
        return out[0] if scalar else out

    def position(self, t) -> np.ndarray:
        return self.value(t, 0)

    def velocity(self, t) -> np.ndarray:
        return self.value(t, 1)

    def acceleration(self, t) -> np.ndarray:
        return self.value(t, 2)

    def cost(self, order: int = 4) -> float:
        """``integral ||d^order sigma / dt^order||^2 dt`` over the whole trajectory."""
        Q = _cost_matrix(self.degree, order)
        weights = self.segment_times ** (1 - 2 * order)
        return float(np.einsum("j,jai,ik,jak->", weights, self.coefficients, Q,
                               self.coefficients))

    def to_piecewise_polynomial(self) -> PiecewisePolynomial:
        """The same trajectory as a Drake ``PiecewisePolynomial`` (dim x 1), e.g. for a
        ``TrajectorySource``."""
        segments = []
        for j, T in enumerate(self.segment_times):
            scale = T ** -np.arange(self.degree + 1)
            segments.append(np.array([[Polynomial(self.coefficients[j, a] * scale)]
                                      for a in range(self.dim)]))
        return PiecewisePolynomial(segments, list(self.breaks))


def _check_waypoints(waypoints, times) -> tuple[np.ndarray, np.ndarray]:
    w = np.asarray(waypoints, dtype=float)
    if w.ndim == 1:
        w = w[:, None]
    t = np.asarray(times, dtype=float)
    if w.ndim != 2 or w.shape[0] < 2:
        raise ValueError(f"waypoints must be an (m+1, dim) array with at least 2 waypoints, "
                         f"got shape {np.shape(waypoints)}")
    if t.shape != (w.shape[0],):
        raise ValueError(f"times must have one entry per waypoint ({w.shape[0]}), "
                         f"got shape {t.shape}")
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(t))):
        raise ValueError("waypoints and times must be finite")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"times must be strictly increasing: times[{k + 1}] = {t[k + 1]} "
                         f"<= times[{k}] = {t[k]}")
    return w, t


def _axis_bounds(value, dim: int, name: str) -> np.ndarray | None:
    if value is None:
        return None
    b = np.broadcast_to(np.asarray(value, dtype=float), (dim,)).copy() if np.ndim(value) == 0 \
        else np.asarray(value, dtype=float)
    if b.shape != (dim,) or not np.all(np.isfinite(b) & (b > 0)):
        raise ValueError(f"{name} must be positive and finite, a scalar or one per axis "
                         f"({dim}), got {value}")
    return b


class MinimumSnap:
    """The minimum-snap QP for a fixed number of segments, built once and re-solved.

    ``order`` is the penalised derivative ``k_r`` (4 = snap); ``degree`` the
    polynomial degree ``n`` (default ``2 order + 1``, the smallest that works
    for one segment); ``continuity`` the highest derivative kept continuous at
    interior keyframes (default ``order``). ``v_max`` / ``a_max`` [m/s, m/s^2]
    (scalar or per axis) bound each axis at ``samples_per_segment`` evenly
    spaced times inside each segment. ``solver`` overrides the automatic choice.
    """

    def __init__(self, num_segments: int, *, order: int = 4, degree: int | None = None,
                 continuity: int | None = None, v_max=None, a_max=None,
                 samples_per_segment: int = 10, solver=None):
        m, k = int(num_segments), int(order)
        n = 2 * k + 1 if degree is None else int(degree)
        c = k if continuity is None else int(continuity)
        if m < 1:
            raise ValueError(f"num_segments must be >= 1 (at least 2 waypoints), got {m}")
        if k < 1:
            raise ValueError(f"order must be >= 1, got {k}")
        if not 1 <= c < n:
            raise ValueError(f"continuity must be in [1, degree), got {c}")
        if m * (n + 1) < 2 * m + 2 * k + c * (m - 1) or n < k:
            raise ValueError(f"degree {n} is too low for {m} segments with order {k}: "
                             "the equality constraints outnumber the coefficients")
        if samples_per_segment < 2:
            raise ValueError("samples_per_segment must be >= 2")
        self.num_segments, self.order, self.degree, self.continuity = m, k, n, c
        self.v_max, self.a_max = v_max, a_max
        Q = _cost_matrix(n, k)
        self._Q = Q / np.abs(Q).max()
        self._rows0 = {d: _derivative_rows(n, d, 0.0)[0] for d in range(max(k, c) + 1)}
        self._rows1 = {d: _derivative_rows(n, d, 1.0)[0] for d in range(max(k, c) + 1)}
        nc = n + 1
        self._num_eq = 2 * m + 2 * k + c * (m - 1)
        self.prog = MathematicalProgram()
        self._c = self.prog.NewContinuousVariables(m * nc, "c")
        self._cost = self.prog.AddQuadraticCost(np.eye(m * nc), np.zeros(m * nc), self._c,
                                                is_convex=True)
        self._eq = self.prog.AddLinearEqualityConstraint(
            np.zeros((self._num_eq, m * nc)), np.zeros(self._num_eq), self._c)
        self._bound_rows = []
        s = np.linspace(0.0, 1.0, samples_per_segment + 2)[1:-1]
        blocks = []
        for d, value in ((1, v_max), (2, a_max)):
            if value is None:
                continue
            rows = _derivative_rows(n, d, s)
            scale = 1.0 / np.abs(rows).max(axis=1)
            blocks.append(np.kron(np.eye(m), rows * scale[:, None]))
            self._bound_rows.append((d, value, scale))
        self._ineq = None
        if blocks:
            A = np.vstack(blocks)
            self._ineq = self.prog.AddLinearConstraint(A, -np.ones(len(A)), np.ones(len(A)),
                                                       self._c)
        if solver is not None:
            self.solver = solver
        elif self._ineq is None:
            self.solver = MakeSolver(ChooseBestSolver(self.prog))
        else:
            self.solver = ClarabelSolver()
        self._options = SolverOptions()
        if self.solver.solver_id().name() == "EqConstrainedQP":
            self._options.SetOption(self.solver.solver_id(), "FeasibilityTol", 1e-10)
        elif self.solver.solver_id() == ClarabelSolver.id():
            # Tight tolerances: the time allocation differentiates the optimal cost.
            for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio"):
                self._options.SetOption(ClarabelSolver.id(), name, 1e-9)
        self._times = None

    def _set_times(self, T: np.ndarray) -> None:
        """Updates the constraint and cost matrices for segment durations ``T``.

        The variables are the coefficients scaled per segment, ``c_j = sigma_j
        c_hat_j`` with ``sigma_j = (T_j / mean T)^(k - 1/2)``, which gives every
        segment the same cost Hessian and keeps uneven durations well conditioned.
        """
        if self._times is not None and np.array_equal(T, self._times):
            return
        m, k, n, c = self.num_segments, self.order, self.degree, self.continuity
        nc = n + 1
        ratio = T / T.mean()
        self._sigma = ratio ** (k - 0.5)
        A = np.zeros((self._num_eq, m * nc))
        r = 0
        for j in range(m):
            A[r, j * nc:(j + 1) * nc] = self._rows0[0]
            A[r + 1, j * nc:(j + 1) * nc] = self._rows1[0]
            r += 2
        for d in range(1, k + 1):
            A[r, 0:nc] = self._rows0[d]
            A[r + 1, (m - 1) * nc:] = self._rows1[d]
            r += 2
        for j in range(1, m):
            for d in range(1, c + 1):
                A[r, (j - 1) * nc:j * nc] = self._rows1[d] / ratio[j - 1] ** d
                A[r, j * nc:(j + 1) * nc] = -self._rows0[d] / ratio[j] ** d
                r += 1
        A *= np.repeat(self._sigma, nc)
        self._row_scale = 1.0 / np.abs(A).max(axis=1)
        self._A_eq = A * self._row_scale[:, None]
        # rho |A c - b|^2 vanishes on the feasible set, so the minimiser is unchanged,
        # but the Hessian becomes positive definite and the KKT solve much cheaper.
        self._hessian = (np.kron(np.eye(m), self._Q)
                         + _AUGMENTATION * self._A_eq.T @ self._A_eq)
        self._times = T.copy()

    def solve(self, waypoints, times, initial_derivatives=None) -> PolynomialTrajectory:
        """Minimum-``order`` trajectory through ``waypoints`` (m+1, dim) at ``times`` (m+1,).

        ``initial_derivatives`` (p, dim), ``p <= order``: derivatives 1..p at ``times[0]``
        (velocity [m/s], acceleration [m/s^2], ...) instead of zero, so a trajectory can
        start from a moving state; the others stay zero. Raises ``ValueError`` naming the
        argument when its shape is wrong or it is not finite.
        """
        w, t = _check_waypoints(waypoints, times)
        start = _initial_derivatives(initial_derivatives, self.order, w.shape[1])
        if w.shape[0] != self.num_segments + 1:
            raise ValueError(f"this program has {self.num_segments} segments and needs "
                             f"{self.num_segments + 1} waypoints, got {w.shape[0]}")
        T = np.diff(t)
        dim = w.shape[1]
        bounds = [(d, _axis_bounds(value, dim, "v_max" if d == 1 else "a_max"), scale)
                  for d, value, scale in self._bound_rows]
        for d, limit, _ in bounds:
            if d == 1:
                mean_speed = np.abs(np.diff(w, axis=0)) / T[:, None]
                if np.any(mean_speed > limit):
                    j, a = np.unravel_index(np.argmax(mean_speed - limit), mean_speed.shape)
                    raise ValueError(
                        f"v_max is infeasible: segment {j} needs a mean speed of "
                        f"{mean_speed[j, a]:.4g} m/s on axis {a} > v_max {limit[a]:.4g} m/s")
        self._set_times(T)
        m, nc = self.num_segments, self.degree + 1
        coefficients = np.empty((m, dim, nc))
        beq = np.zeros(self._num_eq)
        for a in range(dim):
            beq[0:2 * m:2] = w[:-1, a]
            beq[1:2 * m:2] = w[1:, a]
            beq[2 * m:2 * m + 2 * len(start):2] = start[:, a] * T[0] ** np.arange(
                1, len(start) + 1)
            b = beq * self._row_scale
            self._eq.evaluator().UpdateCoefficients(self._A_eq, b)
            self._cost.evaluator().UpdateCoefficients(
                self._hessian, -_AUGMENTATION * (self._A_eq.T @ b), 0.0, True)
            if self._ineq is not None:
                ub = np.concatenate([np.outer(limit[a] * T ** d / self._sigma, scale).ravel()
                                     for d, limit, scale in bounds])
                self._ineq.evaluator().UpdateLowerBound(-ub)
                self._ineq.evaluator().UpdateUpperBound(ub)
            result = self.solver.Solve(self.prog, None, self._options)
            if not result.is_success():
                status = result.get_solution_result()
                raise TrajectoryInfeasibleError(
                    f"minimum-snap QP failed on axis {a} with {result.get_solver_id().name()}: "
                    f"{status.name}", status)
            scaled = result.GetSolution(self._c).reshape(m, nc)
            coefficients[:, a, :] = scaled * self._sigma[:, None]
        return PolynomialTrajectory(breaks=t.copy(), coefficients=coefficients)


def _initial_derivatives(value, order: int, dim: int) -> np.ndarray:
    """``initial_derivatives`` as a (p, dim) array, p <= order (empty for ``None``)."""
    if value is None:
        return np.zeros((0, dim))
    d = np.asarray(value, dtype=float)
    if d.ndim == 1:
        d = d[None]
    if d.ndim != 2 or d.shape[1] != dim or not 1 <= d.shape[0] <= order \
            or not np.all(np.isfinite(d)):
        raise ValueError(f"initial_derivatives must be finite, (p, {dim}) with 1 <= p <= "
                         f"order = {order}, got shape {np.shape(value)}")
    return d


def minimum_snap(waypoints, times, *, order: int = 4, degree: int | None = None,
                 continuity: int | None = None, v_max=None, a_max=None,
                 samples_per_segment: int = 10, solver=None,
                 initial_derivatives=None) -> PolynomialTrajectory:
    """Minimum-snap trajectory through ``waypoints`` (m+1, dim) [m] at ``times`` (m+1,) [s].

    One-shot form of :class:`MinimumSnap` (see there for the options);
    ``initial_derivatives`` as in :meth:`MinimumSnap.solve`.
    """
    w, t = _check_waypoints(waypoints, times)
    program = MinimumSnap(len(w) - 1, order=order, degree=degree, continuity=continuity,
                          v_max=v_max, a_max=a_max,
                          samples_per_segment=samples_per_segment, solver=solver)
    return program.solve(w, t, initial_derivatives)


@dataclasses.dataclass(frozen=True, eq=False)
class TimeAllocationResult:
    """Outcome of :func:`optimize_segment_times`."""

    times: np.ndarray
    """Optimised keyframe times (same first and last time as the input) [s]."""
    trajectory: PolynomialTrajectory
    cost: float
    """Final ``integral ||d^k sigma/dt^k||^2 dt``."""
    initial_cost: float
    """Cost of the initial times."""
    iterations: int
    evaluations: int
    """Number of QP solves (each covers all axes)."""
    cost_history: tuple[float, ...]


def _descent_direction(grad: np.ndarray, at_lower_bound: np.ndarray) -> np.ndarray:
    """Step ``-sum_i grad_i g_i`` restricted to durations that can still shrink.

    ``grad`` holds the directional derivatives along the ``g_i`` of eq. 2.5,
    i.e. ``m/(m-1)`` times the gradient minus its mean. Durations at their lower
    bound that the step would shrink are frozen and the rest re-centred, so
    ``sum T`` stays fixed.
    """
    m = len(grad)
    free = np.ones(m, dtype=bool)
    while True:
        d = np.zeros(m)
        d[free] = -(m / (m - 1)) * (grad[free] - grad[free].mean())
        blocked = free & at_lower_bound & (d < 0)
        if not np.any(blocked):
            return d
        free &= ~blocked
        if free.sum() < 2:
            return np.zeros(m)


class _DurationCost:
    """Optimal minimum-snap cost as a function of the segment durations ``T`` [s].

    The first keyframe and the total time stay those of ``times``; the last
    keyframe is pinned to ``times[-1]`` so that rounding in ``cumsum`` cannot
    move it. Counts the QP solves in ``evaluations``.
    """

    def __init__(self, program: MinimumSnap, waypoints: np.ndarray, times: np.ndarray):
        self.program, self.waypoints, self.times = program, waypoints, times
        self.evaluations = 0

    def keyframes(self, T: np.ndarray) -> np.ndarray:
        """Keyframe times [s] of durations ``T``."""
        k = self.times[0] + np.concatenate([[0.0], np.cumsum(T)])
        k[-1] = self.times[-1]
        return k

    def __call__(self, T: np.ndarray):
        """Cost and trajectory; infinite cost where the bounds cannot be met."""
        self.evaluations += 1
        try:
            trajectory = self.program.solve(self.waypoints, self.keyframes(T))
        except ValueError:
            return np.inf, None
        return trajectory.cost(self.program.order), trajectory


def _initial_durations(times: np.ndarray, T_min: float) -> np.ndarray:
    """Durations [s] of ``times``; raises if one is below the lower bound ``T_min``."""
    T = np.diff(times)
    if np.any(T < T_min):
        raise ValueError(f"initial segment times must be >= min_fraction * total / m = "
                         f"{T_min:.4g} s, got {T.min():.4g} s")
    return T


def _default_difference_step(program: MinimumSnap, difference_step: float | None) -> float:
    """Relative finite-difference step: 1e-6 with the exact equality-QP solver, 1e-4 with an
    iterative one, whose optimal cost is less precise."""
    if difference_step is not None:
        return difference_step
    exact = program.solver.solver_id().name() == "EqConstrainedQP"
    return 1e-6 if exact else 1e-4


def _directional_derivatives(cost: _DurationCost, T: np.ndarray, f: float, h: float):
    """Forward differences of the cost along the sum-preserving directions ``g_i`` of
    Argyropoulos 2020, eq. 2.5 (rows of ``G``); infinite ones are set to zero."""
    m = len(T)
    G = (np.eye(m) * m - np.ones((m, m))) / (m - 1)
    grad = np.array([(cost(T + h * g)[0] - f) / h for g in G])
    grad[~np.isfinite(grad)] = 0.0
    return grad


def _backtrack(cost: _DurationCost, T: np.ndarray, d: np.ndarray, alpha: float, f: float,
               slope: float, armijo: float):
    """Armijo backtracking from step ``alpha`` along ``d``, halving up to 40 times.

    Returns ``(alpha, cost, trajectory)`` of the accepted step, or None if none is accepted.
    """
    for _ in range(40):
        f_new, trajectory_new = cost(T + alpha * d)
        if f_new <= f + armijo * alpha * slope:
            return alpha, f_new, trajectory_new
        alpha *= 0.5
    return None


def _descend(cost: _DurationCost, T: np.ndarray, f: float, trajectory, *, h: float,
             T_min: float, max_iterations: int, tolerance: float, armijo: float,
             history: list[float]):
    """Projected gradient descent on the durations at fixed total time.

    Appends each accepted cost to ``history``; returns the final durations, cost,
    trajectory and the number of iterations.
    """
    m = len(T)
    alpha = None
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        grad = _directional_derivatives(cost, T, f, h)
        d = _descent_direction(grad, T <= T_min * (1.0 + 1e-9))
        slope = (m - 1) / m * (grad @ d)
        shrinking = d < 0
        if not np.any(shrinking) or slope >= 0.0:
            break
        alpha_max = np.min((T[shrinking] - T_min) / -d[shrinking])
        alpha = alpha_max if alpha is None else min(alpha_max, 2.0 * alpha)
        step = _backtrack(cost, T, d, alpha, f, slope, armijo)
        if step is None:
            break
        alpha, f_new, trajectory_new = step
        T = T + alpha * d
        improvement = (f - f_new) / f
        f, trajectory = f_new, trajectory_new
        history.append(f)
        if improvement < tolerance:
            break
    return T, f, trajectory, iterations


def optimize_segment_times(waypoints, times, *, order: int = 4, degree: int | None = None,
                           continuity: int | None = None, v_max=None, a_max=None,
                           samples_per_segment: int = 10, solver=None,
                           max_iterations: int = 100, tolerance: float = 1e-6,
                           difference_step: float | None = None, min_fraction: float = 0.05,
                           armijo: float = 1e-4) -> TimeAllocationResult:
    """Segment durations [s] of minimum cost for a fixed total time (Argyropoulos 2020, eq.
    2.4-2.5).

    The cost ``f(T)`` is the optimal QP value for durations ``T``. Directional
    derivatives along ``g_i`` (1 at ``i``, ``-1/(m-1)`` elsewhere, so ``sum T``
    is preserved) are taken by forward differences of step
    ``difference_step * total / m`` (default 1e-6 with the exact equality-QP
    solver, 1e-4 with an iterative one, whose optimal cost is less precise).
    The step ``-sum_i grad_i g_i`` is searched by backtracking (Armijo constant
    ``armijo``) and limited so that every duration stays ``>= min_fraction *
    total / m``. Stops when an iteration improves the cost by less than
    ``tolerance`` (relative), or after ``max_iterations``.
    """
    w, t = _check_waypoints(waypoints, times)
    program = MinimumSnap(len(w) - 1, order=order, degree=degree, continuity=continuity,
                          v_max=v_max, a_max=a_max,
                          samples_per_segment=samples_per_segment, solver=solver)
    m = program.num_segments
    total = t[-1] - t[0]
    T_min = min_fraction * total / m
    cost = _DurationCost(program, w, t)
    T = _initial_durations(t, T_min)
    trajectory = program.solve(w, t)  # infeasible initial times raise here, with the reason
    f = trajectory.cost(program.order)
    cost.evaluations = 1
    initial_cost, history, iterations = f, [f], 0
    if m >= 2:
        h = _default_difference_step(program, difference_step) * total / m
        T, f, trajectory, iterations = _descend(
            cost, T, f, trajectory, h=h, T_min=T_min, max_iterations=max_iterations,
            tolerance=tolerance, armijo=armijo, history=history)
    return TimeAllocationResult(times=cost.keyframes(T), trajectory=trajectory, cost=f,
                                initial_cost=initial_cost, iterations=iterations,
                                evaluations=cost.evaluations, cost_history=tuple(history))
