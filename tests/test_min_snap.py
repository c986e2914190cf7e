"""Minimum-snap QP (Argyropoulos 2020, eq. 2.1-2.3) and the time allocation of eq. 2.4-2.5."""

import numpy as np
import pytest
from pydrake.solvers import ClarabelSolver, SolutionResult
from scipy.integrate import quad

from drake_uav.optimization.min_snap import (
    MinimumSnap,
    TrajectoryInfeasibleError,
    minimum_snap,
    optimize_segment_times,
)

# A seed-like mission (NED, z up is negative): climb, uneven legs, return.
WAYPOINTS = np.array([[0, 0, 0], [0, 0, -3], [2, 1, -4], [10, 3, -5], [11, 9, -5],
                      [4, 10, -4], [0, 0, -2]], dtype=float)
EQUAL_TIMES = np.linspace(0.0, 24.0, len(WAYPOINTS))


@pytest.fixture(scope="module")
def trajectory():
    return minimum_snap(WAYPOINTS, EQUAL_TIMES)


def _left(t):
    return np.nextafter(t, -np.inf)


def test_passes_every_waypoint(trajectory):
    np.testing.assert_allclose(trajectory.position(EQUAL_TIMES), WAYPOINTS, atol=1e-6)


def test_derivatives_continuous_up_to_order_and_zero_at_ends(trajectory):
    knots = EQUAL_TIMES[1:-1]
    for d in range(1, 5):
        left, right = trajectory.value(_left(knots), d), trajectory.value(knots, d)
        scale = np.abs(trajectory.value(np.linspace(0, 24, 500), d)).max()
        np.testing.assert_allclose(left, right, atol=1e-8 * scale)
        np.testing.assert_allclose(trajectory.value(EQUAL_TIMES[[0, -1]], d), 0, atol=1e-8)
    # The 5th derivative is not constrained and does jump at the keyframes.
    jump = np.abs(trajectory.value(_left(knots), 5) - trajectory.value(knots, 5)).max()
    assert jump > 1e-3


def test_single_segment_is_the_rest_to_rest_smoothstep():
    # With 5 conditions at each end the degree-9 polynomial is unique:
    # 126 s^5 - 420 s^6 + 540 s^7 - 315 s^8 + 70 s^9.
    traj = minimum_snap([[1.0], [3.0]], [2.0, 6.0])
    s = np.linspace(0, 1, 11)
    smooth = 126 * s**5 - 420 * s**6 + 540 * s**7 - 315 * s**8 + 70 * s**9
    np.testing.assert_allclose(traj.position(2.0 + 4.0 * s)[:, 0], 1.0 + 2.0 * smooth,
                               atol=1e-9)


def test_cost_is_the_snap_integral_and_optimal(trajectory):
    integrand = lambda t: np.sum(trajectory.value(t, 4) ** 2)  # noqa: E731
    numeric = sum(quad(integrand, a, b, epsabs=0, epsrel=1e-10)[0]
                  for a, b in zip(EQUAL_TIMES[:-1], EQUAL_TIMES[1:], strict=True))
    assert trajectory.cost() == pytest.approx(numeric, rel=1e-8)
    # Extra continuity shrinks the feasible set, a higher degree enlarges it.
    stricter = minimum_snap(WAYPOINTS, EQUAL_TIMES, continuity=6)
    richer = minimum_snap(WAYPOINTS, EQUAL_TIMES, degree=11)
    assert stricter.cost() >= trajectory.cost() * (1 - 1e-9)
    assert richer.cost() <= trajectory.cost() * (1 + 1e-9)
    # An interior-point solver finds the same optimum.
    clarabel = minimum_snap(WAYPOINTS, EQUAL_TIMES, solver=ClarabelSolver())
    assert clarabel.cost() == pytest.approx(trajectory.cost(), rel=1e-6)


def test_program_built_once_resolves_new_waypoints_and_times():
    program = MinimumSnap(len(WAYPOINTS) - 1)
    rng = np.random.default_rng(0)
    for _ in range(3):
        w = WAYPOINTS + rng.normal(size=WAYPOINTS.shape)
        t = np.concatenate([[0.0], np.cumsum(rng.uniform(1.0, 6.0, len(w) - 1))])
        reused = program.solve(w, t)
        fresh = minimum_snap(w, t)
        np.testing.assert_allclose(reused.coefficients, fresh.coefficients, atol=1e-8)
        np.testing.assert_allclose(reused.position(t), w, atol=1e-6)


def test_drake_piecewise_polynomial_and_holding_outside_span(trajectory):
    pp = trajectory.to_piecewise_polynomial()
    for t in (0.0, 3.3, 11.9, 24.0):
        np.testing.assert_allclose(pp.value(t).ravel(), trajectory.position(t), atol=1e-9)
        np.testing.assert_allclose(pp.EvalDerivative(t, 2).ravel(),
                                   trajectory.acceleration(t), atol=1e-7)
    np.testing.assert_allclose(trajectory.position(30.0), WAYPOINTS[-1], atol=1e-9)
    np.testing.assert_array_equal(trajectory.velocity([-1.0, 30.0]), 0.0)


