"""Batch OLS / TLS / GTLS / PCA-TLS against the Vaiopoulos 2017 simulation results (Tables 3-5).

Synthetic data built like Vaiopoulos 2017's: a 60 s lateral-directional flight sampled at 100 Hz (N
= 6000)
with aileron 3-2-1-1 and rudder doublets plus small multisines and a first-order gust on beta,
simulated with a linear lateral model; regressors [1, beta, p_n, r_n, delta_a, delta_r] with
p_n = b p / (2 V), r_n = b r / (2 V). The true parameters are the reference values of Tables 3-5.
SNR is the amplitude ratio std(signal) / std(noise) (Vaiopoulos 2017 does not define
it; this is the usual reading).
Table 5's regressor noise: every non-constant regressor column has SNR 3.5, the level at which
OLS attenuates C_lp to about -0.65 as in the seed.
"""

import warnings

import numpy as np
import pytest
from scipy import stats
from scipy.linalg import expm

from drake_uav.identification.statistics.regression import (
    InsufficientExcitationWarning,
    ols,
    pca_tls,
    tls,
)

RATE = 100.0  # Hz
SPAN = 2.9  # m
AIRSPEED = 25.0  # m/s
NAMES_Y = ("C_Y0", "C_Ybeta", "C_Ypn", "C_Yrn", "C_Yda", "C_Ydr")
NAMES_L = ("C_l0", "C_lbeta", "C_lpn", "C_lrn", "C_lda", "C_ldr")
THETA_Y = np.array([0.0, -0.98, 0.0, 0.0, 0.0, -0.20])  # Table 3 reference
THETA_L = np.array([0.0, -0.12, -1.00, 0.14, 0.25, -0.0037])  # Tables 4-5 reference
REGRESSOR_SNR = 3.5


def _pulse_train(t, widths, amplitude, start, repeat):
    """Alternating-sign pulses of the given widths [s], restarted every ``repeat`` seconds."""
    u = np.zeros_like(t)
    for t0 in np.arange(start, t[-1], repeat):
        edge, sign = t0, 1.0
        for width in widths:
            u[(t >= edge) & (t < edge + width)] = sign * amplitude
            edge += width
            sign = -sign
    return u


