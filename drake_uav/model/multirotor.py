"""Multirotor rigid-body equations with motor limits, motor faults and optional motor lag.

Model of Argyropoulos 2020, eq. 1.1 written in NED / FRD (thrust along ``-z_b``;
the z-up thesis rotated by pi about x, docs/multirotor.md)::

    p_dot     = v
    v_dot     = R(q) f_b / m + [0, 0, g] + f_ext / m,   f_b = [0, 0, -F] - D R(q)^T v
    q_dot     = 0.5 q (x) [0, omega]
    omega_dot = J^-1 (tau + tau_ext - omega x J omega)

with ``[F, tau] = A diag(h) sat(f)`` (allocation from the frame geometry, health
``h`` in [0, 1] per motor, thrusts saturated to ``[0, f_max]``) and ``D`` the
optional linear rotor drag. With a motor time constant ``T_m > 0`` the produced
thrusts become states: ``f_dot = (sat(u) - f) / T_m``.

Units: m, m/s, rad/s, N, N m, kg m^2. The equations live in plain functions
that accept float, ``AutoDiffXd`` and ``symbolic.Expression`` entries, so the
plant (:class:`drake_uav.systems.MultirotorPlant`), linearisation, the flatness
map and the tracking-error model all evaluate the same equations.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from drake_uav.model.rotations import quat_derivative, quat_to_rotmat
from drake_uav.model.scalar import as_list, clamp

if TYPE_CHECKING:  # parameters are duck-typed: the model layer sits below vehicles
    from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "STATE_SIZE",
    "POSITION",
    "QUATERNION",
    "VELOCITY",
    "BODY_RATES",
    "body_rate_derivative",
    "produced_thrusts",
    "motor_wrench",
    "multirotor_dynamics",
    "multirotor_derivatives",
    "specific_force",
]

STATE_SIZE = 13
"""Rigid-body state size: position (3), quaternion (4), velocity (3), body rates (3)."""
POSITION = slice(0, 3)
"""NED position [m]."""
QUATERNION = slice(3, 7)
"""Unit quaternion (w, x, y, z), body FRD -> NED."""
VELOCITY = slice(7, 10)
"""NED velocity [m/s]."""
BODY_RATES = slice(10, 13)
"""Body rates (p, q, r) in FRD [rad/s]."""


def _limit(values, low: float, high: float) -> np.ndarray:
    """Entry-wise clamp to ``[low, high]``; float arrays take numpy's vectorised path."""
    a = np.asarray(values)
    if a.dtype == float:
        return np.minimum(np.maximum(a, low), high)
    return np.array([clamp(v, low, high) for v in a])


def produced_thrusts(x, commands, params: MultirotorParams, health=None) -> np.ndarray:
    """Thrust each motor produces [N]: saturated command (or lag state) times health.

    ``x`` is the plant state (13, or 13 + n with motor lag, whose last n entries
    are the produced thrusts of healthy motors); ``commands`` the n thrust
    commands [N]; ``health`` n values in [0, 1] (None: all healthy).
    """
    if params.motor_time_constant > 0:
        thrust = np.asarray(x)[STATE_SIZE:STATE_SIZE + params.num_motors]
    else:
        thrust = _limit(commands, 0.0, params.f_max)
    if health is not None:
        thrust = thrust * _limit(health, 0.0, 1.0)
    return thrust


def motor_wrench(thrusts, params: MultirotorParams) -> np.ndarray:
    """``[F, tau_x, tau_y, tau_z]`` [N, N m] of produced motor thrusts (allocation A f)."""
    f = np.asarray(thrusts)
    A = params.allocation_matrix
    if f.dtype == float:
        return A @ f
    # numpy's object matmul raises floating-point flags on symbolic entries.
    return np.array([sum(a * fi for a, fi in zip(row, f, strict=True)) for row in A.tolist()])


def _rotation(q) -> tuple[list, object]:
    """``R(q)`` as nested lists and ``1/|q|^2``: ``R(q)/|q|^2`` is the rotation of ``q/|q|``."""
    return (quat_to_rotmat(q).tolist(),
            1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]))


def _body_force(R, scale, v, thrust, params: MultirotorParams) -> list:
    """Thrust plus rotor drag in body FRD [N] (``R``, ``scale`` from :func:`_rotation`)."""
    dx, dy, dz = params.rotor_drag
    vb = [(R[0][k] * v[0] + R[1][k] * v[1] + R[2][k] * v[2]) * scale for k in range(3)]
    return [-dx * vb[0], -dy * vb[1], -thrust - dz * vb[2]]


