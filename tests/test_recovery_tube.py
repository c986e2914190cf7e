"""Recovery tubes (Argyropoulos 2020, sec. 5.2): the solver set-up on a known answer, the
yaw-free attitude model against the full model, caching, symmetry and run-time queries."""

import math
import subprocess
import sys

import numpy as np
import pytest

from drake_uav.model.multirotor import motor_wrench, multirotor_dynamics
from drake_uav.model.rotations import quat_multiply
from drake_uav.model.tilt import (
    down_in_body,
    quaternion_from_tilt,
    tilt_coordinates,
    tilt_dynamics,
)
from drake_uav.optimization import reachability as rt
from drake_uav.optimization.reachability import (
    TubeSettings,
    backward_reachable_tube,
    recovery_tube,
    solve_value_function,
)
from drake_uav.vehicles import hexacopter

HEX = hexacopter(f_max=10.0)
COARSE = TubeSettings.coarse()


def _states(reduced, yaw=0.0, yaw_rate=0.0):
    """13-states (N, 13) with tilt coordinates and roll/pitch rates ``reduced`` (N, 4)."""
    reduced = np.atleast_2d(reduced)
    x = np.zeros((len(reduced), 13))
    heading = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    for k, (sx, sy, p, q) in enumerate(reduced):
        x[k, 3:7] = quat_multiply(heading, np.array(quaternion_from_tilt((sx, sy))))
        x[k, 10:13] = (p, q, yaw_rate)
    return x


