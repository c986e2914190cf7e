"""A parsimonious baseline (identification.parsimony): the catalog's terms that the flight
does not support are dropped, the strongly excited ones never.

Flights: the aerosonde, whose catalog names C_L_q, C_D_q, C_D_elevator, C_Y_p, C_Y_r and
C_Y_aileron with the value 0, default sensors, light turbulence, 60 s, the measured channels
alone. Seeds 100-111 were looked at (docs/main_job.md, "Baseline"); seeds 0-2 are tested
here, 3-9 with ``-m slow``.
"""

import dataclasses
import functools

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.discovery.coefficient_design import baseline_names, fit_derivatives
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.discovery.parsimony import prune
from drake_uav.identification.pipeline import select_samples
from drake_uav.identification.statistics.blocked_folds import fold_edges
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.coefficients import COEFFICIENTS, regressor_matrix
from drake_uav.vehicles import aerosonde

ZERO = {"CL_q", "CD_q", "CD_elevator", "CY_p", "CY_r", "CY_aileron"}
"""Terms the catalog names with the value 0: the flown aircraft has none of them."""
WEAK = {"CD_alpha", "CD_alpha2", "Cn_p"}
"""True terms the flights barely tell apart from others (alpha stays within a few degrees:
C_D's slope and curvature are nearly one column) or from noise (C_n_p = 0.022)."""
SEEDS = [0, 1, 2] + [pytest.param(s, marks=pytest.mark.slow) for s in range(3, 10)]


@functools.cache
def _flight(seed):
    """(params, samples, discovery result) of one clean flight."""
    params = aerosonde().with_derivatives(CD_q=0.0, CD_elevator=0.0)
    log = fly(params, seed=seed, duration=60.0)
    names = log.measured_names
    log = FlightLog(log.time, {n: log[n] for n in names}, units={n: log.unit(n) for n in names})
    samples = select_samples(log, params)[0]
    return params, samples, discover(samples, params)


def _edge_error(samples, params, names) -> float:
    """RMS over the first and last fifths of the flight of the C_D fitted on the middle
    with the terms ``names`` minus the aircraft's own C_D at the same conditions [-]."""
    n = len(samples)
    middle = samples.subset(slice(n // 5, n - n // 5))
    structure = dataclasses.replace(params, derivatives={
        k: v for k, v in params.derivatives.items() if not k.startswith("CD_") or k in names})
    fit = fit_derivatives(middle, structure, ("CD",))["CD"]
    catalog = baseline_names(params, "CD")
    error = []
    for edge in (samples.subset(slice(0, n // 5)), samples.subset(slice(n - n // 5, n))):
        condition = edge.aligned("CD").condition
        error.append(regressor_matrix(fit.names, condition, params.b, params.c) @ fit.estimate
                     - regressor_matrix(catalog, condition, params.b, params.c)
                     @ np.array([params.derivatives[k] for k in catalog]))
    return float(np.sqrt(np.mean(np.concatenate(error) ** 2)))


@pytest.mark.parametrize("seed", SEEDS)
def test_drag_terms_the_aircraft_lacks_are_dropped_and_extrapolation_is_no_worse(seed):
    params, samples, result = _flight(seed)
    dropped = [t.term for t in result.dropped["CD"]]
    assert {"CD_q", "CD_elevator"} <= set(dropped), dropped
    assert [t for t in dropped if t not in ZERO] in ([], ["CD_alpha"], ["CD_alpha2"]), dropped
    kept = result.baseline["CD"].names
    assert set(kept) | set(dropped) == set(baseline_names(params, "CD"))
    # The pruned drag, fitted on the middle of the flight, extrapolates to its edges no
    # worse than the catalog's structure.
    assert _edge_error(samples, params, kept) <= _edge_error(
        samples, params, baseline_names(params, "CD"))
    # Each term dropped is 0 in the identified model and named in the notes.
    for k in COEFFICIENTS:
        assert not set(result.final[k].names) & {t.term for t in result.dropped.get(k, ())}
    assert [n for n in result.notes if " dropped: held-out error " in n] == [
        t.line for terms in result.dropped.values() for t in terms]


CY_P_KEPT = pytest.mark.xfail(strict=True, reason=(
    "CY_p (0 in the aircraft) is kept: without it the compensated fit's observed held-out "
    "error falls (0.00358 -> 0.00339, edges 0.00369 -> 0.00359), but the noise-corrected "
    "edges error credits the gyro noise its coefficient carries (+2.5 %, over the 2 %), and "
    "the least-squares fit gains 5 % on the folds and 4 % on the edges with it (p stands in "
    "for the noisy beta), so a rule asking both errors of the held-out check keeps it too"))


@pytest.mark.parametrize("seed", [0, 1, 2] + [
    pytest.param(s, marks=[pytest.mark.slow] + ([CY_P_KEPT] if s == 4 else []))
    for s in range(3, 10)])
def test_only_terms_the_flight_cannot_support_are_dropped(seed):
    params, _, result = _flight(seed)
    dropped = {t.term for terms in result.dropped.values() for t in terms}
    assert ZERO <= dropped and dropped <= ZERO | WEAK, sorted(dropped)
    assert not {"CD_alpha", "CD_alpha2"} <= dropped  # drag keeps its growth with alpha
    strong = set(params.derivatives) - ZERO - WEAK - {f"{k}_0" for k in COEFFICIENTS}
    for k in COEFFICIENTS:
        assert {n for n in strong if n.startswith(f"{k}_")} <= set(result.baseline[k].names)
    assert result.message == "no missing effect found"


def _design(seed, curvature):
    """A design [1, x, t^2, noise] over t in [-0.5, 0.5] with z = 2 + 3 x + curvature t^2
    + white noise of unit variance (100 000 samples)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(-0.5, 0.5, 100_000)
    x = rng.normal(size=t.size)
    X = np.column_stack([np.ones(t.size), x, t**2, rng.normal(size=t.size)])
    z = 2.0 + 3.0 * x + curvature * t**2 + rng.normal(size=t.size)
    return ["Z_0", "Z_x", "Z_t2", "Z_noise"], X, z, PropagatedNoise(4, {}, {}, {})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_term_that_only_the_edges_need_is_kept_and_the_constant_always(seed):
    """t^2 of this size lowers the folds' PSE by about 1.3 % (less than the 2 % a term must
    gain) and the edges' extrapolation error by about 3 %: it is kept, and goes once both
    ask for 5 %. A column of noise goes; the constant stays even when 0."""
    names, X, z, noise = _design(seed, 1.3)
    edges = fold_edges(len(z), 5)
    pruning = prune("Z", names, X, z, noise, edges, 0.02, always=("Z_0",))
    assert pruning.kept == ("Z_0", "Z_x", "Z_t2")
    assert [t.term for t in pruning.dropped] == ["Z_noise"]
    strict = prune("Z", names, X, z, noise, edges, 0.05, always=("Z_0",))
    assert strict.kept == ("Z_0", "Z_x")
    curvature = next(t for t in strict.dropped if t.term == "Z_t2")
    assert curvature.pse_gain < 0.02 <= curvature.edges_gain < 0.05
    assert curvature.edges_without > curvature.edges_with
    no_constant = prune("Z", names, X, z - 2.0, noise, edges, 0.02, always=("Z_0",))
    assert no_constant.kept == ("Z_0", "Z_x", "Z_t2")


def test_the_edge_check_needs_three_folds():
    names, X, z, noise = _design(0, 1.3)
    with pytest.raises(ValueError, match="at least 3"):
        prune("Z", names, X, z, noise, fold_edges(len(z), 2), 0.02)
