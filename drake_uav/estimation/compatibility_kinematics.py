"""Kinematic relations of the data-compatibility check: each sensor group against the IMU.

Every relation is written over windows (:mod:`drake_uav.estimation.compatibility_fits`)
and fitted with the skew of the group it tests (Klein & Morelli 2006, ch. 10):

* attitude against the gyro, through the Euler-angle kinematics
  (:func:`~drake_uav.model.rotations.euler_rates`, Vaiopoulos 2017, eq. 3.3), which are
  linear in the body rates: ``d(euler) = E(euler) (omega_m - b_omega) dt`` gives the gyro
  biases and the attitude skew (:func:`attitude_fit`);
* GPS velocity against the accelerometer rotated to NED plus gravity,
  ``dv = R (a_m - b_a + g_B) dt`` with ``g_B`` the body gravity
  (:func:`~drake_uav.model.fixed_wing.body_gravity`), which gives the accelerometer biases
  and the GPS skew (:func:`velocity_fit`); the same integral with the GPS misfit smoothed
  over a second is the reconstructed ground velocity at the IMU rate
  (:func:`reconstructed_velocity`);
* barometric against GPS altitude at the GPS sample times: the baro bias (:func:`baro_fit`);
* the body angular accelerations against the commands, a local linear model per axis
  (the commanded surface, the rates and the specific force as regressors), which gives
  the skew of the commands (:func:`command_fit`).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from drake_uav.estimation.compatibility_fits import (
    ParameterFit,
    coarse_lag,
    fresh_times,
    linear_fit,
    shift_fit,
    wrap,
)
from drake_uav.estimation.signals import Cumulative
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.fixed_wing import body_gravity
from drake_uav.model.rotations import euler_rates, euler_to_rotmat, rotate

__all__ = ["Strapdown", "attitude_fit", "velocity_fit", "reconstructed_velocity", "baro_fit",
           "command_fit", "high_pass"]

MAX_PITCH = np.radians(75.0)
"""Windows with a larger pitch angle are left out of the Euler-angle relation (singular at
+-90 deg)."""
KINEMATIC_BLOCK = 3.0
"""Time block [s] of the covariance of the kinematic relations: several windows, longer
than the correlation of their residuals (overlapping windows, integrated noise)."""


def high_pass(values: np.ndarray, samples: int) -> np.ndarray:
    """``values`` (N, m) minus their centred moving average over ``samples`` samples."""
    v = np.asarray(values, float).reshape(len(values), -1)
    n = max(int(samples), 1)
    padded = np.pad(v, ((n // 2, n - 1 - n // 2), (0, 0)), mode="edge")
    c = np.vstack([np.zeros((1, v.shape[1])), np.cumsum(padded, axis=0)])
    return v - (c[n:] - c[:-n]) / n


def _windows(time: np.ndarray, length: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """First and last sample of windows of ``length`` samples every ``stride`` samples of
    ``time``, leaving out the windows that span a gap of the log (longer than 1.5 times
    the usual window)."""
    start = np.arange(0, max(len(time) - length, 0), max(stride, 1))
    end = start + length
    span = time[end] - time[start]
    keep = span <= 1.5 * np.median(span) if len(span) else np.zeros(0, bool)
    return start[keep], end[keep]


def _weighted(design, components: int, weights: np.ndarray):
    """``design`` whose rows (``components`` per window) are scaled by ``weights``."""
    def scaled(tau):
        X, y, t = design(tau)
        w = np.tile(weights, len(y) // components)
        return X * w[:, None], y * w, t
    return scaled


def _component_weights(fit: ParameterFit, design, components: int) -> np.ndarray:
    """Inverse residual RMS of each component of a first (unweighted) fit; a component
    that fits exactly (a channel held constant) gets the weight of the others' worst."""
    X, y, _ = design(fit.value("skew"))
    r = (y - X @ fit.estimate[:-1]).reshape(-1, components)
    rms = np.sqrt(np.mean(r * r, axis=0))
    return 1.0 / np.maximum(rms, max(float(rms.max()), 1e-300) * 1e-3)


