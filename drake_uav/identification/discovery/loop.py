"""Close the loop with measured data: residual -> missing effect -> updated model.

The loop (:func:`discover`):

1. fit the baseline structure (the aircraft's derivative names) to each
   measured coefficient on the training part of the flight, less the terms that
   improve neither its held-out prediction nor its extrapolation to the flight's
   edges (:mod:`~drake_uav.identification.discovery.parsimony`; each is 0 in the model,
   :attr:`DiscoveryResult.dropped`);
2. diagnose each residual (whiteness, spectrum, drift, correlation with the
   candidate columns: :mod:`drake_uav.identification.statistics.residuals`);
3. score every named effect of :mod:`drake_uav.identification.discovery.effects` on every
   coefficient it can enter, by evidence on data the fit did not see:
   blocked K-fold cross-validation (held-out prediction error, PSE), a partial
   F-test whose degrees of freedom use the residual's effective sample size
   (correlated residuals carry less information than their sample count), and
   the change in BIC;
4. accept the best candidate that passes every test of :class:`EvidenceRule`
   on the coefficients where the held-out tail agrees (its error falls, once the
   noise of sources only its columns carry is set aside, and so does the
   least-squares prediction's; its contribution matters: :class:`HeldOutCheck`),
   add its columns there, and repeat until nothing passes;
   when no named effect is kept, try the data-driven fallback (products of
   signals), which reports the signals involved (or, with
   :attr:`EvidenceRule.named_first` off, both in one pool);
5. check every effect against each coefficient's final fit under the same
   held-out rules, drop those it does not need, judge the terms step 1 dropped again
   beside the effects kept (a term an effect drowned comes back), refit, and report the
   equation-error RMS before and after on the held-out tail of the flight;
6. hold each final fit's error against its noise floor: where the sensor noise
   does not explain it, the model is incomplete there, and the result says where
   (:mod:`~drake_uav.identification.discovery.adequacy`, :attr:`DiscoveryResult.incomplete`).

Coefficients that do not vary in the samples (a purely longitudinal flight's
lateral ones) are skipped with a note (:attr:`DiscoveryResult.skipped`).

Every fit is errors-in-variables corrected. The air data (airspeed, alpha,
beta), the gyros and the signals differentiated from them (alpha-dot, the angular
accelerations) are noisy and enter the measured coefficients and the regressors;
ordinary least squares then attenuates the derivatives (Vaiopoulos 2017, Table 5) and
leaves a systematic residual that any column correlated with them would "explain".
The noise variances estimated by the isolation, carried through its filters
(:mod:`~drake_uav.identification.samples.regressor_noise`), are propagated
to every column and to the observation by finite-difference Jacobians
(:class:`~drake_uav.identification.statistics.errors_in_variables.PropagatedNoise`), and the
normal equations are corrected by the expected noise moments: bias-compensated
least squares (:func:`~drake_uav.identification.statistics.regression.bcls`), the moment form
of GTLS (Vaiopoulos 2017, eq. 4.54-4.63) for noise that differs from sample to sample.

The rule is strict on purpose: it must not invent effects. With no effect in
the data it answers "no missing effect found"; with an error the noise does not
explain and no candidate that does, "the model is incomplete for C_D: ...".
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping, Sequence
from typing import NamedTuple

import numpy as np

from drake_uav.identification.discovery.adequacy import Adequacy, AdequacyRule, assess
from drake_uav.identification.discovery.aliases import (
    CATALOG_ORIGIN,
    AliasedEffect,
    Term,
    aliases_of,
)
from drake_uav.identification.discovery.coefficient_design import (
    ColumnFunction,
    Design,
    Perturbations,
    baseline_design,
    baseline_names,
    columns_and_jacobians,
)
from drake_uav.identification.discovery.effects import (
    PRODUCT_KEYS,
    Effect,
    base_signals,
    effect_library,
    logged_effects,
    product_candidates,
)
from drake_uav.identification.discovery.evidence import (
    Candidate,
    CandidateColumns,
    RoundBase,
    redundant,
    round_base,
    score_together,
)
from drake_uav.identification.discovery.parsimony import Pruning, prune
from drake_uav.identification.discovery.plausibility import implausible_derivatives
from drake_uav.identification.discovery.result import (
    CoefficientFit,
    DiscoveryResult,
    Evidence,
    EvidenceRule,
    FoundEffect,
    HeldOutCheck,
)
from drake_uav.identification.discovery.vector_effects import (
    JointSearch,
    VectorEffect,
    vector_effect_library,
)
from drake_uav.identification.propulsion import THRUST_COLUMN
from drake_uav.identification.samples.aero_samples import LOGGED, AeroSamples
from drake_uav.identification.samples.regressor_noise import noise_variance_per_sample
from drake_uav.identification.statistics.blocked_folds import (
    fold_edges,
)
from drake_uav.identification.statistics.errors_in_variables import (
    PropagatedNoise,
    noise_error_energy,
    solve_normal_equations,
)
from drake_uav.identification.statistics.residuals import diagnose
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["discover", "check_coefficients", "product_candidate", "DATA_DRIVEN"]

DATA_DRIVEN = "data_driven:"
"""Name prefix of the data-driven product effects."""


def _score_named(pairs: Sequence[tuple[Effect, str]], bases: Mapping[str, RoundBase],
                 pool: _Candidates, rule: EvidenceRule, n_tests: int) -> list[Evidence]:
    """The evidence for each named effect on each coefficient of ``pairs``, in that order
    (an effect none of whose columns is new to the design is left out). The candidates of
    one coefficient with as many columns are scored together."""
    groups: dict[tuple[str, int], list[tuple[int, str, CandidateColumns]]] = {}
    for index, (effect, k) in enumerate(pairs):
        candidate = pool.named(effect, k, bases[k].design.noise.variance)
        spanned = redundant(bases[k].basis, np.column_stack(list(candidate.columns.values())))
        columns = [c for c, r in zip(candidate.columns, spanned, strict=True) if not r]
        if columns:
            groups.setdefault((k, len(columns)), []).append(
                (index, effect.name, candidate.pick(columns)))
    blind = {effect.name: effect.blind_folds for effect, _ in pairs}
    scored = {}
    for (k, q), members in groups.items():
        shape = (len(bases[k].design.z), q)
        candidates = [c for _, _, c in members]
        X_new = np.stack([_stacked(c.columns, c.columns, shape) for c in candidates], axis=1)
        J_new = {s: np.stack([_stacked(c.jacobians.get(s), c.columns, shape)
                              for c in candidates], axis=1)
                 for s in dict.fromkeys(s for c in candidates for s in c.jacobians)}
        evidence = score_together([name for _, name, _ in members],
                                [tuple(c.columns) for c in candidates], k, bases[k], X_new,
                                J_new, rule, n_tests,
                                np.array([blind[name] for _, name, _ in members]))
        scored.update((index, ev) for (index, _, _), ev in zip(members, evidence, strict=True)
                      if ev is not None)
    return [scored[i] for i in sorted(scored)]


def _stacked(values: Mapping[str, np.ndarray] | None, names, shape) -> np.ndarray:
    """The columns ``names`` of ``values`` as one array of ``shape`` (None: zeros)."""
    return np.zeros(shape) if values is None else np.column_stack([values[c] for c in names])


def _fit(coefficient: str, train: Design, test: Design, rate: float) -> CoefficientFit:
    result = train.result()
    residual_test = test.z - test.X @ result.estimate
    return CoefficientFit(
        coefficient=coefficient, names=tuple(train.names), result=result,
        rms_train=float(np.sqrt(np.mean(result.residual**2))),
        rms_holdout=float(np.sqrt(np.mean(residual_test**2))),
        holdout_residual=residual_test, holdout_design=test.X,
        diagnosis=diagnose(result.residual, rate),
        holdout_noise=test.noise, training_design=train.X,
    )


def _effect_function(effect: Effect, params: FixedWingParams, coefficient: str):
    return lambda smp: effect.columns(smp.aligned(coefficient), params, coefficient)


def _product_function(params: FixedWingParams, coefficient: str,
                      names: Sequence[str] | None = None):
    def products(smp):
        out = {_product_name(k): v for k, v in
               product_candidates(smp.aligned(coefficient), params).items()}
        return out if names is None else {k: out[k] for k in names}
    return products


def _product_rule(x: np.ndarray, jacobian: np.ndarray, a: np.ndarray, b: np.ndarray
                  ) -> np.ndarray:
    """(m, N) sensitivities of the products ``x[a] * x[b]`` of the signals ``x`` (n, N)
    whose sensitivities are ``jacobian`` (n, N): ``j_a x_b + x_a j_b``, computed only
    where a factor depends on the source (most depend on one or two of them)."""
    out = np.zeros((len(a), x.shape[1]))
    depends = np.any(jacobian != 0.0, axis=1)
    for first, second in ((a, b), (b, a)):
        rows = np.flatnonzero(depends[first])
        out[rows] += jacobian[first[rows]] * x[second[rows]]
    return out


def _product_name(signals: tuple[str, ...]) -> str:
    return "*".join(signals)


_PRODUCT_NAMES = tuple(_product_name(k) for k in PRODUCT_KEYS)
_PRODUCT_INDEX = {n: i for i, n in enumerate(_PRODUCT_NAMES)}


class _Candidates:
    """Candidate columns on the training samples, each computed once per discovery.

    The samples do not change between rounds, only the designs the columns extend; the
    data-driven products of one coefficient are computed together.
    """

    def __init__(self, train: AeroSamples, params: FixedWingParams):
        self.variants = Perturbations(train)
        self.params = params
        self._cache: dict[tuple[str, str], CandidateColumns] = {}
        self._matrices: dict[tuple[str, str], tuple[np.ndarray, dict[str, np.ndarray]]] = {}

    def _get(self, key: tuple[str, str], function: ColumnFunction, variance) -> CandidateColumns:
        if key not in self._cache:
            self._cache[key] = CandidateColumns(*columns_and_jacobians(function, self.variants,
                                                                variance))
        return self._cache[key]

    def named(self, effect: Effect, coefficient: str, variance) -> CandidateColumns:
        """The columns of ``effect`` for ``coefficient``."""
        return self._get((effect.name, coefficient),
                         _effect_function(effect, self.params, coefficient), variance)

    @staticmethod
    def product_names(used: set[str]) -> list[str]:
        """The data-driven products not tried yet."""
        return [n for n in _PRODUCT_NAMES if f"{DATA_DRIVEN}{n}" not in used]

    def product_matrix(self, coefficient: str, variance
                       ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every data-driven product column for ``coefficient`` as one (N, m) array in
        :data:`PRODUCT_KEYS` order, and their sensitivities to each source (N, m), by the
        product rule on the base signals' sensitivities."""
        key = (DATA_DRIVEN, coefficient)
        if key not in self._matrices:
            base = self._get(("base_signals", coefficient), lambda smp: base_signals(
                smp.aligned(coefficient), self.params), variance)
            # Rows are signals here (gathers of contiguous rows); the results are transposed.
            x = np.stack(list(base.columns.values()))
            names = list(base.columns)
            a, b = (np.array([names.index(k[i]) for k in PRODUCT_KEYS]) for i in (0, 1))
            self._matrices[key] = ((x[a] * x[b]).T, {
                s: _product_rule(x, np.stack([j[n] for n in names]), a, b).T
                for s, j in base.jacobians.items()})
        return self._matrices[key]

    def products(self, coefficient: str, variance) -> CandidateColumns:
        """The columns of :meth:`product_matrix` by name."""
        columns, jacobians = self.product_matrix(coefficient, variance)
        return CandidateColumns({n: columns[:, i] for i, n in enumerate(_PRODUCT_NAMES)},
                        {s: {n: j[:, i] for i, n in enumerate(_PRODUCT_NAMES)}
                         for s, j in jacobians.items()})


