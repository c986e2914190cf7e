"""The residual -> effect -> refit loop on synthetic flights (effects through the physics)."""

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.discovery import NO_EFFECT_MESSAGE, discover
from drake_uav.identification.reconstruction import reconstruct


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
    # The other coefficients are untouched.
    for k in ("CD", "CY", "Cl", "Cm", "Cn"):
        assert result.rms_change()[k][0] == pytest.approx(result.rms_change()[k][1])


def test_bias_compensation_recovers_the_true_lift_slope(clean):
    params, samples, _ = clean
    result = discover(samples, params)
    fit = result.baseline["CL"]
    index = fit.names.index("CL_alpha")
    estimate, sigma = fit.result.estimate[index], fit.result.sigma[index]
    assert abs(estimate - params.derivatives["CL_alpha"]) < 3 * sigma + 0.01


def test_reconstruction_is_better_with_the_true_model_than_with_a_wrong_one(clean):
    params, samples, truth = clean
    test = samples.subset(slice(len(samples) // 2, len(samples)))
    from drake_uav.identification.discovery import baseline_names
    from drake_uav.systems.aerodynamics import regressor_matrix

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
