"""Tilt of a multirotor and its rotational dynamics without yaw (Argyropoulos 2020, sec. 5.2).

Whether the body z axis can be brought back to the vertical does not depend on
position, velocity or heading. The *down direction in body axes*
``g = R(q)^T [0, 0, 1]`` (a unit vector, ``g = [0, 0, 1]`` when level) and the body
rates ``omega`` form a closed system with the heading left out::

    g_dot     = g x omega                         (from q_dot = 0.5 q (x) [0, omega])
    omega_dot = J^-1 (tau - omega x J omega)      (Euler's equation, eq. 1.1)

``g`` is written in stereographic *tilt coordinates* seen from the upside-down
attitude, ``s = (g_x, g_y) / (1 + g_z)``: smooth for every attitude but the inverted
one, ``|s| = tan(tilt / 2)`` with ``tilt`` the angle between body z and the vertical,
and ``s`` points where body z leans (in body axes). The quaternion with zero yaw and
tilt coordinates ``s`` is ``(1, s_y, -s_x, 0) / sqrt(1 + |s|^2)``.

Every function does plain arithmetic on its entries, so it serves floats, AutoDiffXd,
and, entry-wise, numpy or JAX arrays of samples.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drake_uav.model.multirotor import body_rate_derivative

if TYPE_CHECKING:
    from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "down_in_body",
    "tilt_coordinates",
    "down_from_tilt",
    "quaternion_from_tilt",
    "tilt_coordinate_rates",
    "tilt_dynamics",
]


def down_in_body(q) -> tuple:
    """``R(q)^T [0, 0, 1]``: the NED down direction in body FRD axes, for ``q / |q|``.

    ``q = (w, x, y, z)`` entries (scalars or arrays of samples); returns three entries.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    k = 1.0 / (w * w + x * x + y * y + z * z)
    return (2.0 * (x * z - w * y) * k, 2.0 * (y * z + w * x) * k,
            (w * w - x * x - y * y + z * z) * k)


def tilt_coordinates(down) -> tuple:
    """Tilt coordinates ``s = (g_x, g_y) / (1 + g_z)`` of a unit down direction ``g``.

    Infinite for the inverted attitude (``g_z = -1``), the one point the chart misses.
    """
    scale = 1.0 / (1.0 + down[2])
    return down[0] * scale, down[1] * scale


def down_from_tilt(s) -> tuple:
    """Unit down direction ``g`` in body axes of tilt coordinates ``s`` (inverse chart)."""
    r2 = s[0] * s[0] + s[1] * s[1]
    k = 1.0 / (1.0 + r2)
    return 2.0 * s[0] * k, 2.0 * s[1] * k, (1.0 - r2) * k


def quaternion_from_tilt(s) -> tuple:
    """Quaternion ``(w, x, y, z)`` with zero yaw whose tilt coordinates are ``s``.

    The rotation about the horizontal axis ``g x e_z`` by the tilt angle; any heading
    ``psi`` is added on the left, ``q_z(psi) (x) q``, without changing ``s``.
    """
    k = 1.0 / (1.0 + s[0] * s[0] + s[1] * s[1]) ** 0.5
    return k, s[1] * k, -s[0] * k, 0.0 * s[0]


def tilt_coordinate_rates(s, omega) -> tuple:
    """``s_dot`` [1/s] for body rates ``omega`` (p, q, r) [rad/s].

    ``s_dot = (1 + |s|^2) / 2 (g_dot_xy - s g_dot_z)`` with ``g_dot = g x omega``.
    """
    g = down_from_tilt(s)
    p, q, r = omega[0], omega[1], omega[2]
    gx_dot = g[1] * r - g[2] * q
    gy_dot = g[2] * p - g[0] * r
    gz_dot = g[0] * q - g[1] * p
    half = 0.5 * (1.0 + s[0] * s[0] + s[1] * s[1])
    return half * (gx_dot - s[0] * gz_dot), half * (gy_dot - s[1] * gz_dot)


def tilt_dynamics(s, omega, torque, params: MultirotorParams) -> tuple:
    """Derivative of the yaw-free attitude state ``(s_x, s_y, p, q, r)``.

    Parameters
    ----------
    s : sequence of 2 entries
        Tilt coordinates (dimensionless).
    omega : sequence of 3 entries
        Body rates (p, q, r) in FRD [rad/s].
    torque : sequence of 3 entries
        Body FRD torque [N m], e.g. rows 1-3 of ``A f``.
    params : MultirotorParams
        Inertia.

    Returns
    -------
    tuple of 5 entries
        ``(s_x_dot, s_y_dot)`` [1/s] then ``omega_dot`` [rad/s^2], the latter from
        :func:`~drake_uav.model.multirotor.body_rate_derivative`, as in the full model.
    """
    sx_dot, sy_dot = tilt_coordinate_rates(s, omega)
    p_dot, q_dot, r_dot = body_rate_derivative(omega, torque, params)
    return sx_dot, sy_dot, p_dot, q_dot, r_dot