def discover(samples: AeroSamples, params: FixedWingParams,
             effects: Sequence[Effect] | None = None, rule: EvidenceRule | None = None,
             coefficients: Sequence[str] = COEFFICIENTS, fallback: bool = True,
             progress=None, vector_effects: Sequence[VectorEffect] | None = None,
             untested: Collection[str] = (),
             fixed: Mapping[str, float] | None = None) -> DiscoveryResult:
    """Runs the residual -> effect -> refit loop on ``samples`` (module docstring).

    The loop's stages (baseline and pruning, rounds, final check, final fits, adequacy)
    read one after the other here, in about 60 lines, so that its order is seen at once;
    the nine parameters are the loop's inputs and switches, each with its default.

    Parameters
    ----------
    samples : AeroSamples
        The measured coefficients and their regressors.
    params : FixedWingParams
        The aircraft's catalog model (its derivative names are the baseline).
    effects : sequence of Effect, optional
        The named effects (None: :func:`effect_library`).
    rule : EvidenceRule, optional
        The thresholds (None: the defaults).
    coefficients : sequence of str
        Fitted in the order of :data:`~drake_uav.model.coefficients.COEFFICIENTS`, except
        those that do not vary (:attr:`DiscoveryResult.skipped`).
    fallback : bool
        Try the data-driven products and logged channels when no named effect passes.
    progress : callable, optional
        Called with one line at each round.
    vector_effects : sequence of VectorEffect, optional
        The forces tested jointly on the coefficients they move (None:
        :func:`~drake_uav.identification.discovery.vector_effects.vector_effect_library`).
    untested : collection of str
        Candidates not to test, by name (named effects, ``data_driven:<a>*<b>`` products,
        vector effects): those the data cannot support (a log's rates,
        :mod:`~drake_uav.identification.assessment.logged_rates`).
    fixed : Mapping[str, float], optional
        Catalog terms fixed at the given values instead of fitted
        (:meth:`~drake_uav.identification.discovery.coefficient_design.Design.with_fixed`):
        those the data cannot support (a derivative needing a faster log). They are
        neither fitted nor pruned, and stay in the identified model at these values
        (:attr:`DiscoveryResult.fixed`).

    Returns
    -------
    DiscoveryResult

    Raises
    ------
    ValueError
        For an unknown coefficient, samples too few for the evidence tests, or when no
        coefficient varies.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CL", "CD"))
    >>> result.message
    'missing effect(s) found: thrust_propwash (CD)'
    """
    rule = rule or EvidenceRule()
    effects = [e for e in (effects or effect_library()) if e.available(samples)]
    effects += logged_effects(samples)  # data-driven: scored with the products
    n = len(samples)
    n_train = int(round(n * (1.0 - rule.holdout_fraction)))
    if n_train < 20 * rule.folds or n - n_train < 20:
        raise ValueError(f"discover: {n} samples are too few for the evidence tests")
    skipped = _constant_coefficients(samples, coefficients, n_train, rule)
    fitted = [k for k in COEFFICIENTS if k in coefficients and k not in skipped]
    if not fitted:
        raise ValueError(f"discover: none of {', '.join(skipped)} varies in the samples: "
                         "nothing to identify")
    rate = 1.0 / float(np.median(np.diff(samples.time)))
    train = samples.subset(slice(0, n_train))
    test = samples.subset(slice(n_train, n))
    edges = fold_edges(n_train, rule.folds)
    fixed = dict(fixed or {})
    designs = {k: baseline_design(train, params, k).with_fixed(fixed) for k in fitted}
    pruned = {k: prune(k, d.names, d.X, d.z, d.noise, edges, rule.min_pse_reduction,
                       always=(f"{k}_0", *(n for n in d.names if n.startswith(THRUST_COLUMN))))
              if rule.parsimonious else Pruning(tuple(d.names), ())
              for k, d in designs.items()}
    # Effects are judged against the catalog's whole structure, so that none takes the
    # place of a term the flight hardly supports; the model reported is the pruned one.
    search = _Search(designs, {k: baseline_design(test, params, k).with_fixed(fixed)
                               for k in fitted},
                     _Candidates(train, params), Perturbations(test), effects, rule,
                     {k: float(np.std(samples.coefficients[k])) for k in fitted})
    baseline = {k: _fit(k, search.designs[k].keeping(pruned[k].kept),
                        search.tests[k].keeping(pruned[k].kept), rate) for k in fitted}
    initial = {k: (search.designs[k], search.tests[k]) for k in fitted}
    vectors = JointSearch(vector_effect_library() if vector_effects is None else vector_effects,
                          samples)

    found: list[FoundEffect] = []
    rounds: list[tuple[Evidence, ...]] = []
    used: set[str] = set(untested)  # never tried: as if tried already
    for round_index in range(rule.max_rounds):
        if progress:
            progress(f"discovery round {round_index + 1}: scoring candidate effects")
        bases = {k: round_base(search.designs[k], edges) for k in fitted}
        evidence, new = _round(search, bases, used, fallback, vectors)
        evidence.sort(key=lambda e: (not e.passed, -e.pse_reduction))
        rounds.append(tuple(evidence))
        if new is None:
            break
        found.append(new)

    unchanged = {k for k in fitted if search.designs[k] is initial[k][0]
                 and search.tests[k] is initial[k][1]}
    whole = {k: (search.designs[k], search.tests[k]) for k in fitted}
    for k in fitted:
        dropped = {t.term for t in pruned[k].dropped}
        if dropped:
            search.designs[k], search.tests[k] = (
                d.keeping([n for n in d.names if n not in dropped])
                for d in (search.designs[k], search.tests[k]))
    # The effects must also hold against the model reported, without the pruned terms.
    found = search.final_check(found)
    # Then the pruned terms are judged again beside the effects kept: a term an unmodelled
    # effect drowned in the baseline comes back once the effect is in the model.
    for k in fitted:
        if pruned[k].dropped and any(k in f.coefficients for f in found):
            pruned[k] = _dropped_again(k, pruned[k], search, whole[k], edges,
                                       rule.min_pse_reduction)
    # A coefficient whose designs the loop left as they were keeps its baseline fit.
    final = {k: baseline[k] if k in unchanged
             else _fit(k, search.designs[k], search.tests[k], rate) for k in fitted}
    fitted_as = [_with_parameters(f, final) for f in found]
    found = vectors.with_parameters(search, fitted_as)
    adequacy = {k: _adequacy(final[k], (train, search.designs[k]), (test, search.tests[k]),
                             params, search.scales[k], rule.adequacy) for k in fitted}
    return DiscoveryResult(baseline=baseline, final=final, found=tuple(found),
                           rounds=tuple(rounds), holdout_start=float(test.time[0]),
                           checks=tuple(search.checks), skipped=skipped, adequacy=adequacy,
                           dropped={k: p.dropped for k, p in pruned.items() if p.dropped},
                           fixed={k: f for k in fitted
                                  if (f := {n: fixed[n] for n in baseline_names(params, k)
                                            if n in fixed})},
                           aliases=_aliases(search, vectors, fitted_as, found, final,
                                            {k: d for k, (d, _) in initial.items()}, pruned))


