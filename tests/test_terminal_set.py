"""Time-varying terminal sets (Argyropoulos 2020, ch. 4) along a minimum-snap reference."""

import numpy as np
import pytest
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff

from drake_uav.model.attitude_error import (
    compose_state,
    error_dynamics,
    error_jacobians,
    state_error,
)
from drake_uav.optimization.flatness import flat_reference, velocity_heading
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.optimization.terminal_set import (
    ErrorBounds,
    ReferenceTable,
    check_invariance,
    ltv_error_system,
    terminal_set,
)
from drake_uav.vehicles.multirotor import hexacopter

SHORT = np.array([[0, 0, -1], [1.5, 0.5, -1.5], [2.5, 2.0, -2.0]], dtype=float)
STAGE_Q = np.diag([10.0] * 3 + [2.0] * 3 + [1.0] * 3 + [0.1] * 3)
STAGE_R = 0.05 * np.eye(6)


def _table(waypoints, duration, params, dt=0.005):
    traj = minimum_snap(waypoints, np.linspace(0.0, duration, len(waypoints)))
    t = np.arange(0.0, duration + dt / 2, dt)
    ref = flat_reference(traj, params, t, yaw=velocity_heading(traj))
    return ReferenceTable(ref.time, ref.state, ref.motor_thrusts)


@pytest.fixture(scope="module")
def params():
    return hexacopter()


@pytest.fixture(scope="module")
def table(params):
    return _table(SHORT, 4.0, params)


@pytest.fixture(scope="module")
def tset(table, params):
    return terminal_set(table, params, R=np.ones(6), samples=128, refine=3)


def test_linearised_error_dynamics_match_autodiff_jacobians(table, params):
    for k in (25, 300, len(table.time) - 1):
        xr, ur = table.state[k], table.thrusts[k]
        z = InitializeAutoDiff(np.concatenate([np.zeros(12), ur]))[:, 0]
        de = error_dynamics(z[:12], z[12:], xr, ur, params)
        A, B = error_jacobians(xr, params.allocation_matrix @ ur, params)
        np.testing.assert_allclose(ExtractValue(de)[:, 0], 0.0, atol=1e-9)
        np.testing.assert_allclose(ExtractGradient(de)[:, :12], A, atol=1e-10)
        np.testing.assert_allclose(ExtractGradient(de)[:, 12:], B @ params.allocation_matrix,
                                   atol=1e-10)


def test_error_map_round_trip(table):
    rng = np.random.default_rng(1)
    for k in (0, 200, 500):
        e = 0.2 * rng.normal(size=12)
        x = compose_state(table.state[k], e)
        assert abs(np.linalg.norm(x[3:7]) - 1.0) < 1e-12
        np.testing.assert_allclose(state_error(x, table.state[k]), e, atol=1e-12)


def test_q_tilde_makes_q_positive_definite(tset):
    Q = tset.Q_tilde + tset.A + tset.A.transpose(0, 2, 1) + \
        tset.B @ np.linalg.inv(tset.R) @ tset.B.transpose(0, 2, 1)
    assert np.linalg.eigvalsh(Q).min() > 0
    assert np.diag(tset.Q_tilde).min() >= 1.0 - 1e-6


def test_riccati_and_lyapunov_decrease(tset):
    """P(T) stationary; on the LTV system dV/dt = -e^T Q~ e (eq. 4.12)."""
    eye = np.eye(12)
    Rinv = np.linalg.inv(tset.R)
    Q = tset.Q_tilde + tset.A + tset.A.transpose(0, 2, 1) + \
        tset.B @ Rinv @ tset.B.transpose(0, 2, 1)
    A, B, P = tset.A[-1], tset.B[-1], tset.P[-1]
    residual = A.T @ P + P @ A - P @ B @ Rinv @ B.T @ P + Q[-1]
    assert np.abs(residual).max() < 1e-6 * np.abs(P).max()
    assert np.linalg.eigvalsh(tset.P).min() >= -1e-9
    dt = tset.reference.dt
    for k in (50, 250, 600):
        M = tset.P[k] + eye
        Mdot = (tset.P[k + 1] - tset.P[k - 1]) / (2 * dt)
        Acl = tset.A[k] + tset.B[k] @ tset.K[k]
        lyap = Mdot + M @ Acl + Acl.T @ M
        assert np.abs(lyap + tset.Q_tilde).max() < 0.02 * np.abs(M).max()


