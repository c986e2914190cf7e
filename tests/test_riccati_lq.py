"""The Riccati solution of equality-constrained LQ problems and its end-state sensitivity."""

import numpy as np
import pytest

from drake_uav.optimization.riccati_lq import solve_lq, terminal_sensitivity


@pytest.fixture(scope="module")
def problem():
    rng = np.random.default_rng(0)
    N, nx, nu = 12, 5, 2
    A = np.eye(nx) + 0.1 * rng.normal(size=(N, nx, nx))
    B = 0.3 * rng.normal(size=(N, nx, nu))
    c = 0.05 * rng.normal(size=(N, nx))
    G = rng.normal(size=(N, nx - 1, nx))  # semi-definite state weights
    Q = np.swapaxes(G, 1, 2) @ G
    q = rng.normal(size=(N, nx))
    R = np.broadcast_to(0.01 * np.eye(nu), (N, nu, nu))
    r = 0.1 * rng.normal(size=(N, nu))
    return rng.normal(size=nx), A, B, c, Q, q, R, r


def _kkt_solution(x0, A, B, c, Q, q, R, r, w):
    """The same problem as one dense KKT system, z = [u_0..u_{N-1}, x_1..x_N]."""
    N, nx, nu = B.shape
    nz = N * (nu + nx)
    H, g = np.zeros((nz, nz)), np.zeros(nz)
    E, e = np.zeros((N * nx, nz)), np.zeros(N * nx)
    for j in range(N):
        u, x = slice(j * nu, (j + 1) * nu), slice(N * nu + j * nx, N * nu + (j + 1) * nx)
        H[u, u], g[u], H[x, x], g[x] = R[j], r[j], Q[j], q[j]
        rows = slice(j * nx, (j + 1) * nx)
        E[rows, x], E[rows, u] = np.eye(nx), -B[j]
        if j:
            E[rows, N * nu + (j - 1) * nx:N * nu + j * nx] = -A[j]
            e[rows] = c[j]
        else:
            e[rows] = c[0] + A[0] @ x0
    g[-nx:] += w
    K = np.block([[H, E.T], [E, np.zeros((N * nx, N * nx))]])
    z = np.linalg.solve(K, np.concatenate([-g, e]))
    return z[N * nu:nz].reshape(N, nx), z[:N * nu].reshape(N, nu)


def test_riccati_matches_the_kkt_system(problem):
    sol = solve_lq(*problem)
    X, U = _kkt_solution(*problem, w=0.0)
    np.testing.assert_allclose(sol.U, U, atol=1e-10)
    np.testing.assert_allclose(sol.X[1:], X, atol=1e-10)
    np.testing.assert_allclose(sol.X[0], problem[0])


def test_terminal_sensitivity_is_the_end_state_response(problem):
    sol = solve_lq(*problem)
    G = terminal_sensitivity(sol, problem[1], problem[2])
    w = np.array([0.3, -0.2, 0.1, 0.5, -0.4])
    moved = solve_lq(*problem, terminal=(0.0, w))
    np.testing.assert_allclose(moved.X[-1], sol.X[-1] + G @ w, atol=1e-10)
    X, _ = _kkt_solution(*problem, w=w)
    np.testing.assert_allclose(moved.X[1:], X, atol=1e-10)
    assert np.linalg.eigvalsh(0.5 * (G + G.T)).max() <= 1e-12