def _dropped_again(coefficient: str, pruned: Pruning, search: _Search,
                   whole: tuple[Design, Design], edges: Sequence[int],
                   min_gain: float) -> Pruning:
    """The catalog terms the baseline dropped, judged again by the same rule
    (:func:`~drake_uav.identification.discovery.parsimony.prune`) on the model that holds
    the effects kept: a term an unmodelled effect drowned (a tether's pitching moment hiding
    C_m_q) comes back, no other term goes. ``whole`` is the training and held-out design
    with every catalog term; ``search``'s designs of ``coefficient`` gain the terms
    restored."""
    dropped = {t.term for t in pruned.dropped}
    train, test = (d.keeping([*search_design.names, *dropped]) for d, search_design in
                   zip(whole, (search.designs[coefficient], search.tests[coefficient]),
                       strict=True))
    again = prune(coefficient, train.names, train.X, train.z, train.noise, edges, min_gain,
                  always=[n for n in train.names if n not in dropped])
    gone = {t.term for t in again.dropped}
    if gone == dropped:
        return pruned
    search.designs[coefficient], search.tests[coefficient] = (
        d.keeping([n for n in d.names if n not in gone]) for d in (train, test))
    return Pruning(tuple(n for n in train.names if n in pruned.kept or n in dropped - gone),
                   again.dropped)


