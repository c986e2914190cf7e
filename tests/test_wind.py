"""Dryden turbulence: discretisation, scales, spectra and variance, coupling to the plant."""

import math

import numpy as np
import pytest
from pydrake.common import RandomDistribution, RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, RandomSource
from scipy.linalg import expm
from scipy.signal import freqs, welch

from drake_uav.model.dryden import (
    TURBULENCE_LEVELS,
    WIND_HOLDS,
    dryden_gust,
    dryden_psd,
    dryden_scales,
    dryden_stationary_factor,
    dryden_transition,
)
from drake_uav.model.rotations import euler_to_quat, quat_to_rotmat
from drake_uav.systems.wind import DrydenFilter, DrydenParams, DrydenWind

FT = 0.3048


def _van_loan(a: float, dt: float):
    """Transition and noise covariance of the cascade by the matrix exponential."""
    A = np.array([[-a, 0.0], [1.0, -a]])
    B = np.array([[1.0], [0.0]])
    M = np.block([[-A, B @ B.T], [np.zeros((2, 2)), A.T]]) * dt
    E = expm(M)
    phi = E[2:, 2:].T
    return phi, phi @ E[:2, 2:]


@pytest.mark.parametrize("a", [1e-3, 0.05, 0.5, 8.0])
@pytest.mark.parametrize("dt", [0.005, 0.1])
def test_transition_is_exact(a, dt):
    phi, chol = dryden_transition(np.array([a]), dt)
    phi_ref, q_ref = _van_loan(a, dt)
    np.testing.assert_allclose(phi[0], phi_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(chol[0] @ chol[0].T, q_ref, rtol=1e-7, atol=1e-18)


@pytest.mark.parametrize("a", [0.01, 0.3, 5.0])
def test_stationary_covariance_solves_lyapunov(a):
    A = np.array([[-a, 0.0], [1.0, -a]])
    L = dryden_stationary_factor(a)
    P = L @ L.T
    np.testing.assert_allclose(A @ P + P @ A.T + np.diag([1.0, 0.0]), 0.0, atol=1e-9 / a**3)


def test_psd_matches_seed_filters_with_lv():
    """The PSD is |H|^2 / pi of eq. (2.11), H_v built with L_v (the seed prints L_u)."""
    scales = dryden_scales("moderate", 150.0)
    assert scales.length_u == scales.length_v  # MIL-F-8785C low altitude
    V = 23.0
    w = np.logspace(-2, 2, 200)
    L_u, L_v, L_w = scales.lengths
    s_u, s_v, s_w = scales.sigmas
    tfs = [
        ([s_u * math.sqrt(2 * V / L_u)], [1.0, V / L_u]),
        (s_v * math.sqrt(3 * V / L_v) * np.array([1.0, V / (math.sqrt(3) * L_v)]),
         np.polymul([1.0, V / L_v], [1.0, V / L_v])),
        (s_w * math.sqrt(3 * V / L_w) * np.array([1.0, V / (math.sqrt(3) * L_w)]),
         np.polymul([1.0, V / L_w], [1.0, V / L_w])),
    ]
    psd = dryden_psd(w, scales, V)
    for i, (num, den) in enumerate(tfs):
        _, h = freqs(num, den, w)
        np.testing.assert_allclose(psd[i], np.abs(h) ** 2 / np.pi, rtol=1e-10)
    # One-sided PSDs integrate to sigma^2.
    wide = np.logspace(-6, 6, 200001)
    var = np.trapezoid(dryden_psd(wide, scales, V), wide, axis=1)
    np.testing.assert_allclose(var, scales.sigmas**2, rtol=2e-3)


def test_mil_low_altitude_scales():
    h = 100.0
    s = dryden_scales("light", h)
    h_ft = h / FT
    assert s.length_w == pytest.approx(h)
    assert s.length_u == pytest.approx(h_ft / (0.177 + 0.000823 * h_ft) ** 1.2 * FT)
    sigma_w = 0.1 * 15 * 0.514444
    assert s.sigma_w == pytest.approx(sigma_w)
    assert s.sigma_u == pytest.approx(sigma_w / (0.177 + 0.000823 * h_ft) ** 0.4)
    # Intensities scale with W20 = 15, 30, 45 kt.
    ratios = [dryden_scales(level, h).sigma_w / sigma_w for level in TURBULENCE_LEVELS]
    np.testing.assert_allclose(ratios, [1.0, 2.0, 3.0])
    # The spec at 50 m gives the seed's low-altitude lengths (L_w = 50 m, L_u ~ 200 m).
    spec, seed = dryden_scales("light", 50.0), dryden_scales("light", 50.0, model="seed")
    assert spec.length_w == pytest.approx(seed.length_w, rel=1e-3)
    assert spec.length_u == pytest.approx(seed.length_u, rel=0.02)


def test_medium_altitude_and_transition_band():
    high = dryden_scales("moderate", 3000 * FT)
    np.testing.assert_allclose(high.lengths, 1750 * FT)
    # Probability-of-exceedance 1e-3 curve between 1750 and 3750 ft: 9.6 -> 10.6 ft/s.
    assert high.sigma_u == pytest.approx((9.6 + (3000 - 1750) / 2000 * 1.0) * FT)
    # Continuous across the 1000-2000 ft interpolation band.
    for edge in (1000 * FT, 2000 * FT):
        below, above = dryden_scales("severe", edge - 1e-6), dryden_scales("severe", edge + 1e-6)
        np.testing.assert_allclose(below.lengths, above.lengths, rtol=1e-6)
        np.testing.assert_allclose(below.sigmas, above.sigmas, rtol=1e-6)
    # The seed's 600 m row has the spec's medium-altitude length scale (533 m = 1750 ft).
    assert dryden_scales("light", 600.0, model="seed").length_w == pytest.approx(1750 * FT, 1e-3)


def test_seed_table_rows():
    low = dryden_scales("moderate", 50.0, model="seed")
    assert (low.length_u, low.length_v, low.length_w) == (200.0, 200.0, 50.0)
    assert (low.sigma_u, low.sigma_v, low.sigma_w) == (2.12, 2.12, 1.4)
    med = dryden_scales("light", 600.0, model="seed")
    assert (med.length_u, med.length_w, med.sigma_u, med.sigma_w) == (533.0, 533.0, 1.5, 1.5)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"level": "extreme"}, "level"),
        ({"model": "von-karman"}, "model"),
        ({"level": "severe", "model": "seed"}, "level"),
        ({"update_period": 0.0}, "update_period"),
        ({"airspeed": -3.0}, "airspeed"),
        ({"steady_wind_ned": (1.0, 2.0)}, "steady_wind_ned"),
        ({"min_airspeed": 0.0}, "min_airspeed"),
        ({"hold": "cubic"}, "hold"),
    ],
)
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ValueError, match=f"^{field}:"):
        DrydenParams(**kwargs).validate()
    with pytest.raises(ValueError, match=f"^{field}:"):
        DrydenWind(DrydenParams(**kwargs))


