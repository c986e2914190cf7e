"""The evidence rule: one scorer for every kind of candidate effect.

A :class:`Candidate` is plant-agnostic: a name, its physical explanation, the measured
quantities it acts on (for the fixed-wing job, the six aerodynamic coefficients), and
the regressor columns it adds to each of them, computed from the samples; the noise
sensitivities of the columns follow by finite differences over the samples' noise
sources (:func:`~drake_uav.identification.discovery.coefficient_design.columns_and_jacobians`).
A per-coefficient effect, a product of logged signals and a logged channel have their own
parameters on each quantity (each quantity tested on its own); a vector effect shares its
parameters over every quantity it moves (one joint test, :attr:`Candidate.joint`).

:func:`score` tests a candidate against the current design of each quantity
(:class:`RoundBase`) on the training part of the flight, by

* blocked K-fold cross-validation: the mean relative reduction of the noise-corrected
  held-out error over the folds, and how many folds improve;
* a partial F-test whose degrees of freedom use the residual's effective sample size
  (correlated residuals carry less information than their sample count), at the
  family-wise level of :class:`~drake_uav.identification.discovery.result.EvidenceRule`
  divided by the number of candidates tested (Bonferroni), and multiplied by the number of
  candidate points a located point was chosen from;
* the change in BIC.

:func:`verdict` is the rule itself, the only place these are combined; the loop scores
many per-coefficient candidates of a quantity at once (:func:`score_together`) and the
vector effects jointly (:func:`score_jointly`), both through it. The held-out check on the
tail of the flight and the plausibility of the fitted derivatives follow for the
candidates that pass (:meth:`~drake_uav.identification.discovery.loop.discover`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from drake_uav.identification.discovery.coefficient_design import (
    Design,
    Perturbations,
    columns_and_jacobians,
)
from drake_uav.identification.discovery.result import Evidence, EvidenceRule
from drake_uav.identification.statistics.blocked_folds import held_out_errors, squared_errors
from drake_uav.identification.statistics.errors_in_variables import (
    BlockMoments,
    is_well_posed,
    noise_error_energy,
    solve_normal_equations,
)
from drake_uav.identification.statistics.regression import f_survival, r_factor
from drake_uav.identification.statistics.residuals import effective_sample_size

__all__ = ["Candidate", "CandidateColumns", "RoundBase", "round_base", "JointEvidence",
           "score", "score_together", "score_jointly", "verdict", "folds_pass", "bic_term",
           "redundant", "nonzero_columns", "JointBlock", "joint_solve"]

POINT_SEARCH_PARAMETERS = 3
"""Parameters a located point adds to a candidate's BIC (its three coordinates)."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A candidate effect, plant-agnostic: what it is and the columns it adds.

    Attributes
    ----------
    name : str
        Its name in the findings.
    explanation : str
        One line of physics: what would cause it.
    quantities : tuple of str
        The measured quantities it may act on (coefficients, for the fixed-wing job).
    columns : callable
        ``columns(samples, quantity) -> {column name: (N,) values}``; a column of zeros
        means the parameter does not enter that quantity.
    parameters : tuple of str
        The parameters shared by every quantity (:attr:`joint`); empty for a candidate with
        its own parameters, one per column, on each quantity.
    joint : bool
        True: one parameter set over all the quantities, tested jointly (a force moves the
        lift, the drag and the side force together); False: each quantity tested on its own.
    blind_folds : int
        Folds the candidate cannot improve by construction (a linear drift's middle fold),
        which the rule does not ask it to.
    searched : int
        Candidate points its point was chosen from (0: none); the p-value is multiplied by
        it (Bonferroni) and the BIC counts :data:`POINT_SEARCH_PARAMETERS` more parameters.
    kind : str
        ``"aerodynamic"`` (changes the dynamics) or ``"sensor"`` (corrupts the data).
    origin : str
        Its physical origin: what would cause it (``"the propeller slipstream"``, ``"an
        external force"``); candidates of one origin are variants of one explanation, and
        a term of another origin whose columns move with an accepted effect's is reported
        as its alias (:mod:`~drake_uav.identification.discovery.aliases`). Empty: the
        candidate's name (an origin of its own).

    Examples
    --------
    A term in the square of the elevator on the pitching moment:

    >>> squared = Candidate("elevator_squared", "the elevator's moment grows with its square",
    ...                     ("Cm",), lambda samples, k: {"de2": samples.condition.elevator ** 2})
    >>> squared.quantities, squared.joint
    (('Cm',), False)
    """

    name: str
    explanation: str
    quantities: tuple[str, ...]
    columns: Callable[[Any, str], Mapping[str, np.ndarray]]
    parameters: tuple[str, ...] = ()
    joint: bool = False
    blind_folds: int = 0
    searched: int = 0
    kind: str = "aerodynamic"
    origin: str = ""

    @property
    def physical_origin(self) -> str:
        """:attr:`origin`, or the candidate's name when none is given."""
        return self.origin or self.name


@dataclasses.dataclass(frozen=True)
class CandidateColumns:
    """A candidate's columns on the training samples and their noise sensitivities.

    Attributes
    ----------
    columns : Mapping[str, numpy.ndarray]
        Column name -> (N,) values.
    jacobians : Mapping[str, Mapping[str, numpy.ndarray]]
        Noise source -> column name -> d column / d source.
    """

    columns: Mapping[str, np.ndarray]
    jacobians: Mapping[str, Mapping[str, np.ndarray]]

    def pick(self, names: Sequence[str]) -> CandidateColumns:
        """The columns ``names`` only.

        Parameters
        ----------
        names : sequence of str
            The columns kept.

        Returns
        -------
        CandidateColumns
            The selected columns and their sensitivities.
        """
        return CandidateColumns({k: self.columns[k] for k in names},
                                {s: {k: j[k] for k in names} for s, j in self.jacobians.items()})


def nonzero_columns(columns: CandidateColumns) -> CandidateColumns:
    """The columns that are not zero everywhere (the parameters that enter).

    Parameters
    ----------
    columns : CandidateColumns
        A candidate's columns.

    Returns
    -------
    CandidateColumns
        Those not zero everywhere.
    """
    return columns.pick([n for n, v in columns.columns.items() if np.any(v != 0.0)])


@dataclasses.dataclass(frozen=True)
class RoundBase:
    """The current design of one quantity and its statistics, shared by the candidates.

    Attributes
    ----------
    design : Design
        The current design.
    n_eff : float
        Effective sample size of the design's residual.
    fold_errors : numpy.ndarray of shape (2, K)
        Observed and noise-corrected held-out errors.
    sse : (float, float)
        Observed and noise-corrected training error.
    blocks : BlockMoments
        The design's moments per fold, which every candidate extends.
    basis : numpy.ndarray
        Orthonormal basis of the design's columns (redundancy test of candidate columns).
    """

    design: Design
    n_eff: float
    fold_errors: np.ndarray
    sse: tuple[float, float]
    blocks: BlockMoments
    basis: np.ndarray


def round_base(design: Design, edges: Sequence[int]) -> RoundBase:
    """The statistics of ``design`` that every candidate is compared with.

    Parameters
    ----------
    design : Design
        The quantity's current design on the training part.
    edges : sequence of int
        The blocked folds' edges
        (:func:`~drake_uav.identification.statistics.blocked_folds.fold_edges`).

    Returns
    -------
    RoundBase
    """
    blocks = design.block_moments(edges)
    A, b, C_xx, c_xz = blocks.total()
    theta = solve_normal_equations(A, b)
    prediction = design.X @ theta
    return RoundBase(design, float(effective_sample_size(design.z - prediction)),
                     held_out_errors(blocks, design.z, lambda t: design.X @ t.T),
                     squared_errors(design.z, prediction, theta, C_xx, c_xz), blocks,
                     _column_space(design.X))


def _column_space(X: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the range of X, to the rank ``numpy.linalg.lstsq`` gives X.

    From the SVD of the small R factor of X (:func:`r_factor`): ``X V S^-1``.
    """
    _, s, vt = np.linalg.svd(r_factor(X))
    if s.size == 0 or s[0] == 0.0:
        return np.zeros((X.shape[0], 0))
    keep = s > np.finfo(float).eps * max(X.shape) * s[0]
    return X @ (vt[keep].T / s[keep])


def redundant(basis: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Which columns are (nearly) in the span of an orthonormal basis, or zero.

    Parameters
    ----------
    basis : numpy.ndarray of shape (N, r)
        Orthonormal columns.
    columns : numpy.ndarray of shape (N, m)
        The columns tested.

    Returns
    -------
    numpy.ndarray of bool, shape (m,)
        True for a redundant or zero column.
    """
    norm = np.linalg.norm(columns, axis=0)
    r = columns - basis @ (basis.T @ columns)
    with np.errstate(invalid="ignore"):
        return ~np.isfinite(norm) | (norm == 0.0) | (np.linalg.norm(r, axis=0) < 1e-3 * norm)


# -- the rule


def folds_pass(reduction, improved, rule: EvidenceRule, blind_folds=0):
    """The cross-validation part of the evidence rule.

    The mean relative reduction of the held-out error reaches
    :attr:`EvidenceRule.min_pse_reduction` and at least :attr:`EvidenceRule.min_folds`
    folds (less ``blind_folds``) improve.

    Parameters
    ----------
    reduction : float or numpy.ndarray
        Mean relative reduction of the held-out error.
    improved : int or numpy.ndarray
        Number of folds improved.
    rule : EvidenceRule
        The thresholds.
    blind_folds : int
        Folds the candidate cannot improve by construction.

    Returns
    -------
    bool or numpy.ndarray of bool
        Whether the folds pass (elementwise for arrays).
    """
    return (reduction >= rule.min_pse_reduction) & (improved >= rule.min_folds - blind_folds)


def bic_term(n_eff, sse: float, drop, parameters):
    """One quantity's part of BIC(with) - BIC(without).

    Parameters
    ----------
    n_eff : float or numpy.ndarray
        Effective number of samples.
    sse : float
        Training squared error without the candidate.
    drop : float or numpy.ndarray
        By how much the candidate lowers it.
    parameters : int
        Number of parameters the candidate adds.

    Returns
    -------
    float or numpy.ndarray
        The BIC difference; negative favours the candidate.
    """
    return n_eff * np.log(np.maximum(sse - drop, 1e-300) / sse) + parameters * np.log(n_eff)


def verdict(drop, observed, residual_dof, delta_bic, reduction, improved, q: int,
            rule: EvidenceRule, n_tests: int, *, searched: int = 0, blind_folds=0):
    """The evidence rule: the F-test, the multiple-test threshold, the folds and the BIC.

    Scalars, or arrays over candidates scored together. The nine statistics are those a
    test of nested least-squares fits has; they are not grouped because each comes from a
    different part of the fit.

    Parameters
    ----------
    drop : float or ndarray
        Noise-corrected training error the candidate removes (weighted sum over the
        quantities of a joint test).
    observed : float or ndarray
        Observed training error with the candidate (same weights).
    residual_dof : float or ndarray
        Sum over the quantities of the effective sample size less their own columns.
    delta_bic : float or ndarray
        BIC(with) - BIC(without) (:func:`bic_term`).
    reduction, improved : float or ndarray, int or ndarray
        Mean relative reduction of the held-out error over the folds, and how many
        folds improve.
    q : int
        The candidate's parameters (the F-test's degrees of freedom).
    rule : EvidenceRule
        The thresholds.
    n_tests : int
        Candidates tested in the round (Bonferroni).
    searched : int
        Candidate points a located point was chosen from (0: none).
    blind_folds : int or ndarray
        Folds the candidate need not improve.

    Returns
    -------
    tuple
        ``(f_statistic, p_value, passed)``.
    """
    dof = np.maximum(residual_dof - q, 1.0)
    f_stat = np.maximum(drop, 0.0) / q / (observed / dof)
    p_value = np.minimum(np.asarray(f_survival(f_stat, q, dof), dtype=float)
                         * max(searched, 1), 1.0)
    passed = ((p_value < rule.p_value / max(n_tests, 1))
              & folds_pass(reduction, improved, rule, blind_folds) & (delta_bic < 0))
    return f_stat, p_value, passed


# -- candidates of their own parameters, many at once


def score_together(names: Sequence[str], columns: Sequence[tuple[str, ...]], quantity: str,
                   base: RoundBase, X_new: np.ndarray, J_new: Mapping[str, np.ndarray],
                   rule: EvidenceRule, n_tests: int, blind_folds=0) -> list[Evidence | None]:
    """The evidence for m candidates of q columns each on one quantity, scored together.

    The nine parameters describe one batch of candidates and the rule it is held to;
    they are not grouped because the loop builds the batch from its pieces.

    Parameters
    ----------
    names : sequence of str
        The m candidates' names.
    columns : sequence of tuple of str
        Each candidate's column names.
    quantity : str
        The quantity they act on.
    base : RoundBase
        Its current design.
    X_new : ndarray
        (N, m, q) the candidates' columns.
    J_new : Mapping
        Noise source -> (N, m, q) sensitivities of the columns.
    rule : EvidenceRule
    n_tests : int
        Candidates tested in the round.
    blind_folds : int or ndarray
        (m,) folds a candidate need not improve.

    Returns
    -------
    list
        One :class:`~drake_uav.identification.discovery.result.Evidence` per candidate,
        None where the extended design is not well posed.
    """
    design = base.design
    p, q = design.X.shape[1], X_new.shape[2]
    blocks = base.blocks.extended(design.X, design.z, design.noise, X_new, J_new)
    A, b, C_xx, c_xz = blocks.total()
    posed = is_well_posed(A)
    theta_folds = solve_normal_equations(*blocks.held_in())
    errors = _batch_fold_errors(blocks, design.X, X_new, design.z, theta_folds)
    # Improvement in the noise-corrected error, relative to the observed error.
    gain = base.fold_errors[1] - errors[1]
    reduction = np.mean(gain / base.fold_errors[0], axis=-1)
    improved = np.sum(gain > 0, axis=-1)
    theta = solve_normal_equations(A, b)
    r = design.z[:, None] - design.X @ theta[:, :p].T - (X_new * theta[:, p:]).sum(axis=-1)
    observed1 = np.einsum("nm,nm->m", r, r)
    corrected1 = observed1 - noise_error_energy(theta, C_xx, c_xz)
    drop = np.maximum(base.sse[1] - corrected1, 0.0)
    # Where the folds passed, the residual's correlation is read with the candidate: a large
    # slow effect left in the base residual would pass for correlated noise.
    n_eff = np.full(len(names), base.n_eff)
    for i in np.flatnonzero(folds_pass(reduction, improved, rule, blind_folds)):
        n_eff[i] = effective_sample_size(r[:, i])
    delta_bic = bic_term(n_eff, base.sse[0], drop, q)
    f_stat, p_value, passed = verdict(drop, observed1, n_eff - p, delta_bic, reduction,
                                      improved, q, rule, n_tests, blind_folds=blind_folds)
    return [Evidence(names[i], quantity, columns[i], float(reduction[i]), int(improved[i]),
                     float(f_stat[i]), float(p_value[i]), float(delta_bic[i]), bool(passed[i]))
            if posed[i] else None for i in range(len(names))]


def _batch_fold_errors(blocks: BlockMoments, X: np.ndarray, X_new: np.ndarray, z: np.ndarray,
                       theta: np.ndarray) -> np.ndarray:
    """(2, m, K): observed and noise-corrected held-out squared error of each blocked fold
    (:func:`~drake_uav.identification.statistics.blocked_folds.squared_errors`) for m
    extensions ``X_new`` (N, m, q) of ``X`` (N, p), whose fits on the other folds are
    ``theta`` (m, K, p + q)."""
    p = X.shape[1]
    out = np.empty((2, *theta.shape[:2]))
    for k, (a, b) in enumerate(zip(blocks.edges[:-1], blocks.edges[1:], strict=True)):
        fit = theta[:, k]
        r = z[a:b, None] - X[a:b] @ fit[:, :p].T - (X_new[a:b] * fit[:, p:]).sum(axis=-1)
        out[0, :, k] = np.einsum("nm,nm->m", r, r)
        out[1, :, k] = out[0, :, k] - noise_error_energy(fit, blocks.noise_xx[:, k],
                                                         blocks.noise_xz[:, k])
    return out


# -- candidates sharing their parameters over several quantities


def _solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A^-1 B`` for stacks of normal matrices, equilibrated to a unit diagonal
    (least squares when singular)."""
    scale = np.sqrt(np.maximum(np.diagonal(A, axis1=-2, axis2=-1), 1e-300))
    E = A / (scale[..., :, None] * scale[..., None, :])
    try:
        return np.linalg.solve(E, B / scale[..., :, None]) / scale[..., :, None]
    except np.linalg.LinAlgError:
        return np.linalg.pinv(E) @ (B / scale[..., :, None]) / scale[..., :, None]


@dataclasses.dataclass(frozen=True)
class JointBlock:
    """One quantity's compensated normal equations ``(A, b)`` of ``[X | V_k]``.

    ``p`` own columns, then the shared parameters ``index`` (of the candidate's) entering it.

    Attributes
    ----------
    A : numpy.ndarray of shape (..., p + m, p + m)
        Compensated normal matrix.
    b : numpy.ndarray of shape (..., p + m)
        Compensated right-hand side.
    p : int
        Number of the quantity's own columns.
    index : numpy.ndarray of int, shape (m,)
        Which of the candidate's shared parameters enter this quantity.
    weight : float
        The quantity's weight in the joint fit [1/quantity^2].
    """

    A: np.ndarray
    b: np.ndarray
    p: int
    index: np.ndarray
    weight: float


def joint_solve(blocks: Sequence[JointBlock], q: int
                ) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """The shared parameters and each quantity's own, from the weighted stacked equations.

    Every quantity's own columns are eliminated (Schur complements), leaving the reduced
    normal matrix of the shared parameters.

    Parameters
    ----------
    blocks : sequence of JointBlock
        One per quantity.
    q : int
        Number of shared parameters.

    Returns
    -------
    phi : numpy.ndarray of shape (..., q)
        The shared parameters.
    thetas : list of numpy.ndarray of shape (..., p)
        Each quantity's own parameters.
    S : numpy.ndarray of shape (..., q, q)
        The reduced normal matrix.
    """
    lead = blocks[0].A.shape[:-2]
    S, s = np.zeros((*lead, q, q)), np.zeros((*lead, q))
    parts = []
    for blk in blocks:
        p, i = blk.p, blk.index
        Axv, bx = blk.A[..., :p, p:], blk.b[..., :p]
        sol = _solve(blk.A[..., :p, :p], np.concatenate([Axv, bx[..., None]], axis=-1))
        Avx = np.swapaxes(Axv, -1, -2)
        S[..., i[:, None], i[None, :]] += blk.weight * (blk.A[..., p:, p:] - Avx @ sol[..., :-1])
        s[..., i] += blk.weight * (blk.b[..., p:] - (Avx @ sol[..., -1:])[..., 0])
        parts.append(sol)
    phi = _solve(S, s[..., None])[..., 0]
    thetas = [sol[..., -1] - (sol[..., :-1] @ phi[..., blk.index, None])[..., 0]
              for sol, blk in zip(parts, blocks, strict=True)]
    return phi, thetas, S


@dataclasses.dataclass(frozen=True)
class JointEvidence:
    """The joint test of one candidate over the quantities it moves.

    Attributes
    ----------
    effect : object
        The candidate tested (for the fixed-wing job, a
        :class:`~drake_uav.identification.discovery.vector_effects.VectorEffect`).
    coefficients : tuple of str
        The quantities it moves.
    parameters : tuple of str
        The shared parameters tested (the degrees of freedom of the test).
    estimate : numpy.ndarray
        Their joint estimate on the training part.
    pse_reduction : float
        Mean over the folds of the held-out error removed, summed over the quantities in
        units of each one's error (:attr:`total` is the same mean taken per quantity).
    folds_improved : int
        Folds whose summed held-out error fell.
    reductions : Mapping[str, float]
        Per quantity: mean relative reduction of its held-out error over the folds.
    improved : Mapping[str, int]
        Per quantity: folds improved.
    f_statistic : float
        Joint partial F statistic.
    p_value : float
        Its p-value (effective sample size).
    delta_bic : float
        BIC(with) - BIC(without); negative favours the candidate.
    passed : bool
        Whether it passed every threshold of the rule.
    """

    effect: Any
    coefficients: tuple[str, ...]
    parameters: tuple[str, ...]
    estimate: np.ndarray
    pse_reduction: float
    folds_improved: int
    reductions: Mapping[str, float]
    improved: Mapping[str, int]
    f_statistic: float
    p_value: float
    delta_bic: float
    passed: bool

    @property
    def total(self) -> float:
        """Held-out error removed, summed over the quantities in units of each one's
        error: the key it competes on."""
        return float(sum(self.reductions.values()))

    def evidence(self) -> list[Evidence]:
        """One :class:`Evidence` per quantity: the joint statistics with its own held-out reduction.

        Returns
        -------
        list of Evidence
            In the order of :attr:`coefficients`.
        """
        return [Evidence(self.effect.name, k, self.parameters, self.reductions[k],
                         self.improved[k], self.f_statistic, self.p_value, self.delta_bic,
                         self.passed) for k in self.coefficients]


def _new_columns(columns: Mapping[str, CandidateColumns], bases: Mapping[str, RoundBase]
                 ) -> dict[str, list[str]]:
    """Quantity -> the names of the candidate's columns not in the span of its design."""
    moved = {}
    for k in bases:
        own = columns.get(k)
        if own is not None and own.columns:
            V = np.column_stack(list(own.columns.values()))
            names = [n for n, r in zip(own.columns, redundant(bases[k].basis, V), strict=True)
                     if not r]
            if names:
                moved[k] = names
    return moved


@dataclasses.dataclass(frozen=True)
class _JointFit:
    """The weighted joint fit of a candidate's shared parameters over the quantities it
    moves, on the training part and on each fold's held-in part."""

    blocks: list[JointBlock]
    extended: dict[str, tuple[np.ndarray, BlockMoments]]
    """Quantity -> the candidate's columns there and the extended design's moments."""
    n_eff: dict[str, float]
    """Quantity -> effective sample size of its residual with the candidate."""
    phi: np.ndarray
    thetas: list[np.ndarray]
    phi_folds: np.ndarray
    theta_folds: list[np.ndarray]

    @classmethod
    def of(cls, moved: Mapping[str, list[str]], columns: Mapping[str, CandidateColumns],
           bases: Mapping[str, RoundBase], parameters: tuple[str, ...]) -> _JointFit | None:
        """The fit (None: not well posed). A first pass weights each quantity by its
        residual's variance; the second by the long-run variance of its residual with the
        candidate (under the null hypothesis the same as without it; with it, not
        inflated by the candidate)."""
        q = len(parameters)
        blocks, extended = [], {}
        for k, names in moved.items():
            design = bases[k].design
            own = columns[k]
            V = np.column_stack([own.columns[n] for n in names])
            J = {s: np.column_stack([j[n] for n in names]) for s, j in own.jacobians.items()}
            moments = bases[k].blocks.extended(design.X, design.z, design.noise, V, J)
            A, b, _, _ = moments.total()
            index = np.array([parameters.index(n) for n in names])
            blocks.append(JointBlock(A, b, design.X.shape[1], index, len(V) / bases[k].sse[0]))
            extended[k] = (V, moments)
        phi, thetas, S = joint_solve(blocks, q)
        if not is_well_posed(S):
            return None
        fits = {}
        for i, (k, blk, theta) in enumerate(zip(moved, blocks, thetas, strict=True)):
            V, _ = extended[k]
            design = bases[k].design
            r = design.z - design.X @ theta - V @ phi[blk.index]
            n_eff = float(effective_sample_size(r))
            blocks[i] = dataclasses.replace(blk, weight=n_eff / float(r @ r))
            fits[k] = n_eff
        phi, thetas, _ = joint_solve(blocks, q)
        phi_folds, theta_folds, _ = joint_solve(
            [JointBlock(*extended[k][1].held_in(), blk.p, blk.index, blk.weight)
             for k, blk in zip(moved, blocks, strict=True)], q)
        return cls(blocks, extended, fits, phi, thetas, phi_folds, theta_folds)


def score_jointly(effect: Any, parameters: Sequence[str],
                  columns: Mapping[str, CandidateColumns], bases: Mapping[str, RoundBase],
                  rule: EvidenceRule, n_tests: int, searched: int = 0) -> JointEvidence | None:
    """The joint evidence of a candidate whose ``parameters`` are shared by the quantities.

    Parameters
    ----------
    effect : object
        The candidate (kept in the result; its ``name`` names it).
    parameters : sequence of str
        Its parameters, in order.
    columns : Mapping
        Quantity -> the candidate's non-zero columns there (named by parameter).
    bases : Mapping
        Quantity -> its current design (:class:`RoundBase`); the quantities of ``columns``
        without one are left out.
    rule : EvidenceRule
    n_tests : int
        Candidates tested in the round.
    searched : int
        Candidate points a located point was chosen from (0: none).

    Returns
    -------
    JointEvidence or None
        None when no column is new to a design or the joint fit is not well posed.
    """
    moved = _new_columns(columns, bases)
    parameters = tuple(n for n in parameters if any(n in v for v in moved.values()))
    if not parameters:
        return None
    fit = _JointFit.of(moved, columns, bases, parameters)
    if fit is None:
        return None
    q = len(parameters)
    searched_parameters = POINT_SEARCH_PARAMETERS if searched else 0
    blocks, extended, fits = fit.blocks, fit.extended, fit.n_eff
    phi, thetas, phi_folds, theta_folds = fit.phi, fit.thetas, fit.phi_folds, fit.theta_folds
    drop_w = observed_w = dof = bic = 0.0
    reductions, improved = {}, {}
    relative = 0.0
    for k, blk, theta, theta_k in zip(moved, blocks, thetas, theta_folds, strict=True):
        base, (V, moments), n_eff = bases[k], extended[k], fits[k]
        design = base.design
        _, _, C_xx, c_xz = moments.total()
        r = design.z - design.X @ theta - V @ phi[blk.index]
        observed = float(r @ r)
        drop = base.sse[1] - (observed - noise_error_energy(
            np.concatenate([theta, phi[blk.index]]), C_xx, c_xz))
        drop_w += blk.weight * drop
        observed_w += blk.weight * observed
        dof += n_eff - blk.p
        bic += bic_term(n_eff, base.sse[0], drop, (q + searched_parameters) / len(moved))
        gain = np.empty(len(moments.edges) - 1)
        for f, (a, b) in enumerate(zip(moments.edges[:-1], moments.edges[1:], strict=True)):
            fit = np.concatenate([theta_k[f], phi_folds[f][blk.index]])
            rf = design.z[a:b] - design.X[a:b] @ fit[:blk.p] - V[a:b] @ fit[blk.p:]
            gain[f] = base.fold_errors[1][f] - (float(rf @ rf) - noise_error_energy(
                fit, moments.noise_xx[f], moments.noise_xz[f]))
        relative = relative + gain / base.fold_errors[0]
        reductions[k] = float(np.mean(gain / base.fold_errors[0]))
        improved[k] = int(np.sum(gain > 0))
    reduction, folds_improved = float(np.mean(relative)), int(np.sum(relative > 0))
    f_stat, p_value, passed = verdict(drop_w, observed_w, dof, bic, reduction, folds_improved,
                                      q, rule, n_tests, searched=searched)
    return JointEvidence(effect, tuple(moved), parameters, phi, reduction, folds_improved,
                         reductions, improved, float(f_stat), float(p_value), float(bic),
                         bool(passed))


# -- one candidate, any kind


def candidate_columns(candidate: Candidate, quantity: str, variants: Perturbations,
                      variance: Mapping[str, float]) -> CandidateColumns:
    """The columns of ``candidate`` on ``quantity`` and their sensitivities to the noise sources.

    Parameters
    ----------
    candidate : Candidate
        The candidate.
    quantity : str
        The quantity (coefficient).
    variants : Perturbations
        The samples, perturbed one source at a time.
    variance : Mapping[str, float]
        Noise source -> variance; its keys are the sources differentiated.

    Returns
    -------
    CandidateColumns
        The columns and their sensitivities.
    """
    return CandidateColumns(*columns_and_jacobians(
        lambda samples: candidate.columns(samples, quantity), variants, variance))


def score(candidate: Candidate, bases: Mapping[str, RoundBase], variants: Perturbations,
          rule: EvidenceRule, n_tests: int = 1) -> list[Evidence]:
    """The evidence for one candidate of any kind, on each quantity it acts on.

    Parameters
    ----------
    candidate : Candidate
        The candidate.
    bases : Mapping
        Quantity -> its current design on the training samples (:func:`round_base`).
    variants : Perturbations
        The training samples and their perturbations by noise source
        (:class:`~drake_uav.identification.discovery.coefficient_design.Perturbations`).
    rule : EvidenceRule
        The thresholds.
    n_tests : int
        Candidates tested in the round (Bonferroni).

    Returns
    -------
    list of Evidence
        One per quantity scored (a joint candidate's share its test); empty where no
        column is new to a design or the fit is not well posed.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import effect_library, samples_from_log
    >>> from drake_uav.identification.discovery.coefficient_design import baseline_design
    >>> from drake_uav.identification.statistics.blocked_folds import fold_edges
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> design = baseline_design(samples, aerosonde(), "CD")
    >>> bases = {"CD": round_base(design, fold_edges(len(samples), 5))}
    >>> propwash = next(e for e in effect_library() if e.name == "thrust_propwash")
    >>> evidence = score(propwash.candidate(aerosonde()), bases, Perturbations(samples),
    ...                  EvidenceRule())
    >>> [(e.coefficient, e.passed) for e in evidence]
    [('CD', True)]
    """
    quantities = [k for k in candidate.quantities if k in bases]
    columns = {k: candidate_columns(candidate, k, variants, bases[k].design.noise.variance)
               for k in quantities}
    if candidate.joint:
        joint = score_jointly(candidate, candidate.parameters,
                              {k: nonzero_columns(c) for k, c in columns.items()}, bases, rule,
                              n_tests, candidate.searched)
        return [] if joint is None else joint.evidence()
    out = []
    for k in quantities:
        base, own = bases[k], columns[k]
        new = [n for n, r in zip(own.columns, redundant(base.basis, np.column_stack(
            list(own.columns.values()))), strict=True) if not r]
        if not new:
            continue
        own = own.pick(new)
        X_new = np.column_stack([own.columns[n] for n in new])[:, None, :]
        J_new = {s: np.column_stack([j[n] for n in new])[:, None, :]
                 for s, j in own.jacobians.items()}
        evidence = score_together([candidate.name], [tuple(new)], k, base, X_new, J_new, rule,
                                  n_tests, np.array([candidate.blind_folds]))[0]
        if evidence is not None:
            out.append(evidence)
    return out
