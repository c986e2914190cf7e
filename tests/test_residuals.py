import json

import numpy as np
import pytest
from scipy import signal

from drake_uav.identification.statistics.residuals import (
    MIN_SAMPLES,
    autocorrelation,
    correlation_lag,
    diagnose,
    effective_sample_size,
    long_run_covariance,
)

FS = 100.0  # Hz


def _ar1(rng, n, phi):
    """Stationary AR(1) series with unit innovations (burn-in discarded)."""
    return signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n + 1000))[1000:]


def test_white_gaussian_noise_is_white_normal_stationary_with_full_n_eff():
    n = 20000
    x = np.random.default_rng(1).normal(0.2, 0.5, n)
    d = diagnose(x, FS)
    assert d.is_white and d.ljung_box_pvalue > 0.05
    assert d.acf_bound == pytest.approx(1.959964 / np.sqrt(n), rel=1e-6)
    assert d.acf_fraction_outside <= 0.15
    assert 0.9 * n <= d.n_eff <= n
    assert d.is_normal and d.probability_plot_r > 0.999
    assert d.spectral_peaks == ()
    assert d.is_stationary and not d.drift_significant
    assert d.mean == pytest.approx(0.2, abs=0.02) and d.std == pytest.approx(0.5, rel=0.02)
    assert d.rms == pytest.approx(np.sqrt(d.mean**2 + d.std**2), rel=1e-9)
    # Probability plot data (Vaiopoulos 2017, eq. 4.16-4.17): sorted residuals against Phi^-1((i -
    # 1/2)/N).
    assert d.normal_quantiles[0] == pytest.approx(-4.0556, abs=1e-3)  # Phi^-1(0.5/20000)
    assert np.all(np.diff(d.ordered_residuals) >= 0.0)
    np.testing.assert_allclose(d.normal_quantiles, -d.normal_quantiles[::-1], atol=1e-12)


def test_ar1_noise_is_not_white_and_n_eff_matches_theory():
    n, phi = 100000, 0.9
    x = _ar1(np.random.default_rng(2), n, phi)
    d = diagnose(x, FS)
    assert not d.is_white and d.ljung_box_pvalue < 1e-12
    assert d.acf[0] == pytest.approx(phi, abs=0.01)
    assert d.acf[4] == pytest.approx(phi**5, abs=0.02)
    assert d.acf_fraction_outside > 0.5
    expected = n * (1 - phi) / (1 + phi)
    assert d.n_eff == pytest.approx(expected, rel=0.2)
    assert d.integrated_time == pytest.approx((1 + phi) / (1 - phi), rel=0.2)
    assert effective_sample_size(x) == pytest.approx(d.n_eff)
    # Gaussian AR(1): normality holds once the tests account for the correlation.
    assert d.is_normal


def test_sinusoid_in_noise_gives_a_spectral_peak_at_its_frequency():
    n, f0 = 20000, 7.3
    rng = np.random.default_rng(3)
    t = np.arange(n) / FS
    x = rng.standard_normal(n) + 0.3 * np.sin(2 * np.pi * f0 * t + 0.4)
    d = diagnose(x, FS)
    assert d.spectral_peaks, d.summary()
    top = d.spectral_peaks[0]
    resolution = d.psd_frequencies[1] - d.psd_frequencies[0]
    assert abs(top.frequency - f0) <= resolution
    assert top.ratio > d.peak_ratio_threshold and top.p_value < 1e-6
    # Peaks are local: every reported one sits at the sinusoid (no spurious far-away peaks).
    assert all(abs(p.frequency - f0) <= 2 * resolution for p in d.spectral_peaks)


def test_steep_coloured_spectrum_gives_no_false_peak():
    # A monotone, steep spectrum (AR(1) phi=0.99) must not be mistaken for a peak.
    d = diagnose(_ar1(np.random.default_rng(4), 50000, 0.99), FS)
    assert d.spectral_peaks == ()


def test_ramp_gives_significant_drift_with_the_right_slope():
    n = 10000
    rng = np.random.default_rng(5)
    t = np.arange(n) / FS
    slope = 0.01  # residual units per second: 1 unit over the 100 s record
    d = diagnose(rng.standard_normal(n) + slope * t, FS)
    assert d.drift_significant and d.drift_pvalue < 1e-10 and not d.is_stationary
    assert abs(d.drift_slope - slope) < 4 * d.drift_slope_sigma
    # White noise: sigma of the slope is std / sqrt(sum (t - tbar)^2).
    assert d.drift_slope_sigma == pytest.approx(1.0 / np.sqrt(np.sum((t - t.mean()) ** 2)),
                                                rel=0.1)


