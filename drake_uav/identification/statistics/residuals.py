"""Diagnostics of an equation-error residual sampled at a known rate (Vaiopoulos 2017, sec. 4.2.2).

A model that captures every effect in the data leaves a residual that is white, Gaussian,
stationary and uncorrelated with any signal the model could still use. :func:`diagnose` checks
each property with a stated test and decision rule at level ``alpha`` (default 0.05):

* **Whiteness.** Sample autocorrelation ``r_k`` (biased estimator, FFT) for lags
  ``1..max_lag`` with the large-sample bound ``+-z_{1-alpha/2}/sqrt(N)`` (1.96/sqrt(N) at 5 %),
  and the Ljung-Box portmanteau ``Q = N(N+2) sum r_k^2/(N-k)`` ~ chi2(max_lag).
  Rule: ``is_white`` iff the Ljung-Box p-value >= alpha.
* **Effective sample size.** ``N_eff = N / tau`` with the integrated autocorrelation time
  ``tau = -1 + 2 sum_m G_m``, ``G_m = r_{2m} + r_{2m+1}``, summed over Geyer's initial
  monotone sequence (pairs up to the first non-positive one, made non-increasing). ``tau`` is
  floored at 1, so ``N_eff <= N``. It is what F- and t-tests on correlated residuals should use.
* **Long-run covariance.** :func:`long_run_covariance` gives ``Var(sum_t psi_t)`` of a
  correlated (N, m) series by Newey-West (Bartlett weights up to 4 times the longest
  :func:`correlation_lag` of its columns): the middle of the sandwich covariance of a
  regression whose residual is correlated (smoothed flight data, turbulence).
* **Normality.** Normal probability plot (Vaiopoulos 2017, eq. 4.16-4.17): ordered residuals against
  ``Phi^-1((i - 1/2)/N)``, with the plot's correlation coefficient; D'Agostino-Pearson K^2
  and Jarque-Bera p-values whose skewness and kurtosis parts are divided by the variance
  inflation of a correlated series, ``1 + 2 sum r_k^3`` and ``1 + 2 sum r_k^4`` (both 1 for a
  white residual). Rule: ``is_normal`` iff the K^2 p-value >= alpha.
* **Spectral peaks.** Welch PSD (Hann window, 50 % overlap). Under a smooth background each
  bin is ``P chi2(nu)/nu`` with ``nu`` the equivalent degrees of freedom of the overlapped
  average. The background is a running median over neighbouring bins (a median leaves a
  monotone spectrum unchanged, so coloured noise does not create peaks). A bin is significant
  when ``PSD/background`` exceeds the chi2 quantile at ``alpha / n_bins`` (Bonferroni over the
  tested bins, DC and Nyquist excluded); each run of significant bins gives one peak, its maximum.
* **Drift / non-stationarity.** Least-squares slope of the residual against time, with its
  standard error inflated by ``sqrt(N / N_eff)`` (``N_eff`` of the detrended residual) and a
  Student-t test on ``N_eff - 2`` degrees of freedom. Segment variance: the detrended residual
  is cut into :data:`N_SEGMENTS` equal segments and ``ln s_j^2`` compared with a chi2(K-1) test
  whose per-segment variance ``[(kappa - 3) + 2(1 + 2 sum r_k^2)]/m`` accounts for the
  kurtosis ``kappa`` and the autocorrelation. Rule: ``is_stationary`` iff neither is significant.
* **Candidate regressors.** Pearson ``r`` between the residual and each candidate column with a
  t-test on ``N_eff,xy - 2`` degrees of freedom, ``N_eff,xy = N / (1 + 2 sum_k r_x(k) r_c(k))``
  (Bartlett's formula for two autocorrelated series, summed up to the residual's Geyer lag,
  clipped to [3, N]). Candidates are ranked by ``|r|``; ``significant`` uses Holm's step-down
  correction over all candidates at level alpha.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import fft as sp_fft
from scipy import ndimage, signal, stats

__all__ = [
    "CandidateCorrelation",
    "MIN_SAMPLES",
    "N_SEGMENTS",
    "ResidualDiagnosis",
    "SpectralPeak",
    "autocorrelation",
    "correlation_lag",
    "diagnose",
    "effective_sample_size",
    "long_run_covariance",
]

#: Shortest residual :func:`diagnose` accepts [samples].
MIN_SAMPLES = 64

#: Autocorrelations up to this lag are computed by direct dot products instead of an FFT.
DIRECT_LAGS = 32

#: Bandwidth of :func:`long_run_covariance` in units of the scores' correlation lag.
LONG_RUN_BANDWIDTH = 4

#: Number of equal segments of the segment-variance test.
N_SEGMENTS = 8

#: Longest Welch segment [samples]; the frequency resolution is ``sample_rate / nperseg``.
MAX_WELCH_SEGMENT = 4096

#: Shortest running-median window [bins] for a PSD bin to be tested for a peak.
MIN_WINDOW = 5

#: At most this many spectral peaks are reported (largest ratio first).
MAX_PEAKS = 10


@dataclass(frozen=True)
class SpectralPeak:
    """A narrow-band component of the residual.

    Attributes
    ----------
    frequency : float
        Centre of the peak bin [Hz].
    ratio : float
        PSD divided by the local median background (dimensionless).
    psd : float
        Power spectral density at the peak [residual unit^2/Hz].
    p_value : float
        Probability of a ratio this large in any tested bin of a smooth spectrum
        (Bonferroni-adjusted, capped at 1).
    """

    frequency: float
    ratio: float
    psd: float
    p_value: float


@dataclass(frozen=True)
class CandidateCorrelation:
    """Correlation of the residual with one candidate regressor column.

    Attributes
    ----------
    name : str
        Candidate name.
    r : float
        Pearson correlation coefficient in [-1, 1] (0 for a constant candidate).
    p_value : float
        Two-sided p-value of ``r = 0`` with ``n_eff - 2`` degrees of freedom.
    p_adjusted : float
        Holm-adjusted p-value over all candidates of the diagnosis.
    n_eff : float
        Effective sample size of the pair (Bartlett), in [3, N].
    significant : bool
        ``p_adjusted < alpha``.
    """

    name: str
    r: float
    p_value: float
    p_adjusted: float
    n_eff: float
    significant: bool


@dataclass(frozen=True, eq=False)
class ResidualDiagnosis:
    """Result of :func:`diagnose`: whiteness, normality, spectrum and stationarity of a residual.

    Residual units are written ``[u]``.

    Attributes
    ----------
    n : int
        Number of samples N.
    sample_rate : float
        [Hz].
    alpha : float
        Test level.
    mean, std, rms : float
        Of the residual [u] (std with ddof 0).
    acf_lags : numpy.ndarray of int
        Lags 1..max_lag [samples].
    acf : numpy.ndarray
        Autocorrelation at those lags.
    acf_bound : float
        Large-sample confidence bound ``z_{1-alpha/2}/sqrt(N)``.
    acf_fraction_outside : float
        Fraction of ``acf_lags`` with ``|r_k| > acf_bound``.
    ljung_box_statistic, ljung_box_dof, ljung_box_pvalue : float, int, float
        Portmanteau test.
    is_white : bool
        ``ljung_box_pvalue >= alpha``.
    n_eff : float
        Effective sample size N / tau (Geyer initial monotone sequence), in [1, N].
    integrated_time : float
        tau [samples], >= 1.
    n_eff_lag : int
        Number of autocorrelation lags summed by the Geyer estimator.
    normal_quantiles : numpy.ndarray
        ``Phi^-1((i - 1/2)/N)``, i = 1..N (x axis of the probability plot).
    ordered_residuals : numpy.ndarray
        Sorted residual [u] (y axis of the probability plot).
    probability_plot_r : float
        Correlation coefficient of the probability plot.
    skewness, excess_kurtosis : float
        Sample moments (0 and 0 for a Gaussian).
    jarque_bera_pvalue, normality_pvalue : float
        Jarque-Bera and D'Agostino-Pearson K^2, both corrected for autocorrelation (module
        docstring).
    is_normal : bool
        ``normality_pvalue >= alpha``.
    psd_frequencies, psd, psd_background : numpy.ndarray
        Welch estimate [Hz], [u^2/Hz] and its running-median background [u^2/Hz] (nan at
        DC and Nyquist, not tested).
    psd_dof : float
        Equivalent chi2 degrees of freedom of a Welch bin.
    peak_ratio_threshold : float
        PSD/background ratio above which a bin is significant.
    spectral_peaks : tuple of SpectralPeak
        Significant peaks, largest ratio first.
    drift_slope, drift_slope_sigma : float
        Linear trend [u/s] and its N_eff-corrected sigma.
    drift_pvalue : float
        Two-sided p-value of zero slope.
    drift_significant : bool
        ``drift_pvalue < alpha``.
    segment_std : numpy.ndarray
        Std of each of the N_SEGMENTS detrended segments [u].
    variance_statistic, variance_pvalue : float
        chi2(N_SEGMENTS - 1) segment-variance test.
    variance_change_significant : bool
        ``variance_pvalue < alpha``.
    is_stationary : bool
        Neither drift nor variance change is significant.
    candidates : tuple of CandidateCorrelation
        Candidate correlations ranked by ``|r|`` (empty without candidates).

    Examples
    --------
    >>> import numpy as np
    >>> diagnosis = diagnose(np.random.default_rng(0).normal(size=2000), 50.0)
    >>> diagnosis.n, diagnosis.sample_rate
    (2000, 50.0)
    """

    n: int
    sample_rate: float
    alpha: float
    mean: float
    std: float
    rms: float
    acf_lags: np.ndarray
    acf: np.ndarray
    acf_bound: float
    acf_fraction_outside: float
    ljung_box_statistic: float
    ljung_box_dof: int
    ljung_box_pvalue: float
    is_white: bool
    n_eff: float
    integrated_time: float
    n_eff_lag: int
    normal_quantiles: np.ndarray
    ordered_residuals: np.ndarray
    probability_plot_r: float
    skewness: float
    excess_kurtosis: float
    jarque_bera_pvalue: float
    normality_pvalue: float
    is_normal: bool
    psd_frequencies: np.ndarray
    psd: np.ndarray
    psd_background: np.ndarray
    psd_dof: float
    peak_ratio_threshold: float
    spectral_peaks: tuple[SpectralPeak, ...]
    drift_slope: float
    drift_slope_sigma: float
    drift_pvalue: float
    drift_significant: bool
    segment_std: np.ndarray
    variance_statistic: float
    variance_pvalue: float
    variance_change_significant: bool
    is_stationary: bool
    candidates: tuple[CandidateCorrelation, ...]

    @property
    def acf_lag_times(self) -> np.ndarray:
        """Autocorrelation lags [s]."""
        return self.acf_lags / self.sample_rate

    @property
    def significant_candidates(self) -> tuple[CandidateCorrelation, ...]:
        """Candidates whose correlation is significant after the Holm correction, ranked."""
        return tuple(c for c in self.candidates if c.significant)

    def summary(self, max_candidates: int = 5) -> str:
        """A few lines of plain text: one per test, then the top candidates.

        Parameters
        ----------
        max_candidates : int
            Number of candidate correlations listed.

        Returns
        -------
        str
            The text, lines separated by newlines.
        """

        def verdict(ok: bool, yes: str, no: str) -> str:
            return yes if ok else no.upper()

        lines = [
            f"residual: N = {self.n} at {self.sample_rate:g} Hz, mean {self.mean:.4g}, "
            f"std {self.std:.4g}, rms {self.rms:.4g}",
            f"whiteness: {verdict(self.is_white, 'white', 'not white')} - Ljung-Box "
            f"Q = {self.ljung_box_statistic:.4g} ({self.ljung_box_dof} lags), "
            f"p = {self.ljung_box_pvalue:.3g}; {100 * self.acf_fraction_outside:.0f} % of lags "
            f"outside +-{self.acf_bound:.3g}; N_eff = {self.n_eff:.0f} "
            f"(tau = {self.integrated_time:.3g} samples)",
            f"normality: {verdict(self.is_normal, 'normal', 'not normal')} - probability-plot "
            f"r = {self.probability_plot_r:.5f}, D'Agostino p = {self.normality_pvalue:.3g}, "
            f"Jarque-Bera p = {self.jarque_bera_pvalue:.3g} (skewness {self.skewness:.3g}, "
            f"excess kurtosis {self.excess_kurtosis:.3g})",
        ]
        if self.spectral_peaks:
            peaks = ", ".join(
                f"{p.frequency:.4g} Hz (x{p.ratio:.3g})" for p in self.spectral_peaks[:5]
            )
            lines.append(f"spectrum: PEAKS at {peaks}")
        else:
            lines.append(
                f"spectrum: no significant peak (threshold x{self.peak_ratio_threshold:.3g})"
            )
        lines.append(
            f"stationarity: {verdict(self.is_stationary, 'stationary', 'not stationary')} - "
            f"drift {self.drift_slope:.3g} +- {self.drift_slope_sigma:.2g} /s "
            f"(p = {self.drift_pvalue:.3g}), segment variance p = {self.variance_pvalue:.3g}"
        )
        for c in self.candidates[:max_candidates]:
            lines.append(
                f"candidate {c.name}: r = {c.r:+.3f}, p = {c.p_value:.3g} "
                f"(Holm {c.p_adjusted:.3g}, N_eff {c.n_eff:.0f})"
                + (" SIGNIFICANT" if c.significant else "")
            )
        return "\n".join(lines)

    def to_dict(self, include_series: bool = False) -> dict:
        """JSON-ready dictionary of the scalar results, the ACF, peaks and candidates.

        Parameters
        ----------
        include_series : bool
            Add the probability-plot and PSD arrays (N and ~nperseg/2 values).

        Returns
        -------
        dict
            Keys ``n``, ``sample_rate_hz``, ``alpha``, ``mean``, ``std``, ``rms``, then one
            dictionary per test (``whiteness``, ``normality``, ``spectrum``, ``stationarity``)
            and the list of ``candidates``.
        """
        return {
            "n": self.n,
            "sample_rate_hz": self.sample_rate,
            "alpha": self.alpha,
            "mean": self.mean,
            "std": self.std,
            "rms": self.rms,
            "whiteness": self._whiteness_dict(),
            "normality": self._normality_dict(include_series),
            "spectrum": self._spectrum_dict(include_series),
            "stationarity": self._stationarity_dict(),
            "candidates": [
                {"name": c.name, "r": c.r, "p_value": c.p_value, "p_adjusted": c.p_adjusted,
                 "n_eff": c.n_eff, "significant": c.significant}
                for c in self.candidates
            ],
        }

    def _whiteness_dict(self) -> dict:
        return {
            "is_white": self.is_white,
            "acf_lags": self.acf_lags.tolist(),
            "acf": self.acf.tolist(),
            "acf_bound": self.acf_bound,
            "acf_fraction_outside": self.acf_fraction_outside,
            "ljung_box_statistic": self.ljung_box_statistic,
            "ljung_box_dof": self.ljung_box_dof,
            "ljung_box_pvalue": self.ljung_box_pvalue,
            "n_eff": self.n_eff,
            "integrated_time_samples": self.integrated_time,
            "n_eff_lag": self.n_eff_lag,
        }

    def _normality_dict(self, include_series: bool) -> dict:
        out = {
            "is_normal": self.is_normal,
            "probability_plot_r": self.probability_plot_r,
            "skewness": self.skewness,
            "excess_kurtosis": self.excess_kurtosis,
            "jarque_bera_pvalue": self.jarque_bera_pvalue,
            "dagostino_pvalue": self.normality_pvalue,
        }
        if include_series:
            out["normal_quantiles"] = self.normal_quantiles.tolist()
            out["ordered_residuals"] = self.ordered_residuals.tolist()
        return out

    def _spectrum_dict(self, include_series: bool) -> dict:
        out = {
            "psd_dof": self.psd_dof,
            "peak_ratio_threshold": self.peak_ratio_threshold,
            "peaks": [
                {"frequency_hz": p.frequency, "ratio": p.ratio, "psd": p.psd,
                 "p_value": p.p_value}
                for p in self.spectral_peaks
            ],
        }
        if include_series:
            out["frequencies_hz"] = self.psd_frequencies.tolist()
            out["psd"] = self.psd.tolist()
            out["background"] = self.psd_background.tolist()
        return out

    def _stationarity_dict(self) -> dict:
        return {
            "is_stationary": self.is_stationary,
            "drift_slope_per_s": self.drift_slope,
            "drift_slope_sigma": self.drift_slope_sigma,
            "drift_pvalue": self.drift_pvalue,
            "drift_significant": self.drift_significant,
            "segment_std": self.segment_std.tolist(),
            "variance_statistic": self.variance_statistic,
            "variance_pvalue": self.variance_pvalue,
            "variance_change_significant": self.variance_change_significant,
        }


# ----------------------------------------------------------------------------- helpers


def autocorrelation(x: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Biased sample autocorrelation of ``x`` at lags 0..max_lag, r_0 = 1.

    ``r_k = sum_t (x_t - m)(x_{t+k} - m) / sum_t (x_t - m)^2``, by FFT of length >= N + max_lag
    (direct dot products for a few lags).

    Parameters
    ----------
    x : numpy.ndarray of shape (N,)
        The series.
    max_lag : int, optional
        Largest lag [samples]; default N - 1.

    Returns
    -------
    numpy.ndarray of shape (max_lag + 1,)
        r_0..r_max_lag.

    Raises
    ------
    ValueError
        When ``x`` is constant.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    max_lag = n - 1 if max_lag is None else int(min(max_lag, n - 1))
    xc = x - x.mean()
    energy = float(xc @ xc)
    if not energy > 0.0:
        raise ValueError("series is constant (zero variance): autocorrelation undefined")
    if max_lag <= DIRECT_LAGS:
        return np.array([1.0] + [float(xc[:-k] @ xc[k:]) / energy for k in range(1, max_lag + 1)])
    nfft = sp_fft.next_fast_len(n + max_lag, real=True)
    spec = sp_fft.rfft(xc, nfft)
    return sp_fft.irfft(spec.real**2 + spec.imag**2, nfft)[: max_lag + 1] / energy


def _geyer_tau(rho: np.ndarray) -> tuple[float, int]:
    """Integrated autocorrelation time (>= 1) and number of lags used (initial monotone seq.)."""
    m = rho.size // 2
    pairs = rho[0 : 2 * m : 2] + rho[1 : 2 * m : 2]
    nonpositive = pairs <= 0.0
    k = int(np.argmax(nonpositive)) if nonpositive.any() else m
    tau = -1.0 + 2.0 * float(np.minimum.accumulate(pairs[:k]).sum()) if k > 0 else 1.0
    return max(tau, 1.0), 2 * k


def effective_sample_size(x: np.ndarray) -> float:
    """``N / tau`` with Geyer's initial monotone sequence estimator of ``tau``; in [1, N].

    Parameters
    ----------
    x : ndarray
        (N,) a residual or any stationary series.

    Returns
    -------
    float
        The number of independent samples the series is worth.

    Examples
    --------
    >>> import numpy as np
    >>> white = np.random.default_rng(0).normal(size=1000)
    >>> 800 < effective_sample_size(white) <= 1000
    True
    """
    x = np.asarray(x, dtype=float)
    tau, _ = _geyer_tau(autocorrelation(x))
    return x.size / tau


def correlation_lag(x: np.ndarray) -> int:
    """Lags over which ``x`` is correlated: the length of Geyer's initial monotone sequence.

    Parameters
    ----------
    x : numpy.ndarray of shape (N,)
        The series (not constant).

    Returns
    -------
    int
        The number of lags [samples].
    """
    return _geyer_tau(autocorrelation(np.asarray(x, dtype=float)))[1]


def long_run_covariance(scores: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Covariance of the sum of a correlated (N, m) series, ``Var(sum_t psi_t)`` (m, m).

    Newey-West estimate: ``G_0 + sum_l w_l (G_l + G_l^T)`` with ``G_l = sum_t psi_t
    psi_(t+l)^T`` of the centred series and Bartlett weights ``w_l = 1 - l / (L + 1)``
    (positive semi-definite). For white scores it is ``G_0``; with correlated ones it is
    what the sandwich covariance of a regression needs (the white formula understates it
    by about the integrated autocorrelation time). ``L`` defaults to
    :data:`LONG_RUN_BANDWIDTH` times the longest :func:`correlation_lag` of the columns;
    the weights then keep at least 3/4 of every correlation inside that lag.

    Parameters
    ----------
    scores : ndarray
        (N, m) the series.
    max_lag : int, optional
        The bandwidth ``L`` (None: from the data, as above).

    Returns
    -------
    ndarray
        (m, m) the covariance of the sum.

    Raises
    ------
    ValueError
        When ``scores`` is not a finite (N, m) array with N >= 2, or ``max_lag`` is not a
        non-negative integer.

    Examples
    --------
    >>> import numpy as np
    >>> scores = np.random.default_rng(0).normal(size=(5000, 1))
    >>> 4000 < float(long_run_covariance(scores)[0, 0]) < 6000   # ~ N for white scores
    True
    """
    psi = np.asarray(scores, dtype=float)
    if psi.ndim == 1:
        psi = psi[:, None]
    if psi.ndim != 2 or psi.shape[0] < 2 or not np.isfinite(psi).all():
        raise ValueError(f"scores must be a finite (N, m) array with N >= 2, got {psi.shape}")
    psi = psi - psi.mean(axis=0)
    n = psi.shape[0]
    if max_lag is None:
        max_lag = LONG_RUN_BANDWIDTH * max(
            (correlation_lag(c) for c in psi.T if np.any(c != 0.0)), default=0)
    elif not (isinstance(max_lag, int | np.integer) and max_lag >= 0):
        raise ValueError(f"max_lag must be a non-negative integer, got {max_lag!r}")
    S = psi.T @ psi
    for lag in range(1, min(int(max_lag), n - 1) + 1):
        G = psi[:-lag].T @ psi[lag:]
        S += (1.0 - lag / (max_lag + 1.0)) * (G + G.T)
    return S