def _aliases(search: _Search, vectors: JointSearch, fitted_as: Sequence[FoundEffect],
             found: Sequence[FoundEffect], final: Mapping[str, CoefficientFit],
             catalog: Mapping[str, Design], pruned: Mapping[str, Pruning]
             ) -> tuple[AliasedEffect, ...]:
    """Each accepted effect's aliases on each coefficient it is kept on
    (:mod:`~drake_uav.identification.discovery.aliases`), on the training part, among the
    terms the final model does not hold: the candidates not accepted and the catalog terms
    dropped (their columns from the ``catalog``'s whole structure). ``fitted_as``: the
    findings under the names their columns carry in the fits, ``found`` the same as
    reported (a force towards a far point is reported as a fixed direction,
    :func:`~drake_uav.identification.discovery.vector_effects.far_point_as_direction`)."""
    origins = {e.name: e.physical_origin for e in (*search.effects, *vectors.effects)}
    out = []
    for fitted, f in zip(fitted_as, found, strict=True):
        for k in f.coefficients:
            fit = final[k]
            model = dict(zip(fit.names, fit.training_design.T, strict=True))
            column = sum(model.pop(n) * fit.result.estimate[i]
                         for i, n in enumerate(fit.names) if n.startswith(f"{fitted.name}:"))
            dropped = [Term(t.term, CATALOG_ORIGIN,
                            catalog[k].X[:, [catalog[k].names.index(t.term)]], baseline=True)
                       for t in pruned[k].dropped]
            aliased = aliases_of(f.name, k, origins.get(fitted.name, fitted.name), column,
                                 model, dropped + _candidate_terms(search, vectors, k,
                                                                   fitted_as))
            if aliased is not None:
                out.append(aliased)
    return tuple(out)


