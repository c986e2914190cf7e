"""Air-data relations: airspeed, alpha and sideslip from the air-relative velocity and back."""

from __future__ import annotations

import numpy as np
from pydrake.math import atan2, cos, sin, sqrt

__all__ = ["air_data_from_velocity", "velocity_from_air_data"]


def air_data_from_velocity(u_r, v_r, w_r) -> tuple:
    """Stability triplet ``(Va, alpha, beta)`` from air-relative body velocity [m/s].

    Vaiopoulos 2017, eq. 2.12-2.14 (corrected): alpha = atan2(w_r, u_r),
    beta = asin(v_r / Va) computed as atan2(v_r, sqrt(u_r^2 + w_r^2)).
    """
    if isinstance(u_r, np.ndarray):
        uw = np.hypot(u_r, w_r)
        return np.hypot(uw, v_r), np.arctan2(w_r, u_r), np.arctan2(v_r, uw)
    uw2 = u_r * u_r + w_r * w_r
    return sqrt(uw2 + v_r * v_r), atan2(w_r, u_r), atan2(v_r, sqrt(uw2))


def velocity_from_air_data(airspeed, alpha, beta) -> tuple:
    """Air-relative body velocity ``(u_r, v_r, w_r)`` [m/s] (Vaiopoulos 2017, eq. 5.35)."""
    if isinstance(alpha, np.ndarray):
        cos_, sin_ = np.cos, np.sin
    else:
        cos_, sin_ = cos, sin
    cb = cos_(beta)
    return airspeed * cos_(alpha) * cb, airspeed * sin_(beta), airspeed * sin_(alpha) * cb