def lateral_flight(duration=60.0, rudder=True, seed=0):
    """Regressor matrix (N, 6) of a synthetic lateral flight (see module docstring)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * RATE))) / RATE
    aileron = _pulse_train(t, (0.9, 0.6, 0.3, 0.3), np.deg2rad(6.0), 1.0, 8.0)
    rudder_cmd = _pulse_train(t, (0.8, 0.8), np.deg2rad(8.0), 5.0, 8.0)
    freq = rng.uniform(0.1, 2.0, (2, 6))
    phase = rng.uniform(0.0, 2 * np.pi, (2, 6))
    wiggle = np.deg2rad(1.5) * np.sin(2 * np.pi * freq[..., None] * t + phase[..., None]).mean(1)
    aileron = aileron + wiggle[0]
    rudder_cmd = (rudder_cmd + wiggle[1]) if rudder else np.zeros_like(t)
    # states beta, p, r, phi; inputs aileron, rudder
    A = np.array(
        [
            [-0.6, 0.05, -1.0, 9.81 / AIRSPEED],
            [-25.0, -11.0, 3.0, 0.0],
            [12.0, -0.8, -1.5, 0.0],
            [0.0, 1.0, 0.0, 0.0],
        ]
    )
    B = np.array([[0.0, 0.1], [60.0, 2.0], [-2.0, -12.0], [0.0, 0.0]])
    M = np.zeros((6, 6))
    M[:4, :4], M[:4, 4:] = A, B
    E = expm(M / RATE)
    Ad, Bd = E[:4, :4], E[:4, 4:]
    u = np.column_stack([aileron, rudder_cmd])
    x = np.zeros(4)
    states = np.empty((t.size, 4))
    for i in range(t.size):
        states[i] = x
        x = Ad @ x + Bd @ u[i]
    a = np.exp(-1.0 / RATE)  # 1 s gust correlation time, 0.8 deg std
    shocks = rng.standard_normal(t.size) * np.deg2rad(0.8) * np.sqrt(1 - a * a)
    gust = np.zeros(t.size)
    for i in range(1, t.size):
        gust[i] = a * gust[i - 1] + shocks[i]
    beta = states[:, 0] + gust
    scale = SPAN / (2 * AIRSPEED)
    return np.column_stack(
        [np.ones(t.size), beta, scale * states[:, 1], scale * states[:, 2], aileron, rudder_cmd]
    )


@pytest.fixture(scope="module")
def flight():
    return lateral_flight()


def _observe(X, theta, snr, rng):
    y = X @ theta
    noise_std = y.std() / snr
    return y + noise_std * rng.standard_normal(y.size), noise_std


def _noisy_regressors(X, snr, rng):
    std = X.std(axis=0) / snr
    std[0] = 0.0  # the constant column is exact
    return X + std * rng.standard_normal(X.shape), std


def _assert_normal_residuals(result):
    # normal probability plot (Vaiopoulos 2017, eq. 4.16-4.17) is a straight line
    (_, _), (_, _, r) = stats.probplot(result.residual, dist="norm")
    assert r > 0.999


def test_ols_statistics_match_reference_formulas(flight):
    rng = np.random.default_rng(1)
    z, _ = _observe(flight, THETA_L, 45.0, rng)
    res = ols(flight, z, NAMES_L)
    # explicit normal equations (4.6-4.8), t-ratios (4.12) and R^2 (4.25)
    XtX = flight.T @ flight
    theta = np.linalg.solve(XtX, flight.T @ z)
    nu = z - flight @ theta
    s2 = nu @ nu / (flight.shape[0] - 6)
    cov = s2 * np.linalg.inv(XtX)
    zbar = z.mean()
    r2 = (theta @ flight.T @ z - z.size * zbar**2) / (z @ z - z.size * zbar**2)
    np.testing.assert_allclose(res.estimate, theta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-7)
    np.testing.assert_allclose(res.t_statistic, theta / np.sqrt(np.diag(cov)), rtol=1e-7)
    assert res.r_squared == pytest.approx(r2, rel=1e-10)
    assert res.dof == z.size - 6
    assert res.t_critical == pytest.approx(stats.t.ppf(0.975, z.size - 6))
    assert res["C_lpn"] == pytest.approx(theta[2])


def test_ols_matches_scipy_linregress():
    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, 500)
    z = 0.3 - 1.7 * x + 0.1 * rng.standard_normal(500)
    ref = stats.linregress(x, z)
    res = ols(np.column_stack([np.ones_like(x), x]), z)
    np.testing.assert_allclose(res.estimate, [ref.intercept, ref.slope], rtol=1e-10)
    np.testing.assert_allclose(res.sigma, [ref.intercept_stderr, ref.stderr], rtol=1e-8)
    assert res.r_squared == pytest.approx(ref.rvalue**2, rel=1e-10)


@pytest.mark.parametrize(
    "theta, names, snr, seed",
    [(THETA_Y, NAMES_Y, 30.0, 3), (THETA_L, NAMES_L, 45.0, 4)],
    ids=["table3_CY_snr30", "table4_Cl_snr45"],
)
def test_tables_3_4_ols_clean_regressors(flight, theta, names, snr, seed):
    z, noise_std = _observe(flight, theta, snr, np.random.default_rng(seed))
    res = ols(flight, z, names)
    print("\n" + res.table())
    assert np.all(np.abs(res.estimate - theta) <= 2.0 * res.sigma)
    assert res.r_squared > 0.85
    assert res.noise_std == pytest.approx(noise_std, rel=0.05)
    # the terms with a nonzero reference value are significant
    np.testing.assert_array_equal(res.significant[np.abs(theta) > 0.1], True)
    _assert_normal_residuals(res)


def test_ols_two_sigma_interval_coverage(flight):
    # the reported sigma is honest: +-2 sigma covers the truth ~95% of the time per parameter
    rng = np.random.default_rng(5)
    X = flight[::3]
    y = X @ THETA_L
    noise_std = y.std() / 45.0
    runs = 200
    z = y + noise_std * rng.standard_normal((runs, y.size))
    fits = [ols(X, zi) for zi in z]
    inside = np.array([np.abs(f.estimate - THETA_L) <= 2 * f.sigma for f in fits])
    coverage = inside.mean(axis=0)
    assert np.all((coverage > 0.90) & (coverage < 0.99)), coverage


def test_table5_ols_bias_and_gtls_recovery(flight):
    rng = np.random.default_rng(6)
    z, noise_std = _observe(flight, THETA_L, 45.0, rng)
    Xm, x_std = _noisy_regressors(flight, REGRESSOR_SNR, rng)
    res_ols = ols(Xm, z, NAMES_L)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # fully excited: no reduction, no warning
        res_tls = tls(Xm, z, np.append(x_std, noise_std), names=NAMES_L)
    print("\n" + res_ols.table() + "\n" + res_tls.table())
    # Table 5: OLS pulls C_lpn from -1.00 to about -0.65 and C_lda from 0.25 to about 0.18 ...
    assert -0.75 < res_ols["C_lpn"] < -0.55
    assert 0.13 < res_ols["C_lda"] < 0.21
    # ... and its sigma does not cover the error
    err = np.abs(res_ols.estimate - THETA_L)
    assert err[2] > 10 * res_ols.sigma[2] and err[4] > 10 * res_ols.sigma[4]
    # GTLS on the same data: every parameter within 5 % or 2 sigma of the truth
    assert res_tls.method == "GTLS" and res_tls.rank == 6
    err = np.abs(res_tls.estimate - THETA_L)
    assert np.all((err <= 0.05 * np.abs(THETA_L)) | (err <= 2 * res_tls.sigma)), err
    assert np.all(res_tls.sigma < 0.02)


def test_gtls_equals_tls_after_explicit_normalisation(flight):
    rng = np.random.default_rng(7)
    z, noise_std = _observe(flight, THETA_L, 45.0, rng)
    Xm, x_std = _noisy_regressors(flight, REGRESSOR_SNR, rng)
    x_std[0] = 1e-4
    c = np.append(x_std, noise_std)
    gtls = tls(Xm, z, c)
    plain = tls(Xm / x_std, z / noise_std)  # C = I when normalised (Vaiopoulos 2017, eq. 4.43-4.47)
    assert gtls.method == "GTLS" and plain.method == "TLS"
    np.testing.assert_allclose(gtls.estimate, plain.estimate * noise_std / x_std, rtol=1e-8)
    np.testing.assert_allclose(gtls.singular_values, plain.singular_values, rtol=1e-10)
    full = tls(Xm, z, error_cov=np.diag(c**2))
    np.testing.assert_allclose(full.estimate, gtls.estimate, rtol=1e-10)
    np.testing.assert_allclose(full.covariance, gtls.covariance, rtol=1e-8)


def test_tls_tends_to_ols_when_regressors_are_exact(flight):
    z, noise_std = _observe(flight, THETA_L, 45.0, np.random.default_rng(8))
    res_ols = ols(flight, z)
    for tiny in (1e-5, 1e-7):
        res_tls = tls(flight, z, np.append(np.full(6, tiny), noise_std))
        np.testing.assert_allclose(res_tls.estimate, res_ols.estimate, atol=1e-4 * tiny / 1e-5)
    np.testing.assert_allclose(res_tls.sigma, res_ols.sigma, rtol=1e-3)


def test_pca_tls_flags_the_unexcited_input():
    X = lateral_flight(rudder=False)  # rudder never moved: its column is sensor noise only
    rng = np.random.default_rng(9)
    z, noise_std = _observe(X, THETA_L, 45.0, rng)
    x_std = X.std(axis=0) / REGRESSOR_SNR
    x_std[0] = 0.0
    x_std[5] = np.deg2rad(0.5)  # rudder position sensor noise
    Xm = X + x_std * rng.standard_normal(X.shape)
    res = pca_tls(Xm, z, np.append(x_std, noise_std), names=NAMES_L, snr_min=1.0)
    print("\n" + res.table())
    assert res.method == "PCA-TLS" and res.rank == 5
    assert res.unidentifiable.shape == (1, 6)
    assert abs(res.unidentifiable[0, 5]) > 0.99  # the flagged combination is C_ldr
    np.testing.assert_array_equal(res.identifiable, [True] * 5 + [False])
    assert np.isinf(res.sigma[5]) and not res.significant[5]
    assert np.all(np.abs(res.estimate[:5] - THETA_L[:5]) <= 2 * res.sigma[:5])
    assert abs(res.estimate[5]) < 0.05  # bounded minimum-norm value, not a wild number
    # the excited singular values clear the threshold, the flagged one sits at the noise floor
    assert res.singular_values[4] > res.excitation_threshold > res.singular_values[5]
    with pytest.warns(InsufficientExcitationWarning):
        res_warn = tls(Xm, z, np.append(x_std, noise_std), names=NAMES_L)
    np.testing.assert_allclose(res_warn.estimate, res.estimate)


def test_rank_deficient_ols_warns_and_returns_reduced_answer(flight):
    z, _ = _observe(flight, THETA_L, 45.0, np.random.default_rng(10))
    X = np.column_stack([flight, flight[:, 4]])  # aileron column twice
    with pytest.warns(InsufficientExcitationWarning):
        res = ols(X, z)
    assert res.rank == 6
    direction = res.unidentifiable[0]
    np.testing.assert_allclose(np.abs(direction), [0, 0, 0, 0, 2**-0.5, 0, 2**-0.5], atol=1e-9)
    assert res.estimate[4] == pytest.approx(res.estimate[6])  # minimum norm splits it
    assert np.all(np.isinf(res.sigma[[4, 6]]))
    # the identifiable parameters are exactly those of the model without the duplicate
    ref = ols(flight, z)
    keep = [0, 1, 2, 3, 5]
    np.testing.assert_allclose(res.estimate[keep], ref.estimate[keep], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(res.sigma[keep], ref.sigma[keep], rtol=1e-6)
    assert res.estimate[4] + res.estimate[6] == pytest.approx(ref.estimate[4], rel=1e-8)


def test_near_collinear_ols_gives_no_huge_numbers(flight):
    rng = np.random.default_rng(11)
    z, _ = _observe(flight, THETA_L, 45.0, rng)
    X = np.column_stack([flight, flight[:, 4] + 1e-9 * rng.standard_normal(flight.shape[0])])
    with pytest.warns(InsufficientExcitationWarning):
        res = ols(X, z)
    assert np.all(np.abs(res.estimate) < 2.0)
    assert res.condition_number > 1e6


def test_zero_column_and_noise_only_observation_are_handled(flight):
    rng = np.random.default_rng(12)
    X = flight.copy()
    X[:, 3] = 0.0
    with pytest.warns(InsufficientExcitationWarning):
        res = ols(X, rng.standard_normal(X.shape[0]))
    assert np.all(np.isfinite(res.estimate)) and not res.identifiable[3]
    # TLS on an observation that is pure noise: no direction explains it, estimate stays small
    c = np.append(X.std(axis=0) / 10 + 1e-3, 1.0)
    with pytest.warns(InsufficientExcitationWarning):
        res = tls(X, rng.standard_normal(X.shape[0]), c)
    assert np.all(np.isfinite(res.estimate)) and np.all(np.abs(res.estimate) < 5.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"X": np.ones((5, 6)), "z": np.ones(5)}, "more samples"),
        ({"z": np.full(6000, np.nan)}, "z contains NaN"),
        ({"z": np.ones(10)}, "z must have shape"),
        ({"names": ("a",)}, "names has 1"),
    ],
)
def test_bad_input_raises(flight, kwargs, match):
    args = {"X": flight, "z": flight @ THETA_L}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        ols(args["X"], args["z"], args.get("names"))


def test_tls_error_model_validation(flight):
    z = flight @ THETA_L
    with pytest.raises(ValueError, match="error_std"):
        tls(flight, z, np.ones(3))
    with pytest.raises(ValueError, match="error_cov"):
        tls(flight, z, error_cov=-np.eye(7))
    with pytest.raises(ValueError, match="snr_min"):
        pca_tls(flight, z, np.ones(7), snr_min=-1.0)