def _two_pass(design, names, components: int, guess: float, step: float,
              reach: int) -> ParameterFit:
    """:func:`shift_fit` weighted by the components' residual RMS of a first pass (whose
    skew the weighted pass refines within two grid steps)."""
    first = shift_fit(design, names, guess, step, reach, KINEMATIC_BLOCK)
    weights = _component_weights(first, design, components)
    return shift_fit(_weighted(design, components, weights), names, first.value("skew"),
                     step, 2, KINEMATIC_BLOCK)


@functools.cache
def _euler_rate_matrix() -> CompiledFunction:
    """Row-major entries of ``E(euler)`` with ``euler_rates(euler, omega) = E omega``."""
    def matrix(rpy):
        columns = [euler_rates(rpy, axis) for axis in np.eye(3)]
        return [columns[j][i] for i in range(3) for j in range(3)]
    return CompiledFunction(matrix, (3,), {}, "euler_rate_matrix")


class _EulerRelation:
    """The Euler-angle kinematics over windows: attitude change against the integrated
    Euler rates of the gyro, ``E(euler) (omega_m - b) dt`` (attitude ``tau`` late)."""

    def __init__(self, time: np.ndarray, gyro: np.ndarray, euler: np.ndarray):
        self.time, self.euler = time, euler
        E = _euler_rate_matrix().batch_value(euler)
        driven = np.einsum("nij,nj->ni", E.reshape(-1, 3, 3), gyro)
        self.rates, self.matrix = Cumulative(time, driven), Cumulative(time, E)

    def design(self, window: float, stride: float):
        """``design(tau)`` of windows of ``window`` [s] every ``stride`` [s]."""
        dt = float(np.median(np.diff(self.time)))
        m = max(int(round(window / dt)), 2)
        i0, i1 = _windows(self.time, m, max(int(round(stride / dt)), 1))
        level = (np.abs(self.euler[i0, 1]) < MAX_PITCH) & (np.abs(self.euler[i1, 1]) < MAX_PITCH)
        i0, i1 = i0[level], i1[level]
        t0, t1 = self.time[i0], self.time[i1]
        change = wrap(self.euler[i1] - self.euler[i0])
        mid = np.repeat(0.5 * (t0 + t1), 3)

        def design(tau):
            y = change - self.rates.between(t0, t1, tau)
            return -self.matrix.between(t0, t1, tau).reshape(-1, 3), y.reshape(-1), mid
        return design


def attitude_fit(time: np.ndarray, gyro: np.ndarray, euler: np.ndarray, *, window: float,
                 max_skew: float) -> ParameterFit:
    """Gyro biases ``bias_p, bias_q, bias_r`` [rad/s] and the attitude skew [s].

    ``gyro`` (N, 3) [rad/s] and ``euler`` (N, 3) roll, pitch, yaw [rad] on ``time`` (N) [s].
    The skew (searched within ``+-max_skew`` [s]; positive: the attitude lags the gyro)
    comes from half windows every eighth of ``window`` [s], whose ends see more of the
    fast attitude changes; the biases, at that skew, from windows of ``window`` every
    quarter window, over which a bias builds up more. The two are taken as uncorrelated.
    """
    dt = float(np.median(np.diff(time)))
    relation = _EulerRelation(time, gyro, euler)
    n = int(round(2.0 / dt))
    guess = coarse_lag(high_pass(relation.rates.values, n),
                       high_pass(np.unwrap(euler, axis=0), n), 1.0 / dt, max_skew)
    names = ("bias_p", "bias_q", "bias_r")
    timing = _two_pass(relation.design(0.5 * window, 0.125 * window), names, 3, guess, dt, 6)
    tau = timing.value("skew")
    design = relation.design(window, 0.25 * window)
    weights = _component_weights(timing, design, 3)
    X, y, row_time = _weighted(design, 3, weights)(tau)
    biases = linear_fit(X, y, names, row_time, KINEMATIC_BLOCK)
    covariance = np.zeros((4, 4))
    covariance[:3, :3], covariance[3, 3] = biases.covariance, timing.covariance[3, 3]
    return ParameterFit((*names, "skew"), np.append(biases.estimate, tau), covariance,
                        min(biases.dof, timing.dof), biases.residual_rms)


