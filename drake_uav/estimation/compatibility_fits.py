"""Least-squares fits of the data-compatibility check: linear parameters plus a time skew,
with standard errors that hold for correlated residuals.

Every kinematic relation of the check (:mod:`drake_uav.estimation.compatibility`) is
written over windows, as flight-path reconstruction does (Klein & Morelli 2006, ch. 10):
the change of a measured signal over a window against the integral of the signals that
drive it over the same window,

    y(t1) - y(t0) = integral_{t0 - tau}^{t1 - tau} (u(t) - X(t) theta) dt + e,

linear in the calibration parameters ``theta`` (biases) for a given skew ``tau`` [s] of
the measured group (its samples are ``tau`` late).
:class:`~drake_uav.estimation.signals.Cumulative` holds the running integrals, read at
any shifted time by linear interpolation, so a skew costs one interpolation per window.
:func:`shift_fit` finds the skew by least squares over a grid around a coarse guess
(:func:`coarse_lag`, the peak of a cross-correlation), refines it between grid points
with a parabola through the residual sums, and fits the linear parameters at that skew.

Uncertainty. The residuals of these relations are correlated in time (integrated sensor
noise, overlapping windows, gusts for the air data), so the usual ``s^2 (X^T X)^-1``
understates the error. The covariance is the sandwich ``A^-1 Omega A^-1`` of the
linearised problem (``A = G^T G``, ``G`` the Jacobian of the residuals with respect to
every parameter, the skew by central difference), with ``Omega`` the sum of the outer
products of the scores summed over contiguous time blocks that are long compared with the
residual's correlation: the cluster covariance with time blocks of Bester, Conley &
Hansen 2011, whose t statistics have ``B - 1`` degrees of freedom for ``B`` blocks.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
from scipy import fft as sp_fft
from scipy import stats

from drake_uav.estimation.signals import is_new_sample

__all__ = ["ParameterFit", "block_covariance", "block_sandwich", "coarse_lag",
           "correlation_time", "correlated_covariance", "larger_errors", "grid_minimum",
           "linear_fit", "shift_fit", "solve", "fresh_times", "wrap", "t_p_value"]

MAX_RECENTRES = 5
"""Times :func:`shift_fit` moves its grid to an edge minimum before giving up."""
MIN_BLOCKS = 2
"""Fewest time blocks a covariance is computed from (1 degree of freedom)."""


def wrap(angle):
    """Angle [rad] wrapped to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def fresh_times(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Indices of the samples at which a held (sample-and-hold) group of channels
    ``values`` (N, m) delivered a new value (any channel changed); the first is new."""
    values = np.asarray(values, float).reshape(len(time), -1)
    new = np.ones(len(time), bool)
    new[1:] = np.any(is_new_sample(values[1:], values[:-1]), axis=1)
    return np.flatnonzero(new)


@dataclasses.dataclass(frozen=True)
class ParameterFit:
    """Estimates of named parameters with their covariance and degrees of freedom."""

    names: tuple[str, ...]
    estimate: np.ndarray
    covariance: np.ndarray
    dof: int
    """Degrees of freedom of the t statistics (time blocks - 1)."""
    residual_rms: float
    """Root mean square of the (weighted) residuals."""

    def value(self, name: str) -> float:
        """Estimate of parameter ``name``."""
        return float(self.estimate[self.names.index(name)])

    def sigma(self, name: str) -> float:
        """Standard error of parameter ``name``."""
        i = self.names.index(name)
        return float(np.sqrt(max(self.covariance[i, i], 0.0)))


def block_edges(row_time: np.ndarray, block_length: float) -> np.ndarray:
    """First row of each contiguous time block, as many whole blocks of at least
    ``block_length`` [s] as the rows span (at least two): a short record gives few blocks
    and few degrees of freedom rather than blocks too short for the residual's
    correlation."""
    span = float(row_time[-1] - row_time[0]) if len(row_time) else 0.0
    count = int(min(max(span // block_length, MIN_BLOCKS), max(len(row_time) // 2, 1)))
    bounds = row_time[0] + span * np.arange(count) / count
    return np.unique(np.searchsorted(row_time, bounds))


def block_sandwich(scores: np.ndarray, bread: np.ndarray, row_time: np.ndarray,
                   block_length: float) -> tuple[np.ndarray, int]:
    """``bread^-1 Omega bread^-T`` with ``Omega`` from the time-block sums of ``scores``
    (n, p), rows at ``row_time`` (n) [s]. Returns the covariance and ``B - 1`` degrees
    of freedom; the factor ``B / (B - 1)`` corrects the ``B`` centred block sums for
    their fitted mean."""
    order = np.argsort(row_time, kind="stable")
    edges = block_edges(row_time[order], block_length)
    sums = np.add.reduceat(scores[order], edges, axis=0)
    blocks = len(edges)
    centred = sums - sums.mean(axis=0)
    omega = centred.T @ centred * blocks / max(blocks - 1, 1)
    inverse = np.linalg.pinv(bread)
    return inverse @ omega @ inverse.T, max(blocks - 1, 1)


def block_covariance(jacobian: np.ndarray, residual: np.ndarray, row_time: np.ndarray,
                     block_length: float) -> tuple[np.ndarray, int]:
    """Sandwich covariance of least-squares parameters (:func:`block_sandwich`):
    ``jacobian`` (n, p) of the residuals with respect to the parameters, ``residual`` (n)
    at the solution, ``row_time`` (n) [s]."""
    return block_sandwich(jacobian * residual[:, None], jacobian.T @ jacobian, row_time,
                          block_length)


def correlation_time(series: np.ndarray) -> float:
    """Integrated autocorrelation time ``1 + 2 sum_k rho_k`` [samples] of a series, the sum
    over Geyer's initial positive sequence (pairs of lags summed while positive; Geyer
    1992): the factor by which correlation inflates the variance of its mean."""
    x = np.asarray(series, float) - np.mean(series)
    n = len(x)
    energy = float(x @ x)
    if n < 4 or not energy > 0.0:
        return 1.0
    size = sp_fft.next_fast_len(2 * n, real=True)
    spectrum = sp_fft.rfft(x, size)
    rho = sp_fft.irfft(spectrum.real**2 + spectrum.imag**2, size)[:n] / energy
    pairs = rho[0 : 2 * (n // 2) : 2] + rho[1 : 2 * (n // 2) : 2]
    positive = np.flatnonzero(pairs <= 0.0)
    count = int(positive[0]) if len(positive) else len(pairs)
    return max(-1.0 + 2.0 * float(pairs[:count].sum()), 1.0)


def correlated_covariance(jacobian: np.ndarray, residual: np.ndarray,
                          groups: np.ndarray) -> np.ndarray:
    """Covariance of least-squares parameters whose residuals are a stationary correlated
    series within each group of rows (rows of a group in time order, equally spaced):
    ``A^-1 (sum_g tau_g s_g^2 G_g^T G_g) A^-1`` with ``tau_g`` the group residual's
    :func:`correlation_time` and ``s_g^2`` its variance (the regressors vary slowly
    against the correlation; the effective-sample-size form of the sandwich)."""
    omega = np.zeros((jacobian.shape[1], jacobian.shape[1]))
    for g in np.unique(groups):
        rows = groups == g
        G, r = jacobian[rows], residual[rows]
        omega += correlation_time(r) * float(np.mean(r * r)) * (G.T @ G)
    inverse = np.linalg.pinv(jacobian.T @ jacobian)
    return inverse @ omega @ inverse


def larger_errors(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The covariance ``first`` with each standard error raised to the larger of the two
    covariances' (correlations of ``first`` kept)."""
    a, b = np.sqrt(np.maximum(np.diag(first), 0.0)), np.sqrt(np.maximum(np.diag(second), 0.0))
    scale = np.where(a > 0, np.maximum(a, b) / np.where(a > 0, a, 1.0), 1.0)
    return first * np.outer(scale, scale)


