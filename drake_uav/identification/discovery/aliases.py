"""Aliases: terms of another physical origin that an accepted effect's columns cannot be
told apart from on this flight.

A term's *physical origin* is what would cause it, read from the candidates' metadata:
:attr:`~drake_uav.identification.discovery.evidence.Candidate.origin` (for the fixed-wing
job, :attr:`~drake_uav.identification.discovery.effects.Effect.origin`; every vector
effect is ``"an external force"``), and for the baseline's terms :data:`CATALOG_ORIGIN`
(an aircraft derivative). Terms of one origin are variants of one explanation (a force at
the centre of gravity or below it); terms of different origins are different explanations,
and when their columns move together on a flight, the flight cannot say which one it saw.

:func:`aliases_of` is plant-agnostic: it works on columns and origins. An accepted effect's
*column* is its fitted contribution to the coefficient (its columns times their estimates);
another term's are its columns. Both are taken beyond the rest of the model (residuals of
their least-squares fit on an intercept and the coefficient's other columns), and the
*correlation* is the multiple correlation of the effect's column with the other term's (for
one column each, the absolute partial correlation coefficient). The rest of the model is
common to both explanations, so what it can represent tells neither apart; what is left is
what the flight has to tell them by. Above :data:`ALIAS_CORRELATION` the term is an alias.

The terms compared are those the model could hold instead of the effect: the candidates not
accepted, and the baseline's terms the model left out (the catalog terms the flight does not
support, :mod:`~drake_uav.identification.discovery.parsimony`). A term the model holds
beside the effect is not an alternative to it (the effect was accepted with it in the
model); its correlation with the effect is among the derivative warnings (regressors the
flight moved together).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

__all__ = ["ALIAS_CORRELATION", "CATALOG_ORIGIN", "Alias", "AliasedEffect",
           "Term", "aliases_of", "partial_correlation"]

ALIAS_CORRELATION = 0.95
"""Smallest |correlation| (beyond the rest of the model) at which a term of another origin
is an alias of an accepted effect: at 0.95 the two share 90 % of the variation the flight
has to tell them by, and the effect's parameter's variance is inflated tenfold by the
other's presence."""

CATALOG_ORIGIN = "the aircraft's catalog model"
"""Origin of a baseline derivative (``CD_alpha``, ...)."""


@dataclasses.dataclass(frozen=True)
class Term:
    """A term the accepted effect is compared with.

    Attributes
    ----------
    name : str
        Its name: a candidate effect's, or a baseline term's.
    origin : str
        Its physical origin.
    columns : numpy.ndarray of shape (N, q)
        Its columns on the flight.
    baseline : bool
        The term is one of the baseline's that the model left out (its alternative is the
        term with a value of its own).
    """

    name: str
    origin: str
    columns: np.ndarray
    baseline: bool = False


@dataclasses.dataclass(frozen=True)
class Alias:
    """A term of another origin the accepted effect cannot be told apart from.

    Attributes
    ----------
    name : str
        The term (a candidate effect, or a baseline term).
    origin : str
        Its physical origin.
    correlation : float
        |correlation| of the two beyond the rest of the model [-].
    baseline : bool
        The term is one of the baseline's that the model left out (its alternative is the
        model with that term).
    """

    name: str
    origin: str
    correlation: float
    baseline: bool = False

    @property
    def label(self) -> str:
        """How a summary line names it: the effect's name, or ``the catalog's <term>`` for a
        baseline term the model left out."""
        return f"the catalog's {self.name}" if self.baseline else self.name


