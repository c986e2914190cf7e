"""Attitude helpers: quaternion (w, x, y, z), rotation matrix and 3-2-1 Euler angles.

Conventions (docs/architecture.md):

* A quaternion ``q`` maps body (FRD) components to NED components:
  ``v_ned = R(q) @ v_body`` (Hamilton product, scalar first, Drake's order).
* Euler angles are aerospace 3-2-1 (yaw psi, pitch theta, roll phi) in radians,
  returned and accepted in the order ``(roll, pitch, yaw)``.

Every function accepts float, ``AutoDiffXd`` or ``symbolic.Expression`` entries
(numpy object arrays for the latter two) and returns an array of the same kind.
The trigonometry goes through :mod:`pydrake.math`, which is overloaded for all
three scalar types.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import asin, atan2, cos, sin, sqrt

__all__ = [
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_to_rotmat",
    "unit_quat_rotation",
    "rotate",
    "rotate_back",
    "rotmat_to_quat",
    "euler_to_quat",
    "quat_to_euler",
    "euler_to_rotmat",
    "rotmat_to_euler",
    "quat_derivative",
    "euler_rates",
    "skew",
]


def _array(values) -> np.ndarray:
    """Builds an array that keeps AutoDiffXd / Expression entries as objects."""
    out = np.array(values)
    if out.dtype.kind not in "fO":
        out = out.astype(float)
    return out


def skew(a) -> np.ndarray:
    """Cross-product matrix ``[a]x`` with ``skew(a) @ b == cross(a, b)``."""
    ax, ay, az = a[0], a[1], a[2]
    zero = ax * 0.0
    return _array([[zero, -az, ay], [az, zero, -ax], [-ay, ax, zero]])


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product ``p (x) q`` of two (w, x, y, z) quaternions."""
    pw, px, py, pz = p[0], p[1], p[2], p[3]
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    return _array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def quat_conjugate(q) -> np.ndarray:
    """Conjugate (the inverse for a unit quaternion)."""
    return _array([q[0], -q[1], -q[2], -q[3]])


def quat_normalize(q) -> np.ndarray:
    """Returns ``q / |q|``."""
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return _array([q[0] / n, q[1] / n, q[2] / n, q[3] / n])


def quat_to_rotmat(q) -> np.ndarray:
    """Rotation matrix body -> NED of a unit quaternion (Argyropoulos 2020, eq. A.55)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return _array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def unit_quat_rotation(q) -> tuple:
    """Rows of the body -> NED rotation of ``q / |q|`` (any nonzero ``q``) as nested
    tuples: no array is built, so float callers inside simulation loops stay cheap."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    k = 1.0 / (w * w + x * x + y * y + z * z)
    return (
        ((w * w + x * x - y * y - z * z) * k, 2 * (x * y - w * z) * k, 2 * (x * z + w * y) * k),
        (2 * (x * y + w * z) * k, (w * w - x * x + y * y - z * z) * k, 2 * (y * z - w * x) * k),
        (2 * (x * z - w * y) * k, 2 * (y * z + w * x) * k, (w * w - x * x - y * y + z * z) * k),
    )


def rotate(R, v) -> list:
    """``R v`` for rows ``R`` (e.g. of :func:`unit_quat_rotation`) and a 3-vector."""
    return [R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2] for i in range(3)]


def rotate_back(R, v) -> list:
    """``R^T v`` for rows ``R`` and a 3-vector (NED -> body for a body -> NED ``R``)."""
    return [R[0][i] * v[0] + R[1][i] * v[1] + R[2][i] * v[2] for i in range(3)]


def _is_numeric(value) -> bool:
    """True when ``value`` can be compared (float or AutoDiffXd), False for Expression."""
    try:
        bool(value > 0)
    except (RuntimeError, TypeError):
        return False
    return True