@dataclasses.dataclass(frozen=True)
class Strapdown:
    """The accelerometer rotated to NED plus gravity, integrated over the log.

    ``acceleration`` = ``R (a_m + g_B)`` [m/s^2] (N, 3), with ``R`` the body -> NED rotation
    of the logged attitude and ``g_B`` the body gravity; ``rotation`` the running integral
    of ``R`` (rows of the 3x3 matrix) [s], what an accelerometer bias is multiplied by.
    """

    velocity: Cumulative
    rotation: Cumulative
    rows: np.ndarray
    """``R`` per sample, (N, 3, 3)."""

    @classmethod
    def from_samples(cls, time, specific_force, euler, gravity: float) -> Strapdown:
        """From the accelerometer (N, 3) [m/s^2], the attitude (N, 3) [rad] and gravity
        [m/s^2] on ``time`` (N) [s]."""
        R = euler_to_rotmat(np.asarray(euler, float).T)
        g_body = body_gravity(R, gravity)
        accel = rotate(R, [specific_force[:, i] + g_body[i] for i in range(3)])
        rows = np.moveaxis(R, 2, 0)
        return cls(Cumulative(time, np.column_stack(accel)),
                   Cumulative(time, rows.reshape(-1, 9)), rows)

    def velocity_at(self, t: np.ndarray, bias: np.ndarray) -> np.ndarray:
        """Integrated velocity change since the first sample at ``t`` [s] (n, 3) [m/s], with
        the accelerometer bias ``bias`` (3) [m/s^2] removed."""
        return self.velocity.at(t) - self.rotation.at(t).reshape(-1, 3, 3) @ bias


def velocity_fit(time: np.ndarray, strapdown: Strapdown, gps_velocity: np.ndarray, *,
                 window: float, max_skew: float) -> ParameterFit:
    """Accelerometer biases ``bias_x, bias_y, bias_z`` [m/s^2] and the GPS skew [s].

    ``gps_velocity`` (N, 3) NED [m/s], held between its samples; windows span about
    ``window`` [s] of GPS samples, every other sample. The skew is the whole delay of
    the GPS velocity behind the IMU (receiver latency included).
    """
    dt = float(np.median(np.diff(time)))
    j = fresh_times(time, gps_velocity)
    period = float(np.median(np.diff(time[j])))
    m = max(int(round(window / period)), 1)
    k0, k1 = _windows(time[j], m, 2)
    t0, t1 = time[j[k0]], time[j[k1]]
    change = gps_velocity[j[k1]] - gps_velocity[j[k0]]
    mid = np.repeat(0.5 * (t0 + t1), 3)

    def design(tau):
        y = change - strapdown.velocity.between(t0, t1, tau)
        return -strapdown.rotation.between(t0, t1, tau).reshape(-1, 3), y.reshape(-1), mid

    held = np.column_stack([np.interp(time, time[j], gps_velocity[j, i]) for i in range(3)])
    n = int(round(2.0 / dt))
    guess = coarse_lag(high_pass(strapdown.velocity.values, n), high_pass(held, n), 1.0 / dt,
                       max_skew)
    return _two_pass(design, ("bias_x", "bias_y", "bias_z"), 3, guess, dt,
                     max(int(round(period / dt)), 5))


def reconstructed_velocity(time: np.ndarray, strapdown: Strapdown, gps_velocity: np.ndarray,
                           bias: np.ndarray, skew: float, smoothing: float = 1.0) -> np.ndarray:
    """Ground velocity NED (N, 3) [m/s] at the IMU's times: the strapdown integral with the
    accelerometer bias removed, plus its misfit to the GPS (at the GPS's own times, the
    samples ``skew`` [s] earlier than logged) averaged over ``smoothing`` [s]."""
    j = fresh_times(time, gps_velocity)
    measured_at = time[j] - skew
    misfit = gps_velocity[j] - strapdown.velocity_at(measured_at, bias)
    period = float(np.median(np.diff(time[j]))) if len(j) > 1 else 1.0
    smooth = misfit - high_pass(misfit, max(int(round(smoothing / period)), 1))
    drift = np.column_stack([np.interp(time, measured_at, smooth[:, i]) for i in range(3)])
    return strapdown.velocity_at(time, bias) + drift


