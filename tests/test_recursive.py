"""Recursive OLS / TLS: equivalence with the batch estimators, forgetting, VFF, excitation."""

import numpy as np
import pytest

from drake_uav.identification.statistics.recursive import (
    RecursiveOLS,
    RecursiveTLS,
    VariableForgetting,
    forgetting_time,
    reconvergence_time,
    vff_forgetting,
)
from drake_uav.identification.statistics.regression import ols, pca_tls, tls

RATE = 50.0  # Hz
THETA = np.array([0.02, -0.38, -3.6, -0.5])  # C_m0, C_malpha, C_mqn, C_mde
THETA_AFTER = np.array([0.03, -0.60, -3.6, -0.35])  # after the mid-flight change


def pitch_record(n, seed, excited=(True, True, True)):
    """Regressors [1, alpha, q_n, delta_e] as first-order filtered noise (0.3 s time constant)."""
    rng = np.random.default_rng(seed)
    a = np.exp(-1.0 / (0.3 * RATE))
    shocks = rng.standard_normal((n, 3)) * np.sqrt(1 - a * a)
    w = np.empty((n, 3))
    w[0] = rng.standard_normal(3)
    for i in range(1, n):
        w[i] = a * w[i - 1] + shocks[i]
    w *= np.array([0.03, 0.01, 0.03]) * np.asarray(excited, dtype=float)
    return np.column_stack([np.ones(n), 0.05 + w[:, 0], w[:, 1], w[:, 2]])


@pytest.fixture(scope="module")
def record():
    X = pitch_record(1500, seed=1)
    rng = np.random.default_rng(2)
    y = X @ THETA
    noise_std = y.std() / 20.0
    return X, y + noise_std * rng.standard_normal(y.size), noise_std


def test_rols_with_unit_forgetting_continues_batch_ols_exactly(record):
    X, z, _ = record
    est = RecursiveOLS.from_batch(ols(X[:40], z[:40]))
    est.run(X[40:], z[40:])
    ref = ols(X, z)
    np.testing.assert_allclose(est.estimate, ref.estimate, rtol=1e-9)
    np.testing.assert_allclose(est.covariance(), ref.covariance, rtol=1e-7)
    assert est.noise_std == pytest.approx(ref.noise_std, rel=1e-9)
    np.testing.assert_allclose(est.sigma(), ref.sigma, rtol=1e-7)


def test_rols_diffuse_start_reaches_batch_ols(record):
    X, z, _ = record
    est = RecursiveOLS(4, p0=1e10)
    history = est.run(X, z)
    ref = ols(X, z)
    np.testing.assert_allclose(est.estimate, ref.estimate, rtol=1e-6)
    assert np.all(history.forgetting == 1.0)
    np.testing.assert_array_equal(history.estimate[-1], est.estimate)


def test_rols_prior_equals_prepended_prior_rows(record):
    # Vaiopoulos 2017, eq. 4.123-4.124: a prior (theta0, P0) is the same as rows sigma P0^-1/2 on
    # top
    X, z, noise_std = record
    theta0 = THETA + np.array([0.01, 0.05, -0.3, 0.02])
    L = np.diag([0.01, 0.05, 0.5, 0.05])
    P0 = L @ np.array([[1, 0.3, 0, 0], [0.3, 1, 0.2, 0], [0, 0.2, 1, 0], [0, 0, 0, 1]]) @ L
    est = RecursiveOLS(4, theta0=theta0, covariance0=P0, noise_std0=noise_std)
    est.run(X[:300], z[:300])
    evals, evecs = np.linalg.eigh(P0)
    prior_rows = noise_std * (evecs / np.sqrt(evals)) @ evecs.T
    stacked = ols(np.vstack([prior_rows, X[:300]]), np.concatenate([prior_rows @ theta0, z[:300]]))
    np.testing.assert_allclose(est.estimate, stacked.estimate, rtol=1e-9)


