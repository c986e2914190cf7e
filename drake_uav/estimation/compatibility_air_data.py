"""Air-data relations of the data-compatibility check: the wind triangle.

The reconstructed ground velocity (NED, at the IMU rate) minus a wind that is constant
over each wind segment (north and east components; the mean vertical wind is taken as
zero), rotated to body axes with the logged attitude, gives the kinematic airspeed,
angle of attack and sideslip (:func:`~drake_uav.model.air_data.air_data_from_velocity`).
The measured air data are compared with them through the calibration model of Klein &
Morelli 2006, ch. 10:

    V_m = k_V V,    alpha_m = b_alpha + k_alpha alpha,    beta_m = b_beta + k_beta beta.

* :func:`wind_fit`: the winds, the airspeed scale factor and the vane offsets (and scale
  factors when asked) by Gauss-Newton on the residuals of the three relations, each
  weighted by its residual RMS, averaged over 0.1 s. The airspeed scale factor and the
  sideslip offset are confounded with the wind along and across the track unless the
  heading changes (:func:`heading_spread`).
* :func:`vane_scale_fit`: a vane's scale factor, and how much of the kinematic flow
  angle's variation the vane does not follow. Gusts move the vane but not the kinematic
  angle computed with a steady wind; they act as errors of the regressor and bias the
  scale factor towards zero by about that share (errors-in-variables attenuation), so a
  scale factor is only trusted where the share is small.
* :func:`air_data_skew`: the skew of the air data against the kinematic air data from
  the 0.2-2 Hz band of both (the manoeuvres; white noise mostly outside it), with the
  IMU signals that see gusts at once, and the commands that move those signals directly,
  as extra regressors.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy import signal

from drake_uav.estimation.compatibility_fits import (
    ParameterFit,
    block_covariance,
    block_sandwich,
    correlated_covariance,
    grid_minimum,
    larger_errors,
    shift_fit,
    solve,
)
from drake_uav.estimation.sensor_noise import noise_floor_variance
from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.model.rotations import rotate_back

__all__ = ["kinematic_air_data", "wind_fit", "heading_spread", "vane_scale_fit",
           "air_data_skew", "AVERAGING", "WIND_BLOCK"]

AVERAGING = 0.1
"""The wind-triangle relations are compared as 0.1 s averages [s] (white noise reduced,
the low frequencies that carry the levels kept)."""
WIND_BLOCK = 20.0
"""Time block [s] of the covariance of the wind-triangle fit: about the correlation time
of low-altitude gusts (Dryden length over airspeed), which dominate its residuals."""
SKEW_BAND = (0.2, 2.0)
"""Band [Hz] of the air-data skew fit."""
COARSE_STEP = 0.05
"""Step [s] of the coarse search of the air-data skew (a tenth of the band's shortest
period)."""
SKEW_BLOCK = 5.0
"""Time block [s] of the covariance of the air-data skew fit."""
GAUSS_NEWTON_STEPS = 8


def heading_spread(yaw: np.ndarray) -> float:
    """Circular variance ``1 - |mean(exp(i psi))|`` of the heading [rad]: 0 for a
    straight track, 0.36 for a steady half circle, 1 for headings spread evenly."""
    return float(1.0 - abs(np.mean(np.exp(1j * np.asarray(yaw, float)))))


def kinematic_air_data(velocity: np.ndarray, rows: np.ndarray, wind: np.ndarray) -> tuple:
    """Airspeed [m/s], alpha and beta [rad] (each (N)) of the ground velocity (N, 3) NED
    [m/s] minus the wind (N, 3) [m/s], in the body axes of the rotations ``rows``
    (N, 3, 3), body -> NED: the wind triangle ``v_B = R^T (v - W)``."""
    body = rotate_back(np.moveaxis(rows, 0, -1), (velocity - wind).T)
    return air_data_from_velocity(body[0], body[1], body[2])


def _averaged(values: np.ndarray, n: int) -> np.ndarray:
    """Means over consecutive groups of ``n`` samples along the first axis."""
    m = len(values) // n
    return values[: m * n].reshape(m, n, *values.shape[1:]).mean(axis=1)


class _WindProblem:
    """Residuals of the wind triangle as a function of the parameters."""

    def __init__(self, velocity, rows, measured: Mapping[str, np.ndarray], segment: np.ndarray,
                 free: Sequence[str], fixed: Mapping[str, float]):
        self.velocity, self.rows, self.measured = velocity, rows, measured
        self.segment, self.count = segment, int(segment.max()) + 1
        self.free, self.fixed = tuple(free), dict(fixed)
        self.names = tuple(f"wind_{c}_{s}" for s in range(self.count) for c in "ne") + self.free
        self.weights = {"airspeed": 1.0, "alpha": 50.0, "beta": 50.0}

    def _calibration(self, p: np.ndarray) -> dict[str, float]:
        values = {**self.fixed, **dict(zip(self.free, p[2 * self.count:], strict=True))}
        return {"airspeed_scale": values.get("airspeed_scale", 1.0),
                **{f"{a}_{kind}": values.get(f"{a}_{kind}", 1.0 if kind == "scale" else 0.0)
                   for a in ("alpha", "beta") for kind in ("offset", "scale")}}

    def kinematic(self, p: np.ndarray) -> dict[str, np.ndarray]:
        w = p[: 2 * self.count].reshape(-1, 2)[self.segment]
        wind = np.column_stack([w, np.zeros(len(w))])
        return dict(zip(("airspeed", "alpha", "beta"),
                        kinematic_air_data(self.velocity, self.rows, wind), strict=True))

    def residuals(self, p: np.ndarray, unweighted: bool = False) -> dict[str, np.ndarray]:
        c, kin = self._calibration(p), self.kinematic(p)
        out = {"airspeed": self.measured["airspeed"] - c["airspeed_scale"] * kin["airspeed"]}
        for a in ("alpha", "beta"):
            if a in self.measured:
                out[a] = self.measured[a] - c[f"{a}_offset"] - c[f"{a}_scale"] * kin[a]
        return out if unweighted else {k: v * self.weights[k] for k, v in out.items()}

    def stacked(self, p: np.ndarray) -> np.ndarray:
        return np.concatenate(list(self.residuals(p).values()))

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        """Derivatives of the stacked residuals: the winds by central differences (all
        segments at once, each row depends on its own segment only), the rest exact."""
        r0, columns = self.stacked(p), []
        seg = np.concatenate([self.segment] * (len(r0) // len(self.segment)))
        for c in range(2):
            h = np.zeros_like(p)
            h[c: 2 * self.count: 2] = 1e-3
            d = (self.stacked(p + h) - self.stacked(p - h)) / 2e-3
            columns += [np.where(seg == s, d, 0.0) for s in range(self.count)]
        wind = np.column_stack(columns)
        wind = wind[:, np.argsort(np.r_[0:2 * self.count:2, 1:2 * self.count:2], kind="stable")]
        return np.column_stack([wind] + [self._calibration_column(p, name) for name in self.free])

    def _calibration_column(self, p: np.ndarray, name: str) -> np.ndarray:
        kin, parts = self.kinematic(p), []
        for channel in self.residuals(p):
            w = self.weights[channel]
            if name == "airspeed_scale" and channel == "airspeed":
                parts.append(-w * kin["airspeed"])
            elif name == f"{channel}_offset":
                parts.append(-w * np.ones(len(self.segment)))
            elif name == f"{channel}_scale":
                parts.append(-w * kin[channel])
            else:
                parts.append(np.zeros(len(self.segment)))
        return np.concatenate(parts)

    def solve(self, p: np.ndarray) -> np.ndarray:
        for _ in range(GAUSS_NEWTON_STEPS):
            step = solve(self.jacobian(p), -self.stacked(p))
            p = p + step
            if np.max(np.abs(step)) < 1e-7:
                break
        return p

    def reweight(self, p: np.ndarray) -> None:
        """Weights = inverse residual RMS of each relation at ``p``."""
        for k, r in self.residuals(p, unweighted=True).items():
            self.weights[k] = 1.0 / max(float(np.sqrt(np.mean(r * r))), 1e-12)


def wind_fit(time: np.ndarray, velocity: np.ndarray, rows: np.ndarray,
             measured: Mapping[str, np.ndarray], segment: np.ndarray,
             free: Sequence[str], fixed: Mapping[str, float] | None = None) -> ParameterFit:
    """Winds per segment and the ``free`` calibration parameters of the wind triangle.

    ``velocity`` (N, 3) NED [m/s] and ``rows`` (N, 3, 3) body -> NED at ``time`` (N) [s];
    ``measured`` maps ``airspeed`` [m/s] (required), ``alpha``, ``beta`` [rad] (the vanes,
    when logged) to samples; ``segment`` (N) the wind segment of each sample (0, 1, ...).
    ``free`` names parameters among ``airspeed_scale``, ``alpha_offset``, ``alpha_scale``,
    ``beta_offset``, ``beta_scale``; the others take ``fixed`` or their nominal values
    (scale 1, offset 0). Returns ``wind_n_<s>, wind_e_<s>`` [m/s] then ``free``.
    """
    n = max(int(round(AVERAGING / float(np.median(np.diff(time))))), 1)
    problem = _WindProblem(_averaged(velocity, n), _averaged(rows, n),
                           {k: _averaged(v, n) for k, v in measured.items()},
                           _averaged(segment.astype(float), n).round().astype(int),
                           free, fixed or {})
    p = np.zeros(len(problem.names))
    p[2 * problem.count:] = [1.0 if name.endswith("scale") else 0.0 for name in free]
    p = problem.solve(p)
    problem.reweight(p)
    p = problem.solve(p)
    problem.reweight(p)
    r, G = problem.stacked(p), -problem.jacobian(p)
    channels = len(r) // len(problem.segment)
    row_time = np.tile(_averaged(time, n), channels)
    cov, dof = block_covariance(G, r, row_time, WIND_BLOCK)
    groups = np.repeat(np.arange(channels), len(problem.segment))
    cov = larger_errors(cov, correlated_covariance(G, r, groups))
    return ParameterFit(problem.names, p, cov, dof, float(np.sqrt(np.mean(r * r))))


def vane_scale_fit(time: np.ndarray, kinematic: np.ndarray, measured: np.ndarray
                   ) -> tuple[ParameterFit, float]:
    """Offset [rad] and scale factor [-] of a vane against its kinematic flow angle, and
    the share of the kinematic angle's variation the vane does not follow [-].

    Both on 0.1 s averages. The kinematic angle carries the white noise of the attitude
    and GPS it is computed from: its floor (:func:`noise_floor_variance`) is removed from
    the normal equations (bias-compensated least squares), with the sandwich covariance
    of the compensated scores over time blocks. Gusts move the vane but not the kinematic
    angle; that error is not white and would bias the scale factor towards zero by about
    the returned share ``var(residual) / (k^2 var(kinematic signal))`` (errors-in-variables
    attenuation; an upper bound, the vane's own noise is in the residual too).
    """
    dt = float(np.median(np.diff(time)))
    n = max(int(round(AVERAGING / dt)), 1)
    white = noise_floor_variance(kinematic, 1.0 / dt) / n
    k, m, t = _averaged(kinematic, n), _averaged(measured, n), _averaged(time, n)
    X = np.column_stack([np.ones(len(k)), k])
    correction = np.diag([0.0, white])
    A = X.T @ X - len(k) * correction
    theta = np.linalg.solve(A, X.T @ m)
    r = m - X @ theta
    cov, dof = block_sandwich(X * r[:, None] + correction @ theta, A, t, WIND_BLOCK)
    signal_variance = max(np.var(k) - white, 1e-300)
    share = float(np.var(r) / max(theta[1] ** 2 * signal_variance, 1e-300))
    return ParameterFit(("offset", "scale"), theta, cov, dof,
                        float(np.sqrt(np.mean(r * r)))), share


def air_data_skew(time: np.ndarray, kinematic: Mapping[str, np.ndarray],
                  measured: Mapping[str, np.ndarray], response: Mapping[str, np.ndarray],
                  max_skew: float) -> ParameterFit:
    """Skew [s] of the air data (positive: they lag the IMU) and their in-band gains.

    ``kinematic``, ``measured`` and ``response`` map the same channel names to samples
    on ``time`` (``response``: (N, m) signals that see a gust at once, as the air data
    do, and what moves them directly: the specific force along the channel's direction
    and the commands of the surfaces or throttle that change it). All
    are band-passed (:data:`SKEW_BAND`); each measured channel, read ``skew`` later, is
    fitted with gains on its kinematic channel and its response signals, so the gust
    part of the air data is explained at the IMU's time rather than by a shift (rows
    weighted by channel).
    """
    dt = float(np.median(np.diff(time)))
    names = list(measured)
    sos = signal.butter(2, SKEW_BAND, btype="band", fs=1.0 / dt, output="sos")
    band = {c: signal.sosfiltfilt(sos, np.column_stack([kinematic[c], response[c]]), axis=0)
            for c in names}
    meas = {c: signal.sosfiltfilt(sos, measured[c]) for c in names}
    names = [c for c in names if np.std(meas[c]) > 0.0 and np.std(band[c][:, 0]) > 0.0]
    if not names:
        raise ValueError("no air-data channel varies in the band of the skew fit")
    margin = max_skew + 0.2
    # Rows at about 20 Hz: ten times the band's upper edge, so the shifted band-passed
    # signals are read exactly enough between samples.
    every = max(int(round(1.0 / (10.0 * SKEW_BAND[1] * dt))), 1)
    inside = (time >= time[0] + margin) & (time <= time[-1] - margin)
    inside &= np.arange(len(time)) % every == 0
    widths = np.cumsum([0] + [band[c].shape[1] for c in names])
    scale = {c: 1.0 / float(np.std(meas[c])) for c in names}
    X = np.zeros((int(inside.sum()), len(names), widths[-1]))
    for i, c in enumerate(names):
        X[:, i, widths[i]:widths[i + 1]] = band[c][inside] * scale[c]
    X = X.reshape(-1, widths[-1])
    row_time = np.repeat(time[inside], len(names))

    def design(tau):
        y = np.column_stack([np.interp(time[inside] + tau, time, meas[c]) * scale[c]
                             for c in names])
        return X, y.reshape(-1), row_time

    labels = [f"{c}_gain_{j}" for c in names for j in range(band[c].shape[1])]
    # Coarse search over the whole range with the full regression (a cross-correlation
    # of the airspeed alone can peak elsewhere), then the fine grid around its minimum.
    coarse = max(int(round(COARSE_STEP / dt)), 1) * dt
    guess = grid_minimum(design, coarse * np.arange(-int(max_skew / coarse),
                                                    int(max_skew / coarse) + 1))
    return shift_fit(design, labels, guess, dt, max(int(round(coarse / dt)), 6), SKEW_BLOCK)