def test_velocity_and_acceleration_bounds_hold():
    free = minimum_snap(WAYPOINTS, EQUAL_TIMES)
    t = np.linspace(0, 24, 4001)
    v_max = 0.85 * np.abs(free.velocity(t)).max()
    a_max = 0.9 * np.abs(free.acceleration(t)).max()
    bounded = minimum_snap(WAYPOINTS, EQUAL_TIMES, v_max=v_max, a_max=a_max,
                           samples_per_segment=20)
    np.testing.assert_allclose(bounded.position(EQUAL_TIMES), WAYPOINTS, atol=1e-6)
    assert np.abs(bounded.velocity(t)).max() <= v_max * 1.01
    assert np.abs(bounded.acceleration(t)).max() <= a_max * 1.01
    assert bounded.cost() > free.cost()


@pytest.mark.parametrize("waypoints, times, match", [
    ([[0, 0, 0]], [0.0], "at least 2 waypoints"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [0.0, 2.0, 2.0], "strictly increasing"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [0.0, 3.0, 1.0], "strictly increasing"),
    ([[0, 0, 0], [1, 0, 0]], [0.0, 1.0, 2.0], "one entry per waypoint"),
    ([[0, 0, np.nan], [1, 0, 0]], [0.0, 1.0], "finite"),
])
def test_bad_waypoints_and_times(waypoints, times, match):
    with pytest.raises(ValueError, match=match):
        minimum_snap(waypoints, times)


def test_infeasible_bounds():
    with pytest.raises(ValueError, match="v_max"):
        minimum_snap(WAYPOINTS, EQUAL_TIMES, v_max=0.0)
    with pytest.raises(ValueError, match="v_max is infeasible"):
        minimum_snap(WAYPOINTS, EQUAL_TIMES, v_max=1.0)  # leg 2->3 needs 2 m/s north
    with pytest.raises(TrajectoryInfeasibleError, match="kInfeasible") as info:
        minimum_snap(WAYPOINTS, EQUAL_TIMES, a_max=0.05)
    assert isinstance(info.value, ValueError)
    assert info.value.solution_result in (SolutionResult.kInfeasibleConstraints,
                                          SolutionResult.kInfeasibleOrUnbounded)


def test_time_allocation_lowers_cost_and_keeps_total_time():
    result = optimize_segment_times(WAYPOINTS, EQUAL_TIMES)
    assert result.times[0] == EQUAL_TIMES[0] and result.times[-1] == EQUAL_TIMES[-1]
    assert np.all(np.diff(result.times) > 0)
    assert result.cost < 0.7 * result.initial_cost
    assert result.initial_cost == pytest.approx(minimum_snap(WAYPOINTS, EQUAL_TIMES).cost())
    assert np.all(np.diff(result.cost_history) <= 0)
    np.testing.assert_allclose(result.trajectory.position(result.times), WAYPOINTS, atol=1e-6)
    assert result.trajectory.cost() == pytest.approx(result.cost)
    # Stationary: moving time between any two segments does not lower the cost.
    T = np.diff(result.times)
    h = 1e-3 * T.min()
    for i, j in [(0, 1), (2, 3), (1, 5), (4, 2)]:
        for sign in (1, -1):
            U = T.copy()
            U[i] += sign * h
            U[j] -= sign * h
            t = np.concatenate([[0.0], np.cumsum(U)])
            assert minimum_snap(WAYPOINTS, t).cost() >= result.cost * (1 - 1e-4)


def test_time_allocation_keeps_segments_above_the_minimum():
    w = np.array([[0, 0, 0], [0.01, 0, 0], [10, 0, 0]], dtype=float)
    result = optimize_segment_times(w, [0.0, 5.0, 10.0], min_fraction=0.2)
    assert np.diff(result.times).min() >= 0.2 * 10.0 / 2 - 1e-9
    assert result.cost < result.initial_cost


def test_time_allocation_respects_an_active_velocity_bound():
    w = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [12, 0, 0]], dtype=float)
    free = optimize_segment_times(w, [0.0, 3.0, 6.0, 16.0])
    t = np.linspace(0, 16, 2001)
    v_max = 0.95 * np.abs(free.trajectory.velocity(t)).max()
    bounded = optimize_segment_times(w, [0.0, 3.0, 6.0, 16.0], v_max=v_max, max_iterations=40)
    assert np.abs(bounded.trajectory.velocity(t)).max() <= v_max * 1.01
    assert free.cost < bounded.cost < 0.1 * bounded.initial_cost
    assert bounded.times[-1] == 16.0