def rotmat_to_quat(R) -> np.ndarray:
    """Unit quaternion (w >= 0) of a body -> NED rotation matrix.

    For float and AutoDiffXd the numerically best of Shepperd's four branches is
    chosen. A symbolic Expression cannot be compared, so it uses the trace
    branch, valid away from 180 degree rotations.
    """
    trace = R[0][0] + R[1][1] + R[2][2]
    diag = [R[0][0], R[1][1], R[2][2]]
    branch = -1
    if _is_numeric(trace):
        candidates = [trace, diag[0], diag[1], diag[2]]
        branch = int(np.argmax([_value(c) for c in candidates])) - 1
    if branch == -1:
        s = 2.0 * sqrt(1.0 + trace)
        q = [0.25 * s, (R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s]
    elif branch == 0:
        s = 2.0 * sqrt(1.0 + R[0][0] - R[1][1] - R[2][2])
        q = [(R[2][1] - R[1][2]) / s, 0.25 * s, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s]
    elif branch == 1:
        s = 2.0 * sqrt(1.0 + R[1][1] - R[0][0] - R[2][2])
        q = [(R[0][2] - R[2][0]) / s, (R[0][1] + R[1][0]) / s, 0.25 * s, (R[1][2] + R[2][1]) / s]
    else:
        s = 2.0 * sqrt(1.0 + R[2][2] - R[0][0] - R[1][1])
        q = [(R[1][0] - R[0][1]) / s, (R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, 0.25 * s]
    if branch != -1 and _value(q[0]) < 0:
        q = [-c for c in q]
    return _array(q)


def _value(x) -> float:
    """Float value of a float or AutoDiffXd."""
    return x.value() if hasattr(x, "value") else float(x)


def euler_to_quat(rpy) -> np.ndarray:
    """Quaternion of 3-2-1 Euler angles ``(roll, pitch, yaw)`` [rad]; a (3, N) float array
    of samples gives (4, N)."""
    cos_, sin_ = (np.cos, np.sin) if np.ndim(rpy) == 2 else (cos, sin)
    hr, hp, hy = rpy[0] * 0.5, rpy[1] * 0.5, rpy[2] * 0.5
    cr, sr = cos_(hr), sin_(hr)
    cp, sp = cos_(hp), sin_(hp)
    cy, sy = cos_(hy), sin_(hy)
    return _array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def quat_to_euler(q) -> np.ndarray:
    """3-2-1 Euler angles ``(roll, pitch, yaw)`` [rad] of a unit quaternion.

    ``q`` is one quaternion (4) of any scalar type, or float samples (4, N)
    giving angles (3, N).
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    sin_pitch = 2 * (w * y - x * z)
    arctan2, arcsin = atan2, asin
    # The argument is clamped against round-off beyond +-1 (gimbal lock).
    if isinstance(sin_pitch, float):  # plain floats: the (cheaper) math module
        arctan2, arcsin = math.atan2, math.asin
        sin_pitch = min(max(sin_pitch, -1.0), 1.0)
    elif isinstance(sin_pitch, np.ndarray):
        arctan2, arcsin = np.arctan2, np.arcsin
        sin_pitch = np.clip(sin_pitch, -1.0, 1.0)
    elif _is_numeric(sin_pitch):  # AutoDiffXd: shifted, keeping the derivatives
        sp = _value(sin_pitch)
        if sp > 1.0:
            sin_pitch = sin_pitch - (sp - 1.0)
        elif sp < -1.0:
            sin_pitch = sin_pitch - (sp + 1.0)
    return _array(
        [
            arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
            arcsin(sin_pitch),
            arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)),
        ]
    )


def euler_to_rotmat(rpy) -> np.ndarray:
    """Body -> NED rotation matrix of 3-2-1 Euler angles ``(roll, pitch, yaw)`` [rad].

    The transpose of Vaiopoulos 2017, eq. 2.2 (NED -> body), whose printed (3,1)
    element is corrected (docs/references.md). A (3, N) float array of samples gives
    (3, 3, N).
    """
    cos_, sin_ = (np.cos, np.sin) if np.ndim(rpy) == 2 else (cos, sin)
    cr, sr = cos_(rpy[0]), sin_(rpy[0])
    cp, sp = cos_(rpy[1]), sin_(rpy[1])
    cy, sy = cos_(rpy[2]), sin_(rpy[2])
    return _array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )


def rotmat_to_euler(R) -> np.ndarray:
    """3-2-1 Euler angles ``(roll, pitch, yaw)`` [rad] of a body -> NED rotation matrix."""
    return _array(
        [atan2(R[2][1], R[2][2]), -asin(R[2][0]), atan2(R[1][0], R[0][0])]
    )


def quat_derivative(q, omega_body, stabilization: float = 0.0) -> np.ndarray:
    """Time derivative ``0.5 q (x) [0, omega]`` of a body -> NED quaternion (Argyropoulos
    2020, eq. B.15).

    ``omega_body`` is the body angular rate (p, q, r) [rad/s]. A positive
    ``stabilization`` gain [1/s] adds ``k (1 - |q|^2) q``, which drives the norm
    back to one without changing the rotation.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    p, qq, r = omega_body[0], omega_body[1], omega_body[2]
    dq = [
        0.5 * (-x * p - y * qq - z * r),
        0.5 * (w * p + y * r - z * qq),
        0.5 * (w * qq - x * r + z * p),
        0.5 * (w * r + x * qq - y * p),
    ]
    if stabilization:
        k = stabilization * (1.0 - (w * w + x * x + y * y + z * z))
        dq = [dq[0] + k * w, dq[1] + k * x, dq[2] + k * y, dq[3] + k * z]
    return _array(dq)


def euler_rates(rpy, omega_body) -> np.ndarray:
    """Euler angle rates ``(roll, pitch, yaw)`` rates [rad/s] from body rates (p, q, r) [rad/s].

    Vaiopoulos 2017, eq. 3.3 (Ortiz & Gutierrez 2009, eq. 25-26, whose pitch-rate
    row is corrected: docs/references.md); singular at pitch = +-90 deg, which is
    why the attitude state is a quaternion.
    """
    cr, sr = cos(rpy[0]), sin(rpy[0])
    cp, tp = cos(rpy[1]), sin(rpy[1]) / cos(rpy[1])
    p, q, r = omega_body[0], omega_body[1], omega_body[2]
    return _array([p + (q * sr + r * cr) * tp, q * cr - r * sr, (q * sr + r * cr) / cp])
