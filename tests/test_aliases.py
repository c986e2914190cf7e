"""Aliases stated, not guessed: an accepted effect whose column this flight cannot tell apart
from a term of another physical origin is reported with that term and their correlation
(drake_uav.identification.discovery.aliases), and a finding without one stays a lone
finding."""

import dataclasses

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.assessment.families import families
from drake_uav.identification.discovery.aliases import (
    ALIAS_CORRELATION,
    CATALOG_ORIGIN,
    Term,
    aliases_of,
    partial_correlation,
)
from drake_uav.identification.discovery.effects import Effect
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.pipeline import identify_samples

SEEDS = (2, 3, 4)
"""Flights (multisine phases and sensor noise) each test runs on; none is tolerated to fail."""


def _curve(n=500, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    return t, rng


def test_a_term_of_another_origin_that_moves_with_the_effect_is_its_alias():
    t, rng = _curve()
    effect = np.sin(7.0 * t)
    near = (effect + 0.05 * rng.standard_normal(t.size))[:, None]
    terms = [Term("lookalike", "the vanes", near),
             Term("sibling", "flow separation", effect[:, None]),   # same origin: a variant
             Term("unrelated", "the ground", np.cos(31.0 * t)[:, None])]
    aliased = aliases_of("lift_break", "CL", "flow separation", 0.3 * effect,
                         {"CL_alpha": t}, terms)
    (alias,) = aliased.aliases
    assert (aliased.effect, aliased.coefficient, alias.name, alias.baseline) == (
        "lift_break", "CL", "lookalike", False)
    assert alias.correlation == pytest.approx(
        partial_correlation(effect, near, t[:, None])) and alias.correlation > 0.99
    assert aliases_of("lift_break", "CL", "flow separation", effect, {"CL_alpha": t},
                      [terms[2]]) is None


def test_a_catalog_term_the_model_left_out_is_compared_beyond_the_model():
    """The effect's column is a dropped catalog term's plus a little of its own: beyond the
    model (an intercept and CL_q), the two are one column; the alternative is the model with
    that term."""
    t, rng = _curve()
    alpha = np.sin(5.0 * t)
    column = alpha + 0.02 * rng.standard_normal(t.size)
    aliased = aliases_of("lift_break", "CL", "flow separation", column,
                         {"CL_q": np.cos(13.0 * t)},
                         [Term("CL_alpha", CATALOG_ORIGIN, alpha[:, None], baseline=True)])
    (alias,) = aliased.aliases
    assert alias.label == "the catalog's CL_alpha" and alias.correlation > ALIAS_CORRELATION


@pytest.fixture(scope="module", params=SEEDS)
def stall_flight(request):
    """A 40 s flight whose lift bends with alpha^3."""
    return synthetic_samples(increment=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0),
                             seed=request.param, duration=40.0)


def _cubic(origin):
    return Effect("lift_break", "the lift falls off with the cube of alpha", ("CL",),
                  lambda samples, params, k: {"alpha3": samples.condition.alpha**3},
                  origin=origin)


_VANE_BEND = Effect(
    "vane_bend", "the vane's calibration bends like the cube of alpha", ("CL",),
    lambda samples, params, k: {"alpha3": samples.condition.alpha**3
                                * (1.0 + samples.condition.alpha**2)}, kind="sensor",
    origin="the vanes")


def test_two_aliased_terms_of_different_origins_give_the_x_or_y_line(stall_flight):
    """The lift's cube and a vane calibration that bends like it differ by alpha^5 (under
    1 % at these angles): the flight cannot tell them apart, on every seed."""
    params, samples, _ = stall_flight
    result = discover(samples, params, effects=[_cubic("flow separation"), _VANE_BEND],
                      coefficients=("CL",), fallback=False, vector_effects=[])
    (found,) = result.found
    other = ({"lift_break", "vane_bend"} - {found.name}).pop()
    (aliased,) = result.aliases
    (alias,) = aliased.aliases
    assert (aliased.effect, aliased.coefficient, alias.name) == (found.name, "CL", other)
    assert alias.correlation > 0.99
    assert result.message == (f"missing effect(s) found: {found.name} or {other} (CL, |corr| "
                              f"{alias.correlation:.2f}: this flight cannot tell them apart)")
    (family,) = families(result)
    assert (family.name, family.member_names) == ("lift-axis family", (found.name, other))


def test_the_same_two_terms_of_one_origin_are_variants_not_aliases(stall_flight):
    params, samples, _ = stall_flight
    vane = dataclasses.replace(_VANE_BEND, origin="flow separation")
    result = discover(samples, params, effects=[_cubic("flow separation"), vane],
                      coefficients=("CL",), fallback=False, vector_effects=[])
    assert len(result.found) == 1 and result.aliases == ()
    assert result.message == f"missing effect(s) found: {result.found[0].name} (CL)"


def test_an_effect_no_term_moves_with_is_a_lone_finding(stall_flight):
    """The default library on the same flights: exactly the stall onset, no alias, no
    family, a plain summary line (no seed tolerated otherwise)."""
    params, samples, _ = stall_flight
    run = identify_samples(samples, params, source="synthetic")
    assert run.findings == ("stall_onset",)
    assert run.discovery.aliases == () and run.families == ()
    assert run.discovery.message == "missing effect(s) found: stall_onset (CL)"
    assert run.summary()["families"] == []
