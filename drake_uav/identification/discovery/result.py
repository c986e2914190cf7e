"""The discovery loop's rule and what it returns.

:class:`EvidenceRule`, the thresholds a candidate must pass; :class:`Evidence`, what one
candidate showed on the folds; :class:`HeldOutCheck`, the decision on the held-out tail;
:class:`FoundEffect`, :class:`CoefficientFit` and :class:`DiscoveryResult`, what
:func:`~drake_uav.identification.discovery.loop.discover` found. The loop and the rules'
reasons are in :mod:`~drake_uav.identification.discovery.loop`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from drake_uav.identification.discovery.adequacy import Adequacy, AdequacyRule, coefficient_symbol
from drake_uav.identification.discovery.aliases import Alias, AliasedEffect
from drake_uav.identification.discovery.parsimony import DroppedTerm
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
from drake_uav.identification.statistics.regression import RegressionResult
from drake_uav.identification.statistics.residuals import ResidualDiagnosis

__all__ = ["NO_EFFECT_MESSAGE", "EvidenceRule", "Evidence", "FoundEffect", "HeldOutCheck",
           "CoefficientFit", "DiscoveryResult"]

NO_EFFECT_MESSAGE = "no missing effect found"


@dataclasses.dataclass(frozen=True)
class EvidenceRule:
    """Thresholds a candidate must pass to be added (all of them).

    ``p_value`` is the family-wise level: it is divided by the number of
    candidates tested in the round (Bonferroni).

    A candidate that passes is then checked, per coefficient, on the held-out tail
    (``holdout_fraction`` of the flight, which no test above saw; :class:`HeldOutCheck`):
    it is kept on a coefficient only if the held-out prediction error falls with it by at
    least ``min_pse_reduction`` (the gain the folds must show on average, so that
    cross-validation and the held-out tail ask the same of an effect), for the
    bias-compensated fit (the noise of sources only the effect's columns carry set aside)
    and the least-squares one alike, and its contribution there (RMS of the change it makes
    to the prediction) reaches both ``min_share_of_variation`` of the coefficient's
    standard deviation over the flight and ``min_share_of_error`` of the held-out error
    left with it.

    Attributes
    ----------
    p_value : float
        Family-wise level of the partial F-test.
    min_pse_reduction : float
        Smallest held-out prediction-error reduction worth a new term (fraction of the
        baseline PSE), and what a catalog term of the baseline must gain on the folds or on
        the flight's edges to be kept
        (:mod:`~drake_uav.identification.discovery.parsimony`).
    folds : int
        Number of blocked cross-validation folds (at least 3).
    min_folds : int
        How many of the folds must improve (less the effect's
        :attr:`~drake_uav.identification.discovery.effects.Effect.blind_folds`).
    holdout_fraction : float
        Share of the flight, at its end, kept for the held-out check.
    max_rounds : int
        Most effects added.
    min_share_of_variation : float
        Smallest held-out contribution, as a share of the coefficient's standard deviation.
    min_share_of_error : float
        Smallest held-out contribution, as a share of the held-out error left with it.
    constant_tolerance : float
        A coefficient whose standard deviation over the training or the held-out part is at
        most this times ``1 + |mean|`` does not vary and is not fitted.
    named_first : bool
        The data-driven products are scored only in a round where no named effect is kept
        (each family at its own Bonferroni level); False puts both in one pool, one level
        over all, where a product ranks ahead of a named effect only when its held-out gain
        is larger by ``min_pse_reduction``.
    parsimonious : bool
        The baseline drops the catalog terms that the flight does not support
        (:mod:`~drake_uav.identification.discovery.parsimony`); False fits the catalog's
        structure as it is.
    adequacy : AdequacyRule
        When the final fit's error is too far above the noise floor to call the model
        complete (:mod:`~drake_uav.identification.discovery.adequacy`).

    Examples
    --------
    >>> import dataclasses
    >>> strict = dataclasses.replace(EvidenceRule(), p_value=1e-5, min_pse_reduction=0.05)
    >>> strict.p_value, strict.folds
    (1e-05, 5)
    """

    p_value: float = 1e-3
    min_pse_reduction: float = 0.02
    folds: int = 5
    min_folds: int = 5
    holdout_fraction: float = 0.3
    max_rounds: int = 6
    min_share_of_variation: float = 0.01
    min_share_of_error: float = 0.1
    constant_tolerance: float = 1e-9
    named_first: bool = True
    parsimonious: bool = True
    adequacy: AdequacyRule = AdequacyRule()


@dataclasses.dataclass(frozen=True)
class Evidence:
    """Statistics of one candidate (an effect on one coefficient).

    Attributes
    ----------
    effect : str
        The effect's name.
    coefficient : str
        The coefficient it was tested on.
    columns : tuple of str
        Its columns.
    pse_reduction : float
        Mean relative reduction of the held-out prediction error over the folds.
    folds_improved : int
        Folds whose held-out error it lowered.
    f_statistic : float
        Partial F statistic.
    p_value : float
        Partial F-test p-value with the effective sample size.
    delta_bic : float
        BIC(with) - BIC(without), effective sample size; negative favours the effect.
    passed : bool
        Whether it passed every threshold of the :class:`EvidenceRule`.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import discover, samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CD",))
    >>> best = result.rounds[0][0]                       # round 1, the best candidate
    >>> best.effect, best.coefficient, best.passed, best.folds_improved
    ('thrust_propwash', 'CD', True, 5)
    """

    effect: str
    coefficient: str
    columns: tuple[str, ...]
    pse_reduction: float
    folds_improved: int
    f_statistic: float
    p_value: float
    delta_bic: float
    passed: bool


@dataclasses.dataclass(frozen=True)
class FoundEffect:
    """A finding: an effect the loop added, or a calibration error the data check corrected.

    An effect comes with its evidence and identified parameters; a calibration error
    (:data:`Finding`) with its estimate.

    Attributes
    ----------
    name : str
        The effect's name.
    explanation : str
        One line on the physics.
    kind : str
        ``"aerodynamic"`` (changes the dynamics), ``"sensor"`` (corrupts the data) or
        ``"calibration"`` (a sensor error the compatibility check estimated and removed).
    coefficients : tuple of str
        The coefficients it acts on (none for a calibration error).
    evidence : tuple of Evidence
        Its evidence on each coefficient it entered.
    parameters : Mapping[str, (float, float)]
        ``"<coefficient>:<column>" -> (estimate, sigma)``; a calibration error's
        ``"<name> [<unit>]" -> (estimate, sigma)``.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import discover, samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CD",))
    >>> found = result.found[0]
    >>> found.name, found.kind, found.coefficients, list(found.parameters)
    ('thrust_propwash', 'aerodynamic', ('CD',), ['CD:Tc'])
    """

    name: str
    explanation: str
    kind: str
    coefficients: tuple[str, ...]
    evidence: tuple[Evidence, ...]
    parameters: Mapping[str, tuple[float, float]]


Finding = FoundEffect
"""What the main job reports it found, whichever stage found it."""


@dataclasses.dataclass(frozen=True)
class HeldOutCheck:
    """The held-out decision on one effect for one coefficient (:class:`EvidenceRule`).

    Both fits are made on the training part; the errors and the contribution are read
    on the held-out tail. Two predictions are judged. The bias-compensated fit's, right
    for the aircraft's parameters, must improve, once the noise of the sources only the
    effect's columns depend on is set aside: a true term on a regressor with noise of its
    own (alpha-dot differentiated from the vane) passes that noise into the prediction
    at full strength. Noise the effect shares with the other columns (the air data)
    earns it nothing: an over-estimated variance would credit any column that depends on
    it. The least-squares fit's, the best predictor of the measured coefficient from the
    measured regressors, which no noise model enters, must improve as much. A term named
    like a derivative of known sign must have a plausible value (:attr:`implausible`).

    Attributes
    ----------
    effect : str
        The effect's name.
    coefficient : str
        The coefficient.
    stage : str
        "round": when the effect won a round; "final": against the final fit without it.
    rms_without : float
        Held-out equation-error RMS of the fit without the effect [-].
    rms_with : float
        The same with the effect [-].
    contribution : float
        RMS over the held-out samples of the change the effect makes to the prediction [-].
    threshold : float
        Smallest contribution that matters [-]: the larger of the two shares of the rule.
    kept : bool
        The decision.
    min_gain : float
        Smallest held-out prediction-error reduction kept (fraction of the PSE without).
    own_noise : float
        Mean square that the noise sources only the effect's columns depend on add to the
        held-out error of the fit with it [-]
        (:func:`~drake_uav.identification.statistics.errors_in_variables.noise_error_energy`).
    prediction_gain : float
        Held-out mean-square reduction of the least-squares prediction with the effect,
        fraction of the one without [-].
    implausible : str
        Why a term of the effect fitted on the training part is not the physics it names
        (a value outside
        :data:`~drake_uav.identification.discovery.plausibility.PLAUSIBLE_RANGES`: a
        downwash lag's alpha-dot derivative of the wrong sign); "" when none is.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import discover, samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CD",))
    >>> check = result.checks[0]
    >>> check.effect, check.stage, check.kept, bool(check.rms_with < check.rms_without)
    ('thrust_propwash', 'round', True, True)
    """

    effect: str
    coefficient: str
    stage: str
    rms_without: float
    rms_with: float
    contribution: float
    threshold: float
    kept: bool
    min_gain: float = 0.0
    own_noise: float = 0.0
    prediction_gain: float = float("inf")
    implausible: str = ""

    @property
    def gain(self) -> float:
        """Held-out prediction-error (mean-square) reduction without the noise of the
        effect's own sources, fraction of the PSE without the effect [-]."""
        if self.rms_without <= 0:
            return 0.0
        return 1.0 - (self.rms_with**2 - self.own_noise) / self.rms_without**2

    @property
    def reason(self) -> str:
        """Why the effect was not kept on the coefficient ("" when it was)."""
        if self.gain < 0.0:
            return (f"its held-out error rises with it ({self.rms_without:.4g} -> "
                    f"{self.rms_with:.4g}"
                    + (f", {np.sqrt(max(self.rms_with**2 - self.own_noise, 0.0)):.4g} without "
                       "the noise of its own sources)" if self.own_noise else ")"))
        if self.gain < self.min_gain:
            return (f"its held-out prediction error falls by {100 * self.gain:.2g} %, less "
                    f"than {100 * self.min_gain:.2g} %")
        if self.prediction_gain < self.min_gain:
            return (f"the held-out error of its least-squares prediction falls by "
                    f"{100 * self.prediction_gain:.2g} %, less than {100 * self.min_gain:.2g} %")
        if self.contribution < self.threshold:
            return (f"its held-out contribution {self.contribution:.2g} is below "
                    f"{self.threshold:.2g}")
        return self.implausible


@dataclasses.dataclass(frozen=True)
class CoefficientFit:
    """A fitted coefficient model: structure, fit and held-out error.

    Attributes
    ----------
    coefficient : str
        The coefficient.
    names : tuple of str
        Its terms (catalog derivatives, then ``"<effect>:<column>"``).
    result : RegressionResult
        The bias-compensated fit on the training part.
    rms_train : float
        Training equation-error RMS [-].
    rms_holdout : float
        Held-out equation-error RMS [-].
    holdout_residual : numpy.ndarray
        Equation error on the held-out samples [-].
    holdout_design : numpy.ndarray of shape (N_holdout, n)
        Regressor columns on the held-out samples, in ``names`` order.
    diagnosis : ResidualDiagnosis
        Of the training residual.
    holdout_noise : PropagatedNoise or None
        The sensor noise the errors-in-variables fit carries to ``holdout_design`` and to
        the held-out coefficient (the noise floor of ``rms_holdout`` reads it).
    training_design : numpy.ndarray of shape (N_train, n) or None
        Regressor columns on the training samples, in ``names`` order.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import discover, samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CD",))
    >>> fit = result.final["CD"]
    >>> fit.names[-1], bool(fit.rms_holdout < result.baseline["CD"].rms_holdout)
    ('thrust_propwash:Tc', True)
    """

    coefficient: str
    names: tuple[str, ...]
    result: RegressionResult
    rms_train: float
    rms_holdout: float
    holdout_residual: np.ndarray
    holdout_design: np.ndarray
    diagnosis: ResidualDiagnosis
    holdout_noise: PropagatedNoise | None = None
    training_design: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class DiscoveryResult:
    """Everything the loop found, before and after.

    Attributes
    ----------
    baseline : Mapping[str, CoefficientFit]
        Coefficient -> the fit of the catalog's (pruned) terms.
    final : Mapping[str, CoefficientFit]
        Coefficient -> the fit with the effects found.
    found : tuple of FoundEffect
        The effects added, in the order found.
    rounds : tuple of tuple of Evidence
        Ranked evidence of every round.
    holdout_start : float
        Time [s] where the held-out tail begins.
    checks : tuple of HeldOutCheck
        Every held-out decision on a passing candidate, in the order made.
    skipped : Mapping[str, str]
        Coefficients asked for but not fitted -> why (they do not vary in the samples).
    adequacy : Mapping[str, Adequacy]
        Fitted coefficient -> its final fit's error against the noise floor.
    dropped : Mapping[str, tuple of DroppedTerm]
        Fitted coefficient -> the catalog's terms the flight does not support
        (:mod:`~drake_uav.identification.discovery.parsimony`), dropped from the baseline
        and not restored beside the effects found; each is 0 in the identified model (the
        baseline fit may leave out more: a term an effect drowned there).
    aliases : tuple of AliasedEffect
        Each accepted effect, on each coefficient it is kept on, whose column this flight
        cannot tell apart from a term of another physical origin, with those terms
        (:mod:`~drake_uav.identification.discovery.aliases`).
    fixed : Mapping[str, Mapping[str, float]]
        Fitted coefficient -> the catalog's terms fixed at these values instead of fitted
        (the ``fixed`` of :func:`~drake_uav.identification.discovery.loop.discover`: terms
        the data cannot support); they are not among its fits' names but are in the
        identified model at these values.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import discover, samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> result = discover(samples, aerosonde(), coefficients=("CD",))
    >>> result.message
    'missing effect(s) found: thrust_propwash (CD)'
    >>> before, after = result.rms_change()["CD"]
    >>> bool(after < before)
    True
    """

    baseline: Mapping[str, CoefficientFit]
    final: Mapping[str, CoefficientFit]
    found: tuple[FoundEffect, ...]
    rounds: tuple[tuple[Evidence, ...], ...]
    holdout_start: float
    checks: tuple[HeldOutCheck, ...] = ()
    skipped: Mapping[str, str] = dataclasses.field(default_factory=dict)
    adequacy: Mapping[str, Adequacy] = dataclasses.field(default_factory=dict)
    dropped: Mapping[str, tuple[DroppedTerm, ...]] = dataclasses.field(default_factory=dict)
    aliases: tuple[AliasedEffect, ...] = ()
    fixed: Mapping[str, Mapping[str, float]] = dataclasses.field(default_factory=dict)

    @property
    def incomplete(self) -> dict[str, Adequacy]:
        """The coefficients whose final error the sensor noise does not explain: the model
        is incomplete there (:class:`~drake_uav.identification.discovery.adequacy.Adequacy`)."""
        return {k: a for k, a in self.adequacy.items() if a.incomplete}

    @property
    def notes(self) -> tuple[str, ...]:
        """One line per skipped coefficient, per baseline term dropped and per effect not
        kept on a coefficient where it passed the evidence tests."""
        notes = [f"{k} skipped: {why}" for k, why in self.skipped.items()]
        notes += [term.line for terms in self.dropped.values() for term in terms]
        notes += [f"{c.effect} not kept on {c.coefficient}: {c.reason}"
                  for c in self.checks if not c.kept]
        return tuple(notes)

    @property
    def message(self) -> str:
        """One line: the effects found, or that none was; and where the model is still
        incomplete ("the model is incomplete for C_D: held-out error 2.1x the noise
        floor, ..."). An effect with aliases (:attr:`aliases`) is named with them: "ned_force
        or thrust_propwash (CD, |corr| 0.98: this flight cannot tell them apart)"."""
        incomplete = "; ".join(f"{coefficient_symbol(k)}: {a.explanation}"
                               for k, a in self.incomplete.items())
        if not self.found:
            return f"the model is incomplete for {incomplete}" if incomplete else \
                NO_EFFECT_MESSAGE
        found = "missing effect(s) found: " + ", ".join(self._finding(f) for f in self.found)
        return f"{found}; the model is still incomplete for {incomplete}" if incomplete \
            else found

    def aliases_of(self, effect: str) -> tuple[Alias, ...]:
        """The aliases of an accepted effect over every coefficient it is kept on, the most
        correlated first (:attr:`aliases`).

        Parameters
        ----------
        effect : str
            The effect's name.

        Returns
        -------
        tuple of Alias
            One per term (its largest correlation over the coefficients); empty when the
            flight tells the effect apart from every term of another origin.
        """
        best: dict[str, Alias] = {}
        for aliased in (a for a in self.aliases if a.effect == effect):
            for alias in aliased.aliases:
                if alias.name not in best or alias.correlation > best[alias.name].correlation:
                    best[alias.name] = alias
        return tuple(sorted(best.values(), key=lambda a: -a.correlation))

    def _finding(self, found: FoundEffect) -> str:
        """``name (coefficients)``, or with aliases ``X or Y (coefficients, |corr| c: this
        flight cannot tell them apart)``, the aliases of one origin named by the most
        correlated with how many other forms of that origin follow it."""
        aliases = self.aliases_of(found.name)
        where = ", ".join(found.coefficients)
        if not aliases:
            return f"{found.name} ({where})"
        groups: dict[str, list[Alias]] = {}
        for alias in aliases:
            groups.setdefault(alias.origin, []).append(alias)
        names = [found.name] + [
            group[0].label + (f" (or {len(group) - 1} other form"
                              f"{'s' if len(group) > 2 else ''} of {origin})"
                              if len(group) > 1 else "")
            for origin, group in groups.items()]
        return (f"{', '.join(names[:-1])} or {names[-1]} ({where}, |corr| "
                f"{aliases[0].correlation:.2f}: this flight cannot tell them apart)")

    def rms_change(self) -> dict[str, tuple[float, float]]:
        """Held-out equation-error RMS before and after, per coefficient.

        Returns
        -------
        dict of str to (float, float)
            Coefficient -> (baseline, final) RMS [-].
        """
        return {k: (self.baseline[k].rms_holdout, self.final[k].rms_holdout)
                for k in self.baseline}
