"""EKF core: compiled Jacobians, time and measurement update, masks, gating, NaN, batches."""

import math

import numpy as np
import pytest
from pydrake.math import abs as sabs
from pydrake.math import acos, asin, atan, atan2, cos, exp, log, sin, sqrt, tan, tanh
from pydrake.math import max as smax
from pydrake.math import min as smin
from scipy.linalg import expm
from scipy.stats import chi2

from drake_uav.estimation import AirDataModel, ModelBasedAirDataModel, ParameterModel
from drake_uav.estimation.ekf import (
    EkfModel,
    EkfNoise,
    ExtendedKalmanFilter,
    chi2_bounds,
    run_filter,
    wrap_angle,
)
from drake_uav.model.compiled import CompiledFunction
from drake_uav.optimization.trim import trim
from drake_uav.vehicles.fixed_wing import aerosonde


def _every_operation(x, u):
    """Touches every node kind the compiler writes (and differentiates)."""
    a, b, c = x[0], x[1], x[2]
    return np.array([
        sqrt(a * a + 1.0) + sin(b) * cos(c) + tan(0.3 * c),
        asin(0.5 * tanh(a)) + acos(0.4 * tanh(b)) + atan(c * u[0]),
        atan2(b, a) + exp(0.1 * c) + log(2.0 + a * a) + sabs(b - u[1]),
        smax(a, b) * smin(b, c) + a / (1.5 + c * c) + (2.0 + a * a) ** 1.5 + b**3,
        u[0] * 3.0 + 0.0 * a,
    ])


def _models():
    params = aerosonde()
    level = trim(params, 25.0)
    return [
        (AirDataModel(params), [24.5, 0.4, 1.8, 3.0, -2.0, 0.2],
         [0.1, 0.2, -9.7, 0.05, 0.1, -0.05, 0.1, 0.05, 1.0]),
        (ModelBasedAirDataModel(params), [25.0, 0.06, 0.02, 3.0, -2.0, 0.2],
         [0.05, 0.1, -0.05, 0.1, 0.05, 1.0, *level.controls]),
        (ParameterModel(params, "longitudinal"), None, None),
        (ParameterModel(params, "lateral"), None, None),
    ]


def _point(model, x, u, rng):
    if x is None:
        physical = {"airspeed": 25.0, "alpha": 0.06, "q": 0.1, "pitch": 0.05, "beta": 0.02,
                    "p": 0.05, "r": -0.04, "roll": 0.1, "yaw": 1.0}
        x = [physical[n] for n in model.physical_names]
        x += [model.params.derivative(n) for n in model.parameter_names]
        u = [physical[n] for n in model.input_names[:4]] + [-0.02, 0.01, 0.005, 0.6]
    x, u = np.array(x, float), np.array(u, float)
    return x * (1.0 + 0.02 * rng.standard_normal(x.size)), u


def test_compiled_jacobians_equal_autodiff_for_every_operation():
    f = CompiledFunction(_every_operation, (3, 2), {0: None, 1: (1,)})
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, u = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 2)
        value, (Jx, Ju) = f.jacobians(x, u)
        ref_value, (ref_x, ref_u) = f.autodiff_jacobians(x, u)
        np.testing.assert_allclose(value, np.array(_every_operation(x, u), float), atol=1e-13)
        np.testing.assert_allclose(value, ref_value, atol=1e-13)
        np.testing.assert_allclose(Jx, ref_x, atol=1e-12)
        np.testing.assert_allclose(Ju, ref_u, atol=1e-12)


