"""Closure and maximum thrust after motor failures (Argyropoulos 2020, sec. 5.1, LP 5.22).

The expected values are derived here from the geometry, independently of the module:
closure by searching a closed half-plane that holds every healthy torque column (its
boundary is then perpendicular to one of them), the maximum thrust by enumerating the
vertices of the polytope ``{0 <= f <= f_max, torques = 0}``.
"""

from itertools import combinations, product

import numpy as np
import pytest

from drake_uav.optimization.allocation import (
    canonical_failed_motors,
    closure_holds,
    largest_angular_gap,
    max_thrust,
    max_thrust_allocation,
)
from drake_uav.vehicles import hexacopter, quadrotor_plus, quadrotor_x

HEX = hexacopter()


def _all_failure_sets(n):
    return [s for k in range(1, n + 1) for s in combinations(range(n), k)]


def _closure_by_half_planes(A, failed):
    """True iff no closed half-plane through the origin holds every healthy column."""
    cols = [A[1:3, i] for i in range(A.shape[1]) if i not in failed]
    cols = [c for c in cols if np.linalg.norm(c) > 1e-12]
    if not cols:
        return False
    for c in cols:
        for u in (np.array([-c[1], c[0]]), np.array([c[1], -c[0]])):
            if max(float(u @ a) for a in cols) <= 1e-12 * np.linalg.norm(u) ** 2:
                return False
    # No boundary candidate works; any direction (e.g. minus a column) must also fail.
    return all(max(float(-c @ a) for a in cols) > 0 for c in cols)


def _max_thrust_by_vertices(A, f_max, failed, yaw_free):
    """Largest sum(f) over the vertices of {0 <= f <= f_max, f_failed = 0, torques = 0}."""
    healthy = [i for i in range(A.shape[1]) if i not in failed]
    if not healthy:
        return 0.0
    # Independent torque equations on the healthy motors (a row basis of their columns).
    _, s, vt = np.linalg.svd((A[1:3] if yaw_free else A[1:4])[:, healthy])
    rows = vt[:int(np.sum(s > 1e-12))]
    m = rows.shape[0]
    best = 0.0  # f = 0 is always feasible
    for basis in combinations(range(len(healthy)), m):
        rest = [j for j in range(len(healthy)) if j not in basis]
        B = rows[:, list(basis)]
        if abs(np.linalg.det(B)) < 1e-12:
            continue
        for levels in product((0.0, f_max), repeat=len(rest)):
            g = np.zeros(len(healthy))
            g[rest] = levels
            g[list(basis)] = np.linalg.solve(B, -rows[:, rest] @ np.asarray(levels))
            f = np.zeros(A.shape[1])
            f[healthy] = g
            if np.all(f > -1e-9) and np.all(f < f_max + 1e-9):
                best = max(best, float(f.sum()))
    return best


def _hexa_class(failed):
    """The issue's names of the hexacopter failure classes (0-based motors on a ring of 6)."""
    k = len(failed)
    if k == 1:
        return "single"
    if k == 2:
        return {1: "adjacent", 2: "one apart", 3: "opposite"}[
            min((failed[1] - failed[0]) % 6, (failed[0] - failed[1]) % 6)]
    if k == 3 and failed in ((0, 2, 4), (1, 3, 5)):
        return "alternating triple"
    return f"{k} motors"


def test_hexacopter_closure_and_max_thrust_match_the_geometry_on_all_63_sets():
    A = HEX.allocation_matrix
    rows = []
    for failed in _all_failure_sets(6):
        expected = (_closure_by_half_planes(A, failed),
                    _max_thrust_by_vertices(A, HEX.f_max, failed, True),
                    _max_thrust_by_vertices(A, HEX.f_max, failed, False))
        got = (closure_holds(HEX, failed), max_thrust(HEX, failed),
               max_thrust(HEX, failed, yaw_free=False))
        assert got[0] == expected[0], failed
        assert got[1] == pytest.approx(expected[1], abs=1e-6), failed
        assert got[2] == pytest.approx(expected[2], abs=1e-6), failed
        rows.append((failed, *got))
    assert len(rows) == 63
    # The table, per class: closure, F_max/f_max yaw free, F_max/f_max zero yaw.
    table = {}
    for failed, closure, yaw_free, zero_yaw in rows:
        entry = (closure, round(yaw_free / HEX.f_max, 6), round(zero_yaw / HEX.f_max, 6))
        table.setdefault(_hexa_class(failed), set()).add(entry)
    print("\nclass: {(closure, F_max/f_max yaw free, zero yaw)}")
    for name, entries in table.items():
        print(f"  {name}: {sorted(entries)}")
    assert table["single"] == {(True, 4.0, 4.0)}
    assert table["opposite"] == {(True, 4.0, 4.0)}
    assert table["one apart"] == {(True, 3.0, 2.0)}
    assert table["adjacent"] == {(False, 2.0, 2.0)}
    assert table["alternating triple"] == {(True, 3.0, 0.0)}
    assert {c for c, _, _ in table["3 motors"]} == {False}
    assert {y for _, y, _ in table["3 motors"]} == {0.0, 2.0}
    assert sum(closure for _, closure, _, _ in rows) == 17
    assert closure_holds(HEX, []) and max_thrust(HEX, []) == pytest.approx(6 * HEX.f_max)


@pytest.mark.parametrize("params", [quadrotor_x(), quadrotor_plus()], ids=lambda p: p.name)
def test_quadrotors_lose_closure_on_any_failure(params):
    A = params.allocation_matrix
    assert closure_holds(params, [])
    for failed in _all_failure_sets(4):
        assert not closure_holds(params, failed), failed
        assert not _closure_by_half_planes(A, failed), failed
        assert max_thrust(params, failed) == pytest.approx(
            _max_thrust_by_vertices(A, params.f_max, failed, True), abs=1e-6)
    # One motor out: the three columns leave the origin on the hull's edge (gap exactly pi).
    assert largest_angular_gap(params, [0]) == pytest.approx(np.pi)


def test_max_thrust_allocation_balances_the_torques():
    for failed in [(0,), (0, 2), (0, 3), (1, 3, 5)]:
        for yaw_free in (True, False):
            f = max_thrust_allocation(HEX, failed, yaw_free)
            assert f.shape == (6,)
            assert np.all(f[list(failed)] == 0.0)
            assert np.all((f >= 0.0) & (f <= HEX.f_max))
            torque = HEX.allocation_matrix[1:3 if yaw_free else 4] @ f
            assert np.allclose(torque, 0.0, atol=1e-6 * HEX.arm_length * HEX.f_max)


def test_failed_motor_order_does_not_matter():
    assert canonical_failed_motors(HEX, [4, 0, np.int64(2)]) == (0, 2, 4)
    assert max_thrust(HEX, (4, 1)) == max_thrust(HEX, [1, 4])


@pytest.mark.parametrize("bad, match", [
    ([6], "failed_motors: motor 6 does not exist"),
    ([-1], "failed_motors: motor -1 does not exist"),
    ([1, 1], "failed_motors lists a motor twice"),
    ([1.5], "failed_motors entries must be motor indices"),
    ([True], "failed_motors entries must be motor indices"),
])
def test_bad_failed_motors_are_refused_by_name(bad, match):
    for function in (closure_holds, max_thrust, max_thrust_allocation, largest_angular_gap):
        with pytest.raises(ValueError, match=match):
            function(HEX, bad)
