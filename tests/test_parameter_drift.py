"""A coefficient that drifts over the flight is tested as such: a drag coefficient growing
linearly in time, flown through the physics with the default sensors in light turbulence,
is found as ``coefficient_drift`` on C_D and nothing else; clean flights of the same seeds
give no finding."""

import functools

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.diagrams import fly
from drake_uav.identification.discovery.effects import DRIFT_TIME_SCALE, effect_library
from drake_uav.identification.pipeline import identify
from drake_uav.identification.samples.segments import concatenate_samples
from drake_uav.model.coefficients import body_to_lift_drag
from drake_uav.vehicles.fixed_wing import aerosonde

pytestmark = pytest.mark.filterwarnings("ignore:identify_thrust")  # thrust/C_X confounding

PARAMS = aerosonde()
DURATION = 60.0
CD_VARIATION = 0.00163
"""Standard deviation of the true C_D over a clean 60 s flight in light turbulence, from the
truth channels (CX, CZ, alpha) of tuning seed 100 (0.00163-0.00168 on seeds 100-102)."""
SHARE = 2.0
"""The drift's standard deviation over the flight as a multiple of CD_VARIATION: a total
rise of 0.011 (a fifth of C_D0) over the minute. On the 60 s tuning flights (seeds 100-111)
the drift was found exactly on 0, 2, 10 and 12 of 12 at 0.3, 1.0, 1.5 and 2.0 times
CD_VARIATION. At 0.3 (a rise of 0.0017) it is out of reach of the default accelerometers:
even over 120 s (C_D's per-sample noise 0.0056, about 750 effective samples) its expected
F statistic on the training part is about 3, against the 20 the family-wise level asks."""
RATE = SHARE * CD_VARIATION * np.sqrt(12.0) / DURATION
"""Growth of C_D [1/s]: a ramp's standard deviation is its total change over sqrt(12)."""


def _drift(condition, t):
    return (0.0, RATE * (t - DURATION / 2.0), 0.0, 0.0, 0.0, 0.0)


@functools.cache
def _flight(seed, drift=True):
    return fly(PARAMS, turbulence="light", seed=seed, duration=DURATION,
               disturbance=_drift if drift else None)


def _findings(log):
    return [(f.name, f.coefficients) for f in identify(log, PARAMS).discovery.found]


def test_the_drift_columns_are_one_function_of_the_log_time():
    """The training part and the held-out tail are built apart, and joined spans keep their
    gap: every part's columns are the whole flight's on its samples."""
    params, samples, _ = synthetic_samples(seed=0, duration=20.0, noise=False)
    effect = next(e for e in effect_library() if e.name == "coefficient_drift")
    keep = np.r_[0:400, 600:len(samples)]
    joined = concatenate_samples([samples.subset(slice(600, None)),
                                  samples.subset(slice(0, 400))])
    for coefficient, main in (("CD", "alpha"), ("Cn", "beta")):
        whole = effect.columns(samples, params, coefficient)
        np.testing.assert_array_equal(whole["drift"], samples.time / DRIFT_TIME_SCALE)
        np.testing.assert_array_equal(whole[f"drift_{main}"], whole["drift"] * getattr(
            samples.condition, main))
        for part, index in ((joined, keep), (samples.subset(slice(600, None)), keep[400:])):
            for name, values in effect.columns(part, params, coefficient).items():
                np.testing.assert_array_equal(values, whole[name][index])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_drifting_drag_coefficient_is_found_as_a_drift(seed):
    """Tuned on seeds 100-111 (60 s): found exactly, and nothing else, on all 12, its rate
    at the mean alpha 0.79-1.39 times the true one."""
    run = identify(_flight(seed), PARAMS)
    found = run.discovery.found
    assert [(f.name, f.coefficients) for f in found] == [("coefficient_drift", ("CD",))]
    assert not run.discovery.incomplete
    estimate = found[0].parameters
    rate = (estimate["CD:drift"][0] + estimate["CD:drift_alpha"][0]
            * np.mean(run.samples.condition.alpha)) / DRIFT_TIME_SCALE
    assert rate == pytest.approx(RATE, rel=0.5)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clean_flights_of_the_same_seeds_give_no_finding(seed):
    log = _flight(seed, drift=False)
    cd = body_to_lift_drag(log["CX"], log["CZ"], log["alpha"])[1]
    assert np.std(cd) == pytest.approx(CD_VARIATION, rel=0.1)  # the size the drift is set by
    assert _findings(log) == []


@pytest.mark.slow
def test_the_drift_on_seeds_3_to_9():
    """The tuning rate (60 s, seeds 100-111: 12 of 12 exact; clean seeds 100-139: no drift
    called on any of 40, no finding at all on 38) allows one miss in seven: at least six
    exact, and on the clean flights the drift never and at most one other finding."""
    seeds = range(3, 10)
    exact = [_findings(_flight(s)) == [("coefficient_drift", ("CD",))] for s in seeds]
    clean = [_findings(_flight(s, drift=False)) for s in seeds]
    assert sum(exact) >= 6, dict(zip(seeds, exact, strict=True))
    assert not any(name == "coefficient_drift" for found in clean for name, _ in found), clean
    assert sum(bool(found) for found in clean) <= 1, clean