def test_rols_constant_forgetting_is_exponentially_weighted_least_squares(record):
    X, z, _ = record
    lam = 0.99
    est = RecursiveOLS(4, lam, p0=1e12)
    est.run(X, z)
    w = np.sqrt(lam ** np.arange(len(z))[::-1])
    ref = ols(X * w[:, None], z * w)
    np.testing.assert_allclose(est.estimate, ref.estimate, rtol=1e-6)


def _noisy(X, z, noise_std, seed, regressor_snr=5.0):
    rng = np.random.default_rng(seed)
    x_std = X.std(axis=0) / regressor_snr
    x_std[0] = 1e-6
    return X + x_std * rng.standard_normal(X.shape), np.append(x_std, noise_std)


def test_recursive_svd_with_unit_forgetting_equals_batch_tls(record):
    X, z, noise_std = record
    Xm, c = _noisy(X, z, noise_std, seed=3)
    est = RecursiveTLS(4, c)
    est.run(Xm, z)
    ref = tls(Xm, z, c)
    np.testing.assert_allclose(est.s, ref.singular_values, rtol=1e-10)
    np.testing.assert_allclose(est.estimate, ref.estimate, rtol=1e-9)
    np.testing.assert_allclose(est.sigma(), ref.sigma, rtol=1e-6)
    assert est.noise_std == pytest.approx(ref.noise_std, rel=1e-9)
    assert est.rank == ref.rank == 4


def test_recursive_svd_under_insufficient_excitation_equals_batch_pca_tls(record):
    X = pitch_record(1500, seed=1, excited=(True, True, False))  # elevator never moved
    z = X @ THETA + record[2] * np.random.default_rng(4).standard_normal(1500)
    Xm, c = _noisy(X, z, record[2], seed=5)
    c[3] = 0.002  # elevator position sensor noise [rad]
    Xm[:, 3] = X[:, 3] + c[3] * np.random.default_rng(6).standard_normal(1500)
    est = RecursiveTLS(4, c, snr_min=1.0)
    est.run(Xm, z)
    ref = pca_tls(Xm, z, c, snr_min=1.0)
    assert est.rank == ref.rank == 3
    np.testing.assert_allclose(est.estimate, ref.estimate, rtol=1e-8, atol=1e-12)
    status = est.excitation()
    np.testing.assert_array_equal(status.identifiable, ref.identifiable)
    np.testing.assert_array_equal(status.identifiable, [True, True, True, False])
    np.testing.assert_allclose(np.abs(status.unidentifiable), np.abs(ref.unidentifiable), atol=1e-8)
    assert status.rank == 3 and status.threshold == pytest.approx(ref.excitation_threshold)
    assert np.isinf(est.sigma()[3])


def test_recursive_svd_forgetting_scales_past_rows_by_sqrt_lambda(record):
    X, z, noise_std = record
    Xm, c = _noisy(X, z, noise_std, seed=7)
    lam = 0.995
    est = RecursiveTLS(4, c, forgetting=lam)
    est.run(Xm, z)
    w = np.sqrt(lam ** np.arange(len(z))[::-1])
    D = np.column_stack([Xm, z]) * w[:, None] / c
    s_ref = np.linalg.svd(D, compute_uv=False)
    np.testing.assert_allclose(est.s, s_ref, rtol=1e-9)
    assert est.effective_samples == pytest.approx(np.sum(w**2))


def test_recursive_tls_prior_rows_carry_the_prior(record):
    X, z, noise_std = record
    Xm, c = _noisy(X, z, noise_std, seed=8)
    prior = tls(Xm[:500], z[:500], c)
    est = RecursiveTLS(
        4, c, theta0=prior.estimate, covariance0=prior.covariance, scale_from_data=False
    )
    # before any data the prior rows alone give back theta0 and covariance0
    np.testing.assert_allclose(est.theta, prior.estimate, rtol=1e-12)
    np.testing.assert_allclose(est.covariance(), prior.covariance, rtol=1e-6)
    est.run(Xm[500:], z[500:])
    full = tls(Xm, z, c)
    assert np.all(np.abs(est.estimate - full.estimate) < 0.3 * full.sigma)