def _candidate_terms(search: _Search, vectors: JointSearch, k: str,
                     found: Sequence[FoundEffect]) -> list[Term]:
    """The named and vector effects on coefficient ``k`` not accepted (a force towards a
    point the data locate aside: its direction is only known where it was accepted)."""
    accepted = {f.name for f in found}
    terms = []
    for effect in (e for e in search.effects if k in e.coefficients and e.name not in accepted):
        columns = search.pool.named(effect, k, search.designs[k].noise.variance).columns
        terms.append(Term(effect.name, effect.physical_origin,
                          np.column_stack(list(columns.values()))))
    for effect in (e for e in vectors.effects if not e.fitted and e.name not in accepted):
        columns = vectors.training_columns(search, effect, k)
        if columns:
            terms.append(Term(effect.name, effect.physical_origin,
                              np.column_stack(list(columns.values()))))
    return terms


def _adequacy(fit: CoefficientFit, train: tuple[AeroSamples, Design],
              test: tuple[AeroSamples, Design], params: FixedWingParams, scale: float,
              rule: AdequacyRule) -> Adequacy:
    """The final fit's error against its noise floor on the training part and the
    held-out tail (:func:`~drake_uav.identification.discovery.adequacy.assess`)."""
    k, theta = fit.coefficient, fit.result.estimate
    parts = []
    for (samples, design), residual in ((train, fit.result.residual),
                                        (test, fit.holdout_residual)):
        variance = noise_variance_per_sample(samples, k, params, design.noise, theta)
        parts.append((samples.time, residual,
                      np.sum(list(variance.values()), axis=0) + np.zeros(len(samples))))
    signals = {}
    for view in (train[0].aligned(k), test[0].aligned(k)):
        logged = {**{name: np.broadcast_to(value, view.time.shape)
                     for name, value in view.condition._asdict().items()},
                  "throttle": view.throttle, **view.signals}
        for name, value in logged.items():
            signals.setdefault(name, []).append(value)
    return assess(k, parts[0], parts[1], {n: np.concatenate(v) for n, v in signals.items()},
                  scale, rule)


