"""Cramer-Rao bounds, and OLS / GTLS against them in 200-run Monte-Carlo campaigns."""

import warnings

import numpy as np
import pytest

from drake_uav.identification.statistics.crlb import (
    crlb_errors_in_variables,
    crlb_ols,
    sample_errors_in_variables,
)
from drake_uav.identification.statistics.regression import ols, tls

THETA = np.array([0.02, -0.38, -3.6, -0.5])  # C_m0, C_malpha, C_mqn, C_mde
RUNS = 200


def pitch_regressors(n=3000, rate=50.0):
    """[1, alpha, q_n, delta_e] from sums of sinusoids (a 60 s record at 50 Hz)."""
    rng = np.random.default_rng(0)
    t = np.arange(n) / rate
    freq = rng.uniform(0.05, 1.5, (3, 5))
    phase = rng.uniform(0.0, 2 * np.pi, (3, 5))
    waves = np.sin(2 * np.pi * freq[..., None] * t + phase[..., None]).sum(axis=1)
    amplitude = np.array([0.03, 0.01, 0.03])[:, None] / np.sqrt(2.5)
    alpha, qn, de = amplitude * waves
    return np.column_stack([np.ones(n), 0.05 + alpha, qn, de])


@pytest.fixture(scope="module")
def X0():
    return pitch_regressors()


def _fisher_bound(X0, theta, W):
    """Brute-force bound: invert the Fisher information of (theta, all true regressors)."""
    N, n = X0.shape
    m = n + 1
    # mean of row i: [xi_i, xi_i theta]; parameters p = [theta, xi_1, ..., xi_N]
    H = np.zeros((N * m, n + N * n))
    for i in range(N):
        rows = slice(i * m, (i + 1) * m)
        H[i * m + n, :n] = X0[i]  # d(xi_i theta)/d theta
        H[rows, n + i * n : n + (i + 1) * n] = np.vstack([np.eye(n), theta])  # d/d xi_i
    W_inv = np.linalg.inv(W)
    info = sum(H[i * m : (i + 1) * m].T @ W_inv @ H[i * m : (i + 1) * m] for i in range(N))
    return np.linalg.inv(info)[:n, :n]


def test_errors_in_variables_bound_is_the_fisher_bound():
    rng = np.random.default_rng(1)
    X = rng.standard_normal((12, 3))
    theta = np.array([0.7, -1.2, 0.3])
    L = rng.standard_normal((4, 4))
    W = 0.05 * (L @ L.T + 0.5 * np.eye(4))  # correlated errors, regressors and observation
    np.testing.assert_allclose(
        crlb_errors_in_variables(X, theta, W), _fisher_bound(X, theta, W), rtol=1e-8
    )


def test_bound_without_regressor_noise_is_the_ols_bound(X0):
    sigma = 0.003
    np.testing.assert_allclose(
        crlb_errors_in_variables(X0, THETA, np.append(np.zeros(4), sigma**2)),
        crlb_ols(X0, sigma),
        rtol=1e-12,
    )
    np.testing.assert_allclose(crlb_ols(X0, sigma), sigma**2 * np.linalg.inv(X0.T @ X0), rtol=1e-8)


def _campaign(estimates, bound):
    """Empirical std / CRLB std and bias / standard error, per parameter."""
    std = estimates.std(axis=0, ddof=1)
    ratio = std / np.sqrt(np.diag(bound))
    bias_in_se = (estimates.mean(axis=0) - THETA) / (std / np.sqrt(len(estimates)))
    return std, ratio, bias_in_se


def test_monte_carlo_ols_attains_the_bound(X0):
    y = X0 @ THETA
    noise_std = y.std() / 20.0
    # antithetic pairs: the mean shows the estimator's bias, not the luck of the draw
    _, z = sample_errors_in_variables(
        X0,
        THETA,
        np.append(np.zeros(4), noise_std),
        np.random.default_rng(2),
        RUNS,
        antithetic=True,
    )
    estimates = np.array([ols(X0, zi).estimate for zi in z])
    _, ratio, bias = _campaign(estimates, crlb_ols(X0, noise_std))
    print("\nOLS std/CRLB", ratio.round(3), "bias/SE", bias.round(2))
    # a bound cannot be beaten: allow 4 standard errors of a std from 100 independent pairs
    assert np.all(ratio <= 1.3) and np.all(ratio > 1.0 - 4.0 / np.sqrt(2 * RUNS // 2))
    assert np.all(np.abs(bias) <= 2.0)


def test_monte_carlo_gtls_near_the_bound_with_honest_sigma(X0):
    y = X0 @ THETA
    error_std = np.append(X0.std(axis=0) / 3.5, y.std() / 20.0)
    error_std[0] = 0.0  # exact constant column
    Xm, zm = sample_errors_in_variables(
        X0, THETA, error_std, np.random.default_rng(3), RUNS, antithetic=True
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fits = [tls(Xi, zi, error_std) for Xi, zi in zip(Xm, zm, strict=True)]
    estimates = np.array([f.estimate for f in fits])
    std, ratio, bias = _campaign(estimates, crlb_errors_in_variables(X0, THETA, error_std**2))
    reported = np.mean([f.sigma for f in fits], axis=0)
    print(
        "\nGTLS std/CRLB",
        ratio.round(3),
        "bias/SE",
        bias.round(2),
        "reported/empirical sigma",
        (reported / std).round(3),
    )
    assert np.all(ratio <= 1.3)
    assert np.all(np.abs(bias) <= 2.0)
    assert np.all(np.abs(reported / std - 1.0) < 0.2)
    # OLS on the same data is far outside: its bias is many standard errors
    ols_estimates = np.array([ols(Xi, zi).estimate for Xi, zi in zip(Xm, zm, strict=True)])
    _, _, ols_bias = _campaign(ols_estimates, crlb_ols(X0, error_std[-1]))
    assert np.max(np.abs(ols_bias)) > 50


def test_sampling_is_seeded_and_antithetic(X0):
    c = np.array([0.0, 1e-3, 1e-3, 1e-3, 1e-4])
    a = sample_errors_in_variables(X0, THETA, c, np.random.default_rng(4), 4, antithetic=True)
    b = sample_errors_in_variables(X0, THETA, c, np.random.default_rng(4), 4, antithetic=True)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_allclose(a[0][0] + a[0][2], 2 * X0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(a[1][1] + a[1][3], 2 * X0 @ THETA, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(a[0][:, :, 0], 1.0)  # exact column untouched
    X1, z1 = sample_errors_in_variables(X0, THETA, c, np.random.default_rng(4))
    assert X1.shape == X0.shape and z1.shape == (X0.shape[0],)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda X: crlb_ols(X, 0.0), "noise_std"),
        (lambda X: crlb_ols(X[:2], 1.0), "X must be"),
        (lambda X: crlb_errors_in_variables(X, THETA[:2], np.ones(5)), "theta"),
        (lambda X: crlb_errors_in_variables(X, THETA, np.ones(3)), "error_cov"),
        (lambda X: crlb_errors_in_variables(X, THETA, -np.eye(5)), "semidefinite"),
        (
            lambda X: sample_errors_in_variables(X, THETA, np.ones(5), None, 3, antithetic=True),
            "even",
        ),
    ],
)
def test_bad_arguments_raise(X0, call, match):
    with pytest.raises(ValueError, match=match):
        call(X0)
