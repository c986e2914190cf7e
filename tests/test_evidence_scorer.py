"""One evidence rule for every kind of candidate: a per-coefficient effect, a vector effect,
a product of signals and a logged channel, each scored through ``evidence.score`` as the
discovery loop scores it."""

import dataclasses

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.discovery.coefficient_design import Perturbations, baseline_design
from drake_uav.identification.discovery.effects import effect_library, logged_effects
from drake_uav.identification.discovery.evidence import Candidate, round_base, score
from drake_uav.identification.discovery.loop import discover, product_candidate
from drake_uav.identification.discovery.result import EvidenceRule
from drake_uav.identification.discovery.vector_effects import vector_effect
from drake_uav.identification.statistics.blocked_folds import fold_edges

RULE = EvidenceRule()
STATISTICS = ("pse_reduction", "folds_improved", "f_statistic", "p_value", "delta_bic")


def _with_logged_channel(samples, rng):
    """The samples with a logged channel unrelated to the coefficients (a slow voltage)."""
    volts = 12.0 + np.cumsum(rng.normal(0.0, 0.01, len(samples)))

    samples = samples.with_moments(lambda m: dataclasses.replace(
        m, logged={**m.logged, "logged:voltage": volts},
        noise_variance={**m.noise_variance, "logged:voltage": 1e-6}))
    return dataclasses.replace(
        samples, signals={**samples.signals, "logged:voltage": volts},
        noise_variance={**samples.noise_variance, "logged:voltage": 1e-6},
        signal_units={**samples.signal_units, "logged:voltage": "V"})


def _context(samples, params, coefficients):
    """The loop's first-round designs on the training part, and the training samples."""
    n_train = int(round(len(samples) * (1.0 - RULE.holdout_fraction)))
    train = samples.subset(slice(0, n_train))
    edges = fold_edges(n_train, RULE.folds)
    return ({k: round_base(baseline_design(train, params, k), edges) for k in coefficients},
            Perturbations(train))


@pytest.fixture(scope="module")
def clean():
    params, samples, _ = synthetic_samples(seed=1)
    samples = _with_logged_channel(samples, np.random.default_rng(5))
    result = discover(samples, params, rule=RULE)
    return params, samples, result


def _named(name):
    return next(e for e in effect_library() if e.name == name)


def test_each_kind_of_candidate_scores_as_in_the_loop(clean):
    params, samples, result = clean
    bases, variants = _context(samples, params, result.final)
    first = {(e.effect, e.coefficient): e for e in result.rounds[0]}
    body_x = vector_effect("body_x", lever_arm=True)
    candidates = [_named("stall_onset").candidate(params),
                  body_x.candidate(params),
                  product_candidate(("alpha", "q_hat"), params),
                  next(e for e in logged_effects(samples)
                       if e.name == "logged:voltage").candidate(params)]
    assert [c.joint for c in candidates] == [False, True, False, False]
    for candidate in candidates:
        evidence = score(candidate, bases, variants, RULE, n_tests=len(first))
        assert evidence, candidate.name
        for e in evidence:
            loop = first[(e.effect, e.coefficient)]
            assert e.columns == loop.columns
            assert e.passed is loop.passed is False
            for name in STATISTICS:
                assert getattr(e, name) == pytest.approx(getattr(loop, name), rel=1e-9,
                                                         abs=1e-12), (e.effect, name)


def test_a_candidate_built_from_a_function_passes_where_its_effect_is():
    params, samples, _ = synthetic_samples(
        increment=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0), seed=2)
    bases, variants = _context(samples, params, ("CL", "CD"))
    cubic = Candidate("alpha_cubed", "the lift falls with the cube of alpha", ("CL", "CD"),
                      lambda s, k: {"alpha3": s.aligned(k).condition.alpha ** 3})
    evidence = {e.coefficient: e for e in score(cubic, bases, variants, RULE, n_tests=50)}
    assert evidence["CL"].passed
    assert evidence["CL"].folds_improved == RULE.folds
    assert not evidence["CD"].passed


def test_a_product_outside_the_library_is_refused():
    params, _, _ = synthetic_samples(seed=1, duration=10.0)
    with pytest.raises(ValueError, match="PRODUCT_KEYS"):
        product_candidate(("alpha", "nonsense"), params)
