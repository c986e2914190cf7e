"""The signals the filters read: their names, the flight-log channel of each, and which
samples of a held (sample-and-hold) sensor channel are new.

A filter model names its inputs and measurements with the names below; the offline runs
find them in a :class:`~drake_uav.io.flight_log.FlightLog` through
:data:`LOG_CHANNELS`, the LeafSystems on the sensor ports.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "Cumulative",
    "HELD_FRACTION",
    "unheld",
    "IMU",
    "ATTITUDE",
    "CONTROLS",
    "GPS_VELOCITY",
    "AIR_DATA_SENSORS",
    "AIR_DATA",
    "WIND",
    "LOG_CHANNELS",
    "is_new_sample",
    "fresh_samples",
]

IMU = ("ax", "ay", "az", "p", "q", "r")
"""Accelerometer [m/s^2] and gyro [rad/s]."""
ATTITUDE = ("roll", "pitch", "yaw")
"""Attitude sensor [rad]."""
CONTROLS = ("elevator", "aileron", "rudder", "throttle")
"""Commands [rad, rad, rad, 0..1]."""
GPS_VELOCITY = ("gps_vn", "gps_ve", "gps_vd")
"""GPS ground velocity NED [m/s]."""
AIR_DATA_SENSORS = ("pitot", "alpha_vane", "beta_vane")
"""Pitot dynamic pressure [Pa] and vanes [rad]."""
AIR_DATA = ("airspeed", "alpha", "beta")
"""Stability triplet [m/s, rad, rad] (the truth channels of a simulated flight)."""
WIND = ("wind_n", "wind_e", "wind_d")
"""Wind NED [m/s] (the truth channels of a simulated flight)."""

LOG_CHANNELS = {
    "ax": "imu_ax", "ay": "imu_ay", "az": "imu_az", "p": "imu_p", "q": "imu_q", "r": "imu_r",
    "roll": "att_roll", "pitch": "att_pitch", "yaw": "att_yaw", "gps_vn": "gps_vn",
    "gps_ve": "gps_ve", "gps_vd": "gps_vd", "pitot": "pitot_qbar", "alpha_vane": "vane_alpha",
    "beta_vane": "vane_beta", "airspeed": "pitot_airspeed", "alpha": "vane_alpha",
    "beta": "vane_beta", "elevator": "cmd_elevator", "aileron": "cmd_aileron",
    "rudder": "cmd_rudder", "throttle": "cmd_throttle",
}
"""Filter signal name -> measured channel of :func:`~drake_uav.diagrams.fly` logs."""


def is_new_sample(value, previous) -> np.ndarray:
    """True where a held (sample-and-hold) sensor value differs from the previous one;
    a NaN that repeats is not new (so a NaN sample is counted once)."""
    value, previous = np.asarray(value, float), np.asarray(previous, float)
    return ~((value == previous) | (np.isnan(value) & np.isnan(previous)))


def fresh_samples(values: np.ndarray) -> np.ndarray:
    """True where a held sensor channel delivered a new sample (the first row is new);
    for (N, m) channels held together, where any of them did."""
    values = np.asarray(values, float)
    fresh = np.ones(len(values), bool)
    new = is_new_sample(values[1:], values[:-1])
    fresh[1:] = new if new.ndim == 1 else np.any(new, axis=tuple(range(1, new.ndim)))
    return fresh


HELD_FRACTION = 0.6
"""A channel with new values at fewer than this fraction of its samples is taken as held."""


def unheld(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A held channel as straight lines between the samples it delivered.

    Each new value is placed at the sample where it arrived. A channel with a new
    value at most samples (:data:`HELD_FRACTION`) is returned unchanged.
    """
    values = np.asarray(values, float)
    fresh = np.flatnonzero(fresh_samples(values))
    if fresh.size < 2 or fresh.size > HELD_FRACTION * values.size:
        return values
    return np.interp(time, np.asarray(time, float)[fresh], values[fresh])


class Cumulative:
    """Running integrals of sampled signals [unit s], read at any time in the log's span.

    ``values`` (N, m) sampled at ``time`` (N) [s]. ``held`` signals (commands) keep each
    sample until the next one (rectangle rule, the sample acting after its time stamp);
    the others vary linearly between samples (trapezoid rule).
    """

    def __init__(self, time: np.ndarray, values: np.ndarray, held: bool = False):
        self.time = np.asarray(time, float)
        v = np.asarray(values, float).reshape(len(self.time), -1)
        step = np.diff(self.time)[:, None]
        increments = v[:-1] * step if held else 0.5 * (v[1:] + v[:-1]) * step
        self.values = np.vstack([np.zeros((1, v.shape[1])), np.cumsum(increments, axis=0)])

    def at(self, t: np.ndarray) -> np.ndarray:
        """Integrals from the first sample to the times ``t`` (n) [s]: (n, m); times
        outside the span are clamped to it."""
        t = np.clip(np.asarray(t, float), self.time[0], self.time[-1])
        i = np.clip(np.searchsorted(self.time, t, side="right") - 1, 0, len(self.time) - 2)
        w = ((t - self.time[i]) / (self.time[i + 1] - self.time[i]))[:, None]
        return self.values[i] * (1.0 - w) + self.values[i + 1] * w

    def between(self, start: np.ndarray, end: np.ndarray, shift: float = 0.0) -> np.ndarray:
        """Integrals over the windows ``[start - shift, end - shift]`` [s]: (n, m)."""
        return self.at(np.asarray(end) - shift) - self.at(np.asarray(start) - shift)