def linear_fit(X: np.ndarray, y: np.ndarray, names: Sequence[str], row_time: np.ndarray,
               block_length: float) -> ParameterFit:
    """Ordinary least squares ``y = X theta`` with the block covariance."""
    theta = solve(X, y)
    r = y - X @ theta
    cov, dof = block_covariance(X, r, row_time, block_length)
    return ParameterFit(tuple(names), theta, cov, dof, float(np.sqrt(np.mean(r * r))))


def solve(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares ``theta`` of ``y = X theta`` from the normal equations of the
    column-scaled ``X`` (a few well-scaled columns and many rows: faster than an SVD);
    a singular system falls back to the minimum-norm SVD solution."""
    scale = np.sqrt(np.einsum("ij,ij->j", X, X))
    scale[scale == 0.0] = 1.0
    Xs = X / scale
    try:
        theta = np.linalg.solve(Xs.T @ Xs, Xs.T @ y)
    except np.linalg.LinAlgError:
        theta = np.linalg.lstsq(Xs, y, rcond=None)[0]
    return theta / scale


class _Residuals:
    """Least-squares residual sums; the factorisation is kept while the design returns
    the same regressor matrix (a skew that moves only the observations)."""

    def __init__(self):
        self._X, self._pinv = None, None

    def __call__(self, X: np.ndarray, y: np.ndarray) -> float:
        if X is self._X:
            if self._pinv is None:
                self._pinv = np.linalg.pinv(X)
            theta = self._pinv @ y
        else:
            self._X, self._pinv = X, None
            theta = solve(X, y)
        r = y - X @ theta
        return float(r @ r)


def _parabola_minimum(grid: np.ndarray, rss: np.ndarray) -> float:
    """Skew at the minimum of the parabola through the best grid point and its neighbours."""
    i = int(np.clip(np.argmin(rss), 1, len(grid) - 2))
    r0, r1, r2 = rss[i - 1], rss[i], rss[i + 1]
    curvature = r0 - 2.0 * r1 + r2
    step = grid[i + 1] - grid[i]
    offset = 0.5 * (r0 - r2) / curvature if curvature > 0 else 0.0
    return float(grid[i] + step * np.clip(offset, -1.0, 1.0))


Design = Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""``design(tau) -> (X (n, p), y (n), row_time (n))`` of a relation at skew ``tau`` [s]."""


def grid_minimum(design: Design, grid: np.ndarray) -> float:
    """The point of ``grid`` [s] with the smallest residual sum of ``design`` (a coarse
    search for a design whose regressors do not move with the skew: one factorisation)."""
    residual_sum = _Residuals()
    return float(grid[int(np.argmin([residual_sum(*design(tau)[:2]) for tau in grid]))])


def shift_fit(design: Design, names: Sequence[str], guess: float, step: float, reach: int,
              block_length: float) -> ParameterFit:
    """Linear parameters ``names`` and the skew (last, named ``"skew"``) [s] of ``design``.

    The residual sum is evaluated on the grid ``guess + step * k``, ``|k| <= reach``
    (centred again on its best point while that is at an edge, up to
    :data:`MAX_RECENTRES` times); the skew is the minimum of the parabola through the
    best point and its neighbours. The
    covariance is :func:`block_covariance` of the problem linearised there.
    """
    residual_sum = _Residuals()
    for _ in range(MAX_RECENTRES + 1):  # a minimum at the grid's edge moves the grid
        grid = guess + step * np.arange(-reach, reach + 1)
        rss = np.array([residual_sum(*design(tau)[:2]) for tau in grid])
        best = int(np.argmin(rss))
        if 0 < best < len(grid) - 1:
            break
        guess = grid[best]
    tau = _parabola_minimum(grid, rss)
    X, y, row_time = design(tau)
    theta = solve(X, y)
    r = y - X @ theta
    h = 0.25 * step
    (Xp, yp, _), (Xm, ym, _) = design(tau + h), design(tau - h)
    dr = ((yp - Xp @ theta) - (ym - Xm @ theta)) / (2.0 * h)
    cov, dof = block_covariance(np.column_stack([-X, dr]), r, row_time, block_length)
    return ParameterFit((*names, "skew"), np.append(theta, tau), cov, dof,
                        float(np.sqrt(np.mean(r * r))))


def coarse_lag(reference: np.ndarray, delayed: np.ndarray, rate_hz: float,
               max_lag: float) -> float:
    """Lag [s] (within ``+-max_lag``) by which ``delayed`` (N, m) follows ``reference``
    (N, m), sampled uniformly at ``rate_hz``: the peak of the summed squared normalised
    cross-correlations of the matched columns (a response of either sign counts)."""
    a = np.asarray(reference, float).reshape(len(reference), -1)
    b = np.asarray(delayed, float).reshape(len(delayed), -1)
    a = (a - a.mean(axis=0)) / np.maximum(a.std(axis=0), 1e-300)
    b = (b - b.mean(axis=0)) / np.maximum(b.std(axis=0), 1e-300)
    n = len(a)
    lags = int(min(max_lag * rate_hz, n // 2))
    size = sp_fft.next_fast_len(n + lags, real=True)
    spectrum = np.conj(sp_fft.rfft(a, size, axis=0)) * sp_fft.rfft(b, size, axis=0)
    corr = sp_fft.irfft(spectrum, size, axis=0) / n
    score = np.sum(np.concatenate([corr[-lags:], corr[: lags + 1]]) ** 2, axis=1) if lags \
        else np.sum(corr[:1] ** 2, axis=1)
    return float((int(np.argmax(score)) - lags) / rate_hz)


def t_p_value(z: float, dof: int) -> float:
    """Two-sided p-value of a t statistic ``z`` with ``dof`` degrees of freedom."""
    return float(2.0 * stats.t.sf(abs(z), dof)) if np.isfinite(z) else 1.0