def _ensemble(level: str, airspeed: float, altitude: float, dt: float, steps: int,
              runs: int, seed: int) -> np.ndarray:
    """Gusts (runs, steps, 3) of independent realisations of the exact recursion."""
    rng = np.random.default_rng(seed)
    scales = dryden_scales(level, altitude)
    a = airspeed / scales.lengths
    phi, chol = dryden_transition(a, dt)
    z = np.einsum("kij,rkj->rki", dryden_stationary_factor(a), rng.standard_normal((runs, 3, 2)))
    out = np.empty((runs, steps, 3))
    for k in range(steps):
        z = np.einsum("kij,rkj->rki", phi, z) + np.einsum(
            "kij,rkj->rki", chol, rng.standard_normal((runs, 3, 2)))
        out[:, k] = dryden_gust(z, a, scales.sigmas)
    return out


def _log_average_ratio(x: np.ndarray, dt: float, scales, airspeed: float,
                       nperseg: int) -> np.ndarray:
    """exp(mean log(Welch / analytic)) per component over 0.1-10 rad/s; x (..., n, 3)."""
    f, p = welch(x, fs=1.0 / dt, nperseg=nperseg, axis=-2)
    p = p.reshape(-1, f.size, 3).mean(axis=0)
    omega = 2 * np.pi * f
    band = (omega >= 0.1) & (omega <= 10.0)
    # Analytic PSD of the sampled sequence: the continuous one plus its aliases.
    fold = 2 * np.pi / dt
    analytic = sum(dryden_psd(np.abs(omega[band] + m * fold), scales, airspeed)
                   for m in range(-3, 4))
    estimate = p[band].T / (2 * np.pi)
    return np.exp(np.mean(np.log(estimate / analytic), axis=1))


@pytest.mark.parametrize("level, altitude", [("light", 50.0), ("moderate", 450.0),
                                             ("severe", 1500.0)])
def test_long_run_psd_and_variance_of_exact_recursion(level, altitude):
    """160 runs of 820 s per level, at a low, a transition-band and a medium altitude."""
    airspeed, dt = 25.0, 0.05
    x = _ensemble(level, airspeed, altitude, dt, steps=2**14, runs=160, seed=7)
    scales = dryden_scales(level, altitude)
    ratio = _log_average_ratio(x, dt, scales, airspeed, nperseg=2**13)
    np.testing.assert_allclose(ratio, 1.0, atol=0.25)
    np.testing.assert_allclose(x.reshape(-1, 3).var(axis=0) / scales.sigmas**2, 1.0, atol=0.10)