def _round(search: _Search, bases: Mapping[str, RoundBase], used: set[str],
           fallback: bool, vectors: JointSearch) -> tuple[list[Evidence], FoundEffect | None]:
    """One round of the loop: the evidence of every candidate scored and the effect
    accepted (None: nothing passed and was kept).

    Named effects first (:attr:`EvidenceRule.named_first`): the data-driven products are
    scored only when no named effect is kept, each family at its own family-wise level.
    Otherwise both form one pool at one level over all of them. The vector effects are
    named effects with one joint test each (:meth:`JointSearch.accept` says which goes
    first); their evidence is listed per coefficient, after the others. A passing force
    proportional to a logged channel brings the channel itself (``logged:<channel>``, at
    the logged channels' level) into the named pool, its rival.
    """
    rule, pool = search.rule, search.pool
    pairs = [(e, k) for e in search.effects if e.name not in used for k in e.coefficients
             if k in bases]
    logged = [p for p in pairs if p[0].name.startswith(LOGGED)] if fallback else []
    pairs = [p for p in pairs if not p[0].name.startswith(LOGGED)]
    products = pool.product_names(used) if fallback else []
    n_products = len(products) * len(bases) + len(logged)
    n_named = (len(pairs) + len(vectors.candidates(used))
               + (0 if rule.named_first else n_products))
    evidence = _score_named(pairs, bases, pool, rule, n_named)
    if not rule.named_first:
        evidence += _score_data_driven(bases, pool, rule, products, logged, n_named)
    joint = vectors.score(search, bases, rule, n_named, used)
    # A force proportional to a logged channel competes with the channel itself.
    channels = {j.effect.magnitude for j in joint if j.passed and j.effect.magnitude}
    rivals = [p for p in logged if p[0].name in channels]
    if rivals:
        logged = [p for p in logged if p not in rivals]
        evidence += _score_named(rivals, bases, pool, rule, len(rivals) + len(logged))
    new = vectors.accept(search, joint, evidence, used, search.accept_best)
    if new is None and (products or logged) and rule.named_first:
        evidence += _score_data_driven(bases, pool, rule, products, logged)
        new = search.accept_best(evidence, used)
    return evidence + vectors.evidence(joint), new


def check_coefficients(coefficients: Sequence[str]) -> None:
    """Check a selection of coefficients.

    Names are case-sensitive: ``CL`` is the lift, ``Cl`` the rolling moment.

    Parameters
    ----------
    coefficients : sequence of str
        The selection.

    Raises
    ------
    ValueError
        Unless ``coefficients`` is a non-empty selection of
        :data:`~drake_uav.model.coefficients.COEFFICIENTS`.
    """
    if isinstance(coefficients, str) or not coefficients:
        raise ValueError(f"coefficients: expected a non-empty sequence of names of "
                         f"{', '.join(COEFFICIENTS)}, got {coefficients!r}")
    unknown = [k for k in coefficients if k not in COEFFICIENTS]
    if unknown:
        raise ValueError(f"unknown coefficient {', '.join(map(repr, unknown))} (known: "
                         f"{', '.join(COEFFICIENTS)}; CL is the lift, Cl the rolling moment)")


def _constant_coefficients(samples: AeroSamples, coefficients: Sequence[str], n_train: int,
                           rule: EvidenceRule) -> dict[str, str]:
    """The ``coefficients`` that do not vary over the training part or the held-out tail
    (:attr:`EvidenceRule.constant_tolerance`) -> why; ValueError for an unknown name."""
    check_coefficients(coefficients)
    skipped = {}
    for k in dict.fromkeys(coefficients):
        z = np.asarray(samples.coefficients[k], dtype=float)
        flat = [part for part, values in (("training part", z[:n_train]),
                                          ("held-out tail", z[n_train:]))
                if np.std(values) <= rule.constant_tolerance * (1.0 + abs(np.mean(values)))]
        if flat:
            where = "the flight" if len(flat) == 2 else f"the {flat[0]} of the flight"
            skipped[k] = (f"it does not vary over {where} (mean {np.mean(z):.3g}, standard "
                          f"deviation {np.std(z):.2g}): nothing to fit")
    return skipped


