"""Air data without vanes: forward EKF + RTS smoother over a log (estimate_air_data)."""

import math

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.estimation import (
    ExtendedKalmanFilter,
    VanelessAirDataModel,
    chi2_bounds,
    estimate_air_data,
    filter_pass,
    rts_smooth,
)
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.vehicles import aerosonde

SEEDS = (100, 101)
DURATION = 40.0  # s
SETTLE = 5.0  # s after the start left out of the error figures
MAE_BOUND_DEG = 0.75  # alpha and beta, each flight (light turbulence, default sensors)
AIRSPEED_MAE_BOUND = 0.2  # m/s


def _measured_only(log: FlightLog, drop=(), metadata=None, **replace) -> FlightLog:
    """What a real log holds: measured channels without vanes, no noise metadata;
    ``replace`` channels may hold NaN (no sample yet), so they skip validation."""
    names = [n for n in log.measured_names
             if not n.startswith("vane_") and n not in drop]
    channels = {n: replace.get(n, log[n]) for n in names}
    meta = {k: v for k, v in log.metadata.items() if k != "sensor_noise_std"}
    meta.update(metadata or {})
    return FlightLog(log.time, channels, {}, {n: log.unit(n) for n in names}, meta,
                     validate=not replace)


@pytest.fixture(scope="module")
def flights():
    return {seed: fly(aerosonde(), "light", duration=DURATION, seed=seed) for seed in SEEDS}


@pytest.fixture(scope="module")
def estimates(flights):
    return {seed: estimate_air_data(_measured_only(log), aerosonde())
            for seed, log in flights.items()}


def _errors(estimate, log):
    keep = estimate.valid & (estimate.time >= estimate.segments[0][0] + SETTLE)
    return (keep, estimate.alpha - log["alpha"], estimate.beta - log["beta"],
            estimate.airspeed - log["airspeed"])


def test_alpha_beta_within_bound(flights, estimates):
    for seed, log in flights.items():
        keep, alpha, beta, airspeed = _errors(estimates[seed], log)
        assert math.degrees(np.abs(alpha[keep]).mean()) < MAE_BOUND_DEG, seed
        assert math.degrees(np.abs(beta[keep]).mean()) < MAE_BOUND_DEG, seed
        assert np.abs(airspeed[keep]).mean() < AIRSPEED_MAE_BOUND, seed


def test_smoothed_std_consistent_with_error(flights, estimates):
    """Normalised squared errors of samples 2 s apart, pooled over the flights: the
    airspeed within the 99 % chi-square bounds; alpha conservative (its std includes the
    uncertainty of the segment's mean vertical wind, which the 2 s samples share); beta
    at most 5 (its std is too small by up to 1.5x, docs/estimation.md)."""
    pooled = {"alpha": [], "beta": [], "airspeed": []}
    for seed, log in flights.items():
        estimate = estimates[seed]
        keep, alpha, beta, airspeed = _errors(estimate, log)
        picks = np.flatnonzero(keep)[::200]
        for name, error in (("alpha", alpha), ("beta", beta), ("airspeed", airspeed)):
            std = getattr(estimate, f"{name}_std")
            pooled[name].extend((error[picks] / std[picks]) ** 2)
    low, high = chi2_bounds(1, len(pooled["airspeed"]), 0.99)
    assert low < np.mean(pooled["airspeed"]) < high
    assert 0.05 < np.mean(pooled["alpha"]) < 1.0
    assert 0.5 < np.mean(pooled["beta"]) < 5.0


def test_segments_smoothed_separately(flights):
    log = _measured_only(flights[SEEDS[0]], metadata={"segments": [[0.0, 18.0],
                                                                    [22.0, DURATION]]})
    estimate = estimate_air_data(log, aerosonde())
    assert len(estimate.segments) == 2
    gap = (estimate.time > 18.0) & (estimate.time < 22.0)
    assert not estimate.valid[gap].any() and np.isnan(estimate.alpha[gap]).all()
    # The second segment does not see the first: the same as estimating it alone.
    alone = estimate_air_data(log, aerosonde(), segments=[[22.0, DURATION]])
    second = estimate.time >= 22.0
    np.testing.assert_allclose(estimate.alpha[second], alone.alpha[second], rtol=0, atol=1e-12)


