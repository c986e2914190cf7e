"""Time-varying terminal sets and terminal penalty for tracking NMPC (Argyropoulos 2020, ch. 4).

Along a reference ``(x_r(t), u_r(t))`` that ends in hover at ``T`` (assumptions
A1-A3), with motor thrusts as inputs and the error state of
:mod:`drake_uav.model.attitude_error`:

1. LTV error system ``de/dt = A(t) e + B_f(t) w``, ``w = u - u_r``, with
   ``B_f = B A_alloc diag(h)`` (eq. 4.7, B.31-B.37; failed motors are zero columns).
2. ``Q~`` from a time-discretised LMI (a small SDP): the diagonal ``Q~ >= q_min I`` of
   least trace with ``Q(t_k) = Q~ + A + A^T + B R^-1 B^T >= margin I`` on the grid
   (eq. 4.13), so that ``dV/dt = -e^T Q~ e`` on the LTV system.
3. Backward Riccati ``dP/dt = P B R^-1 B^T P - Q - P A - A^T P`` from the stationary
   solution at ``T`` (eq. 4.10); ``K = -1/2 R^-1 B^T (P - I)`` (eq. 4.9),
   ``V = e^T (P + I) e`` (eq. 4.11), ``S = sqrt(P + I)``.
4. The LP (4.24) for the level ``pi(t)`` with every state and input bound
   (absolute values of the scalar gaps, as the corrected eq. 4.24e-h).
5. The nonlinear shrink ``pi~(t) <= pi(t)`` (eq. 4.26-4.28), backwards in time:
   ``phi = 2 e^T P~ Phi(t, e) - e^T Q~ e - 2 pi~ dpi~/dt`` (``+ eps e^T P~ e`` at ``T``)
   must be <= 0 on the boundary ``e = pi~ S^-1 b``, ``|b| = 1``; its maximum is
   found by sampling the sphere plus local refinement of the worst samples.
6. The terminal penalty ``E(t)`` (eq. 4.29 with the corrected exponent
   ``exp(-2 gamma (t - T))``).

The terminal region at time ``t`` is ``{e : e^T (P(t) + I) e <= pi~(t)^2}``; for
``t >= T`` every quantity keeps its value at ``T``.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from pydrake.solvers import (
    ClarabelSolver,
    ClpSolver,
    CsdpSolver,
    MathematicalProgram,
    ScsSolver,
)
from scipy.linalg import solve_continuous_are, solve_continuous_lyapunov, sqrtm

from drake_uav.model.attitude_error import (
    ERROR_SIZE,
    compose_state,
    error_dynamics,
    error_jacobians,
    state_error,
)
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.multirotor import STATE_SIZE, multirotor_derivatives
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "ErrorBounds",
    "TerminalSet",
    "ReferenceTable",
    "positive_definite",
    "terminal_set",
    "ltv_error_system",
    "compiled_error_dynamics",
    "InvarianceCheck",
    "check_invariance",
    "compose_states",
]


def positive_definite(name: str, value, size: int) -> np.ndarray:
    """``value`` as a symmetric positive-definite (size, size) matrix (a vector = diagonal).

    Raises ``ValueError`` naming ``name`` when it is not.
    """
    M = np.asarray(value, dtype=float)
    if M.ndim == 1:
        M = np.diag(M)
    if M.shape != (size, size) or not np.all(np.isfinite(M)):
        raise ValueError(f"{name} must be a finite ({size}, {size}) matrix or {size} "
                         f"diagonal entries, got shape {M.shape}")
    if not np.allclose(M, M.T, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise ValueError(f"{name} must be symmetric")
    if np.linalg.eigvalsh(M).min() <= 0:
        raise ValueError(f"{name} must be positive definite (smallest eigenvalue "
                         f"{np.linalg.eigvalsh(M).min():.3g})")
    return M


@dataclasses.dataclass(frozen=True)
class ErrorBounds:
    """Box bounds of Argyropoulos 2020, assumption A4, in error-state layout.

    ``position`` [m], ``velocity`` [m/s] and ``rates`` [rad/s] bound the plant
    state itself (NED / FRD components, ``inf`` = unbounded); ``attitude``
    [rad] bounds each component of the attitude error ``theta_e`` (the attitude
    has no box of its own). Inputs are bounded by ``[0, f_max]`` per motor.
    """

    position: float = np.inf
    attitude: float = 0.6
    velocity: float = 12.0
    rates: float = 6.0

    def __post_init__(self):
        for field in ("position", "attitude", "velocity", "rates"):
            if not getattr(self, field) > 0:
                raise ValueError(f"ErrorBounds.{field} must be positive, got "
                                 f"{getattr(self, field)}")

    def upper(self) -> np.ndarray:
        """Upper bounds (12) in error layout (lower = minus these)."""
        return np.repeat([self.position, self.attitude, self.velocity, self.rates], 3)


class ReferenceTable:
    """Reference state (13) and motor thrusts (n) on a uniform grid, held after the end.

    ``time`` must start at 0 and be uniform; values between samples are linear
    (the quaternion renormalised), values after the end are the last sample.
    """

    def __init__(self, time, state, thrusts):
        self.time = np.asarray(time, dtype=float)
        self.state = np.asarray(state, dtype=float)
        self.thrusts = np.asarray(thrusts, dtype=float)
        dt = np.diff(self.time)
        if len(self.time) < 2 or abs(self.time[0]) > 1e-12 or np.ptp(dt) > 1e-9 * dt.max():
            raise ValueError("reference.time must start at 0 and be uniform")
        if self.state.shape != (len(self.time), STATE_SIZE):
            raise ValueError(f"reference.state must be ({len(self.time)}, {STATE_SIZE})")
        self.dt = float(dt[0])
        self.end_time = float(self.time[-1])

    def _weights(self, t):
        s = np.clip(np.asarray(t, dtype=float) / self.dt, 0.0, len(self.time) - 1.0)
        i = np.minimum(s.astype(int), len(self.time) - 2)
        return i, (s - i)[..., None]

    def interpolate(self, values: np.ndarray, t) -> np.ndarray:
        """Linear interpolation of per-sample ``values`` (N, ...) at times ``t``."""
        i, w = self._weights(t)
        w = w.reshape(w.shape + (1,) * (values.ndim - 2))
        return values[i] * (1.0 - w) + values[i + 1] * w

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Reference state(s) and thrusts at ``t`` (scalar or array of times)."""
        x = self.interpolate(self.state, t)
        x[..., 3:7] /= np.linalg.norm(x[..., 3:7], axis=-1, keepdims=True)
        return x, self.interpolate(self.thrusts, t)


