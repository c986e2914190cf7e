"""Equality-constrained linear-quadratic problems along a horizon, by a Riccati recursion.

The problem (time-varying, affine dynamics, initial state fixed)::

    minimise    sum_{j=0}^{N-1} (1/2 u_j^T R_j u_j + r_j^T u_j)
              + sum_{j=1}^{N}   (1/2 x_j^T Q_j x_j + q_j^T x_j)
    subject to  x_{j+1} = A_j x_j + B_j u_j + c_j,   x_0 given,

with ``Q_j`` positive semi-definite and ``R_j`` positive definite, is solved exactly
by the backward Riccati recursion of the value function ``1/2 x^T P_j x + p_j^T x``
and a forward rollout of ``u_j = K_j x_j + k_j`` (dynamic programming; Rawlings,
Mayne & Diehl 2017, sec. 1.3 and 8.8.3). The cost is ``O(N)`` small dense products,
against ``O(N^3)`` for the dense condensed problem.

A QP with inequality constraints added to this problem has this solution whenever it
satisfies every inequality: it then meets the QP's KKT conditions with zero
multipliers, and a convex QP has no other optimum. The NMPC uses that as the fast
path of its sparse QP (:mod:`drake_uav.optimization.nmpc`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.linalg.lapack import dposv

__all__ = ["LqSolution", "solve_lq", "terminal_sensitivity"]


@dataclasses.dataclass(frozen=True)
class LqSolution:
    """States (N+1, nx), inputs (N, nu), feedback gains ``u_j = K_j x_j + k_j`` (N, nu, nx)
    and the stage Hessians ``R_j + B_j^T P_{j+1} B_j`` (N, nu, nu)."""

    X: np.ndarray
    U: np.ndarray
    K: np.ndarray
    Huu: np.ndarray


def solve_lq(x0, A, B, c, Q, q, R, r, terminal=None) -> LqSolution:
    """The solution of the problem of the module docstring.

    ``A`` (N, nx, nx), ``B`` (N, nx, nu), ``c`` (N, nx); ``Q`` (N, nx, nx), ``q`` (N, nx)
    weight ``x_1..x_N``; ``R`` (N, nu, nu), ``r`` (N, nu) weight ``u_0..u_{N-1}``.
    ``terminal = (W, w)`` adds ``1/2 x_N^T W x_N + w^T x_N`` (a multiplier term).
    Units are those of the caller. Raises ``numpy.linalg.LinAlgError`` when a stage
    Hessian ``R_j + B_j^T P_{j+1} B_j`` is not positive definite.

    The value function is carried in homogeneous form ``[x; 1]^T Pa [x; 1]`` and each
    stage as one product ``Ma^T Pa Ma`` with ``Ma = [[A, c, B], [0, 1, 0]]``, so that a
    stage costs three small products and one Cholesky solve (LAPACK ``dposv``).
    """
    N, nx, nu = B.shape
    na = nx + 1
    Ma = np.zeros((N, na, na + nu))
    Ma[:, :nx, :nx], Ma[:, :nx, nx], Ma[:, :nx, na:] = A, c, B
    Ma[:, nx, nx] = 1.0
    Ca = np.zeros((N, na + nu, na + nu))  # input cost in homogeneous form
    Ca[:, na:, na:], Ca[:, na:, nx], Ca[:, nx, na:] = R, r, r
    Qa = np.zeros((N, na, na))  # state cost of x_1..x_N in homogeneous form
    Qa[:, :nx, :nx], Qa[:, :nx, nx], Qa[:, nx, :nx] = Q, q, q
    Pa = Qa[-1].copy()
    if terminal is not None:
        Pa[:nx, :nx] += terminal[0]
        Pa[:nx, nx] += terminal[1]
        Pa[nx, :nx] += terminal[1]
    gains = np.empty((N, nu, na))
    Huu = np.empty((N, nu, nu))
    for j in range(N - 1, -1, -1):
        W = Ma[j].T @ (Pa @ Ma[j]) + Ca[j]
        Huu[j] = W[na:, na:]
        _, sol, info = dposv(W[na:, na:], W[na:, :na])
        if info:
            raise np.linalg.LinAlgError(f"stage Hessian {j} is not positive definite")
        gains[j] = sol
        if j:
            Pa = Qa[j - 1] + W[:na, :na] - W[:na, na:] @ sol
    X = np.empty((N + 1, nx))
    U = np.empty((N, nu))
    X[0] = x0
    z = np.ones(na + nu)
    z[:nx] = x0
    for j in range(N):
        U[j] = z[na:] = -(gains[j] @ z[:na])
        X[j + 1] = z[:nx] = Ma[j, :nx] @ z
    return LqSolution(X, U, -gains[:, :, :nx], Huu)


def terminal_sensitivity(sol: LqSolution, A, B) -> np.ndarray:
    """``G = dx_N / dw`` (nx, nx) for a linear term ``w^T x_N`` added to the cost.

    ``G = -sum_j Phi_{N,j+1} B_j H_j^-1 B_j^T Phi_{N,j+1}^T`` with the closed-loop
    transitions ``Phi`` of ``A_j + B_j K_j`` and the stage Hessians ``H_j`` (the
    feedforward of stage ``j`` moves by ``-H_j^-1 B_j^T Phi_{N,j+1}^T w``). Negative
    semi-definite; singular where ``x_N`` cannot be moved.
    """
    N, nx = A.shape[0], A.shape[1]
    Phi = np.empty((N, nx, nx))  # Phi[j] = Phi_{N, j+1}
    Phi[N - 1] = np.eye(nx)
    closed = A + B @ sol.K
    for j in range(N - 1, 0, -1):
        Phi[j - 1] = Phi[j] @ closed[j]
    Y = Phi @ B
    return -np.sum(Y @ np.linalg.solve(sol.Huu, np.swapaxes(Y, 1, 2)), axis=0)
