"""Air-data relations: airspeed, alpha and sideslip from the air-relative velocity and back,
their rates, and the dynamic pressure."""

from __future__ import annotations

import numpy as np
from pydrake.math import atan2, cos, sin, sqrt

from drake_uav.model.scalar import smax

__all__ = ["air_data_from_velocity", "velocity_from_air_data", "air_data_rates",
           "dynamic_pressure", "airspeed_from_dynamic_pressure"]


def air_data_from_velocity(u_r, v_r, w_r) -> tuple:
    """Stability triplet ``(Va, alpha, beta)`` from air-relative body velocity [m/s].

    Vaiopoulos 2017, eq. 2.12-2.14 (corrected: docs/references.md): alpha =
    atan2(w_r, u_r), beta = asin(v_r / Va) computed as atan2(v_r, sqrt(u_r^2 + w_r^2)),
    which keeps the quadrant and stays finite at Va = 0. Angles in rad; numpy
    arrays of samples are handled elementwise.
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


def air_data_rates(v_r, v_r_dot) -> tuple:
    """``(Va_dot, alpha_dot, beta_dot)`` [m/s^2, rad/s, rad/s] from the air-relative body
    velocity [m/s] and its rate [m/s^2].

    Time derivative of Vaiopoulos 2017, eq. 2.12-2.14 (``Va = |v_r|``,
    ``alpha = atan2(w, u)``, ``beta = atan2(v, sqrt(u^2 + w^2))``).
    """
    u, v, w = v_r[0], v_r[1], v_r[2]
    ud, vd, wd = v_r_dot[0], v_r_dot[1], v_r_dot[2]
    uw2 = u * u + w * w
    va2 = uw2 + v * v
    uw_dot = u * ud + w * wd
    va_dot = (uw_dot + v * vd) / sqrt(va2)
    alpha_dot = (u * wd - w * ud) / uw2
    beta_dot = (uw2 * vd - v * uw_dot) / (va2 * sqrt(uw2))
    return va_dot, alpha_dot, beta_dot


def dynamic_pressure(airspeed, rho):
    """Dynamic pressure ``qbar = rho Va^2 / 2`` [Pa] at ``airspeed`` [m/s] and air density
    ``rho`` [kg/m^3] (what a pitot-static probe measures)."""
    return 0.5 * rho * airspeed * airspeed


def airspeed_from_dynamic_pressure(qbar, rho):
    """Airspeed ``sqrt(2 qbar / rho)`` [m/s] of a dynamic pressure [Pa] at air density
    ``rho`` [kg/m^3]; a negative pressure (sensor noise near rest) gives 0, NaN stays NaN."""
    return sqrt(2.0 * smax(0.0, qbar) / rho)