def test_dryden_wind_system_long_run():
    """DrydenWind (its own RandomSource) over 6000 s: PSD, variance, steady wind."""
    level, airspeed, altitude, dt, duration = "moderate", 100.0, 50.0, 0.1, 6000.0
    steady = (3.0, -2.0, 0.5)
    builder = DiagramBuilder()
    wind = builder.AddSystem(DrydenWind(DrydenParams(
        level, airspeed=airspeed, altitude=altitude, update_period=dt, steady_wind_ned=steady)))
    gust_log = LogVectorOutput(wind.GetOutputPort("gust_body"), builder, dt)
    wind_log = LogVectorOutput(wind.GetOutputPort("wind_ned"), builder, dt)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(11))
    simulator.AdvanceTo(duration)
    gust = gust_log.FindLog(context).data()[:, 1:].T
    total = wind_log.FindLog(context).data()[:, 1:].T
    # No attitude input: NED = body, wind = steady + gust.
    np.testing.assert_allclose(total - gust, np.tile(steady, (len(total), 1)), atol=1e-12)
    scales = dryden_scales(level, altitude)
    ratio = _log_average_ratio(gust, dt, scales, airspeed, nperseg=2**11)
    np.testing.assert_allclose(ratio, 1.0, atol=0.25)
    np.testing.assert_allclose(gust.var(axis=0) / scales.sigmas**2, 1.0, atol=0.10)


@pytest.mark.parametrize("hold", WIND_HOLDS)
def test_hold_between_filter_samples(hold):
    """First-order hold: continuous, linear between the samples, one period late;
    zero-order hold: each sample held for a period."""
    dt, fine = 0.05, 5
    steady = np.array([2.0, -1.0, 0.0])
    builder = DiagramBuilder()
    wind = builder.AddSystem(DrydenWind(DrydenParams(
        "moderate", airspeed=20.0, altitude=80.0, update_period=dt, steady_wind_ned=steady,
        hold=hold)))
    wind_log = LogVectorOutput(wind.GetOutputPort("wind_ned"), builder, dt / fine)
    gust_log = LogVectorOutput(wind.GetOutputPort("gust_body"), builder, dt)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(5))
    simulator.AdvanceTo(2.0)
    context = simulator.get_context()
    # A sample drawn at t_k is logged from t_(k+1) (loggers publish before the updates).
    samples = steady + gust_log.FindLog(context).data()[:, 1:].T
    fine_wind = wind_log.FindLog(context).data().T[fine:]
    n = len(samples) - 1
    for j in range(fine):
        # Logged at t_(k+1) + j dt / fine, k = 0..n-1; sample k is W_k.
        rows = fine_wind[j::fine][:n]
        if hold == "first_order":  # W_k at t_(k+1), then straight on to W_(k+1)
            expected = samples[:n] + (j / fine) * (samples[1:n + 1] - samples[:n])
        else:  # W_k until the update at t_(k+1) replaces it
            expected = samples[:n] if j == 0 else samples[1:n + 1]
        np.testing.assert_allclose(rows, expected, atol=1e-9)
    jumps = np.abs(np.diff(fine_wind, axis=0)).max()
    assert (jumps < 0.5 * np.abs(np.diff(samples, axis=0)).max()) == (hold == "first_order")