@dataclasses.dataclass(frozen=True)
class AliasedEffect:
    """An accepted effect on one coefficient and its aliases on this flight.

    Attributes
    ----------
    effect : str
        The accepted effect.
    coefficient : str
        The coefficient.
    origin : str
        The effect's physical origin.
    aliases : tuple of Alias
        Its aliases, the most correlated first.
    """

    effect: str
    coefficient: str
    origin: str
    aliases: tuple[Alias, ...]

    @property
    def correlation(self) -> float:
        """The largest |correlation| of an alias [-]."""
        return max(a.correlation for a in self.aliases)

    def summary(self) -> dict:
        """JSON-ready summary.

        Returns
        -------
        dict
            ``effect``, ``coefficient``, ``origin`` and ``aliases`` (name, origin,
            correlation, baseline).
        """
        return {"effect": self.effect, "coefficient": self.coefficient, "origin": self.origin,
                "aliases": [dataclasses.asdict(a) for a in self.aliases]}


def _beyond(values: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """``values`` (N, q) less their projection on the orthonormal ``basis`` (N, r)."""
    return values - basis @ (basis.T @ values)


def _basis(rest: np.ndarray) -> np.ndarray:
    """Orthonormal basis of an intercept and the columns ``rest`` (N, r)."""
    X = np.column_stack([np.ones(len(rest)), rest])
    u, s, _ = np.linalg.svd(X, full_matrices=False)
    keep = s > np.finfo(float).eps * max(X.shape) * s[0]
    return u[:, keep]


def partial_correlation(column: np.ndarray, other: np.ndarray, rest: np.ndarray) -> float:
    """Multiple correlation of ``column`` with the columns ``other``, both beyond an
    intercept and ``rest``.

    Parameters
    ----------
    column : numpy.ndarray of shape (N,)
        One column.
    other : numpy.ndarray of shape (N, q)
        The other term's columns.
    rest : numpy.ndarray of shape (N, r)
        The columns common to both (r may be 0).

    Returns
    -------
    float
        In [0, 1]; 0 when either has no variation beyond ``rest``.

    Examples
    --------
    Over ``t`` in [0, 1], beyond a straight line, ``t^2`` moves with ``t^3`` and less with
    ``t^4``:

    >>> t = np.linspace(0.0, 1.0, 200)
    >>> round(partial_correlation(t**2, t[:, None] ** 3, t[:, None]), 3)
    0.986
    >>> round(partial_correlation(t**2, t[:, None] ** 4, t[:, None]), 3)
    0.958
    """
    basis = _basis(rest)
    x = _beyond(np.asarray(column, dtype=float)[:, None], basis)[:, 0]
    Y = _beyond(np.asarray(other, dtype=float).reshape(len(x), -1), basis)
    scale = float(np.linalg.norm(x))
    if scale <= 1e-9 * max(float(np.linalg.norm(column)), 1e-300) or not np.any(Y):
        return 0.0
    fit = Y @ np.linalg.lstsq(Y, x, rcond=None)[0]
    return float(min(np.linalg.norm(fit) / scale, 1.0))


def aliases_of(effect: str, coefficient: str, origin: str, column: np.ndarray,
               model: Mapping[str, np.ndarray], terms: list[Term],
               threshold: float = ALIAS_CORRELATION) -> AliasedEffect | None:
    """The terms of another origin an accepted effect cannot be told apart from.

    Parameters
    ----------
    effect : str
        The accepted effect's name.
    coefficient : str
        The coefficient it is kept on.
    origin : str
        Its physical origin.
    column : numpy.ndarray of shape (N,)
        Its fitted contribution to the coefficient on the flight.
    model : Mapping[str, numpy.ndarray]
        The coefficient's other fitted columns, by name (N,) each.
    terms : list of Term
        The terms outside the model it is compared with; those of its own origin are not.
    threshold : float
        Smallest |correlation| of an alias (:data:`ALIAS_CORRELATION`).

    Returns
    -------
    AliasedEffect or None
        None when it has no alias.

    """
    rest = (np.column_stack(list(model.values())) if model
            else np.zeros((len(column), 0)))
    found = []
    for term in (t for t in terms if t.origin != origin):
        correlation = partial_correlation(column, term.columns, rest)
        if correlation > threshold:
            found.append(Alias(term.name, term.origin, correlation, term.baseline))
    if not found:
        return None
    return AliasedEffect(effect, coefficient, origin,
                         tuple(sorted(found, key=lambda a: -a.correlation)))