@pytest.mark.parametrize(
    "lam, rate, expected",
    [(0.997, 100.0, 9.97), (0.9997, 100.0, 99.84), (0.997, 50.0, 19.94), (0.997, 10.0, 99.71)],
)
def test_five_percent_forgetting_time(lam, rate, expected):
    assert forgetting_time(lam, rate) == pytest.approx(expected, abs=0.005)


def test_vff_law():
    kw = {"gamma": 1.5, "lambda_max": 1.0, "varsigma": 1e-8}
    # no model change declared inside the dead band
    assert vff_forgetting(1.0, 1.0, 1e-3, **kw) == 1.0
    assert vff_forgetting(1.5, 1.0, 1e-3, **kw) == 1.0
    assert vff_forgetting(1.49, 1.0, 5.0, **{**kw, "lambda_max": 0.999}) == 0.999
    # outside: sigma_q sigma_eps / (varsigma + |sigma_nu - sigma_eps|), capped at lambda_max
    assert vff_forgetting(2.0, 1.0, 0.01, **kw) == pytest.approx(0.01 / (1.0 + 1e-8))
    assert vff_forgetting(3.0, 1.0, 0.5, **kw) == pytest.approx(0.25, rel=1e-7)
    assert vff_forgetting(3.0, 1.0, 10.0, **kw) == 1.0


def _step_flight(seed):
    """120 s at 50 Hz, parameters change at 60 s; clean regressors, SNR 20 on z."""
    n = int(120 * RATE)
    t = np.arange(n) / RATE
    X = pitch_record(n, seed)
    truth = np.where((t >= 60.0)[:, None], THETA_AFTER, THETA)
    y = np.sum(X * truth, axis=1)
    z = y + (np.std(X @ THETA) / 20.0) * np.random.default_rng(seed + 100).standard_normal(n)
    return t, X, z, truth


def test_vff_reconverges_faster_than_best_cff_of_equal_variance():
    t, X, z, truth = _step_flight(seed=11)
    band = 0.1 * np.abs(THETA_AFTER - THETA)  # 10 % of the step ...
    band[band == 0] = 0.1 * np.abs(THETA[band == 0])  # ... or of an unchanged value
    before = (t >= 40.0) & (t < 60.0)  # steady state before the change

    def figures(forgetting):
        est = RecursiveOLS(4, forgetting).run(X, z).estimate
        variance = np.mean(np.mean((est[before] - truth[before]) ** 2, axis=0) / band**2)
        return reconvergence_time(t, est, truth, 60.0, band), variance

    vff_time, vff_var = figures(VariableForgetting())
    cff = {lam: figures(lam) for lam in (0.99, 0.995, 0.997, 0.998, 0.999, 0.9995, 0.9997, 1.0)}
    quiet = {lam: f for lam, f in cff.items() if f[1] <= vff_var}
    pool = quiet or {min(cff, key=lambda lam: cff[lam][1]): None}
    best = min(pool, key=lambda lam: cff[lam][0])
    print(f"\nVFF: re-convergence {vff_time:.2f} s, normalised variance {vff_var:.4f}")
    print(
        f"best CFF at equal variance: lambda {best}, re-convergence {cff[best][0]:.2f} s, "
        f"variance {cff[best][1]:.4f}"
    )
    assert vff_time < 5.0
    assert vff_time < cff[best][0]
    # a CFF that re-converges within a few seconds pays with a larger variance
    for lam, (reconv, variance) in cff.items():
        print(f"  CFF lambda {lam}: re-convergence {reconv:.2f} s, variance {variance:.4f}")
        if reconv < 10.0:
            assert variance > 2 * vff_var