@pytest.mark.parametrize("hold", WIND_HOLDS)
def test_wind_rate_is_the_slope_the_wind_follows(hold):
    """``wind_rate_ned`` is the derivative of ``wind_ned`` between the updates: the hold's
    slope for the first-order hold, zero for the steps of the zero-order hold."""
    dt, fine = 0.05, 5
    builder = DiagramBuilder()
    wind = builder.AddSystem(DrydenWind(DrydenParams(
        "moderate", airspeed=20.0, altitude=80.0, update_period=dt, hold=hold,
        update_offset=dt / 2)))
    wind_log = LogVectorOutput(wind.GetOutputPort("wind_ned"), builder, dt / fine)
    rate_log = LogVectorOutput(wind.GetOutputPort("wind_rate_ned"), builder, dt / fine)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(3))
    simulator.AdvanceTo(2.0)
    context = simulator.get_context()
    wind_ned = wind_log.FindLog(context).data().T
    rate = rate_log.FindLog(context).data().T
    # Samples at (k + 0.5 j / fine) dt ... the updates at (k + 1/2) dt: pairs within one
    # period between updates (j = 0 .. 1 and 3 .. 4 of each period).
    within = [i for i in range(len(wind_ned) - 1) if i % fine not in (fine // 2,)]
    slopes = np.diff(wind_ned, axis=0)[within] / (dt / fine)
    np.testing.assert_allclose(rate[within], slopes, atol=1e-6)
    assert (np.abs(rate).max() > 0.1) == (hold == "first_order")


def test_filter_reproduces_exact_recursion_and_is_seeded():
    params = DrydenParams("moderate", airspeed=20.0, altitude=80.0, update_period=0.02)
    builder = DiagramBuilder()
    noise = builder.AddSystem(RandomSource(RandomDistribution.kGaussian, 6, 0.02))
    dryden = builder.AddSystem(DrydenFilter(params))
    builder.Connect(noise.get_output_port(0), dryden.GetInputPort("noise"))
    noise_log = LogVectorOutput(noise.get_output_port(0), builder, 0.02)
    gust_log = LogVectorOutput(dryden.GetOutputPort("gust_body"), builder, 0.02)
    diagram = builder.Build()

    def run(seed):
        simulator = Simulator(diagram)
        context = simulator.get_mutable_context()
        diagram.SetRandomContext(context, RandomGenerator(seed))
        simulator.AdvanceTo(10.0)
        return noise_log.FindLog(context).data(), gust_log.FindLog(context).data()

    n, g = run(3)
    scales = dryden_scales("moderate", 80.0)
    a = 20.0 / scales.lengths
    phi, chol = dryden_transition(a, 0.02)
    # The noise source (an unrestricted update) draws at t_k before the filter's
    # discrete update at t_k reads it; both new values are logged at t_(k+1).
    z = np.einsum("kij,kj->ki", dryden_stationary_factor(a), n[:, 1].reshape(3, 2))
    np.testing.assert_allclose(g[:, 1], dryden_gust(z, a, scales.sigmas), rtol=1e-12)
    for k in range(1, n.shape[1] - 1):
        z = np.einsum("kij,kj->ki", phi, z) + np.einsum("kij,kj->ki", chol,
                                                           n[:, k + 1].reshape(3, 2))
        np.testing.assert_allclose(g[:, k + 1], dryden_gust(z, a, scales.sigmas), rtol=1e-9,
                                   atol=1e-12)
    assert np.array_equal(run(3)[1], g)
    assert not np.array_equal(run(4)[1], g)


def test_coupling_reads_airspeed_altitude_and_attitude():
    steady = np.array([5.0, 0.0, 0.0])
    params = DrydenParams("light", steady_wind_ned=tuple(steady))
    dryden = DrydenFilter(params)
    context = dryden.CreateDefaultContext()
    noise = np.array([0.3, -1.2, 0.8, 0.1, -0.5, 1.7])
    dryden.GetInputPort("noise").FixValue(context, noise)
    q = euler_to_quat([0.1, 0.05, math.pi / 2])
    state = np.concatenate([[0.0, 0.0, -120.0], q, [25.0, 1.0, 2.0], np.zeros(3)])
    dryden.GetInputPort("plant_state").FixValue(context, state)
    update = dryden.EvalUniquePeriodicDiscreteUpdate(context)
    context.get_mutable_discrete_state().SetFrom(update)
    gust = dryden.GetOutputPort("gust_body").Eval(context)
    wind = dryden.GetOutputPort("wind_ned").Eval(context)
    R = quat_to_rotmat(q)
    np.testing.assert_allclose(wind, steady + R @ gust, atol=1e-12)
    # First sample: stationary draw at V = |v - R^T W_steady| and h = -pD.
    airspeed = np.linalg.norm(state[7:10] - R.T @ steady)
    scales = dryden_scales("light", 120.0)
    a = airspeed / scales.lengths
    z = np.einsum("kij,kj->ki", dryden_stationary_factor(a), noise.reshape(3, 2))
    np.testing.assert_allclose(gust, dryden_gust(z, a, scales.sigmas), rtol=1e-12)


def test_diverged_plant_state_is_reported_not_divided_by():
    dryden = DrydenFilter(DrydenParams("light"))
    context = dryden.CreateDefaultContext()
    dryden.GetInputPort("noise").FixValue(context, np.zeros(6))
    state = np.concatenate([[0.0, 0.0, -100.0], [1.0, 0, 0, 0], [np.inf, 0.0, 0.0], np.zeros(3)])
    dryden.GetInputPort("plant_state").FixValue(context, state)
    with pytest.raises(RuntimeError, match="plant_state.*diverged"):
        dryden.EvalUniquePeriodicDiscreteUpdate(context)


def test_unconnected_state_with_free_airspeed_is_an_error():
    dryden = DrydenFilter(DrydenParams("light"))
    context = dryden.CreateDefaultContext()
    dryden.GetInputPort("noise").FixValue(context, np.zeros(6))
    with pytest.raises(RuntimeError, match="plant_state"):
        dryden.EvalUniquePeriodicDiscreteUpdate(context)
