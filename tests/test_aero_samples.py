"""The samples type: forces and moments on one time base without a copy of itself, and
the named signals typed."""

import dataclasses

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.samples.aero_samples import (
    ATTITUDE,
    AeroSamples,
    MomentInputs,
    Signal,
    logged,
)


@pytest.fixture(scope="module")
def samples():
    return synthetic_samples(seed=1, duration=20.0)[1]


def test_the_samples_type_does_not_hold_itself():
    assert all("AeroSamples" not in str(f.type) for f in dataclasses.fields(AeroSamples))
    assert all("AeroSamples" not in str(f.type) for f in dataclasses.fields(MomentInputs))


def test_the_moments_see_their_own_regressors(samples):
    assert samples.moments is not None
    view = samples.aligned("Cm")
    assert view is samples.aligned("Cl") is samples.moment_view  # built once
    assert samples.aligned("CL") is samples
    assert view.moments is None
    np.testing.assert_array_equal(view.condition.elevator, samples.moments.condition.elevator)
    np.testing.assert_array_equal(view.rate_derivatives, samples.moments.rate_derivatives)
    assert not np.array_equal(view.condition.elevator, samples.condition.elevator)


def test_every_transform_reaches_both_views(samples):
    up = samples.perturbed("airspeed", 0.1)
    np.testing.assert_allclose(up.condition.airspeed, samples.condition.airspeed + 0.1)
    np.testing.assert_allclose(up.aligned("Cm").condition.airspeed,
                               samples.moments.condition.airspeed + 0.1)
    np.testing.assert_allclose(up.aligned("Cm").dynamic_pressure,
                               samples.moments.dynamic_pressure
                               * ((samples.moments.condition.airspeed + 0.1)
                                  / samples.moments.condition.airspeed) ** 2)
    part = samples.subset(slice(0, 100))
    assert len(part) == len(part.aligned("Cm")) == 100
    np.testing.assert_array_equal(part.aligned("Cm").rate_derivatives,
                                  samples.moments.rate_derivatives[:100])


def test_signal_names_are_typed_and_still_strings(samples):
    assert tuple(ATTITUDE) == ("roll", "pitch", "yaw")
    assert all(isinstance(s, Signal) for s in ATTITUDE)
    assert Signal.ROLL in samples.signals and "roll" in samples.signals
    assert logged("tension") == "logged:tension"
