"""Local flat-earth NED positions and WGS-84 latitude, longitude and altitude.

Near an origin, a north offset ``dn`` [m] is ``dlat R_N`` and an east offset is
``dlon R_E cos(lat0)``, with the WGS-84 meridian radius of curvature ``R_N = a (1 - e^2) /
(1 - e^2 sin^2 lat0)^1.5`` and prime-vertical radius ``R_E = a / sqrt(1 - e^2 sin^2 lat0)``
(Beard & McLain 2012 use the spherical special case; good to a few km from the origin).
Autopilot logs store positions as latitude and longitude; the project works in NED.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["WGS84_A", "WGS84_E2", "local_radii", "ned_from_geodetic", "geodetic_from_ned"]

WGS84_A = 6378137.0
"""WGS-84 semi-major axis [m]."""
WGS84_E2 = 6.69437999014e-3
"""WGS-84 first eccentricity squared."""


def local_radii(lat0_deg: float) -> tuple[float, float]:
    """Metres per radian of latitude (``R_N``) and of longitude (``R_E cos lat0``) at
    latitude ``lat0_deg`` [deg]."""
    lat0 = math.radians(lat0_deg)
    s2 = 1.0 - WGS84_E2 * math.sin(lat0) ** 2
    return WGS84_A * (1.0 - WGS84_E2) / s2 ** 1.5, WGS84_A / math.sqrt(s2) * math.cos(lat0)


def ned_from_geodetic(lat, lon, alt, origin) -> tuple:
    """North, east, down [m] of latitude, longitude [deg] and altitude [m] about
    ``origin`` = (lat0 [deg], lon0 [deg], alt0 [m]); arrays of samples work elementwise."""
    r_north, r_east = local_radii(origin[0])
    return (np.radians(np.subtract(lat, origin[0])) * r_north,
            np.radians(np.subtract(lon, origin[1])) * r_east,
            -np.subtract(alt, origin[2]))


def geodetic_from_ned(pn, pe, pd, origin) -> tuple:
    """Latitude, longitude [deg] and altitude [m] of north, east, down [m] about
    ``origin`` (the inverse of :func:`ned_from_geodetic`)."""
    r_north, r_east = local_radii(origin[0])
    return (origin[0] + np.degrees(np.divide(pn, r_north)),
            origin[1] + np.degrees(np.divide(pe, r_east)),
            origin[2] - np.asarray(pd))