class _Search:
    """The training and held-out designs of the fitted coefficients as the loop extends
    them, and the held-out decisions on the effects that pass the evidence tests
    (:class:`EvidenceRule`, :class:`HeldOutCheck`)."""

    def __init__(self, designs: dict[str, Design], tests: dict[str, Design],
                 pool: _Candidates, test_variants: Perturbations, effects: Sequence[Effect],
                 rule: EvidenceRule, scales: Mapping[str, float]):
        self.designs, self.tests = designs, tests
        self.pool, self.test_variants = pool, test_variants
        self.effects, self.rule, self.scales = effects, rule, scales
        self.checks: list[HeldOutCheck] = []

    def accept_best(self, evidence: Sequence[Evidence], used: set[str]) -> FoundEffect | None:
        """The best passing effect not tried yet that the held-out check keeps on at least
        one coefficient, its columns added there; None if there is none. Every effect tried
        joins ``used``."""
        ranked = sorted((e for e in evidence if e.passed), key=self._rank)
        for name in dict.fromkeys(e.effect for e in ranked):
            if name in used:
                continue
            used.add(name)
            effect = next((e for e in self.effects if e.name == name), None)
            kept = []
            for ev in (e for e in ranked if e.effect == name):
                k = ev.coefficient
                extended = _with_effect(self.designs[k], self.tests[k], ev, effect, self.pool,
                                        self.test_variants)
                check = self.check(name, k, (self.designs[k], self.tests[k]), extended, "round")
                self.checks.append(check)
                if check.kept:
                    self.designs[k], self.tests[k] = extended
                    kept.append(ev)
            if kept:
                return _found(name, effect, kept)
        return None

    def _rank(self, evidence: Evidence) -> float:
        """Sort key of a passing candidate: minus its held-out gain; a data-driven product,
        one choice among many, ranks ahead of a named effect only when it gains
        :attr:`EvidenceRule.min_pse_reduction` more."""
        data_driven = evidence.effect.startswith((DATA_DRIVEN, LOGGED))
        margin = self.rule.min_pse_reduction if data_driven else 0.0
        return margin - evidence.pse_reduction

    def check(self, name: str, k: str, without: tuple[Design, Design],
              with_effect: tuple[Design, Design], stage: str) -> HeldOutCheck:
        """The held-out decision on effect ``name`` for coefficient ``k``: each pair of
        (training, held-out) designs fitted on the first and evaluated on the second."""
        before, after = (_HeldOut.of(*designs, f"{name}:") for designs in (without, with_effect))
        contribution = float(np.sqrt(np.mean((after.prediction - before.prediction) ** 2)))
        threshold = max(self.rule.min_share_of_variation * self.scales[k],
                        self.rule.min_share_of_error * after.rms)
        implausible = implausible_derivatives(
            {f"{k}_{column}": value for column, value in after.parameters.items()})
        check = HeldOutCheck(name, k, stage, before.rms, after.rms, contribution, threshold,
                             kept=False, min_gain=self.rule.min_pse_reduction,
                             own_noise=after.own_noise,
                             prediction_gain=1.0 - (after.least_squares_rms
                                                    / before.least_squares_rms) ** 2,
                             implausible="; ".join(w.message for w in implausible))
        return dataclasses.replace(check, kept=not check.reason)

    def final_check(self, found: Sequence[FoundEffect]) -> list[FoundEffect]:
        """Against the final fit of each coefficient, the effects it does not need are
        dropped one at a time (the one whose removal leaves the smallest held-out error
        first); returns the effects found with the coefficients they keep."""
        dropped: set[tuple[str, str]] = set()
        for k in self.designs:
            while True:
                names = [f.name for f in found
                         if k in f.coefficients and (f.name, k) not in dropped]
                checks = [self.check(name, k, (self.designs[k].without(f"{name}:"),
                                               self.tests[k].without(f"{name}:")),
                                     (self.designs[k], self.tests[k]), "final")
                          for name in names]
                failing = [c for c in checks if not c.kept]
                if not failing:
                    break
                worst = min(failing, key=lambda c: c.rms_without)
                self.checks.append(worst)
                dropped.add((worst.effect, k))
                prefix = f"{worst.effect}:"
                self.designs[k] = self.designs[k].without(prefix)
                self.tests[k] = self.tests[k].without(prefix)
        return [f for f in (_keep(f, dropped) for f in found) if f is not None]


class _HeldOut(NamedTuple):
    """A design fitted on the training part and read on the held-out tail."""

    rms: float
    """Held-out RMS of the bias-compensated fit [-]."""
    prediction: np.ndarray
    """Its held-out prediction."""
    own_noise: float
    """Mean square that the noise sources only the columns named ``prefix...`` depend on
    add to its error [-]."""
    least_squares_rms: float
    """Held-out RMS of the least-squares fit [-]."""
    parameters: dict[str, float]
    """The fitted values of the columns named ``prefix...``, by the rest of their name."""

    @classmethod
    def of(cls, train: Design, test: Design, prefix: str) -> _HeldOut:
        theta = train.solve()
        prediction = test.X @ theta
        own = np.array([name.startswith(prefix) for name in test.names])
        noise = test.noise
        sources = {s: J for s, J in noise.regressors.items()
                   if own.any() and not np.any(J[:, ~own])}
        own_noise = noise_error_energy(theta, *PropagatedNoise(
            noise.columns, sources, noise.observation, noise.variance).moments())
        least_squares = solve_normal_equations(train.X.T @ train.X, train.X.T @ train.z)
        return cls(float(np.sqrt(np.mean((test.z - prediction) ** 2))), prediction,
                   float(own_noise) / len(test.z),
                   float(np.sqrt(np.mean((test.z - test.X @ least_squares) ** 2))),
                   {name[len(prefix):]: float(value)
                    for name, value, mine in zip(test.names, theta, own, strict=True) if mine})


def _keep(found: FoundEffect, dropped: set[tuple[str, str]]) -> FoundEffect | None:
    """``found`` without the coefficients it was dropped from (None: from all of them)."""
    evidence = tuple(e for e in found.evidence if (found.name, e.coefficient) not in dropped)
    if not evidence:
        return None
    return dataclasses.replace(found, coefficients=tuple(e.coefficient for e in evidence),
                               evidence=evidence)