def test_vff_tracks_a_step_in_recursive_tls():
    t, X, z, truth = _step_flight(seed=12)
    rng = np.random.default_rng(13)
    # regressor noise 1/20 of the regressor signal: the step is ~4x the equation error
    c = np.append(np.array([1e-6, 0.0015, 0.0005, 0.0015]), np.std(X @ THETA) / 20.0)
    Xm = X + c[:4] * rng.standard_normal(X.shape)
    band = 0.2 * np.abs(THETA_AFTER - THETA)
    band[band == 0] = 0.1 * np.abs(THETA[band == 0])
    vff = RecursiveTLS(4, c, forgetting=VariableForgetting()).run(Xm, z)
    keep_all = RecursiveTLS(4, c).run(Xm, z)
    assert np.min(vff.forgetting) < 0.5  # the change was detected
    assert np.all(vff.forgetting[t < 55.0] == 1.0)  # and nothing before it
    assert reconvergence_time(t, vff.estimate, truth, 60.0, band) < 10.0
    assert reconvergence_time(t, keep_all.estimate, truth, 60.0, band) == np.inf


def test_excitation_monitor_of_rols():
    X = pitch_record(1000, seed=14, excited=(True, False, True))  # no pitch-rate excitation
    z = X @ THETA + 1e-3 * np.random.default_rng(15).standard_normal(1000)
    regressor_std = np.array([1e-6, 0.002, 0.001, 0.002])
    est = RecursiveOLS(4)
    est.run(X[:, :], z)
    status = est.excitation(regressor_std, snr_min=1.0)
    np.testing.assert_array_equal(status.identifiable, [True, True, False, True])
    assert status.rank == 3 and status.singular_values[3] < status.threshold
    assert abs(status.unidentifiable[0, 2]) > 0.99
    # once pitch rate is excited, the flag clears
    X2 = pitch_record(1000, seed=16)
    est.run(X2, X2 @ THETA)
    assert np.all(est.excitation(regressor_std, snr_min=1.0).identifiable)


def test_state_vector_reproduces_the_estimator(record):
    X, z, noise_std = record
    Xm, c = _noisy(X, z, noise_std, seed=17)
    for make in (
        lambda: RecursiveOLS(4, VariableForgetting()),
        lambda: RecursiveTLS(4, c, forgetting=VariableForgetting()),
    ):
        a = make()
        a.run(Xm[:700], z[:700])
        b = make()
        b.set_state(a.state)
        ha = a.run(Xm[700:], z[700:])
        hb = b.run(Xm[700:], z[700:])
        np.testing.assert_array_equal(ha.estimate, hb.estimate)
        np.testing.assert_array_equal(a.state, b.state)


def test_reconvergence_time():
    t = np.arange(10.0)
    est = np.array([[0.0], [0.0], [5.0], [0.0], [5.0], [1.05], [0.95], [1.0], [1.0], [1.0]])
    assert reconvergence_time(t, est, np.ones((10, 1)), 2.0, 0.1) == pytest.approx(3.0)
    assert reconvergence_time(t, est, 1.0, 2.0, 0.01) == pytest.approx(5.0)
    assert reconvergence_time(t, est[::-1], 1.0, 2.0, 0.1) == np.inf


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: VariableForgetting(k_e=1.0).validate(), "k_e"),
        (lambda: VariableForgetting(k_eps=1.5).validate(), "k_eps"),
        (lambda: VariableForgetting(gamma=3.0).validate(), "gamma"),
        (lambda: VariableForgetting(lambda_min=1.0).validate(), "lambda_min"),
        (lambda: RecursiveOLS(4, 1.5), "forgetting"),
        (lambda: RecursiveOLS(4, theta0=np.ones(3)), "theta0"),
        (lambda: RecursiveOLS(4, covariance0=-np.eye(4)), "covariance0"),
        (lambda: RecursiveTLS(4), "error_std"),
        (lambda: RecursiveTLS(4, np.zeros(5)), "error_std"),
        (lambda: forgetting_time(1.0, 100.0), "forgetting"),
    ],
)
def test_invalid_settings_raise(make, match):
    with pytest.raises(ValueError, match=match):
        make()
