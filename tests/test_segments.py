"""Joining the samples of several flight segments."""

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.segments import concatenate_samples


@pytest.fixture(scope="module")
def samples():
    return synthetic_samples(seed=5, duration=20.0)[1]


def test_joined_segments_equal_the_selected_samples(samples):
    n = len(samples)
    first, second = np.arange(0, n // 3), np.arange(n // 2, n)
    joined = concatenate_samples([samples.subset(second), samples.subset(first)])
    whole = samples.subset(np.concatenate([first, second]))
    np.testing.assert_array_equal(joined.time, whole.time)
    for a, b in zip(joined.condition, whole.condition, strict=True):
        np.testing.assert_array_equal(a, np.broadcast_to(b, whole.time.shape))
    for name in whole.coefficients:
        np.testing.assert_array_equal(joined.coefficients[name], whole.coefficients[name])
    np.testing.assert_array_equal(joined.specific_force, whole.specific_force)
    assert joined.noise_variance == pytest.approx(whole.noise_variance)
    assert (joined.moment_view is None) == (whole.moment_view is None)


def test_overlapping_segments_are_refused(samples):
    with pytest.raises(ValueError, match="overlap"):
        concatenate_samples([samples.subset(slice(0, 100)), samples.subset(slice(50, 150))])