def _with_effect(train: Design, test: Design, evidence: Evidence, effect: Effect | None,
                 pool: _Candidates, test_variants: Perturbations) -> tuple[Design, Design]:
    """The training and held-out designs of one coefficient with an accepted effect's columns
    (``effect`` None: a data-driven product)."""
    k, prefix = evidence.coefficient, f"{evidence.effect}:"
    if effect is not None:
        function = _effect_function(effect, pool.params, k)
        columns = pool.named(effect, k, train.noise.variance)
    else:
        function = _product_function(pool.params, k, evidence.columns)
        columns = pool.products(k, train.noise.variance)
    held_out = CandidateColumns(*columns_and_jacobians(function, test_variants,
                                                       test.noise.variance))
    columns, held_out = columns.pick(evidence.columns), held_out.pick(evidence.columns)
    return (train.extended(columns.columns, columns.jacobians, prefix=prefix),
            test.extended(held_out.columns, held_out.jacobians, prefix=prefix))


def _score_data_driven(bases, pool: _Candidates, rule, products, logged,
                       n_tests: int | None = None) -> list[Evidence]:
    """The data-driven candidates: the ``products`` and those of the log's extra channels
    (``logged``: (effect, coefficient) pairs of
    :func:`~drake_uav.identification.discovery.effects.logged_effects`), at one family-wise level
    over ``n_tests``, or (None) each family at its own: the logged channels are a few
    hypotheses the log names, the products hundreds."""
    n_products = len(products) * len(bases) if n_tests is None else n_tests
    return (_score_products(bases, pool, rule, products, n_products)
            + _score_named(logged, bases, pool, rule, n_tests or len(logged)))


def _score_products(bases, pool: _Candidates, rule, names, n_tests) -> list[Evidence]:
    """The evidence for every data-driven product ``names`` on every coefficient of
    ``bases``, each coefficient's scored together."""
    out = []
    for k, base in bases.items():
        columns, jacobians = pool.product_matrix(k, base.design.noise.variance)
        index = [_PRODUCT_INDEX[n] for n in names]
        index = [i for i, r in zip(index, redundant(base.basis, columns[:, index]),
                                   strict=True) if not r]
        if index:
            out += score_together([f"{DATA_DRIVEN}{_PRODUCT_NAMES[i]}" for i in index],
                                [(_PRODUCT_NAMES[i],) for i in index], k, base,
                                columns[:, index, None],
                                {s: j[:, index, None] for s, j in jacobians.items()}, rule,
                                n_tests)
    return [e for e in out if e is not None]


def _product_explanation(name: str) -> str:
    signals = name.split(":", 1)[1].replace("*", " x ")
    return (f"no named effect explains the residual; a data-driven term in the "
            f"product of the logged signals {signals} does")


def product_candidate(signals: tuple[str, str], params: FixedWingParams) -> Candidate:
    """The data-driven product of two base signals
    (:data:`~drake_uav.identification.discovery.effects.PRODUCT_KEYS`) as a candidate of
    the evidence rule, on every coefficient.

    Parameters
    ----------
    signals : tuple of str
        A key of :data:`~drake_uav.identification.discovery.effects.PRODUCT_KEYS`.
    params : FixedWingParams
        The aircraft (the signals' normalisation).

    Returns
    -------
    Candidate
        Named ``data_driven:<a>*<b>``, its one column named ``<a>*<b>``.

    Raises
    ------
    ValueError
        When ``signals`` is not a product the loop tests.
    """
    if tuple(signals) not in PRODUCT_KEYS:
        raise ValueError(f"product_candidate: {signals!r} is not one of the products of "
                         "effects.PRODUCT_KEYS")
    column = _product_name(tuple(signals))
    name = f"{DATA_DRIVEN}{column}"
    return Candidate(name, _product_explanation(name), COEFFICIENTS,
                     lambda samples, k: _product_function(params, k, [column])(samples))


def _found(name: str, effect: Effect | None, accepted: list[Evidence]) -> FoundEffect:
    if effect is None:
        explanation, kind = _product_explanation(name), "aerodynamic"
    else:
        explanation, kind = effect.explanation, effect.kind
    return FoundEffect(name, explanation, kind, tuple(e.coefficient for e in accepted),
                       tuple(accepted), {})


def _with_parameters(found: FoundEffect, final: Mapping[str, CoefficientFit]) -> FoundEffect:
    parameters = {}
    for k in found.coefficients:
        fit = final[k]
        prefix = found.name + ":"
        for i, name in enumerate(fit.names):
            if name.startswith(prefix):
                column = name[len(prefix):]
                parameters[f"{k}:{column}"] = (float(fit.result.estimate[i]),
                                               float(fit.result.sigma[i]))
    return dataclasses.replace(found, parameters=parameters)
