"""Tracking error of a multirotor about a reference, with a multiplicative attitude error.

Argyropoulos 2020, app. B.8: the attitude error is the rotation ``q_e`` with
``q = q_r (x) q_e``, and for small errors ``q_e ~ [1, theta_e / 2]``. The error
state (12) replaces the quaternion slot of the plant state (13) by ``theta_e``::

    e = [p - p_r, theta_e, v - v_r, omega - omega_r],   theta_e = 2 vec(q_r* (x) q)

(NED position [m], attitude error [rad], NED velocity [m/s], FRD body rates
[rad/s]). ``theta_e`` is linear in ``q``; it is the exact inverse of
:func:`compose_state` for ``|theta_e| < 2`` and for ``q`` in the hemisphere of
``q_r`` (``q . q_r > 0``, which the callers arrange by flipping the sign of ``q``).

The nonlinear error dynamics (Argyropoulos 2020, eq. 4.3) are the plant
equations of :func:`~drake_uav.model.multirotor.multirotor_dynamics` seen through
this error map; their linearisation about the reference (eq. B.31-B.37 in NED /
FRD, thrust along ``-z_b``) is :func:`error_jacobians`. Every function accepts
float, ``AutoDiffXd`` and ``Expression`` entries.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from pydrake.math import sqrt

from drake_uav.model.multirotor import motor_wrench, multirotor_dynamics
from drake_uav.model.rotations import quat_conjugate, quat_multiply, quat_to_rotmat, skew
from drake_uav.model.scalar import as_list

if TYPE_CHECKING:  # parameters are duck-typed: the model layer sits below vehicles
    from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "ERROR_SIZE",
    "POSITION_ERROR",
    "ATTITUDE_ERROR",
    "VELOCITY_ERROR",
    "RATE_ERROR",
    "state_error",
    "compose_state",
    "error_dynamics",
    "error_jacobians",
]

ERROR_SIZE = 12
"""Error state size: position (3), attitude (3), velocity (3), body rates (3)."""
POSITION_ERROR = slice(0, 3)
ATTITUDE_ERROR = slice(3, 6)
VELOCITY_ERROR = slice(6, 9)
RATE_ERROR = slice(9, 12)


def _array(values) -> np.ndarray:
    out = np.array(values)
    return out.astype(float) if out.dtype.kind not in "fO" else out


def state_error(x, x_ref) -> np.ndarray:
    """Error state (12) of the plant state ``x`` (13) about ``x_ref`` (13)."""
    x, r = as_list(x), as_list(x_ref)
    qe = quat_multiply(quat_conjugate(r[3:7]), x[3:7])
    return _array([x[0] - r[0], x[1] - r[1], x[2] - r[2],
                   2 * qe[1], 2 * qe[2], 2 * qe[3],
                   *[x[k] - r[k] for k in range(7, 13)]])


def compose_state(x_ref, e) -> np.ndarray:
    """Plant state (13) at error ``e`` (12) about ``x_ref``: the inverse of :func:`state_error`.

    The attitude is ``q_r (x) [sqrt(1 - |theta_e|^2 / 4), theta_e / 2]`` (unit for a
    unit ``q_r``; needs ``|theta_e| <= 2``).
    """
    r, e = as_list(x_ref), as_list(e)
    h = [0.5 * e[3], 0.5 * e[4], 0.5 * e[5]]
    qe = [sqrt(1.0 - h[0] * h[0] - h[1] * h[1] - h[2] * h[2]), *h]
    q = quat_multiply(r[3:7], qe).tolist()
    return _array([r[0] + e[0], r[1] + e[1], r[2] + e[2], *q,
                   *[r[k] + e[k - 1] for k in range(7, 13)]])


def error_dynamics(e, thrusts, x_ref, thrusts_ref, params: MultirotorParams,
                   external_wrench=None) -> np.ndarray:
    """Error derivative ``de/dt = f~(t, e, u)`` (Argyropoulos 2020, eq. 4.3) (12).

    ``thrusts``: motor thrusts (n) [N] (failed motors: zero columns of the
    allocation, so pass them as zero or scale them beforehand); ``x_ref``,
    ``thrusts_ref``: the reference state and its input, which must satisfy the
    plant dynamics (``dx_r/dt = f(x_r, u_r)``, Argyropoulos 2020, assumption A2).
    The plant derivative is :func:`~drake_uav.model.multirotor.multirotor_dynamics`
    at ``compose_state(x_ref, e)``; the attitude part is
    ``2 vec(dq_r*/dt (x) q + q_r* (x) dq/dt)``.
    """
    x = compose_state(x_ref, e)
    xdot = as_list(multirotor_dynamics(x, motor_wrench(thrusts, params), params,
                                       external_wrench, quaternion_stabilization=0.0))
    rdot = as_list(multirotor_dynamics(x_ref, motor_wrench(thrusts_ref, params), params,
                                       quaternion_stabilization=0.0))
    r = as_list(x_ref)
    qx = as_list(x)[3:7]
    a = quat_multiply(quat_conjugate(rdot[3:7]), qx)
    b = quat_multiply(quat_conjugate(r[3:7]), xdot[3:7])
    return _array([xdot[k] - rdot[k] for k in range(3)]
                  + [2 * (a[k] + b[k]) for k in range(1, 4)]
                  + [xdot[k] - rdot[k] for k in range(7, 13)])


def error_jacobians(x_ref, wrench_ref, params: MultirotorParams) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (12, 12) and ``B`` (12, 4) of the linearised error dynamics (eq. B.31-B.37).

    ``de/dt = A e + B [F - F_r, tau - tau_r]`` at the reference state ``x_ref``
    (13) and wrench ``wrench_ref = [F_r, tau_r]``. In NED / FRD with the thrust
    along ``-z_b`` (body force ``f_r = [0, 0, -F_r]``)::

        dp_e     = v_e
        dtheta_e = -[omega_r]x theta_e + omega_e
        dv_e     = -R_r [f_r / m]x theta_e + R_r [0, 0, -F_e] / m
        domega_e = J^-1 ([J omega_r]x - [omega_r]x J) omega_e + J^-1 tau_e

    For motor-thrust inputs use ``B @ A_alloc`` (zeroed columns for failed motors).
    Rotor drag is not part of this linearisation.
    """
    r = as_list(x_ref)
    F = as_list(wrench_ref)[0]
    R = quat_to_rotmat(r[3:7])
    w = np.array(r[10:13])
    J = params.inertia_matrix
    Jinv = params.inertia_inverse
    m = params.mass
    zero = F * 0.0
    A = np.full((12, 12), zero, dtype=object)
    B = np.full((12, 4), zero, dtype=object)
    eye = np.eye(3)
    A[0:3, 6:9] = eye
    A[3:6, 3:6] = -skew(w)
    A[3:6, 9:12] = eye
    A[6:9, 3:6] = -R @ skew([zero, zero, -F / m])
    A[9:12, 9:12] = Jinv @ (skew(J @ w) - skew(w) @ J)
    B[6:9, 0] = -R[:, 2] / m
    B[9:12, 1:4] = Jinv
    if all(isinstance(v, float) for v in (*r, F)):
        return A.astype(float), B.astype(float)
    return A, B