@functools.cache
def compiled_error_dynamics(params: MultirotorParams) -> CompiledFunction:
    """:func:`~drake_uav.model.attitude_error.error_dynamics` compiled, arguments
    ``(e, thrusts, x_ref, thrusts_ref)``; batches run on numpy arrays."""
    n = params.num_motors
    return CompiledFunction(lambda e, u, xr, ur: error_dynamics(e, u, xr, ur, params),
                            [ERROR_SIZE, n, STATE_SIZE, n], name="error_dynamics")


def ltv_error_system(reference: ReferenceTable, params: MultirotorParams,
                     health=None) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (N, 12, 12) and ``B_f = B A_alloc diag(h)`` (N, 12, n) on the reference grid."""
    alloc = params.effective_allocation(health)
    wrench = reference.thrusts @ alloc.T
    AB = [error_jacobians(x, w, params) for x, w in zip(reference.state, wrench, strict=True)]
    return np.array([a for a, _ in AB]), np.array([b @ alloc for _, b in AB])


def _q_tilde_sdp(A, G, q_min: float, margin: float) -> np.ndarray:
    """Least-trace diagonal ``Q~ >= q_min I`` with ``Q~ + A_k + A_k^T + G_k >= margin I``."""
    n = A.shape[1]
    prog = MathematicalProgram()
    d = prog.NewContinuousVariables(n, "q")
    basis = [np.diag(np.eye(n)[i]) for i in range(n)]
    for Ak, Gk in zip(A, G, strict=True):
        F0 = Ak + Ak.T + Gk - margin * np.eye(n)
        prog.AddLinearMatrixInequalityConstraint([0.5 * (F0 + F0.T), *basis], d)
    prog.AddBoundingBoxConstraint(q_min, np.inf, d)
    prog.AddLinearCost(np.ones(n), 0.0, d)
    for solver in (ClarabelSolver(), ScsSolver(), CsdpSolver()):
        if solver.available() and solver.enabled():
            result = solver.Solve(prog)
            if result.is_success():
                return np.diag(result.GetSolution(d))
    raise ValueError("no diagonal Q~ makes Q(t) positive definite on the reference "
                     "(the LMI of Argyropoulos 2020, eq. 4.13 is infeasible)")


def find_q_tilde(A, G, q_min: float = 1.0, margin: float = 0.1,
                 coarse_step: int = 4) -> np.ndarray:
    """Time-discretised LMI: solve on every ``coarse_step``-th grid time, then add any
    grid time where ``Q(t)`` is not positive definite and solve again."""
    index = set(range(0, len(A), coarse_step)) | {len(A) - 1}
    for _ in range(10):
        keep = sorted(index)
        Qt = _q_tilde_sdp(A[keep], G[keep], q_min, margin)
        low = np.linalg.eigvalsh(Qt + A + A.transpose(0, 2, 1) + G).min(axis=1)
        bad = set(np.flatnonzero(low < 0.5 * margin)) - index
        if not bad:
            return Qt
        index |= bad
    raise ValueError("the discretised LMI for Q~ did not converge")


def _riccati_backward(A, B, Q, R, dt: float, P_T: np.ndarray) -> np.ndarray:
    """``dP/dt = P B R^-1 B^T P - Q - P A - A^T P`` integrated backwards from ``P_T``.

    The Riccati flow is stiff (its fast modes are the closed-loop poles of
    ``A - B R^-1 B^T P``), so each step is implicit Euler: ``P_k = P_{k+1} - h f(P_k)``
    is the algebraic Riccati equation ``Ah^T P + P Ah - h P G P + h Q + P_{k+1} = 0``
    with ``Ah = h A - I/2`` and ``G = B R^-1 B^T``, solved by Newton-Kleinman
    iterations (one Lyapunov equation each) from ``P_{k+1}``. ``A``, ``B``, ``Q`` are
    linear between grid samples; the result is on the grid (N, 12, 12).
    """
    N, n = len(A), A.shape[1]
    P = np.empty_like(A)
    P[-1] = P_T
    substeps = max(int(np.ceil(dt / 0.0125 - 1e-9)), 1)
    h = dt / substeps
    G = B @ np.linalg.inv(R) @ B.transpose(0, 2, 1)
    for k in range(N - 2, -1, -1):
        Pk = P[k + 1]
        for s in range(substeps - 1, -1, -1):
            w = s / substeps  # weight of sample k + 1 at the new time
            Ak, Gk, Qk = ((1.0 - w) * M[k] + w * M[k + 1] for M in (A, G, Q))
            Ah, rhs = h * Ak - 0.5 * np.eye(n), h * Qk + Pk
            X = Pk
            for _ in range(20):
                Ac = Ah - h * Gk @ X
                X_new = solve_continuous_lyapunov(Ac.T, -(rhs + h * X @ Gk @ X))
                done = np.abs(X_new - X).max() <= 1e-10 * max(1.0, np.abs(X_new).max())
                X = 0.5 * (X_new + X_new.T)
                if done:
                    break
            Pk = X
        P[k] = Pk
    return P


def _level_lp(dt: float, q: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """LP (4.24) discretised: max sum(pi) s.t. pi_{k+1} = pi_k + dt w_k, 2 w_k >= -q_k pi_k,
    w_N = 0, 0 <= pi_k <= cap_k (the state and input rows, folded into one bound)."""
    N = len(q)
    prog = MathematicalProgram()
    pi = prog.NewContinuousVariables(N, "pi")
    w = prog.NewContinuousVariables(N, "w")
    for k in range(N - 1):
        prog.AddLinearEqualityConstraint(np.array([[1.0, -1.0, -dt]]), [0.0],
                                         [pi[k + 1], pi[k], w[k]])
    prog.AddLinearConstraint(np.hstack([np.diag(2.0 * np.ones(N)), np.diag(q)]),
                             np.zeros(N), np.full(N, np.inf), np.concatenate([w, pi]))
    prog.AddBoundingBoxConstraint(0.0, 0.0, w[-1])
    prog.AddBoundingBoxConstraint(np.zeros(N), cap, pi)
    prog.AddLinearCost(-dt * np.ones(N), 0.0, pi)
    result = ClpSolver().Solve(prog)
    if not result.is_success():
        raise ValueError(f"the level LP (Argyropoulos 2020, eq. 4.24) failed: "
                         f"{result.get_solution_result()}")
    out = np.clip(result.GetSolution(pi), 0.0, cap)
    for k in range(N - 2, -1, -1):  # restore feasibility lost to the solver tolerance
        out[k] = min(out[k], out[k + 1] / max(1.0 - 0.5 * dt * q[k], 1e-12))
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class TerminalSet:
    """Time-varying level sets ``e^T (P(t) + I) e <= pi~(t)^2`` and their ingredients.

    Arrays are per grid time of :attr:`reference` (N samples); ``n`` motors.
    """

    reference: ReferenceTable
    params: MultirotorParams
    health: np.ndarray
    R: np.ndarray
    """Input weight of the construction (n, n)."""
    Q_tilde: np.ndarray
    """Decay weight (12, 12): ``dV/dt = -e^T Q~ e`` on the LTV system."""
    A: np.ndarray
    B: np.ndarray
    P: np.ndarray
    K: np.ndarray
    """Feedback ``u = K e + u_r`` (N, n, 12)."""
    S_inv: np.ndarray
    """``(P + I)^(-1/2)`` (N, 12, 12)."""
    q: np.ndarray
    """``lambda_min(S^-1 Q~ S^-1)`` (N,) [1/s]."""
    pi: np.ndarray
    """Level of the LP (4.24) (N,)."""
    pi_shrunk: np.ndarray
    """Level after the nonlinear shrink (4.26-4.28) (N,)."""
    upper: np.ndarray
    """Error-state bounds (12) (symmetric) used by the LP."""
    shrink_margin: np.ndarray
    """Largest sampled ``phi`` (4.26 / 4.28) on each boundary (N,) (<= 0)."""

    @property
    def end_time(self) -> float:
        return self.reference.end_time

    def matrices_at(self, t) -> tuple[np.ndarray, np.ndarray, float]:
        """``P~(t) = P + I``, ``K(t)`` and ``pi~(t)`` (held after the end)."""
        Pt = self.reference.interpolate(self.P, t) + np.eye(ERROR_SIZE)
        return Pt, self.reference.interpolate(self.K, t), float(
            self.reference.interpolate(self.pi_shrunk[:, None], t)[0])

    def value(self, t, e) -> float:
        """``V(t, e) = e^T (P(t) + I) e``."""
        Pt, _, _ = self.matrices_at(t)
        return float(e @ Pt @ e)

    def contains(self, t, e, tolerance: float = 0.0) -> bool:
        """True when ``e`` is in the shrunk level set at ``t``."""
        Pt, _, level = self.matrices_at(t)
        return float(e @ Pt @ e) <= level**2 * (1.0 + tolerance)

    def feedback(self, t, x) -> np.ndarray:
        """The local law ``u = K(t) e + u_r(t)`` [N] at plant state ``x`` (not saturated)."""
        xr, ur = self.reference.at(t)
        x = np.asarray(x, dtype=float)
        if x[3:7] @ xr[3:7] < 0:
            x = np.concatenate([x[:3], -x[3:7], x[7:]])
        _, K, _ = self.matrices_at(t)
        return K @ state_error(x, xr) + ur

    def alpha(self, stage_Q, stage_R) -> np.ndarray:
        """``alpha(t) = pi~^2 |S^-1|^2 |Q_F + K^T R_F K|`` (eq. 4.29) (N,)."""
        s = np.linalg.norm(self.S_inv, 2, axis=(1, 2))
        M = stage_Q + np.einsum("kij,il,klm->kjm", self.K, stage_R, self.K)
        return self.pi_shrunk**2 * s**2 * np.linalg.norm(M, 2, axis=(1, 2))

    def penalty_constants(self) -> tuple[float, float]:
        """``beta = p_bar + 1`` and ``gamma = lambda_min(S^-1 Q~ S^-1 |_T) / (2 beta)``."""
        beta = float(np.linalg.norm(self.P, 2, axis=(1, 2)).max()) + 1.0
        return beta, float(self.q[-1]) / (2.0 * beta)

    def terminal_penalty(self, t, stage_Q, stage_R) -> np.ndarray:
        """``E(t)`` of eq. 4.29 (corrected exponent ``exp(-2 gamma (t - T))``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        alpha = self.alpha(stage_Q, stage_R)
        beta, gamma = self.penalty_constants()
        tail = beta * alpha[-1] / (2.0 * gamma)
        dt = self.reference.dt
        # integral_t^T alpha beta: cumulative trapezoid from the end
        segment = 0.5 * dt * (alpha[1:] + alpha[:-1]) * beta
        to_end = np.concatenate([np.cumsum(segment[::-1])[::-1], [0.0]])
        before = self.reference.interpolate(to_end[:, None], t)[:, 0] + tail
        after = tail * np.exp(-2.0 * gamma * np.maximum(t - self.end_time, 0.0))
        return np.where(t < self.end_time, before, after)


def _check_reference(reference: ReferenceTable, params, health, upper: np.ndarray):
    """Raises ``ValueError`` when the reference breaks A1-A4 (bounds, hover at the end)."""
    f_max = params.f_max * (health > 0)
    u = reference.thrusts
    inside = (u >= -1e-9) & (u <= f_max + 1e-9)
    if not inside.all():
        k, i = np.argwhere(~inside)[0]
        raise ValueError(f"reference.motor_thrusts[{i}] = {u[k, i]:.4g} N at t = "
                         f"{reference.time[k]:.3g} s is outside the thrust bounds "
                         f"[0, {f_max[i]:.4g}] N")
    x = reference.state
    for name, block, bound in (("position", slice(0, 3), upper[0]),
                               ("velocity", slice(7, 10), upper[6]),
                               ("rates", slice(10, 13), upper[9])):
        if np.abs(x[:, block]).max() >= bound:
            raise ValueError(f"reference.state {name} leaves the bounds.{name} = {bound:g}")
    if np.abs(x[-1, 7:13]).max() > 1e-6:
        raise ValueError("reference must end in hover (zero velocity and rates at T, "
                         "Argyropoulos 2020, assumption A1)")


def terminal_set(reference: ReferenceTable, params: MultirotorParams, *, R=None,
                 bounds: ErrorBounds | None = None, health=None, q_min: float = 1.0,
                 samples: int = 256, refine: int = 4, shrink_interval: float = 0.1,
                 decay_fraction: float = 0.5, seed: int = 0) -> TerminalSet:
    """Terminal sets along ``reference`` (steps 1-5 of the module docstring).

    ``R`` (n, n or n diagonal) is the input weight of the construction (default
    ``0.1 I`` [1/N^2]); ``bounds`` the state box; ``health`` (n) in [0, 1], 0 for
    failed motors. The shrink samples ``samples`` boundary directions (seeded by
    ``seed``), refines the ``refine`` worst by a local ascent on the sphere, and
    runs every ``shrink_interval`` [s] of the grid (the level in between is linear).
    Raises ``ValueError`` naming the field for a weight that is not positive definite
    or a reference outside (or on) the bounds. At ``T`` the decay rate of eq. 4.26 is
    ``eps = decay_fraction * lambda_min(S^-1 Q~ S^-1)``: with the full ``lambda_min``
    the quadratic part of ``phi_T`` vanishes along the slowest direction and the odd
    cubic remainder is positive on one side of it at every level.
    """
    n = params.num_motors
    h = np.ones(n) if health is None else np.asarray(health, dtype=float)
    R = positive_definite("R", 0.1 * np.ones(n) if R is None else R, n)
    bounds = bounds or ErrorBounds()
    upper = bounds.upper()
    _check_reference(reference, params, h, upper)
    A, B = ltv_error_system(reference, params, h)
    Rinv = np.linalg.inv(R)
    G = B @ Rinv @ B.transpose(0, 2, 1)
    Qt = find_q_tilde(A, G, q_min, coarse_step=max(int(round(0.1 / reference.dt)), 1))
    Q = Qt + A + A.transpose(0, 2, 1) + G
    P_T = solve_continuous_are(A[-1], B[-1], Q[-1], R)
    P = _riccati_backward(A, B, Q, R, reference.dt, P_T)
    eye = np.eye(ERROR_SIZE)
    K = -0.5 * np.einsum("ij,kjl->kil", Rinv, B.transpose(0, 2, 1) @ (P - eye))
    S_inv = np.array([np.real(np.linalg.inv(sqrtm(Pk + eye))) for Pk in P])
    S_inv = 0.5 * (S_inv + S_inv.transpose(0, 2, 1))
    q = np.array([np.linalg.eigvalsh(Si @ Qt @ Si).min() for Si in S_inv])
    caps = _level_caps(reference, params, h, upper, K, S_inv)
    if caps.min() <= 0:
        k = int(np.argmin(caps))
        raise ValueError(f"reference.motor_thrusts or reference.state sits on a bound at "
                         f"t = {reference.time[k]:.3g} s: the terminal set is empty there")
    pi = _level_lp(reference.dt, q, caps)
    shrunk, margin = _shrink(reference, params, h, A, B, K, P, Qt, S_inv, pi, q,
                             samples, refine,
                             max(int(round(shrink_interval / reference.dt)), 1), seed,
                             decay_fraction)
    return TerminalSet(reference=reference, params=params, health=h, R=R, Q_tilde=Qt, A=A,
                       B=B, P=P, K=K, S_inv=S_inv, q=q, pi=pi, pi_shrunk=shrunk,
                       upper=upper, shrink_margin=margin)


def _level_caps(reference, params, h, upper, K, S_inv) -> np.ndarray:
    """Largest ``pi`` each row of eq. 4.24e-h allows, per grid time (N,)."""
    sigma = np.linalg.norm(S_inv, axis=2)  # rows of S^-1 (N, 12)
    ref_err = np.zeros((len(reference.time), ERROR_SIZE))  # reference error layout
    x = reference.state
    ref_err[:, 0:3], ref_err[:, 6:9], ref_err[:, 9:12] = x[:, 0:3], x[:, 7:10], x[:, 10:13]
    gap = np.minimum(np.abs(upper - ref_err), np.abs(-upper - ref_err))
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.where(sigma > 0, gap / sigma, np.inf).min(axis=1)
        kappa = np.linalg.norm(K @ S_inv, axis=2)  # (N, n)
        f_max = params.f_max * (h > 0)
        ugap = np.minimum(np.abs(reference.thrusts), np.abs(f_max - reference.thrusts))
        ucap = np.where(kappa > 1e-12, ugap / kappa, np.inf).min(axis=1)
    return np.minimum(cap, ucap)


def _sphere(rng, count: int, dim: int) -> np.ndarray:
    b = rng.normal(size=(count, dim))
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def _shrink(reference, params, h, A, B, K, P, Qt, S_inv, pi, q, samples, refine, stride,
            seed, eps_fraction):
    """Backward sweep of eq. 4.26-4.28 (halving, then bisection between the last failing
    and the first passing level)."""
    fn = compiled_error_dynamics(params)
    rng = np.random.default_rng(seed)
    directions = _sphere(rng, samples, ERROR_SIZE)
    eye = np.eye(ERROR_SIZE)
    N = len(pi)
    idx = sorted(set(range(0, N, stride)) | {N - 1})
    shrunk = np.array(pi, dtype=float)
    margin = np.zeros(N)
    eps = eps_fraction * q[-1]
    nxt = None  # (index, level) of the later grid time already shrunk

    def worst(k, level, rate):
        Pt = P[k] + eye
        Acl = A[k] + B[k] @ K[k]
        xr, ur = reference.state[k], reference.thrusts[k] * h

        def phi(b):
            e = level * b @ S_inv[k]
            u = (e @ K[k].T + ur) * h
            Phi = fn.batch_value(e, u, np.broadcast_to(xr, (len(e), STATE_SIZE)),
                                 np.broadcast_to(ur, u.shape)) - e @ Acl.T
            val = 2 * np.einsum("bi,ij,bj->b", e, Pt, Phi) - np.einsum("bi,ij,bj->b", e, Qt, e)
            return val + (eps * np.einsum("bi,ij,bj->b", e, Pt, e) if rate is None
                          else -2.0 * level * rate)
        weak = np.linalg.eigh(S_inv[k] @ Qt @ S_inv[k])[1].T  # slowest decay first
        return _sphere_max(phi, np.concatenate([directions, weak, -weak]), refine)

    for k in reversed(idx):
        level = pi[k] if nxt is None else min(pi[k], 1.05 * nxt[1])
        rate_of = (lambda lv, k=k: None) if nxt is None else \
            (lambda lv, k=k, j=nxt: (j[1] - lv) / (reference.dt * (j[0] - k)))
        value = worst(k, level, rate_of(level))
        passing, fail = (level, None) if value <= 0 else (None, level)
        while passing is None and level > 1e-9 * pi[k]:
            level *= 0.5
            v = worst(k, level, rate_of(level))
            if v <= 0:
                passing, value = level, v
            else:
                fail = level
        if passing is None:
            raise ValueError(f"no level passes the shrink test at t = {reference.time[k]:.3g} s")
        for _ in range(5 if fail is not None else 0):  # bisection: passing < fail
            mid = 0.5 * (passing + fail)
            v = worst(k, mid, rate_of(mid))
            if v <= 0:
                passing, value = mid, v
            else:
                fail = mid
        shrunk[k], margin[k] = passing, value
        nxt = (k, passing)
    for a, b in zip(idx[:-1], idx[1:], strict=True):  # linear between shrink times
        w = (np.arange(a + 1, b) - a) / (b - a)
        shrunk[a + 1:b] = np.minimum((1.0 - w) * shrunk[a] + w * shrunk[b], pi[a + 1:b])
        margin[a + 1:b] = np.maximum(margin[a], margin[b])
    return shrunk, margin


def _sphere_max(phi, directions, refine: int, steps: int = 6) -> float:
    """Max of ``phi`` over the unit sphere: the sampled ``directions``, then projected
    gradient ascent (central differences, one batch per step, three trial step sizes)
    from the ``refine`` best samples."""
    values = phi(directions)
    best = float(values.max())
    if refine <= 0:
        return best
    order = np.argsort(values)[-refine:]
    b, base = directions[order].copy(), values[order]
    d = directions.shape[1]
    delta, step = 1e-4, 0.3
    eye = np.eye(d)
    for _ in range(steps):
        probes = np.concatenate([b[:, None, :] + delta * eye, b[:, None, :] - delta * eye], 1)
        v = phi(probes.reshape(-1, d)).reshape(refine, 2 * d)
        grad = (v[:, :d] - v[:, d:]) / (2 * delta)
        grad -= np.einsum("ri,ri->r", grad, b)[:, None] * b  # tangent to the sphere
        norm = np.linalg.norm(grad, axis=1, keepdims=True)
        direction = grad / np.maximum(norm, 1e-300)
        trials = b[:, None, :] + np.array([step, step / 4, step / 16])[None, :, None] \
            * direction[:, None, :]
        trials /= np.linalg.norm(trials, axis=2, keepdims=True)
        tv = phi(trials.reshape(-1, d)).reshape(refine, 3)
        j = tv.argmax(axis=1)
        better = tv[np.arange(refine), j] > base
        b[better] = trials[np.arange(refine), j][better]
        base = np.maximum(base, tv[np.arange(refine), j])
        step *= 0.5
    return max(best, float(base.max()))


@dataclasses.dataclass(frozen=True)
class InvarianceCheck:
    """Sampled check of Argyropoulos 2020, Theorem 1 (eq. 4.5) on the nonlinear plant."""

    trajectories: int
    worst_level_ratio: float
    """Largest ``V(t, e(t)) / pi~(t)^2`` met along the trajectories (<= 1: invariant)."""
    worst_decrease: float
    """Largest ``(dE/dt + F) / |dE/dt|`` (<= 0: eq. 4.5b holds)."""
    worst_input_excess: float
    """Largest excursion of ``K e + u_r`` outside ``[0, f_max]`` [N] (<= 0: inside)."""
    worst_state_ratio: float
    """Largest ``|x_i - bound|`` ratio ``|e_i| / gap_i`` of the box rows (<= 1: inside)."""


@functools.cache
def _compiled_plant(params: MultirotorParams) -> tuple[CompiledFunction, CompiledFunction]:
    n = params.num_motors
    plant = CompiledFunction(lambda x, u, h: multirotor_derivatives(x, u, params, h),
                             [STATE_SIZE, n, n], name="multirotor_derivatives")
    error = CompiledFunction(state_error, [STATE_SIZE, STATE_SIZE], name="state_error")
    return plant, error


def check_invariance(ts: TerminalSet, times, count: int, stage_Q, stage_R, *,
                     duration: float = 2.0, step: float = 0.01, seed: int = 0) -> InvarianceCheck:
    """Simulates the nonlinear plant under ``u = K(t) e + u_r`` from ``count`` initial
    errors on the boundary of the shrunk set at each start time in ``times`` (RK4,
    ``step`` [s], for ``duration`` [s]) and reports the worst margins of eq. 4.5."""
    if ts.params.motor_time_constant > 0:
        raise ValueError("check_invariance needs params.motor_time_constant = 0")
    plant, error = _compiled_plant(ts.params)
    rng = np.random.default_rng(seed)
    beta, gamma = ts.penalty_constants()
    alpha = ts.alpha(stage_Q, stage_R)
    f_max = ts.params.f_max * (ts.health > 0)
    h = np.broadcast_to(ts.health, (count, ts.params.num_motors))
    worst = np.full(4, -np.inf)
    for t0 in np.atleast_1d(times):
        xr, _ = ts.reference.at(t0)
        _, _, level = ts.matrices_at(t0)
        S_inv = ts.reference.interpolate(ts.S_inv, t0)
        e0 = level * _sphere(rng, count, ERROR_SIZE) @ S_inv
        x = compose_states(xr, e0)
        t = float(t0)
        for _ in range(int(round(duration / step)) + 1):
            e, u, stats = _law(ts, error, x, t, count)
            ratio = stats[0] / stats[1] ** 2
            F = (np.einsum("bi,ij,bj->b", e, stage_Q, e)
                 + np.einsum("bi,ij,bj->b", stats[2], stage_R, stats[2]))
            Edot = -beta * (float(ts.reference.interpolate(alpha[:, None], t)[0])
                            if t < ts.end_time else
                            alpha[-1] * np.exp(-2.0 * gamma * (t - ts.end_time)))
            gap = np.maximum(ts.upper - np.abs(_reference_layout(xr)), 1e-12)
            worst = np.maximum(worst, [ratio.max(), ((Edot + F) / abs(Edot)).max(),
                                       max((-u).max(), (u - f_max).max()),
                                       (np.abs(e) / gap).max()])
            x = _rk4(lambda xx, tt: plant.batch_value(xx, _law(ts, error, xx, tt, count)[1], h),
                     x, t, step)
            t += step
            xr, _ = ts.reference.at(t)
    return InvarianceCheck(count * len(np.atleast_1d(times)), *map(float, worst))


def compose_states(x_ref, errors) -> np.ndarray:
    """Plant states (B, 13) at errors (B, 12) about one reference state (float batch)."""
    return np.array([compose_state(x_ref, e) for e in errors])


def _reference_layout(x_ref) -> np.ndarray:
    out = np.zeros(ERROR_SIZE)
    out[0:3], out[6:9], out[9:12] = x_ref[0:3], x_ref[7:10], x_ref[10:13]
    return out


def _law(ts: TerminalSet, error: CompiledFunction, x, t, count):
    """Error, local-law input and ``(V, pi~, u - u_r)`` for a batch of plant states."""
    xr, ur = ts.reference.at(t)
    e = error.batch_value(x, np.broadcast_to(xr, x.shape))
    Pt, K, level = ts.matrices_at(t)
    w = e @ K.T
    return e, (w + ur) * ts.health, (np.einsum("bi,ij,bj->b", e, Pt, e), level, w)


def _rk4(f, x, t, h):
    k1 = f(x, t)
    k2 = f(x + 0.5 * h * k1, t + 0.5 * h)
    k3 = f(x + 0.5 * h * k2, t + 0.5 * h)
    k4 = f(x + h * k3, t + h)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
