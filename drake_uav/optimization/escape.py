"""Category-II escape geometry after a motor failure (Argyropoulos 2020, eq. 5.17-5.25).

Written in the project's NED frame (the source's z axis points up): the ground is
``p_d = 0``, altitude is ``-p_d``, and a vehicle's thrust acts along ``-z_b``.

* :func:`free_fall_impact`: where and when a vehicle that lost all thrust would hit
  the ground from its current position and velocity (eq. 5.17-5.18).
* :func:`altitude_hold_thrust`: the vertical thrust of the altitude hold (eq. 5.20-5.21,
  with the gain signs that make it stable: ``a_up = -k1 (h - h0) - k2 v_up``).
* :func:`escape_attitude`: the attitude that tilts the thrust away from the centre of
  the unsafe disc (eq. 5.19, 5.23-5.24) so that the vertical part of the maximum thrust
  ``F_max`` (LP 5.22, :func:`~drake_uav.optimization.allocation.max_thrust`) holds the
  altitude and the rest accelerates the vehicle outwards.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["FreeFallImpact", "free_fall_impact", "altitude_hold_thrust", "escape_attitude",
           "outward_direction"]


@dataclasses.dataclass(frozen=True)
class FreeFallImpact:
    """Predicted ground impact of a vehicle without thrust (eq. 5.17-5.18)."""

    time: float
    """Time to impact from now [s]."""
    point: np.ndarray
    """Horizontal impact point (north, east) [m]."""
    vertical_speed: float
    """Downward speed at impact [m/s] (positive)."""


def free_fall_impact(position, velocity, gravity: float) -> FreeFallImpact:
    """Free fall from NED ``position`` [m] and ``velocity`` [m/s] to the ground ``p_d = 0``
    (Argyropoulos 2020, eq. 5.17-5.18; drag neglected, as there).

    ``t_fall = (v_up + sqrt(v_up^2 + 2 g h)) / g`` with ``h = -p_d``, ``v_up = -v_d``; a
    vehicle already on or below the ground has ``t_fall = 0``.
    """
    p, v = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
    h, v_up = max(-p[2], 0.0), -v[2]
    speed = float(np.sqrt(v_up**2 + 2.0 * gravity * h))
    t = (v_up + speed) / gravity if h > 0 else 0.0
    return FreeFallImpact(time=float(t), point=p[:2] + v[:2] * t, vertical_speed=speed)


def altitude_hold_thrust(altitude: float, climb_rate: float, target: float, mass: float,
                         gravity: float, gains: tuple[float, float]) -> float:
    """Vertical thrust [N] of the altitude hold (eq. 5.20-5.21): ``m (g - k1 (h - h0) - k2
    v_up)`` for altitude ``h`` [m], climb rate ``v_up`` [m/s] and target ``h0`` [m], never
    negative. The source prints ``a_z = [k1 k2] [z - z0; v_z]``, which is unstable for
    positive gains; the gains here are positive with the minus signs written out."""
    k1, k2 = gains
    return max(mass * (gravity - k1 * (altitude - target) - k2 * climb_rate), 0.0)


def outward_direction(position, center) -> np.ndarray:
    """Horizontal unit vector (north, east) from the disc ``center`` to ``position``; the
    north axis when the vehicle is exactly above the centre."""
    d = np.asarray(position, dtype=float)[:2] - np.asarray(center, dtype=float)
    norm = np.linalg.norm(d)
    return d / norm if norm > 1e-9 else np.array([1.0, 0.0])


def escape_attitude(position, center, vertical_thrust: float, max_thrust: float
                    ) -> tuple[np.ndarray, float]:
    """Attitude ``q_d`` (w, x, y, z; body to NED, zero yaw) and tilt ``phi`` [rad] that point
    the thrust away from the disc ``center`` (north, east) [m] (eq. 5.19, 5.23-5.24).

    ``cos phi = F_z / F_max`` (``phi = 0`` when ``F_z >= F_max``: the altitude cannot be held
    and the whole thrust points up). The rotation axis ``u = d x e_down`` (the source's
    ``k x (xi - r_avoid)`` in NED) turns the thrust direction ``-z_b`` from straight up to
    ``up cos phi + d sin phi``, with ``d`` the outward direction.
    """
    cos_phi = min(max(vertical_thrust / max_thrust, 0.0), 1.0) if max_thrust > 0 else 1.0
    phi = float(np.arccos(cos_phi))
    d = outward_direction(position, center)
    axis = np.array([d[1], -d[0], 0.0])  # d x e_down for d = (d_n, d_e, 0)
    return np.concatenate([[np.cos(phi / 2)], np.sin(phi / 2) * axis]), phi