def baro_fit(time: np.ndarray, baro_altitude: np.ndarray, gps_down: np.ndarray,
             gps_skew: float, block: float) -> ParameterFit:
    """Bias ``bias`` [m] of the barometric altitude against the GPS altitude ``-gps_down``,
    compared at the GPS samples' own times (``gps_skew`` [s] before they were logged)."""
    j = fresh_times(time, gps_down)
    fresh = fresh_times(time, baro_altitude)
    at = time[j] - gps_skew
    keep = (at >= time[0]) & (at <= time[-1])
    baro = np.interp(at[keep], time[fresh], baro_altitude[fresh])
    y = baro + gps_down[j][keep]
    return linear_fit(np.ones((len(y), 1)), y, ("bias",), at[keep], block)


# Regressors of the angular accelerations besides the commands: the body rates and the
# lateral or normal specific force (a stand-in for sideslip and angle of attack).
_RESPONSE = {"p": (("aileron", "rudder"), ("p", "r", "ay")),
             "q": (("elevator",), ("q", "az")),
             "r": (("rudder", "aileron"), ("r", "p", "ay"))}


def command_fit(time: np.ndarray, imu: dict[str, np.ndarray], commands: dict[str, np.ndarray],
                *, max_skew: float, window: int = 6) -> ParameterFit | None:
    """Skew [s] of the commands against the angular accelerations they cause.

    Per body axis, the rate change over ``window`` samples against the integral over the
    window of a constant, the commanded surfaces ``skew`` earlier (held between samples)
    and the other regressors of :data:`_RESPONSE`; the axes share the skew. ``imu`` maps
    ``p q r ax ay az`` to samples, ``commands`` maps surface names to samples (absent
    surfaces are left out). None when no axis has its command.
    """
    dt = float(np.median(np.diff(time)))
    axes = [a for a, (surfaces, _) in _RESPONSE.items() if surfaces[0] in commands]
    if not axes:
        return None
    i0, i1 = _windows(time, window, window)
    t0, t1 = time[i0], time[i1]
    parts, names = [], []
    for axis in axes:
        surfaces = [s for s in _RESPONSE[axis][0] if s in commands]
        held = Cumulative(time, np.column_stack([commands[s] for s in surfaces]), held=True)
        other = Cumulative(time, np.column_stack([np.ones_like(time)]
                                                 + [imu[s] for s in _RESPONSE[axis][1]]))
        parts.append((imu[axis][i1] - imu[axis][i0], held, other.between(t0, t1)))
        names += [f"{axis}_{s}" for s in surfaces] + [f"{axis}_{s}" for s in
                                                      ("bias", *_RESPONSE[axis][1])]
    design = _block_design(parts, t0, t1)
    reference = np.column_stack([commands[_RESPONSE[a][0][0]] for a in axes])
    response = np.column_stack([np.gradient(imu[a], time) for a in axes])
    n = max(int(round(0.1 / dt)), 1)
    guess = coarse_lag(reference - high_pass(reference, n), response - high_pass(response, n),
                       1.0 / dt, max_skew)
    return _two_pass(design, names, len(axes), guess, dt, 6)


def _block_design(parts, t0: np.ndarray, t1: np.ndarray):
    """Stacked per-axis rows (axis fastest) with a block-diagonal regressor matrix."""
    widths = [held.values.shape[1] + other.shape[1] for _, held, other in parts]
    offsets = np.concatenate([[0], np.cumsum(widths)])
    count, mid = len(parts), 0.5 * (t0 + t1)

    def design(tau):
        X = np.zeros((len(t0), count, offsets[-1]))
        y = np.empty((len(t0), count))
        for a, (change, held, other) in enumerate(parts):
            block = np.column_stack([held.between(t0, t1, tau), other])
            X[:, a, offsets[a]:offsets[a + 1]] = block
            y[:, a] = change
        return X.reshape(-1, offsets[-1]), y.reshape(-1), np.repeat(mid, count)
    return design
