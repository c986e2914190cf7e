"""GPS receiver latency: the ground-velocity change over the latency from the IMU.

A GPS velocity is measured ``latency`` seconds before it is delivered. Adding the
velocity change since then, integrated from the accelerometer rotated to NED plus
gravity (strapdown), gives the velocity at delivery. The offline runs use
:func:`gps_latency_correction` over a whole log; the LeafSystems integrate
:func:`ned_acceleration` sample by sample.
"""

from __future__ import annotations

import functools

import numpy as np

from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.rotations import euler_to_rotmat, rotate
from drake_uav.model.scalar import as_list
from drake_uav.vehicles.sensors import GpsParams

__all__ = ["DEFAULT_GPS_LATENCY", "ned_acceleration", "gps_latency_correction"]

DEFAULT_GPS_LATENCY = GpsParams().latency
"""GPS latency [s] assumed for logs unless told otherwise (the sensor suite's default)."""


@functools.cache
def _ned_acceleration_function(gravity: float) -> CompiledFunction:
    def ned_acceleration(z):
        accel = rotate(euler_to_rotmat(z[3:6]), z[0:3])
        return np.array([accel[0], accel[1], accel[2] + gravity])

    return CompiledFunction(ned_acceleration, (6,), {}, "ned_acceleration")


def ned_acceleration(specific_force, euler, gravity: float) -> np.ndarray:
    """Ground acceleration NED [m/s^2] of one IMU sample: ``R(euler) a + g e_D`` from the
    specific force [m/s^2], the roll, pitch, yaw [rad] and gravity [m/s^2]."""
    return _ned_acceleration_function(float(gravity)).program(
        as_list(specific_force) + as_list(euler))


def gps_latency_correction(time: np.ndarray, specific_force: np.ndarray, euler: np.ndarray,
                           latency: float, gravity: float) -> np.ndarray:
    """Ground-velocity change [m/s] (N, 3) over the last ``latency`` seconds.

    Strapdown integration (trapezoid) of ``R(euler) a + g e_D`` from the
    accelerometer [m/s^2] and attitude [rad] samples at ``time`` [s]; added to a GPS
    velocity measured ``latency`` seconds ago it gives the velocity now.
    """
    time = np.asarray(time, float)
    accel = _ned_acceleration_function(float(gravity)).batch_value(
        np.column_stack([specific_force, euler]))
    increments = np.zeros_like(accel)
    increments[1:] = 0.5 * (accel[1:] + accel[:-1]) * np.diff(time)[:, None]
    cumulative = np.cumsum(increments, axis=0)
    start = np.searchsorted(time, time - latency - 1e-9)
    return cumulative - cumulative[start]
