"""A parsimonious baseline: the catalog's derivative terms the flight does not support go.

The aircraft's catalog names a structure for each coefficient (C_D: a constant, alpha,
alpha^2, q, elevator). A flight that hardly moves a term's regressor, or whose coefficient
does not depend on it, leaves the term's estimate to the noise and to whatever it
correlates with; such a term adds nothing where the fit was made and spoils the
prediction elsewhere (extra drag terms made a purely longitudinal glide's drag
extrapolation 4x worse than a plain polar). Backward elimination (stepwise regression,
Klein & Morelli 2006, ch. 5) removes them, judged by the discovery loop's own evidence
on the training part of the flight (:mod:`~drake_uav.identification.statistics.blocked_folds`):

* **cross-validation**: the blocked K-fold held-out prediction error (PSE), each block
  predicted by the bias-compensated fit on the others;
* **extrapolation to the flight's edges**: the first and last blocks predicted by the fit
  on the middle ones.

A term is dropped when removing it raises neither the folds' mean PSE nor the edges' error
by ``min_gain`` or more (the discovery loop's ``EvidenceRule.min_pse_reduction``), each
error taken without its regressor-noise part and as a fraction of the error without the
term: what adding the term back would gain, the share a new effect must gain to be added,
so that adding and dropping ask the same. Among the terms that may go, the one whose
removal raises the PSE least goes first; the others are judged again without it, until
none may go. The constant is never dropped. A dropped term is 0 in the identified model;
the discovery loop still tests the effects against the catalog's whole structure, so that
no effect takes the place of a dropped term, and once effects are accepted it judges the
dropped terms again beside them (the same rule, with every other term kept), so that a term
an unmodelled effect drowned in the baseline comes back.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from drake_uav.identification.statistics.blocked_folds import held_out_errors, squared_errors
from drake_uav.identification.statistics.errors_in_variables import (
    BlockMoments,
    PropagatedNoise,
    solve_normal_equations,
)

__all__ = ["DroppedTerm", "Pruning", "prune"]


@dataclasses.dataclass(frozen=True)
class DroppedTerm:
    """A baseline term the flight does not support, with the figures that dropped it.

    The errors are RMS of the observed equation error [-], before and after the term was
    removed (the terms dropped before it already out); the gains are what the rule read.

    Attributes
    ----------
    coefficient : str
        The coefficient.
    term : str
        The term dropped.
    pse_with : float
        Cross-validated held-out RMS with the term: each fold predicted by the fit on the
        others [-].
    pse_without : float
        The same without it [-].
    edges_with : float
        RMS over the first and last blocks predicted by the fit on the middle ones, with the
        term [-].
    edges_without : float
        The same without it [-].
    pse_gain : float
        Mean over the folds of the held-out error the term removes, without its
        regressor-noise part, fraction of the error without it [-].
    edges_gain : float
        The same on the edges [-].
    """

    coefficient: str
    term: str
    pse_with: float
    pse_without: float
    edges_with: float
    edges_without: float
    pse_gain: float
    edges_gain: float

    @property
    def line(self) -> str:
        """One line: "CD_q dropped: held-out error 0.00123 -> 0.00121 without it, ..."."""
        return (f"{self.term} dropped: held-out error {self.pse_with:.3g} -> "
                f"{self.pse_without:.3g} without it, edges {self.edges_with:.3g} -> "
                f"{self.edges_without:.3g} (it gains {100 * self.pse_gain:+.2g} % on the "
                f"folds and {100 * self.edges_gain:+.2g} % on the edges; 0 in the model)")


@dataclasses.dataclass(frozen=True)
class Pruning:
    """The terms of one coefficient kept and those dropped.

    Attributes
    ----------
    kept : tuple of str
        The terms kept, in their order.
    dropped : tuple of DroppedTerm
        The terms dropped, in the order dropped.
    """

    kept: tuple[str, ...]
    dropped: tuple[DroppedTerm, ...]


class _Errors(NamedTuple):
    """Observed and noise-corrected squared errors of one structure."""

    folds: np.ndarray
    """(2, K) of each fold, fitted on the others."""
    edges: np.ndarray
    """(2,) of the first and last blocks together, fitted on the middle ones."""


def _columns(blocks: BlockMoments, keep: Sequence[int]) -> BlockMoments:
    """The block moments of the design restricted to the columns ``keep``."""
    pair = np.ix_(keep, keep)
    return BlockMoments(blocks.edges, blocks.xx[:, pair[0], pair[1]], blocks.xz[:, keep],
                        blocks.noise_xx[:, pair[0], pair[1]], blocks.noise_xz[:, keep])


def _errors(blocks: BlockMoments, X: np.ndarray, z: np.ndarray, keep: Sequence[int]
            ) -> _Errors:
    """The fold and edge errors of the structure ``keep`` (columns of ``X``)."""
    sub, X = _columns(blocks, keep), X[:, keep]
    folds = held_out_errors(sub, z, lambda theta: X @ theta.T)
    middle = slice(1, len(blocks.edges) - 2)
    theta = solve_normal_equations((sub.xx[middle] - sub.noise_xx[middle]).sum(axis=0),
                                   (sub.xz[middle] - sub.noise_xz[middle]).sum(axis=0))
    edges = np.zeros(2)
    for k in (0, len(blocks.edges) - 2):
        a, b = blocks.edges[k], blocks.edges[k + 1]
        edges += squared_errors(z[a:b], X[a:b] @ theta, theta, sub.noise_xx[k],
                                sub.noise_xz[k])
    return _Errors(folds, edges)


def prune(coefficient: str, names: Sequence[str], X: np.ndarray, z: np.ndarray,
          noise: PropagatedNoise, edges: Sequence[int], min_gain: float,
          always: Sequence[str] = ()) -> Pruning:
    """Backward elimination of the columns of the design ``(X, z)`` (see the module).

    Parameters
    ----------
    coefficient : str
        The coefficient (for the records).
    names : sequence of str
        The column names.
    X : numpy.ndarray of shape (N, n)
        Regressor columns.
    z : numpy.ndarray of shape (N,)
        The measured coefficient.
    noise : PropagatedNoise
        The regressor noise.
    edges : sequence of int
        Blocked fold boundaries (at least three folds: the edge check fits the middle ones).
    min_gain : float
        Gain a term must show on the folds or on the edges to be kept (fraction).
    always : sequence of str
        Terms never dropped (the constant).

    Returns
    -------
    Pruning
        The terms kept and dropped.

    Raises
    ------
    ValueError
        With fewer than three folds.
    """
    if len(edges) < 4:
        raise ValueError(f"prune: {len(edges) - 1} folds; the edge check needs at least 3")
    blocks = BlockMoments.of(X, z, noise, edges)
    n_edges = edges[1] - edges[0] + edges[-1] - edges[-2]
    keep = list(range(len(names)))
    current = _errors(blocks, X, z, keep)
    dropped = []
    while True:
        trials = []
        for j in (j for j in keep if names[j] not in always):
            without = _errors(blocks, X, z, [i for i in keep if i != j])
            pse_gain = float(np.mean((without.folds[1] - current.folds[1]) / without.folds[0]))
            edges_gain = float((without.edges[1] - current.edges[1]) / without.edges[0])
            if pse_gain < min_gain and edges_gain < min_gain:
                trials.append((pse_gain, edges_gain, j, without))
        if not trials:
            return Pruning(tuple(names[i] for i in keep), tuple(dropped))
        pse_gain, edges_gain, j, without = min(trials, key=lambda t: t[0])
        dropped.append(DroppedTerm(
            coefficient, names[j],
            *(float(v) for v in np.sqrt([current.folds[0].sum() / len(z),
                                         without.folds[0].sum() / len(z),
                                         current.edges[0] / n_edges,
                                         without.edges[0] / n_edges])),
            pse_gain, edges_gain))
        keep.remove(j)
        current = without