def test_late_gps(flights):
    original = flights[SEEDS[0]]
    late = original.time < 10.0
    gps = {n: np.where(late, np.nan, original[n]) for n in ("gps_vn", "gps_ve", "gps_vd")}
    estimate = estimate_air_data(_measured_only(original, **gps), aerosonde())
    assert not estimate.valid[late].any()
    assert estimate.segments[0][0] >= 10.0
    keep, alpha, beta, _ = _errors(estimate, original)
    assert math.degrees(np.abs(alpha[keep]).mean()) < MAE_BOUND_DEG
    assert math.degrees(np.abs(beta[keep]).mean()) < MAE_BOUND_DEG


@pytest.mark.parametrize("channel", ["gps_vn", "pitot_qbar"])
def test_missing_sensor_is_a_clear_error(flights, channel):
    log = _measured_only(flights[SEEDS[0]], drop=(channel,))
    with pytest.raises(FlightLogError, match=channel):
        estimate_air_data(log, aerosonde())


def test_noise_std_argument_checked(flights):
    log = _measured_only(flights[SEEDS[0]])
    with pytest.raises(ValueError, match="unknown channel 'imu_xx'"):
        estimate_air_data(log, aerosonde(), noise_std={"imu_xx": 0.1})


def test_smoother_beats_forward_filter_on_airspeed(flights):
    """The backward pass uses the future samples: the smoothed airspeed is closer to the
    truth than the forward filter's, and its variance is never larger."""
    log = flights[SEEDS[0]]
    model = VanelessAirDataModel(aerosonde())
    data = model.log_data(_measured_only(log))
    ekf = ExtendedKalmanFilter(model, model.default_noise())
    forward = filter_pass(ekf, data.time, data.inputs, data.measurements, data.available)
    smoothed = rts_smooth(forward)
    truth = log["airspeed"]
    keep = data.time > SETTLE
    errors = [np.abs(np.linalg.norm(s[:, :3], axis=1) - truth)[keep].mean()
              for s in (forward.state, smoothed.state)]
    assert errors[1] < errors[0]
    variances = [np.einsum("kii->ki", P) for P in (forward.covariance, smoothed.covariance)]
    assert np.all(variances[1] <= variances[0] * (1 + 1e-9) + 1e-15)


def test_rts_smooth_equals_the_batch_posterior():
    """On a linear-Gaussian model the smoothed means and covariances are those of the
    posterior of all states given all measurements (one dense solve)."""
    from drake_uav.estimation import FilterPass

    rng = np.random.default_rng(3)
    n, nx = 30, 2
    Phi = np.array([[1.0, 0.1], [0.0, 0.95]])
    Q, H, R = np.diag([1e-3, 1e-2]), np.array([[1.0, 0.0]]), np.array([[0.04]])
    P0, y = np.eye(nx), rng.standard_normal(n)
    x, P = np.zeros(nx), P0
    arrays = {k: [] for k in ("prior_x", "prior_P", "x", "P", "Phi")}
    for k in range(n):
        if k:
            x, P = Phi @ x, Phi @ P @ Phi.T + Q
        arrays["prior_x"].append(x)
        arrays["prior_P"].append(P)
        arrays["Phi"].append(Phi if k else np.eye(nx))
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        x, P = x + K @ (y[k:k + 1] - H @ x), (np.eye(nx) - K @ H) @ P
        arrays["x"].append(x)
        arrays["P"].append(P)
    forward = FilterPass(np.arange(n) * 0.1, *(np.array(arrays[k]) for k in (
        "prior_x", "prior_P", "x", "P", "Phi")), np.zeros((n, 1)), np.zeros(1))
    smoothed = rts_smooth(forward)
    # Information matrix of the stacked states: prior, dynamics and measurements.
    info, vector = np.zeros((n * nx, n * nx)), np.zeros(n * nx)
    info[:nx, :nx] += np.linalg.inv(P0)
    Qi, Ri = np.linalg.inv(Q), np.linalg.inv(R)
    for k in range(n):
        i = slice(k * nx, (k + 1) * nx)
        info[i, i] += H.T @ Ri @ H
        vector[i] += (H.T @ Ri)[:, 0] * y[k]
        if k:
            j = slice((k - 1) * nx, k * nx)
            info[i, i] += Qi
            info[j, j] += Phi.T @ Qi @ Phi
            info[i, j] -= Qi @ Phi
            info[j, i] -= Phi.T @ Qi
    covariance = np.linalg.inv(info)
    mean = covariance @ vector
    np.testing.assert_allclose(smoothed.state.ravel(), mean, atol=1e-10)
    blocks = [covariance[k * nx:(k + 1) * nx, k * nx:(k + 1) * nx] for k in range(n)]
    np.testing.assert_allclose(smoothed.covariance, np.array(blocks), atol=1e-10)
