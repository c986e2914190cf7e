"""Which motor failures a multirotor survives, and the thrust it keeps (Argyropoulos 2020, ch. 5).

Hovering with yaw free needs every combination of roll and pitch torque from
non-negative thrusts: the roll/pitch rows of the allocation (eq. 5.1), with the
columns of failed motors removed, must *positively span* R^2 (force closure,
borrowed from grasping). Two independent tests decide it:

* an LP (a :class:`~pydrake.solvers.MathematicalProgram` solved by CLP):
  ``maximise t`` subject to ``sum_i lambda_i a_i = 0``, ``sum_i lambda_i = 1``,
  ``lambda_i >= t`` over the healthy columns ``a_i`` (normalised to unit length);
  the columns positively span R^2 iff they have rank 2 and the optimum is ``t > 0``;
* the angular gap: the largest gap between consecutive column directions is below pi.

:func:`closure_holds` returns the LP's answer and checks it against the gap test.

:func:`max_thrust` is LP (5.22) with the upper bound the printed equation lacks:
``maximise sum_i f_i`` subject to zero roll and pitch torque (and zero yaw torque
when ``yaw_free`` is False), ``0 <= f_i <= f_max`` and ``f_i = 0`` for failed motors.
It is the largest thrust the vehicle can point along its body z axis while keeping
its attitude (the escape manoeuvre of category II, eq. 5.23).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from pydrake.solvers import ClpSolver, MathematicalProgram

from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "ClosureMismatchError",
    "canonical_failed_motors",
    "closure_holds",
    "largest_angular_gap",
    "max_thrust",
    "max_thrust_allocation",
]

_TOL = 1e-9
"""Tolerance on the normalised LP optima, the torque balance (per N of f_max and m of arm)
and the angular gap [rad]."""


class ClosureMismatchError(ArithmeticError):
    """The closure LP and the angular-gap test disagree (a geometry on the boundary)."""


def canonical_failed_motors(params: MultirotorParams, failed_motors: Iterable[int]
                            ) -> tuple[int, ...]:
    """Sorted tuple of failed motor indices, validated against the vehicle.

    Parameters
    ----------
    params : MultirotorParams
        The vehicle.
    failed_motors : iterable of int
        0-based indices of the totally failed motors (may be empty).

    Returns
    -------
    tuple of int
        The indices in increasing order.

    Raises
    ------
    ValueError
        ``failed_motors`` holds a non-integer, an index outside ``0..n-1`` or a
        duplicate.
    """
    n = params.num_motors
    indices = []
    for value in failed_motors:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"failed_motors entries must be motor indices (int), got {value!r}")
        if not 0 <= int(value) < n:
            raise ValueError(f"failed_motors: motor {int(value)} does not exist on "
                             f"{params.name} (motors 0..{n - 1})")
        indices.append(int(value))
    if len(set(indices)) != len(indices):
        raise ValueError(f"failed_motors lists a motor twice: {indices}")
    return tuple(sorted(indices))


def _healthy_torque_columns(params: MultirotorParams, failed: tuple[int, ...]) -> np.ndarray:
    """Roll/pitch torque columns (2, k) [N m per N] of the healthy motors."""
    healthy = [i for i in range(params.num_motors) if i not in failed]
    return params.allocation_matrix[1:3, healthy]


def largest_angular_gap(params: MultirotorParams, failed_motors: Iterable[int]) -> float:
    """Largest angle [rad] between consecutive directions of the healthy roll/pitch columns.

    Columns with zero torque (a rotor on the centre of gravity) have no direction and
    are left out; with no such direction the gap is ``2 pi``. The columns positively span
    R^2 iff the gap is below pi.

    Raises
    ------
    ValueError
        Invalid ``failed_motors`` (see :func:`canonical_failed_motors`).
    """
    failed = canonical_failed_motors(params, failed_motors)
    columns = _healthy_torque_columns(params, failed)
    norms = np.linalg.norm(columns, axis=0)
    columns = columns[:, norms > _TOL * params.arm_length]
    if columns.shape[1] == 0:
        return 2.0 * np.pi
    angles = np.sort(np.arctan2(columns[1], columns[0]))
    gaps = np.diff(np.concatenate([angles, [angles[0] + 2.0 * np.pi]]))
    return float(gaps.max())


def _closure_lp(columns: np.ndarray) -> float:
    """Optimum ``t`` of the closure LP on unit-length columns (2, k); -inf if infeasible."""
    k = columns.shape[1]
    prog = MathematicalProgram()
    lam = prog.NewContinuousVariables(k, "lambda")
    t = prog.NewContinuousVariables(1, "t")[0]
    prog.AddLinearEqualityConstraint(columns, np.zeros(2), lam)
    prog.AddLinearEqualityConstraint(np.ones((1, k)), np.ones(1), lam)
    for i in range(k):
        prog.AddLinearConstraint(lam[i] - t >= 0.0)
    prog.AddBoundingBoxConstraint(-1.0, 1.0, t)
    prog.AddLinearCost(-t)
    result = ClpSolver().Solve(prog)
    if not result.is_success():
        return -np.inf  # no convex combination reaches the origin
    return float(result.GetSolution(t))


def closure_holds(params: MultirotorParams, failed_motors: Iterable[int]) -> bool:
    """Whether the vehicle can still hold hover with yaw free (Argyropoulos 2020, sec. 5.1).

    The healthy roll/pitch torque columns must positively span R^2 (their convex hull
    holds the origin strictly inside), which needs at least three working motors.

    Parameters
    ----------
    params : MultirotorParams
        The vehicle; its allocation matrix gives the torque columns.
    failed_motors : iterable of int
        0-based indices of totally failed motors.

    Returns
    -------
    bool
        The closure LP's verdict.

    Raises
    ------
    ValueError
        Invalid ``failed_motors``.
    ClosureMismatchError
        The LP and the angular-gap test disagree: the geometry sits within the
        tolerance of the boundary (e.g. two columns almost exactly opposite).
    """
    failed = canonical_failed_motors(params, failed_motors)
    columns = _healthy_torque_columns(params, failed)
    norms = np.linalg.norm(columns, axis=0)
    columns = columns[:, norms > _TOL * params.arm_length]
    if columns.shape[1] < 3 or np.linalg.matrix_rank(columns, tol=_TOL) < 2:
        lp_verdict = False
    else:
        lp_verdict = _closure_lp(columns / np.linalg.norm(columns, axis=0)) > _TOL
    gap_verdict = largest_angular_gap(params, failed) < np.pi - _TOL
    if lp_verdict != gap_verdict:
        raise ClosureMismatchError(
            f"closure of {params.name} without motors {list(failed)}: the LP says "
            f"{lp_verdict}, the angular gap says {gap_verdict} (geometry on the boundary)")
    return lp_verdict


def max_thrust_allocation(params: MultirotorParams, failed_motors: Iterable[int],
                          yaw_free: bool = True) -> np.ndarray:
    """Motor thrusts [N] of the largest total thrust with zero roll and pitch torque.

    LP (5.22) of Argyropoulos 2020 with the bounds ``0 <= f_i <= f_max`` (as printed it
    is unbounded) and ``f_i = 0`` for failed motors; with ``yaw_free=False`` the yaw
    torque is held at zero too.

    Parameters
    ----------
    params : MultirotorParams
        The vehicle.
    failed_motors : iterable of int
        0-based indices of totally failed motors.
    yaw_free : bool
        True: the yaw torque is left free (the vehicle spins); False: zero yaw torque.

    Returns
    -------
    numpy.ndarray
        Thrusts ``f`` (n,) [N], zero on failed motors; all zero when no non-zero
        thrust keeps the torques at zero.

    Raises
    ------
    ValueError
        Invalid ``failed_motors``.
    RuntimeError
        CLP reports a failure on this (always feasible, bounded) LP.
    """
    failed = canonical_failed_motors(params, failed_motors)
    n = params.num_motors
    rows = params.allocation_matrix[1:3] if yaw_free else params.allocation_matrix[1:4]
    prog = MathematicalProgram()
    f = prog.NewContinuousVariables(n, "f")
    upper = np.full(n, params.f_max)
    upper[list(failed)] = 0.0
    prog.AddBoundingBoxConstraint(np.zeros(n), upper, f)
    # Zero torque up to round-off: arm angles in radians leave ~1e-17 m where an exact
    # geometry has zeros, and an exact equality would then forbid a valid pair of opposite
    # motors.
    slack = np.full(len(rows), _TOL * params.f_max)
    prog.AddLinearConstraint(rows / params.arm_length, -slack, slack, f)
    prog.AddLinearCost(-np.ones(n), 0.0, f)
    result = ClpSolver().Solve(prog)
    if not result.is_success():
        raise RuntimeError(f"maximum-thrust LP failed for {params.name} without motors "
                           f"{list(failed)}: {result.get_solution_result()}")
    return np.clip(result.GetSolution(f), 0.0, upper)


def max_thrust(params: MultirotorParams, failed_motors: Iterable[int],
               yaw_free: bool = True) -> float:
    """Largest total thrust [N] with zero roll and pitch torque (LP 5.22 with bounds).

    See :func:`max_thrust_allocation` for the program, parameters and errors.

    Returns
    -------
    float
        ``sum_i f_i`` at the optimum [N].
    """
    return float(max_thrust_allocation(params, failed_motors, yaw_free).sum())
