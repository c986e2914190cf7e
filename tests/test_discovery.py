"""The residual -> effect -> refit loop on synthetic flights (effects through the physics)."""

import numpy as np
import pytest
from synthetic_flight import measured_samples, synthetic_flight, synthetic_samples

from drake_uav.identification.assessment.reconstruction import reconstruct
from drake_uav.identification.discovery.coefficient_design import fit_derivatives
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.discovery.result import NO_EFFECT_MESSAGE


@pytest.fixture(scope="module")
def clean():
    return synthetic_samples(seed=1)


@pytest.fixture(scope="module")
def stall():
    return synthetic_samples(increment=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0), seed=2)


def test_no_effect_in_the_data_means_no_discovery(clean):
    params, samples, _ = clean
    result = discover(samples, params)
    assert result.message == NO_EFFECT_MESSAGE
    assert not result.found


def test_stall_onset_is_found_and_halves_the_lift_residual(stall):
    params, samples, _ = stall
    result = discover(samples, params)
    assert [f.name for f in result.found] == ["stall_onset"]
    assert result.found[0].coefficients == ("CL",)
    before, after = result.rms_change()["CL"]
    assert after <= 0.5 * before
    # The other coefficients are untouched: they keep their baseline fit.
    assert result.final["CL"] is not result.baseline["CL"]
    for k in ("CD", "CY", "Cl", "Cm", "Cn"):
        assert result.final[k] is result.baseline[k]
        assert result.rms_change()[k][0] == result.rms_change()[k][1]


def test_bias_compensation_recovers_the_true_lift_slope(clean):
    params, samples, _ = clean
    result = discover(samples, params)
    fit = result.baseline["CL"]
    index = fit.names.index("CL_alpha")
    estimate, sigma = fit.result.estimate[index], fit.result.sigma[index]
    assert abs(estimate - params.derivatives["CL_alpha"]) < 3 * sigma + 0.01


def test_fit_sigma_is_the_spread_of_the_estimates_over_noise_draws():
    """The smoothed coefficients' equation error is correlated over about the smoothing
    window: the reported sigma must still be the spread of the estimates over sensor-noise
    draws (the white-residual formula gave half of it), and the joint covariance must
    carry the correlation between coefficients that share sensors (C_l and C_n)."""
    params, truth = synthetic_flight(np.random.default_rng(3), duration=30.0)
    rng = np.random.default_rng(0)
    fits = [fit_derivatives(measured_samples(params, truth, rng), params, ("Cl", "Cn"))
            for _ in range(80)]
    estimates = np.array([f.estimate for f in fits])
    covariance = np.mean([f.covariance for f in fits], axis=0)
    sigma = np.sqrt(np.diag(covariance))
    # 80 draws: the spread is known to about 8 %; the bias to 11 % of a sigma.
    ratio = estimates.std(axis=0, ddof=1) / sigma
    names = fits[0].names
    assert np.all((ratio > 0.75) & (ratio < 1.3)), dict(zip(names, ratio.round(2), strict=True))
    truth_values = np.array([params.derivative(n) for n in names])
    bias = (estimates.mean(axis=0) - truth_values) / sigma
    assert np.all(np.abs(bias) < 0.5), dict(zip(names, bias.round(2), strict=True))
    correlation = covariance / np.outer(sigma, sigma)
    assert np.abs(np.corrcoef(estimates.T) - correlation).max() < 0.25
    assert np.abs(correlation[:6, 6:]).max() > 0.5  # C_l and C_n errors are coupled
    one = fits[0]
    np.testing.assert_allclose(one.covariance[:6, :6], one["Cl"].covariance)
    np.testing.assert_allclose(one.sigma[6:], one["Cn"].sigma)
    assert one.names == one["Cl"].names + one["Cn"].names