@pytest.mark.parametrize("index", range(4))
def test_compiled_model_jacobians_equal_autodiff(index):
    model, x0, u0 = _models()[index]
    rng = np.random.default_rng(index)
    x, u = _point(model, x0, u0, rng)
    nx, nu, nw, _ = model.sizes
    w = 0.1 * rng.standard_normal(nw)
    f = CompiledFunction(model.dynamics, (nx, nu, nw), {0: None, 1: None, 2: None})
    h = CompiledFunction(model.measurement, (nx, nu), {0: None, 1: None})
    for function, args in ((f, (x, u, w)), (h, (x, u))):
        value, blocks = function.jacobians(*args)
        ref_value, ref_blocks = function.autodiff_jacobians(*args)
        scale = 1.0 + np.abs(ref_value).max()
        np.testing.assert_allclose(value, ref_value, atol=1e-12 * scale)
        for block, ref in zip(blocks, ref_blocks, strict=True):
            np.testing.assert_allclose(block, ref, atol=1e-10 * (1.0 + np.abs(ref).max()))


@pytest.mark.parametrize("batch", [3, 20])
def test_batch_evaluation_equals_per_sample(batch):
    model, x0, u0 = _models()[1]
    rng = np.random.default_rng(batch)
    points = [_point(model, x0, u0, rng) for _ in range(batch)]
    X, U = np.array([p[0] for p in points]), np.array([p[1] for p in points])
    h = CompiledFunction(model.measurement, (6, 10), {0: None, 1: (0, 1, 2)})
    values, (H, D) = h.batch_jacobians(X, U)
    for b in range(batch):
        value, (Hb, Db) = h.jacobians(X[b], U[b])
        np.testing.assert_allclose(values[b], value, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(H[b], Hb, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(D[b], Db, rtol=1e-12, atol=1e-13)


class _RandomWalk(EkfModel):
    """x_dot = w (two independent random walks), measured directly by two sensors."""

    state_names = ("a", "b")
    input_names = ("offset",)
    noise_names = ("wa", "wb")
    measurement_names = ("ya", "yb")
    groups = {"first": (0,), "second": (1,)}

    def dynamics(self, x, u, w):
        return np.array([w[0] + 0.0 * x[0], w[1] + 0.0 * x[1]])

    def measurement(self, x, u):
        return np.array([x[0] + u[0], x[1]])

    def initial_state(self, u, y, available):
        return np.array([y[0] - u[0], y[1]])


def _walk_filter(q=0.2, r=0.3, gate=0.9999) -> ExtendedKalmanFilter:
    noise = EkfNoise(process_psd={"wa": q, "wb": q}, input_std={},
                     measurement_std={"ya": r, "yb": r}, initial_std={"a": 1.0, "b": 1.0})
    return ExtendedKalmanFilter(_RandomWalk(), noise, gate)


def test_random_walk_reaches_the_riccati_steady_state():
    q, r, dt = 0.2, 0.3, 0.05
    ekf = _walk_filter(q, r)
    x, P = np.zeros(2), np.eye(2)
    for _ in range(400):
        x, P = ekf.predict(x, P, np.zeros(1), dt)
        P = ekf.update(x, P, np.zeros(1), np.zeros(2)).P
    prior = 0.5 * (q * dt + math.sqrt((q * dt) ** 2 + 4.0 * q * dt * r * r))
    posterior = prior * r * r / (prior + r * r)
    np.testing.assert_allclose(np.diag(P), posterior, rtol=1e-9)
    assert P[0, 1] == 0.0


def test_exponential_integration_of_a_linear_system():
    class Oscillator(EkfModel):
        state_names, input_names, noise_names = ("x", "v"), ("force",), ("w",)
        measurement_names, groups = ("y",), {"y": (0,)}

        def dynamics(self, x, u, w):
            return np.array([x[1], -4.0 * x[0] - 0.4 * x[1] + u[0] + w[0]])

        def measurement(self, x, u):
            return np.array([x[0]])

    noise = EkfNoise({"w": 0.0}, {}, {"y": 1.0}, {"x": 1.0, "v": 1.0})
    ekf = ExtendedKalmanFilter(Oscillator(), noise)
    A = np.array([[0.0, 1.0], [-4.0, -0.4]])
    x0, P0, dt, steps = np.array([1.0, 0.0]), np.diag([0.5, 0.2]), 0.01, 300
    x, P = x0, P0
    for _ in range(steps):
        x, P = ekf.predict(x, P, np.zeros(1), dt)
    Phi = expm(A * dt * steps)
    np.testing.assert_allclose(x, Phi @ x0, atol=1e-7)
    np.testing.assert_allclose(P, Phi @ P0 @ Phi.T, atol=1e-6)


def test_availability_mask_equals_the_single_sensor_update():
    ekf = _walk_filter()
    x, P = np.array([0.3, -0.2]), np.array([[0.5, 0.2], [0.2, 0.4]])
    y = np.array([1.0, 5.0])
    result = ekf.update(x, P, np.zeros(1), y, np.array([True, False]))
    H, R = np.array([[1.0, 0.0]]), 0.3**2
    S = H @ P @ H.T + R
    K = P @ H.T / S
    np.testing.assert_allclose(result.x, x + (K * (y[0] - x[0])).ravel(), atol=1e-14)
    np.testing.assert_allclose(result.P, (np.eye(2) - K @ H) @ P, atol=1e-14)
    assert result.dof == 1 and result.nis == pytest.approx((y[0] - x[0]) ** 2 / S[0, 0])
    assert np.isnan(result.innovation[1]) and not result.used[1]


def test_joseph_update_keeps_the_covariance_symmetric_positive_definite():
    noise = EkfNoise({"wa": 1e-8, "wb": 1e-8}, {}, {"ya": 1e-6, "yb": 1e-6},
                     {"a": 1e3, "b": 1e3})
    ekf = ExtendedKalmanFilter(_RandomWalk(), noise)
    rng = np.random.default_rng(1)
    x, P = np.zeros(2), np.array([[1e6, 999e3], [999e3, 1e6]])
    for _ in range(200):
        x, P = ekf.predict(x, P, np.zeros(1), 0.01)
        result = ekf.update(x, P, np.zeros(1), rng.normal(0.0, 1e-6, 2))
        x, P = result.x, result.P
        assert np.array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0.0


def test_gate_rejects_a_twenty_sigma_sample_and_counts_it():
    ekf = _walk_filter()
    x, P = np.zeros(2), 0.01 * np.eye(2)
    sigma = math.sqrt(0.01 + 0.3**2)
    result = ekf.update(x, P, np.zeros(1), np.array([20.0 * sigma, 0.5 * sigma]))
    assert result.rejected.tolist() == [True, False]
    assert result.used.tolist() == [False, True] and result.dof == 1
    assert result.x[0] == 0.0 and result.x[1] != 0.0
    threshold = math.sqrt(chi2.ppf(0.9999, 1)) * sigma
    assert not ekf.update(x, P, np.zeros(1), np.array([0.99 * threshold, 0.0])).rejected.any()
    assert ekf.update(x, P, np.zeros(1), np.array([1.01 * threshold, 0.0])).rejected[0]
    open_gate = _walk_filter(gate=1.0)
    assert not open_gate.update(x, P, np.zeros(1), np.array([1e6, 0.0])).rejected.any()


def _walk_data(n=400, seed=2, q=0.2, r=0.3, dt=0.05):
    rng = np.random.default_rng(seed)
    truth = np.cumsum(rng.normal(0.0, math.sqrt(q * dt), (n, 2)), axis=0)
    offset = rng.uniform(-1, 1, (n, 1))
    y = truth + rng.normal(0.0, r, (n, 2))
    y[:, 0] += offset[:, 0]
    return np.arange(n) * dt, offset, y, truth


def test_run_filter_nis_and_nees_match_chi_square_statistics():
    ekf = _walk_filter()
    time, offsets, ys, truths = zip(*[_walk_data(seed=s) for s in range(40)], strict=True)
    run = run_filter(ekf, time[0], np.array(offsets), np.array(ys), truth=np.array(truths))
    nees = run.nees[:, 50:].mean(axis=1)
    nis = (run.nis[:, 50:] / run.dof[:, 50:]).mean(axis=1)
    low, high = chi2_bounds(2, 40)
    assert low <= nees.mean() <= high
    assert low / 2 <= nis.mean() <= high / 2
    assert run.state.shape == (40, 400, 2) and run.rejected.shape == (40, 2)
    assert run.rejected_by_group() == {"first": int(run.rejected[:, 0].sum()),
                                       "second": int(run.rejected[:, 1].sum())}


def test_nan_samples_are_skipped_and_counted():
    ekf = _walk_filter()
    time, offset, y, _ = _walk_data()
    y[100, 1] = np.nan
    offset[200, 0] = np.nan
    run = run_filter(ekf, time, offset, y, np.ones(y.shape, bool))
    assert np.all(np.isfinite(run.state))
    assert run.nan_measurements.tolist() == [0, 1]
    assert run.nan_inputs.tolist() == [1]
    assert run.dof[100] == 1 and not run.used[100, 1]
    bad = offset.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="first input"):
        run_filter(ekf, time, bad, y)


def test_batch_run_equals_single_runs_and_backends_agree():
    ekf = _walk_filter()
    data = [_walk_data(n=60, seed=s) for s in range(3)]
    batch = run_filter(ekf, data[0][0], np.array([d[1] for d in data]),
                       np.array([d[2] for d in data]))
    autodiff = ExtendedKalmanFilter(ekf.model, ekf.noise, backend="autodiff")
    for b, (time, offset, y, _) in enumerate(data):
        single = run_filter(ekf, time, offset, y)
        np.testing.assert_allclose(batch.state[b], single.state, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(batch.nis[b], single.nis, rtol=1e-12)
    reference = run_filter(autodiff, data[0][0], data[0][1], data[0][2])
    np.testing.assert_allclose(reference.state, batch.state[0], rtol=1e-12, atol=1e-14)


def test_noise_validation_names_the_field():
    model = _RandomWalk()
    good = dict(process_psd={"wa": 1.0, "wb": 1.0}, input_std={},
                measurement_std={"ya": 1.0, "yb": 1.0}, initial_std={"a": 1.0, "b": 1.0})
    EkfNoise(**good).validate(model)
    with pytest.raises(ValueError, match="measurement_std"):
        EkfNoise(**{**good, "measurement_std": {"ya": 1.0}}).validate(model)
    with pytest.raises(ValueError, match=r"process_psd\['wa'\]"):
        EkfNoise(**{**good, "process_psd": {"wa": -1.0, "wb": 1.0}}).validate(model)
    with pytest.raises(ValueError, match="input_std: unknown"):
        EkfNoise(**{**good, "input_std": {"nope": 1.0}}).validate(model)
    with pytest.raises(ValueError, match=r"initial_std\['a'\] must be positive"):
        EkfNoise(**{**good, "initial_std": {"a": 0.0, "b": 1.0}}).validate(model)
    with pytest.raises(ValueError, match="gate_probability"):
        ExtendedKalmanFilter(model, EkfNoise(**good), gate_probability=0.0)
    replaced = EkfNoise(**good).replace(process_psd={"wa": 3.0})
    assert replaced.process_psd == {"wa": 3.0, "wb": 1.0}


def test_wrap_angle_and_chi2_bounds():
    np.testing.assert_allclose(wrap_angle([3.5 * math.pi, -math.pi, 0.1]),
                               [-0.5 * math.pi, -math.pi, 0.1])
    low, high = chi2_bounds(3, 1)
    assert low == pytest.approx(chi2.ppf(0.025, 3)) and high == pytest.approx(chi2.ppf(0.975, 3))
    low20, high20 = chi2_bounds(3, 20)
    assert low < low20 < 3.0 < high20 < high