def test_drift_sigma_accounts_for_autocorrelation():
    n, phi = 50000, 0.9
    x = _ar1(np.random.default_rng(6), n, phi)
    d = diagnose(x, FS)
    t = np.arange(n) / FS
    white_sigma = x.std() / np.sqrt(np.sum((t - t.mean()) ** 2))
    # Long-run variance of AR(1) is tau = (1 + phi)/(1 - phi) = 19 times the white one.
    assert d.drift_slope_sigma / white_sigma == pytest.approx(np.sqrt(19.0), rel=0.2)


def test_variance_change_is_detected():
    n = 16000
    rng = np.random.default_rng(7)
    scale = np.where(np.arange(n) < n // 2, 1.0, 1.5)
    d = diagnose(rng.standard_normal(n) * scale, FS)
    assert d.variance_change_significant and d.variance_pvalue < 1e-6 and not d.is_stationary
    assert d.segment_std[-1] / d.segment_std[0] == pytest.approx(1.5, rel=0.1)


def test_candidate_in_residual_is_ranked_first_and_others_not_significant():
    n = 20000
    rng = np.random.default_rng(8)
    cands = {
        "alpha_cubed": _ar1(rng, n, 0.95) / 3.2,  # smooth, unit variance
        "q_hat": rng.standard_normal(n),
        "elevator_sq": _ar1(rng, n, 0.99),
        "beta_dot": _ar1(rng, n, 0.5),
    }
    noise = _ar1(rng, n, 0.8)
    d = diagnose(noise + 0.3 * cands["alpha_cubed"] * noise.std(), FS, candidates=cands)
    first = d.candidates[0]
    assert first.name == "alpha_cubed" and first.significant
    assert first.p_value < 1e-10 and first.r > 0.2
    assert [c.name for c in d.significant_candidates] == ["alpha_cubed"]
    assert all(c.p_adjusted > 0.05 for c in d.candidates[1:])
    # Ranked by |r|; pair N_eff below N for two correlated series.
    assert np.all(np.diff([abs(c.r) for c in d.candidates]) <= 0.0)
    assert next(c for c in d.candidates if c.name == "elevator_sq").n_eff < 0.5 * n


@pytest.mark.parametrize("kind", ["laplace", "student_t3"])
def test_heavy_tailed_residuals_fail_normality(kind):
    rng = np.random.default_rng(9)
    n = 5000
    x = rng.laplace(size=n) if kind == "laplace" else rng.standard_t(3, size=n)
    d = diagnose(x, FS)
    assert not d.is_normal and d.normality_pvalue < 1e-6 and d.jarque_bera_pvalue < 1e-6
    assert d.excess_kurtosis > 1.5
    assert d.is_white  # tails, not correlation


def test_false_alarm_rates_are_near_alpha_for_correlated_noise():
    # 40 seeds of AR(1) noise (tau = 9) with a smooth unrelated candidate: tests that ignored
    # the autocorrelation would flag drift / correlation in about half of them.
    counts = dict(drift=0, variance=0, candidate=0, peak=0, normal=0)
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        x = _ar1(rng, 2000, 0.8)
        d = diagnose(x, FS, candidates={"slow": _ar1(rng, 2000, 0.99)})
        counts["drift"] += d.drift_significant
        counts["variance"] += d.variance_change_significant
        counts["candidate"] += bool(d.significant_candidates)
        counts["peak"] += bool(d.spectral_peaks)
        counts["normal"] += not d.is_normal
    assert max(counts.values()) <= 6, counts


def test_white_noise_false_whiteness_rejections_are_rare():
    rejected = sum(
        not diagnose(np.random.default_rng(200 + s).standard_normal(1000), FS).is_white
        for s in range(40)
    )
    assert rejected <= 6


def test_max_lag_summary_and_json():
    x = np.random.default_rng(10).standard_normal(500)
    c = {"a": np.random.default_rng(11).standard_normal(500), "const": np.ones(500)}
    d = diagnose(x, 50.0, candidates=c, max_lag=30)
    assert d.acf_lags.tolist() == list(range(1, 31))
    np.testing.assert_allclose(d.acf_lag_times, d.acf_lags / 50.0)
    np.testing.assert_allclose(d.acf, autocorrelation(x)[1:31])
    const = next(cc for cc in d.candidates if cc.name == "const")
    assert const.r == 0.0 and const.p_value == 1.0 and not const.significant
    data = json.loads(json.dumps(d.to_dict()))
    assert data["whiteness"]["ljung_box_dof"] == 30 and len(data["whiteness"]["acf"]) == 30
    assert {cc["name"] for cc in data["candidates"]} == {"a", "const"}
    full = d.to_dict(include_series=True)
    assert len(full["normality"]["ordered_residuals"]) == 500
    text = d.summary()
    assert "Ljung-Box" in text and "N_eff" in text and "candidate a" in text


def test_autocorrelation_direct_and_fft_agree_with_the_definition():
    x = np.random.default_rng(13).standard_normal(400).cumsum()
    xc = x - x.mean()
    expected = np.correlate(xc, xc, mode="full")[x.size - 1 :] / (xc @ xc)
    np.testing.assert_allclose(autocorrelation(x), expected, atol=1e-12)
    np.testing.assert_allclose(autocorrelation(x, max_lag=10), expected[:11], atol=1e-12)
    np.testing.assert_allclose(autocorrelation(x, max_lag=150), expected[:151], atol=1e-12)


def test_same_input_same_result():
    x = np.random.default_rng(12).standard_normal(3000)
    a, b = diagnose(x, FS), diagnose(x, FS)
    assert json.dumps(a.to_dict(include_series=True)) == json.dumps(b.to_dict(include_series=True))


def test_long_run_covariance_of_correlated_series_matches_theory():
    """Var(sum psi_t): N (sum h)^2 for white noise through a filter h, where the white
    formula N var(psi) is (sum h)^2 / sum h^2 times too small (11 for an 11-sample mean);
    N / (1 - phi)^2 for AR(1), shared between correlated columns."""
    n = 100000
    rng = np.random.default_rng(11)
    smoothed = np.convolve(rng.standard_normal(n + 10), np.ones(11) / 11, mode="valid")
    assert correlation_lag(smoothed) >= 10 and correlation_lag(rng.standard_normal(n)) <= 4
    assert long_run_covariance(smoothed)[0, 0] / n == pytest.approx(1.0, rel=0.15)
    assert n * smoothed.var() / long_run_covariance(smoothed)[0, 0] == pytest.approx(
        1 / 11, rel=0.15)
    phi = 0.9
    u, w = _ar1(rng, n, phi), rng.standard_normal(n)
    S = long_run_covariance(np.column_stack([u, u + w])) / n
    expected = 1.0 / (1.0 - phi) ** 2
    np.testing.assert_allclose(S, [[expected, expected], [expected, expected + 1.0]],
                               rtol=0.15)
    assert np.all(np.linalg.eigvalsh(S) >= 0.0)
    # Lag 0 only: the centred sum of squares and products.
    x = rng.standard_normal((500, 3)) + 5.0
    centred = x - x.mean(axis=0)
    np.testing.assert_allclose(long_run_covariance(x, max_lag=0), centred.T @ centred)


@pytest.mark.parametrize(("scores", "kwargs", "message"), [
    (np.ones((1, 2)), {}, "scores"),
    (np.r_[np.arange(9.0), np.nan], {}, "scores"),
    (np.ones((10, 2, 2)), {}, "scores"),
    (np.arange(10.0), {"max_lag": -1}, "max_lag"),
    (np.arange(10.0), {"max_lag": 1.5}, "max_lag"),
])
def test_long_run_covariance_bad_input(scores, kwargs, message):
    with pytest.raises(ValueError, match=message):
        long_run_covariance(scores, **kwargs)


@pytest.mark.parametrize(
    ("residual", "rate", "kwargs", "message"),
    [
        (np.r_[np.zeros(99), np.nan] + np.arange(100), FS, {}, "NaN"),
        (np.arange(MIN_SAMPLES - 1.0), FS, {}, "too short"),
        (np.arange(100.0), 0.0, {}, "sample_rate"),
        (np.arange(100.0), -5.0, {}, "sample_rate"),
        (np.arange(100.0), np.nan, {}, "sample_rate"),
        (np.ones((50, 2)), FS, {}, "1-D"),
        (np.full(100, 3.0), FS, {}, "constant"),
        (np.arange(100.0), FS, {"max_lag": 0}, "max_lag"),
        (np.arange(100.0), FS, {"max_lag": 51}, "max_lag"),
        (np.arange(100.0), FS, {"alpha": 1.5}, "alpha"),
        (np.arange(100.0), FS, {"candidates": {"rpm": np.ones(99)}}, "'rpm'"),
        (np.arange(100.0), FS, {"candidates": {"gps": np.r_[np.ones(99), np.inf]}}, "'gps'"),
    ],
)
def test_bad_input_raises_value_error_naming_the_problem(residual, rate, kwargs, message):
    with pytest.raises(ValueError, match=message):
        diagnose(residual, rate, **kwargs)