def _matvec(M, v) -> list:
    return [M[0][0] * v[0] + M[0][1] * v[1] + M[0][2] * v[2],
            M[1][0] * v[0] + M[1][1] * v[1] + M[1][2] * v[2],
            M[2][0] * v[0] + M[2][1] * v[1] + M[2][2] * v[2]]


def multirotor_dynamics(x, wrench, params: MultirotorParams, external_wrench=None,
                        quaternion_stabilization: float = 1.0) -> np.ndarray:
    """Rigid-body state derivative (13) for a body wrench.

    ``x``: state (13) [m, -, m/s, rad/s]; ``wrench``: ``[F, tau_x, tau_y, tau_z]``
    with ``F`` the thrust along ``-z_b`` [N] and torques in FRD [N m];
    ``external_wrench``: ``[f_N, f_E, f_D]`` NED force [N] then body FRD torque
    [N m] (None: zero). ``quaternion_stabilization`` [1/s] pulls ``|q|`` to 1.
    """
    x = as_list(x)
    F, tx, ty, tz = as_list(wrench)
    q, v, w = x[3:7], x[7:10], x[10:13]
    R, scale = _rotation(q)
    k = scale / params.mass
    if params.rotor_drag == (0.0, 0.0, 0.0):  # thrust only: -F times the body z axis
        acc = [-F * k * R[0][2], -F * k * R[1][2], params.gravity - F * k * R[2][2]]
    else:
        acc = _matvec(R, _body_force(R, scale, v, F, params))
        acc = [acc[0] * k, acc[1] * k, acc[2] * k + params.gravity]
    if external_wrench is not None:
        e = as_list(external_wrench)
        inv_m = 1.0 / params.mass
        acc = [acc[0] + e[0] * inv_m, acc[1] + e[1] * inv_m, acc[2] + e[2] * inv_m]
        tx, ty, tz = tx + e[3], ty + e[4], tz + e[5]
    w_dot = body_rate_derivative(w, [tx, ty, tz], params)
    q_dot = quat_derivative(q, w, quaternion_stabilization).tolist()
    return np.array(v + q_dot + acc + w_dot)


def body_rate_derivative(omega, torque, params: MultirotorParams) -> list:
    """Euler's equation ``omega_dot = J^-1 (tau - omega x J omega)`` [rad/s^2] (eq. 1.1).

    ``omega``: body rates (p, q, r) in FRD [rad/s]; ``torque``: body FRD torque [N m].
    Plain arithmetic on the three entries, so it serves every scalar type of the
    model and, entry-wise, numpy or JAX arrays of samples (the reachable tubes).
    """
    w, (tx, ty, tz) = omega, torque
    Jx, Jy, Jz = params.inertia
    principal = params.inertia_products == (0.0, 0.0, 0.0)
    Jw = [Jx * w[0], Jy * w[1], Jz * w[2]] if principal else \
        _matvec(params.inertia_matrix.tolist(), w)
    net = [tx - (w[1] * Jw[2] - w[2] * Jw[1]),
           ty - (w[2] * Jw[0] - w[0] * Jw[2]),
           tz - (w[0] * Jw[1] - w[1] * Jw[0])]
    return [net[0] / Jx, net[1] / Jy, net[2] / Jz] if principal else \
        _matvec(params.inertia_inverse.tolist(), net)


def multirotor_derivatives(x, commands, params: MultirotorParams, health=None,
                           external_wrench=None,
                           quaternion_stabilization: float = 1.0) -> np.ndarray:
    """Full plant state derivative: rigid body (13) plus motor lag states (n) if any.

    ``commands``: n motor thrust commands [N]; see :func:`produced_thrusts` and
    :func:`multirotor_dynamics` for the other arguments.
    """
    wrench = motor_wrench(produced_thrusts(x, commands, params, health), params)
    xdot = multirotor_dynamics(x, wrench, params, external_wrench, quaternion_stabilization)
    if params.motor_time_constant <= 0:
        return xdot
    lag = (_limit(commands, 0.0, params.f_max) - np.asarray(x)[STATE_SIZE:]) \
        / params.motor_time_constant
    return np.concatenate([xdot, lag])


def specific_force(x, wrench, params: MultirotorParams, external_wrench=None) -> np.ndarray:
    """Accelerometer reading in body FRD [m/s^2]: non-gravitational force / mass."""
    x = as_list(x)
    R, scale = _rotation(x[3:7])
    fb = _body_force(R, scale, x[7:10], as_list(wrench)[0], params)
    if external_wrench is not None:
        e = as_list(external_wrench)
        fb = [fb[k] + (R[0][k] * e[0] + R[1][k] * e[1] + R[2][k] * e[2]) * scale
              for k in range(3)]
    return np.array(fb) / params.mass