def test_level_lp_constraints(tset, params):
    pi, q, dt = tset.pi, tset.q, tset.reference.dt
    assert pi.min() > 0
    assert np.all(2 * np.diff(pi) >= -dt * pi[:-1] * q[:-1] - 1e-12)  # 2 w >= -q pi
    kappa = np.linalg.norm(tset.K @ tset.S_inv, axis=2)
    u = tset.reference.thrusts
    assert np.all(pi[:, None] * kappa <= np.minimum(u, params.f_max - u) + 1e-6)
    sigma = np.linalg.norm(tset.S_inv, axis=2)
    assert np.all(pi[:, None] * sigma[:, 3:6] <= tset.upper[3] + 1e-6)
    assert np.all(tset.pi_shrunk <= pi + 1e-12) and tset.pi_shrunk.min() > 0
    assert tset.shrink_margin.max() <= 0


def test_terminal_penalty_decreases_with_the_corrected_exponent(tset):
    beta, gamma = tset.penalty_constants()
    T = tset.end_time
    E = tset.terminal_penalty([0.0, 1.0, T - 1e-9, T, T + 1.0], STAGE_Q, STAGE_R)
    assert np.all(np.diff(E) < 0) and E[-1] > 0
    assert abs(E[2] - E[3]) < 1e-6 * E[3]
    assert E[4] == pytest.approx(E[3] * np.exp(-2 * gamma), rel=1e-12)
    alpha = tset.alpha(STAGE_Q, STAGE_R)
    dE = tset.terminal_penalty([1.0 + 1e-4], STAGE_Q, STAGE_R) - \
        tset.terminal_penalty([1.0 - 1e-4], STAGE_Q, STAGE_R)
    k = int(round(1.0 / tset.reference.dt))
    assert dE[0] / 2e-4 == pytest.approx(-alpha[k] * beta, rel=1e-2)


def test_failed_motor_is_a_zero_column(table, params):
    health = np.ones(6)
    health[[0, 3]] = 0.0
    _, B = ltv_error_system(table, params, health)
    _, B1 = ltv_error_system(table, params)
    assert np.all(B[:, :, [0, 3]] == 0.0)
    np.testing.assert_array_equal(B[:, :, [1, 2, 4, 5]], B1[:, :, [1, 2, 4, 5]])


def test_theorem1_sampled_on_the_nonlinear_plant(tset):
    check = check_invariance(tset, [0.0, 2.0, 3.9], 100, STAGE_Q, STAGE_R, duration=1.0)
    assert check.worst_level_ratio <= 1.0 + 1e-6
    assert check.worst_decrease <= 0.0
    assert check.worst_input_excess <= 0.0
    assert check.worst_state_ratio <= 1.0


@pytest.mark.slow
def test_theorem1_campaign(params):
    """2,000 boundary errors at 20 times along the 6-waypoint reference (docs/nmpc.md)."""
    from drake_uav.optimization.nmpc import default_waypoints

    waypoints, duration = default_waypoints()
    ts = terminal_set(_table(waypoints, duration, params), params, R=np.ones(6))
    times = np.linspace(0.0, duration, 20)
    check = check_invariance(ts, times, 2000, STAGE_Q, STAGE_R, duration=2.0)
    print(check)
    # RK4 steps and the linear level between shrink times leave ~1e-5 (docs/nmpc.md)
    assert check.worst_level_ratio <= 1.0 + 1e-4
    assert check.worst_decrease <= 0.0
    assert check.worst_input_excess <= 0.0 and check.worst_state_ratio <= 1.0


def test_bad_input_names_the_field(table, params):
    with pytest.raises(ValueError, match="R must be positive definite"):
        terminal_set(table, params, R=-np.ones(6))
    with pytest.raises(ValueError, match="velocity"):
        terminal_set(table, params, bounds=ErrorBounds(velocity=0.5))
    too_high = ReferenceTable(table.time, table.state, table.thrusts + params.f_max)
    with pytest.raises(ValueError, match="motor_thrusts"):
        terminal_set(too_high, params)
    health = np.ones(6)
    health[2] = 0.0  # the opposite motor idles at hover: on its lower bound
    idle = ReferenceTable(table.time, table.state, params.thrusts_for_wrench(
        table.thrusts @ params.allocation_matrix.T, health))
    with pytest.raises(ValueError, match="sits on a bound"):
        terminal_set(idle, params, health=health)
    with pytest.raises(ValueError, match="ErrorBounds.attitude"):
        ErrorBounds(attitude=0.0)