def test_reconstruction_is_better_with_the_true_model_than_with_a_wrong_one(clean):
    params, samples, truth = clean
    test = samples.subset(slice(len(samples) // 2, len(samples)))
    from drake_uav.identification.discovery.coefficient_design import baseline_names
    from drake_uav.model.coefficients import regressor_matrix

    def models(scale_lift_slope):
        out = {}
        for k in ("CL", "CD", "CY", "Cl", "Cm", "Cn"):
            names = baseline_names(params, k)
            theta = np.array([params.derivatives.get(n, 0.0) for n in names])
            if k == "CL":
                theta[names.index("CL_alpha")] *= scale_lift_slope
            out[k] = (tuple(names), theta,
                      regressor_matrix(names, test.condition, params.b, params.c))
        return out

    right = reconstruct(test, params, models(1.0))
    wrong = reconstruct(test, params, models(0.8))
    assert right.mae[1] < 0.5 * wrong.mae[1]
    assert right.mae[0] < 0.2 and np.degrees(right.mae[1]) < 0.2
    assert np.degrees(np.max(right.mae[3:])) < 0.5  # body rates [deg/s]


def test_the_servo_delay_column_lags_the_throttle_not_the_airspeed():
    """At a steady throttle a servo delay changes no thrust, however the thrust moves
    with the airspeed: the delay column's thrust part is zero."""
    import dataclasses

    from drake_uav.identification.discovery.effects import effect_library

    params, samples, _ = synthetic_samples(seed=3, duration=20.0, noise=False)
    throttle = np.full_like(samples.throttle, 0.6)
    thrust = params.propulsion.thrust_torque(samples.condition.airspeed, throttle,
                                             params.rho)[0]
    steady = dataclasses.replace(samples, throttle=throttle, thrust=thrust)
    delay = next(e for e in effect_library() if e.name == "actuator_time_delay")
    column = delay.columns(steady, params, "CD")["throttle_rate"]
    thrust_rate = np.gradient(thrust, samples.time) / (
        samples.dynamic_pressure * samples.reference_area)
    assert np.std(thrust_rate) > 0.0
    assert np.max(np.abs(column)) < 0.05 * np.std(thrust_rate)


def test_a_measured_servo_delay_shifts_the_commands_instead_of_differentiating_them():
    """With the delay the data-compatibility check measured, the thrust column is the drag
    the late throttle really adds (its parameter 1), to 5 %; the first-order column,
    the throttle's rate times the delay, misses a multisine that moves within 60 ms by
    over 20 %."""
    from drake_uav.identification.discovery.effects import effect_library
    from drake_uav.model.coefficients import body_to_lift_drag

    params, samples, _ = synthetic_samples(seed=3, duration=20.0, noise=False)
    delay, t = 0.06, samples.time
    late_throttle = np.interp(np.maximum(t - delay, t[0]), t, samples.throttle)
    real = params.propulsion.thrust_torque(samples.condition.airspeed, late_throttle,
                                           params.rho)[0]
    per_force = 1.0 / (samples.dynamic_pressure * samples.reference_area)
    drag = body_to_lift_drag((real - samples.thrust) * per_force, 0.0 * real,
                             samples.condition.alpha)[1]

    def column(library, name):
        effect = next(e for e in library if e.name == "actuator_time_delay")
        return effect.columns(samples, params, "CD")[name]

    shifted = column(effect_library(command_delay=delay), "throttle_delayed")
    first_order = delay * column(effect_library(), "throttle_rate")
    assert np.std(shifted - drag) < 0.05 * np.std(drag)
    assert np.std(first_order - drag) > 0.2 * np.std(drag)


def test_a_thrust_from_the_shaft_speed_has_no_servo_delay_column():
    """The shaft speed already follows the throttle as the motor did: a command delay puts
    no error on a thrust computed from it, so the delay has its surface columns only."""
    import dataclasses

    from drake_uav.identification.discovery.effects import effect_library

    params, samples, _ = synthetic_samples(seed=3, duration=20.0, noise=False)
    measured = dataclasses.replace(samples, thrust_from_shaft_speed=True)
    for delay in (None, 0.06):
        effect = next(e for e in effect_library(command_delay=delay)
                      if e.name == "actuator_time_delay")
        for coefficient in ("CL", "CD"):
            modelled = effect.columns(samples, params, coefficient)
            assert set(effect.columns(measured, params, coefficient)) == {
                name for name in modelled if not name.startswith("throttle_")}
            assert any(name.startswith("throttle_") for name in modelled)