def _sample_reduced(settings, count, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(settings.lower, settings.upper, size=(count, 4))


def test_double_integrator_tube_matches_the_minimum_time_answer_within_one_cell():
    """x1' = x2, x2' = u, |u| <= 1, target |x1| <= a: the tube of horizon T holds the
    states whose minimum time t* = |x2| +- ... reaching the slab is <= T (analytic)."""
    import hj_reachability as hj
    import jax.numpy as jnp

    class DoubleIntegrator(hj.ControlAndDisturbanceAffineDynamics):
        def open_loop_dynamics(self, state, time):
            return jnp.array([state[1], 0.0])

        def control_jacobian(self, state, time):
            return jnp.array([[0.0], [1.0]])

        def disturbance_jacobian(self, state, time):
            return jnp.zeros((2, 1))

    dynamics = DoubleIntegrator("min", "max", hj.sets.Box(jnp.array([-1.0]), jnp.array([1.0])),
                                hj.sets.Box(jnp.zeros(1), jnp.zeros(1)))
    a, T, n = 0.5, 1.0, 81
    grid = hj.Grid.from_lattice_parameters_and_boundary_conditions(
        hj.sets.Box(jnp.array([-3.0, -3.0]), jnp.array([3.0, 3.0])), (n, n))
    x1, x2 = np.meshgrid(*[np.asarray(c) for c in grid.coordinate_vectors], indexing="ij")
    value = backward_reachable_tube(dynamics, grid, jnp.asarray(np.abs(x1) - a), T, "medium")
    # Minimum time to the slab: outside it, push towards it at full acceleration.
    with np.errstate(invalid="ignore"):
        reach = np.where(x1 > a, x2 + np.sqrt(x2 ** 2 + 2 * (x1 - a)),
                         np.where(x1 < -a, -x2 + np.sqrt(x2 ** 2 + 2 * (-a - x1)), 0.0))
    analytic = np.nan_to_num(reach, nan=np.inf) <= T
    numeric = value <= 0.0
    # A node may differ only where the analytic membership changes within one cell.
    padded = np.pad(analytic, 1, mode="edge")
    near_boundary = np.zeros_like(analytic)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            near_boundary |= padded[1 + di:n + 1 + di, 1 + dj:n + 1 + dj] != analytic
    wrong = numeric != analytic
    print(f"\ndouble integrator: {wrong.sum()} of {n * n} nodes differ, "
          f"{(wrong & ~near_boundary).sum()} more than one cell from the analytic boundary; "
          f"tube {numeric.mean():.3f} of the grid vs {analytic.mean():.3f}")
    assert not np.any(wrong & ~near_boundary)
    # The tube is non-trivial and bigger than the target (freezing keeps the target in).
    assert 0.3 < analytic.mean() < 0.8 and np.all(numeric[np.abs(x1) <= a])


def test_tilt_dynamics_reproduce_the_full_model():
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        if down_in_body(q)[2] < -0.5:
            q = q[[1, 0, 3, 2]] * [1, -1, 1, -1]  # keep away from the inverted pole
        x = np.zeros(13)
        x[3:7], x[10:13] = q, rng.normal(scale=3.0, size=3)
        f = rng.uniform(0.0, HEX.f_max, size=6)
        full = multirotor_dynamics(x, motor_wrench(f, HEX), HEX)
        s = np.array(tilt_coordinates(down_in_body(q)))
        h = 1e-7
        s_next = np.array(tilt_coordinates(down_in_body(q + h * full[3:7])))
        reduced = tilt_dynamics(s, x[10:13], motor_wrench(f, HEX)[1:], HEX)
        np.testing.assert_allclose(reduced[:2], (s_next - s) / h, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(reduced[2:], full[10:13], rtol=1e-12)
        np.testing.assert_allclose(down_in_body(quaternion_from_tilt(s)), down_in_body(q),
                                   atol=1e-12)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("tubes")


@pytest.fixture(scope="module")
def single(cache):
    return recovery_tube(HEX, [0], COARSE, cache_dir=cache)


def test_hover_is_inside_and_a_tumble_is_outside(single):
    hover = _states([0.0, 0.0, 0.0, 0.0], yaw=1.0)[0]
    assert single.contains(hover) and single.value(hover) <= -0.99
    tumble = _states([0.9, 0.0, 0.0, -COARSE.rate_limit])[0]  # 84 deg, pitching further away
    assert not single.contains(tumble)
    # The target set (a cone of theta_th, rates within omega_th) lies in the tube.
    half = np.array([math.tan(COARSE.theta_th / 2)] * 2 + [COARSE.omega_th] * 2)
    target = np.random.default_rng(3).uniform(-half, half, size=(2000, 4))
    tilt = 2 * np.arctan(np.hypot(target[:, 0], target[:, 1]))
    inside_target = (tilt < 0.9 * COARSE.theta_th) & (
        np.hypot(target[:, 2], target[:, 3]) < 0.9 * COARSE.omega_th)
    assert inside_target.sum() > 0 and np.all(single.contains(_states(target[inside_target])))


def test_value_of_a_batch_equals_the_values_one_by_one(single):
    states = _states(_sample_reduced(COARSE, 20, seed=4), yaw=-2.0, yaw_rate=0.5)
    batch = single.value(states)
    assert batch.shape == (20,)
    np.testing.assert_allclose(batch, [single.value(x) for x in states], rtol=0, atol=1e-12)
    assert np.array_equal(single.contains(states), batch <= 0)
    # Heading does not matter.
    np.testing.assert_allclose(single.value(_states(_sample_reduced(COARSE, 20, seed=4),
                                                    yaw=2.5, yaw_rate=0.5)), batch, atol=1e-9)


def test_states_beyond_the_grid_or_spinning_fast_are_outside(single):
    level = _states([0.0, 0.0, 0.0, 0.0])[0]
    fast_roll = level.copy()
    fast_roll[10] = 2 * COARSE.rate_limit
    spinning = level.copy()
    spinning[12] = single.yaw_rate_limit + 0.1
    inverted = level.copy()
    inverted[3:7] = [0.0, 1.0, 0.0, 0.0]
    for state in (fast_roll, spinning, inverted):
        assert not single.contains(state)
    assert single.value(inverted) == np.inf
    # Band: the query limit plus 0.3 s of the largest yaw acceleration (3 motors of one
    # spin at f_max: 3 km f_max / J_z = 12 rad/s^2).
    assert single.yaw_rate_band == pytest.approx(COARSE.yaw_rate_limit + 0.3 * 12.0)


def test_cached_tube_loads_without_solving_and_without_jax(single, cache, monkeypatch):
    files = list(cache.glob("*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(rt, "solve_value_function", lambda *a: pytest.fail("solved again"))
    again = recovery_tube(HEX, [0], COARSE, cache_dir=cache)
    np.testing.assert_array_equal(again.values.values, single.values.values)
    # A fresh interpreter loads and queries the cached tube without importing JAX.
    script = (
        "import sys, numpy as np\n"
        "from drake_uav.optimization.reachability import recovery_tube, TubeSettings\n"
        "from drake_uav.vehicles import hexacopter\n"
        f"tube = recovery_tube(hexacopter(f_max=10.0), [3], TubeSettings.coarse(), "
        f"cache_dir={str(cache)!r})\n"
        "x = np.zeros(13); x[3] = 1.0\n"
        "assert tube.contains(x) and tube.canonical_failed_motors == (0,)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'hj_reachability')))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


def test_other_settings_or_vehicles_get_their_own_cache_entry(single, cache, monkeypatch):
    calls = []
    monkeypatch.setattr(rt, "solve_value_function",
                        lambda p, f, s: calls.append((p.f_max, f, s.horizon))
                        or np.zeros(s.shape))
    recovery_tube(HEX, [0], TubeSettings.coarse(horizon=0.4), cache_dir=cache)
    recovery_tube(hexacopter(f_max=9.0), [0], COARSE, cache_dir=cache)
    recovery_tube(HEX, [0, 3], COARSE, cache_dir=cache)
    assert calls == [(10.0, (0,), 0.4), (9.0, (0,), 0.3), (10.0, (0, 3), 0.3)]


def test_symmetric_failure_sets_share_one_solution(cache):
    # The mirror y -> -y maps motor 0 onto motor 5 and the grid onto itself.
    mirrored = recovery_tube(HEX, [5], COARSE, cache_dir=cache)
    assert mirrored.canonical_failed_motors == (0,) and mirrored.symmetry.orientation == -1
    direct = solve_value_function(HEX, [5], COARSE)
    nodes = np.stack(np.meshgrid(*mirrored.values.coordinates, indexing="ij"), -1)
    nodes = nodes.reshape(-1, 4)
    from_symmetry = mirrored.value(_states(nodes, yaw=0.3, yaw_rate=0.0))
    # Equal up to the float32 solver and the upwind stencils' tie-breaking.
    np.testing.assert_allclose(from_symmetry, direct.ravel(), atol=5e-3)
    orbit = {recovery_tube(HEX, [k], COARSE, cache_dir=cache).canonical_failed_motors
             for k in range(6)}
    assert orbit == {(0,)}


@pytest.mark.parametrize("failed, match", [
    ([6], "failed_motors: motor 6 does not exist"),
    ([2, 2], "failed_motors lists a motor twice"),
])
def test_bad_failure_sets_are_refused_by_name(failed, match, tmp_path):
    with pytest.raises(ValueError, match=match):
        recovery_tube(HEX, failed, COARSE, cache_dir=tmp_path)


@pytest.mark.parametrize("field, value", [
    ("theta_th", -0.1), ("omega_th", float("nan")), ("horizon", 0.0), ("tilt_limit", 3.5),
    ("yaw_rate_limit", -1.0),
    ("tilt_points", 16), ("rate_points", 3), ("accuracy", "best"), ("rate_target", "cube"),
])
def test_bad_settings_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=f"TubeSettings.{field}"):
        TubeSettings(**{field: value})


def test_a_target_finer_than_the_grid_is_refused():
    with pytest.raises(ValueError, match="TubeSettings.tilt_points"):
        TubeSettings(theta_th=math.radians(2.0))


def test_bad_states_are_refused(single):
    with pytest.raises(ValueError, match="state must be"):
        single.value(np.zeros(12))
    with pytest.raises(ValueError, match="non-finite"):
        single.value(np.full(13, np.nan))


@pytest.mark.slow
@pytest.mark.parametrize("failed", [[0], [0, 2]], ids=["single", "one-apart pair"])
def test_two_resolutions_agree_on_membership(failed, tmp_path):
    """The default grid against a finer one: same membership on >= 95 % of random states."""
    coarse = TubeSettings()
    fine = TubeSettings(tilt_points=coarse.tilt_points + 4, rate_points=coarse.rate_points + 4)
    tubes = [recovery_tube(HEX, failed, s, cache_dir=tmp_path) for s in (coarse, fine)]
    states = _states(_sample_reduced(fine, 20000, seed=2026), yaw=0.7, yaw_rate=1.0)
    inside = [tube.contains(states) for tube in tubes]
    agreement = np.mean(inside[0] == inside[1])
    print(f"\nmotors {failed} out: grids {coarse.shape} and {fine.shape} agree on "
          f"{agreement:.4f} of 20000 states (inside: {inside[0].mean():.3f}, "
          f"{inside[1].mean():.3f})")
    assert agreement >= 0.95


def test_the_hexacopter_frame_has_six_symmetries_and_four_closure_classes():
    from itertools import combinations

    from drake_uav.optimization.allocation import closure_holds
    from drake_uav.optimization.frame_symmetry import canonical_failure_set, frame_symmetries

    group = frame_symmetries(HEX)
    assert len(group) == 6 and sorted(s.orientation for s in group) == [-1, -1, -1, 1, 1, 1]
    closure_sets = [c for k in (1, 2, 3) for c in combinations(range(6), k)
                    if closure_holds(HEX, c)]
    classes = {}
    for failed in closure_sets:
        canonical, symmetry = canonical_failure_set(group, failed)
        assert symmetry.apply(failed) == canonical
        classes.setdefault(canonical, []).append(failed)
    assert {c: len(members) for c, members in classes.items()} == {
        (0,): 6, (0, 3): 3, (0, 2): 6, (0, 2, 4): 2}
    # Keeping the square |p|, |q| <= c leaves the identity and the mirror y -> -y.
    square = frame_symmetries(HEX, square_rates=True)
    assert [s.permutation for s in square] == [(0, 1, 2, 3, 4, 5), (5, 4, 3, 2, 1, 0)]
