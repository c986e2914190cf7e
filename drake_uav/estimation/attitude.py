"""Attitude inputs smoothed with the gyro (a complementary filter) for the air-data filters.

The GPS rows of the air-data filters see the attitude through ``R(euler)``; the raw
samples' noise across the air velocity would hide GPS spikes from the innovation gate.
The filters therefore use the attitude carried forward with the gyro and pulled
towards each sample (``docs/estimation.md``, Attitude smoothing).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from pydrake.math import atan2, cos, sin

from drake_uav.estimation.signals import ATTITUDE
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.rotations import euler_rates

__all__ = [
    "ATTITUDE_TIME_CONSTANT",
    "smoothed_attitude",
    "smoothed_attitude_std",
    "SmoothedAttitude",
]

ATTITUDE_TIME_CONSTANT = 0.05
"""Time constant [s] of the attitude smoothing of the air-data filters: the GPS sample
period of the default suite, so consecutive GPS samples see nearly independent
attitude errors (correlation e^-1)."""


def smoothed_attitude(z):
    """One step of the attitude smoothing (scalar-generic): ``z`` = previous smoothed
    roll, pitch, yaw [rad], body rates over the step [rad/s], attitude sample [rad],
    gain [-], step [s].

    The previous attitude is carried forward with the Euler-angle rates of the
    gyro (Vaiopoulos 2017, eq. 3.3) and pulled towards the sample by ``gain`` (a
    complementary filter, time constant ``step / gain``). Angles wrapped to
    (-pi, pi].
    """
    previous, rates = z[0:3], euler_rates(z[0:3], z[3:6])
    out = []
    for i in range(3):
        predicted = previous[i] + z[10] * rates[i]
        difference = z[6 + i] - predicted
        angle = predicted + z[9] * atan2(sin(difference), cos(difference))
        out.append(atan2(sin(angle), cos(angle)))
    return out


@functools.cache
def _attitude_smoother() -> CompiledFunction:
    return CompiledFunction(smoothed_attitude, (11,), {}, "smoothed_attitude")


def smoothed_attitude_std(gyro_std: float, attitude_std: float, dt: float,
                          time_constant: float) -> float:
    """Steady-state error std [rad] of :func:`smoothed_attitude` (gain ``dt / time_constant``,
    both in s) on white gyro noise ``gyro_std`` [rad/s] and attitude noise ``attitude_std``
    [rad]: ``((1 - K)^2 (gyro_std dt)^2 + K^2 attitude_std^2) / (1 - (1 - K)^2)``."""
    gain = min(dt / time_constant, 1.0) if time_constant > 0 else 1.0
    if gain >= 1.0:
        return attitude_std
    keep = (1.0 - gain) ** 2
    return math.sqrt((keep * (gyro_std * dt) ** 2 + gain**2 * attitude_std**2) / (1.0 - keep))


class SmoothedAttitude:
    """Mixin of an :class:`~drake_uav.estimation.ekf.EkfModel` whose attitude inputs are
    smoothed with its gyro inputs (:func:`smoothed_attitude`).

    The class sets ``_rates`` and ``_angles`` (slices of its input vector) and calls
    :meth:`_init_smoothing`. The error of the smoothed attitude seen by ``h`` is
    :func:`smoothed_attitude_std`; its low-frequency part, which drives the prediction,
    is still that of the samples (``input_std``).
    """

    _rates: slice
    _angles: slice

    def _init_smoothing(self, time_constant: float) -> None:
        if not (math.isfinite(time_constant) and time_constant >= 0):
            raise ValueError(f"attitude_time_constant must be >= 0, got {time_constant}")
        self.attitude_time_constant = time_constant
        self.smoothed_inputs = tuple(range(self._angles.start, self._angles.stop)) if (
            time_constant > 0) else ()

    def smooth_inputs(self, previous, u, dt):
        """``u`` with its attitude smoothed from ``previous`` (see ``EkfModel``)."""
        gain = min(dt / self.attitude_time_constant, 1.0)
        rates, angles = self._rates, self._angles
        out = np.array(u, float)
        if out.ndim == 1:
            p, q = previous.tolist(), out.tolist()
            z = (p[angles] + [0.5 * (a + b) for a, b in zip(p[rates], q[rates], strict=True)]
                 + q[angles] + [gain, dt])
            out[angles] = _attitude_smoother().program(z)
        else:
            z = np.concatenate([previous[:, angles], 0.5 * (previous[:, rates] + out[:, rates]),
                                out[:, angles], np.broadcast_to([gain, dt], (len(out), 2))],
                               axis=1)
            out[:, angles] = _attitude_smoother().batch_value(z)
        return out

    def _attitude_noise(self, std: dict[str, float], period: float) -> dict[str, float]:
        """``measurement_input_std`` of the smoothed attitude at the update ``period`` [s]
        (empty without smoothing)."""
        if not self.smoothed_inputs:
            return {}
        gyro = max(std["p"], std["q"], std["r"])
        return {n: smoothed_attitude_std(gyro, std[n], period, self.attitude_time_constant)
                for n in ATTITUDE}
