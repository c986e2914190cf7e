"""Joining the samples of several flight segments."""

import dataclasses

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.samples.segments import concatenate_samples


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


def test_joined_segments_keep_every_thrust_term_one_of_them_was_identified_with(samples):
    n = len(samples)
    first = dataclasses.replace(samples.subset(np.arange(0, n // 3)),
                                thrust_correction_terms=("throttle_airspeed",))
    second = dataclasses.replace(samples.subset(np.arange(n // 2, n)),
                                 thrust_correction_terms=("throttle",))
    joined = concatenate_samples([first, second])
    assert joined.thrust_correction_terms == ("throttle", "throttle_airspeed")
    assert joined.subset(np.arange(10)).thrust_correction_terms == (
        "throttle", "throttle_airspeed")


def test_overlapping_segments_are_refused(samples):
    with pytest.raises(ValueError, match="overlap"):
        concatenate_samples([samples.subset(slice(0, 100)), samples.subset(slice(50, 150))])


def test_a_span_without_a_gps_fix_leaves_the_gps_out_of_every_span_with_a_note():
    """Two airborne spans, the GPS fixed only in the second: the joined samples hold no GPS
    (the effects that need it are not tested) and the selection says why."""
    from drake_uav.diagrams import fly
    from drake_uav.identification.pipeline import select_samples
    from drake_uav.vehicles import load_fixed_wing

    params = load_fixed_wing("aerosonde")
    log = fly(params, turbulence="light", seed=3, duration=60.0)
    log = log.select(log.measured_names)
    log.metadata["segments"] = [[0.0, 29.9], [30.1, float(log.time[-1])]]
    both, _ = select_samples(log, params)
    assert {"gps_vn", "gps_pn"} <= set(both.signals)
    gps = [n for n in log.measured_names if n.startswith("gps_")]
    early = log.time < 30.0
    no_fix = log.with_measured({n: np.where(early, 0.0, log[n]) for n in gps})
    samples, selection = select_samples(no_fix, params)
    assert not any(k.startswith("gps_") for k in samples.signals)
    assert not any(k.startswith("gps_") for k in samples.moment_view.signals)
    assert len(selection.spans) == 2
    note, = [n for n in selection.notes if n.startswith("left out")]
    assert "gps_vn" in note and "no GPS fix" in note