def _holm(p: np.ndarray) -> np.ndarray:
    """Holm step-down adjusted p-values (same order as ``p``)."""
    m = p.size
    order = np.argsort(p, kind="stable")
    adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def _check_inputs(residual, sample_rate, candidates, alpha):
    x = np.asarray(residual, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"residual must be a 1-D array, got shape {x.shape}")
    if x.size < MIN_SAMPLES:
        raise ValueError(f"residual is too short: {x.size} samples, need >= {MIN_SAMPLES}")
    bad = ~np.isfinite(x)
    if bad.any():
        raise ValueError(
            f"residual contains NaN or inf ({int(bad.sum())} samples, first at index "
            f"{int(np.argmax(bad))})"
        )
    if not np.ptp(x) > 0.0:
        raise ValueError("residual is constant (zero variance): nothing to diagnose")
    if not (np.isfinite(sample_rate) and sample_rate > 0.0):
        raise ValueError(f"sample_rate must be positive and finite, got {sample_rate}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    cols = {}
    for name, col in (candidates or {}).items():
        c = np.asarray(col, dtype=float)
        if c.shape != x.shape:
            raise ValueError(
                f"candidate {name!r} has shape {c.shape}, residual has shape {x.shape}"
            )
        if not np.isfinite(c).all():
            raise ValueError(f"candidate {name!r} contains NaN or inf")
        cols[str(name)] = c
    return x, float(sample_rate), cols


def _normality_pvalues(x: np.ndarray, rho: np.ndarray) -> tuple[float, float]:
    """D'Agostino-Pearson K^2 and Jarque-Bera p-values corrected for autocorrelation.

    ``rho`` holds the autocorrelation at lags 1..L. For a Gaussian series the sample skewness
    and kurtosis have variances inflated by ``c3 = 1 + 2 sum rho_k^3`` and
    ``c4 = 1 + 2 sum rho_k^4`` (Lomnicki 1961): both squared standardised parts are divided
    by them, so a white residual gives the classical tests.
    """
    n = x.size
    c3 = max(1.0 + 2.0 * float(np.sum(rho**3)), 1.0)
    c4 = max(1.0 + 2.0 * float(np.sum(rho**4)), 1.0)
    k2 = stats.skewtest(x).statistic ** 2 / c3 + stats.kurtosistest(x).statistic ** 2 / c4
    skew = stats.skew(x)
    excess = stats.kurtosis(x)
    jb = n * skew**2 / (6.0 * c3) + n * excess**2 / (24.0 * c4)
    return float(stats.chi2.sf(k2, 2)), float(stats.chi2.sf(jb, 2))


def _default_max_lag(n: int) -> int:
    return int(min(n // 5, max(20, np.ceil(10.0 * np.log10(n)))))


def _welch_dof(window: np.ndarray, step: int, segments: int) -> float:
    """Equivalent chi2 dof of a Welch average of ``segments`` windows ``step`` apart."""
    nper = window.size
    energy = float(window @ window)
    j = np.arange(1, segments)
    j = j[j * step < nper]
    rho = np.array([(window[: nper - s] @ window[s:]) ** 2 for s in j * step]) / energy**2
    return 2.0 * segments / (1.0 + 2.0 * float(np.sum((1.0 - j / segments) * rho)))


def _spectrum(x: np.ndarray, fs: float, alpha: float):
    n = x.size
    nper = int(min(MAX_WELCH_SEGMENT, 2 ** int(np.floor(np.log2(n / 8)))))
    step = nper // 2
    window = signal.get_window("hann", nper)
    f, p = signal.welch(x, fs, window=window, noverlap=nper - step, detrend="constant")
    nu = _welch_dof(window, step, 1 + (n - nper) // step)
    # Candidate bins: all but DC and Nyquist (those are chi2 with half the dof). The background
    # of bin j is the median of the 2h+1 bins centred on it, h = min(half, distance to the end of
    # the range): symmetric windows keep a monotone spectrum free of false peaks.
    pt = p[1:-1]
    idx = np.arange(pt.size)
    half = max(8, pt.size // 64)
    h = np.minimum(half, np.minimum(idx, idx[::-1]))
    med = ndimage.median_filter(pt, size=2 * half + 1, mode="nearest")
    for j in np.flatnonzero(h < half):  # at most 2 * half edge bins
        med[j] = np.median(pt[j - h[j] : j + h[j] + 1])
    # ln(PSD / background) has variance ~ (2/nu)(1 + pi/(2w)) for a w-bin median: the ratio is
    # compared with a chi2 of nu' = nu / (1 + pi/(2w)) dof normalised by its median, at level
    # alpha / (number of tested bins) (Bonferroni). Windows shorter than MIN_WINDOW: not tested.
    w = 2 * h + 1
    tested = w >= MIN_WINDOW
    n_tested = max(int(tested.sum()), 1)
    nu_eff = nu / (1.0 + np.pi / (2.0 * w))
    med_eff = stats.chi2.median(nu_eff)
    thresholds = stats.chi2.isf(alpha / n_tested, nu_eff) / med_eff
    ratio = pt / med
    above = tested & (ratio > thresholds)
    # One peak per run of significant bins: the bin with the largest ratio.
    edges = np.flatnonzero(np.diff(np.concatenate(([0], above.astype(np.int8), [0]))))
    peaks = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        j = start + int(np.argmax(ratio[start:stop]))
        pval = min(1.0, n_tested * float(stats.chi2.sf(ratio[j] * med_eff[j], nu_eff[j])))
        peaks.append(SpectralPeak(float(f[j + 1]), float(ratio[j]), float(pt[j]), pval))
    peaks.sort(key=lambda pk: -pk.ratio)
    background = np.concatenate(([np.nan], med, [np.nan]))
    full_window_threshold = float(thresholds[int(np.argmax(h))])
    return f, p, background, nu, full_window_threshold, tuple(peaks[:MAX_PEAKS])


def _drift(x: np.ndarray, fs: float):
    n = x.size
    tc = (np.arange(n) - 0.5 * (n - 1)) / fs
    sxx = float(tc @ tc)
    slope = float(tc @ x) / sxx
    detrended = x - x.mean() - slope * tc
    rho = autocorrelation(detrended)
    tau, lag = _geyer_tau(rho)
    n_eff = n / tau
    s2 = float(detrended @ detrended) / (n - 2)
    sigma = float(np.sqrt(s2 / sxx * tau))
    dof = max(n_eff - 2.0, 1.0)
    pvalue = float(2.0 * stats.t.sf(abs(slope) / sigma, dof))

    m = n // N_SEGMENTS
    seg = detrended[: m * N_SEGMENTS].reshape(N_SEGMENTS, m)
    seg_var = seg.var(axis=1, ddof=1)
    kurtosis = float(stats.kurtosis(detrended, fisher=False))
    v = ((kurtosis - 3.0) + 2.0 * (1.0 + 2.0 * float(rho[1:lag] @ rho[1:lag]))) / m
    log_var = np.log(seg_var)
    stat = float(np.sum((log_var - log_var.mean()) ** 2) / max(v, 1e-12))
    var_p = float(stats.chi2.sf(stat, N_SEGMENTS - 1))
    return slope, sigma, pvalue, np.sqrt(seg_var), stat, var_p


def _candidate_correlations(x, rho_x, lag, cols, alpha):
    n = x.size
    xc = (x - x.mean()) / np.linalg.norm(x - x.mean())
    names, r, n_eff = [], [], []
    for name, c in cols.items():
        cc = c - c.mean()
        norm = np.linalg.norm(cc)
        names.append(name)
        if not norm > 0.0:  # a constant column cannot explain a zero-mean residual
            r.append(0.0)
            n_eff.append(float(n))
            continue
        r.append(float(np.clip(xc @ cc / norm, -1.0, 1.0)))
        rho_c = autocorrelation(c, max_lag=lag - 1)
        factor = 1.0 + 2.0 * float(rho_x[1:lag] @ rho_c[1:lag])
        n_eff.append(float(np.clip(n / max(factor, 1e-12), 3.0, n)))
    if not names:
        return ()
    r_arr = np.array(r)
    ne = np.array(n_eff)
    t_stat = np.abs(r_arr) * np.sqrt((ne - 2.0) / np.maximum(1.0 - r_arr**2, 1e-300))
    pvals = 2.0 * stats.t.sf(t_stat, ne - 2.0)
    adjusted = _holm(pvals)
    ranked = np.argsort(-np.abs(r_arr), kind="stable")
    return tuple(
        CandidateCorrelation(names[i], float(r_arr[i]), float(pvals[i]), float(adjusted[i]),
                             float(ne[i]), bool(adjusted[i] < alpha))
        for i in ranked
    )


# ----------------------------------------------------------------------------- main


def diagnose(
    residual: np.ndarray,
    sample_rate: float,
    candidates: Mapping[str, np.ndarray] | None = None,
    max_lag: int | None = None,
    alpha: float = 0.05,
) -> ResidualDiagnosis:
    """Runs every residual test (module docstring) on a uniformly sampled residual.

    Parameters
    ----------
    residual : ndarray
        (N,) equation-error residual [u], N >= MIN_SAMPLES, finite, not constant.
    sample_rate : float
        Sampling rate [Hz], > 0.
    candidates : Mapping, optional
        Name -> (N,) candidate regressor column, same sampling as the residual.
    max_lag : int, optional
        Autocorrelation lags shown and used by Ljung-Box, 1 <= max_lag <= N/2; default
        ``min(N/5, max(20, ceil(10 log10 N)))``.
    alpha : float
        Level of every test (two-sided where it applies).

    Returns
    -------
    ResidualDiagnosis

    Raises
    ------
    ValueError
        Naming the problem (NaN, too short, constant, bad rate, bad candidate...).

    Examples
    --------
    >>> import numpy as np
    >>> white = np.random.default_rng(0).normal(size=2000)
    >>> diagnose(white, 50.0).is_white
    True
    """
    x, fs, cols = _check_inputs(residual, sample_rate, candidates, alpha)
    n = x.size
    if max_lag is None:
        max_lag = _default_max_lag(n)
    elif not (isinstance(max_lag, int | np.integer) and 1 <= max_lag <= n // 2):
        raise ValueError(f"max_lag must be an integer in [1, {n // 2}], got {max_lag!r}")
    rho = autocorrelation(x)
    tau, lag = _geyer_tau(rho)
    return ResidualDiagnosis(
        n=n, sample_rate=fs, alpha=float(alpha), mean=float(x.mean()), std=float(x.std()),
        rms=float(np.sqrt(np.mean(x**2))),
        **_whiteness(rho, n, int(max_lag), alpha),
        n_eff=n / tau, integrated_time=tau, n_eff_lag=lag,
        **_normality(x, rho[1:lag], alpha),
        **_spectrum_fields(x, fs, alpha),
        **_stationarity_fields(x, fs, alpha),
        candidates=_candidate_correlations(x, rho, lag, cols, alpha),
    )


def _whiteness(rho: np.ndarray, n: int, max_lag: int, alpha: float) -> dict:
    """Autocorrelation with its bound and the Ljung-Box test (module docstring)."""
    lags = np.arange(1, max_lag + 1)
    acf = rho[1 : max_lag + 1]
    bound = float(stats.norm.ppf(1.0 - alpha / 2.0)) / np.sqrt(n)
    q = float(n * (n + 2.0) * np.sum(acf**2 / (n - lags)))
    lb_p = float(stats.chi2.sf(q, max_lag))
    return dict(acf_lags=lags, acf=acf.copy(), acf_bound=float(bound),
                acf_fraction_outside=float(np.mean(np.abs(acf) > bound)),
                ljung_box_statistic=q, ljung_box_dof=max_lag, ljung_box_pvalue=lb_p,
                is_white=lb_p >= alpha)


def _normality(x: np.ndarray, rho: np.ndarray, alpha: float) -> dict:
    """Normal probability plot and the autocorrelation-corrected normality tests."""
    n = x.size
    ordered = np.sort(x)
    quantiles = stats.norm.ppf((np.arange(1, n + 1) - 0.5) / n)
    normal_p, jb_p = _normality_pvalues(x, rho)
    return dict(normal_quantiles=quantiles, ordered_residuals=ordered,
                probability_plot_r=float(np.corrcoef(quantiles, ordered)[0, 1]),
                skewness=float(stats.skew(x)), excess_kurtosis=float(stats.kurtosis(x)),
                jarque_bera_pvalue=jb_p, normality_pvalue=normal_p, is_normal=normal_p >= alpha)


def _spectrum_fields(x: np.ndarray, fs: float, alpha: float) -> dict:
    f, psd, background, nu, threshold, peaks = _spectrum(x, fs, alpha)
    return dict(psd_frequencies=f, psd=psd, psd_background=background, psd_dof=float(nu),
                peak_ratio_threshold=threshold, spectral_peaks=peaks)


def _stationarity_fields(x: np.ndarray, fs: float, alpha: float) -> dict:
    slope, slope_sigma, drift_p, seg_std, var_stat, var_p = _drift(x, fs)
    return dict(drift_slope=slope, drift_slope_sigma=slope_sigma, drift_pvalue=drift_p,
                drift_significant=drift_p < alpha, segment_std=seg_std,
                variance_statistic=var_stat, variance_pvalue=var_p,
                variance_change_significant=var_p < alpha,
                is_stationary=not (drift_p < alpha or var_p < alpha))
