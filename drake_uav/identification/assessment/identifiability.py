"""What one flight can tell about each derivative: correlated and unexcited regressors.

A derivative is identified from how its regressor varies independently of the others.
Two regressors the flight moved together (pitch rate and alpha in a phugoid, elevator
and alpha at trim) let their derivatives trade against each other: each alone is poorly
determined, however well the fit predicts. A regressor that hardly varies leaves its
derivative to the noise. The diagnostics are the classical ones of data collinearity
(Klein & Morelli 2006, ch. 5): pairwise correlation, variance inflation factor
``VIF_j = 1 / (1 - R_j^2)`` (``R_j`` the multiple correlation of column j with the
others) and the relative standard error of the estimate.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from drake_uav.identification.discovery.plausibility import (
    DerivativeWarning,
    implausible_derivatives,
)
from drake_uav.identification.discovery.result import CoefficientFit

__all__ = ["CORRELATION_LIMIT", "VIF_LIMIT", "RELATIVE_SIGMA_LIMIT", "CONSTANT_TOLERANCE",
           "correlated_regressors", "unexcited_derivatives", "variance_inflation",
           "derivative_warnings"]

CORRELATION_LIMIT = 0.95
"""Pairwise |correlation| above which two regressors are named as moving together."""
VIF_LIMIT = 10.0
"""Variance inflation factor above which a regressor is named as nearly a combination of
the others (the usual rule of thumb, Klein & Morelli 2006, ch. 5)."""
RELATIVE_SIGMA_LIMIT = 0.5
"""Standard error above this share of the estimate: the flight does not pin it down."""
CONSTANT_TOLERANCE = 1e-9
"""A column whose std is at most this times ``1 + |mean|`` does not vary."""


def _varying(names: Sequence[str], X: np.ndarray) -> list[int]:
    """Indices of the columns that vary (the constant term and constant columns left out)."""
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != len(names):
        raise ValueError(f"{len(names)} derivative names for regressor columns of shape "
                         f"{X.shape}")
    std, mean = X.std(axis=0), np.abs(X.mean(axis=0))
    return [j for j in range(len(names)) if std[j] > CONSTANT_TOLERANCE * (1.0 + mean[j])]


def variance_inflation(X: np.ndarray) -> np.ndarray:
    """Variance inflation factor of every column of ``X``.

    The diagonal of the inverse correlation matrix: how much a column's variance of
    estimate grows because the other columns explain it.

    Parameters
    ----------
    X : numpy.ndarray of shape (N, n)
        Regressor columns, n >= 2, all varying.

    Returns
    -------
    numpy.ndarray of shape (n,)
        VIF >= 1 of each column; inf where a column is a combination of the others.
    """
    R = np.corrcoef(np.asarray(X, dtype=float), rowvar=False)
    try:
        return np.diag(np.linalg.inv(R)).copy()
    except np.linalg.LinAlgError:
        return np.full(R.shape[0], np.inf)


def correlated_regressors(names: Sequence[str], X: np.ndarray) -> list[DerivativeWarning]:
    """Warnings for regressor pairs and columns the flight does not separate.

    A pair with |correlation| > :data:`CORRELATION_LIMIT`, and a column with VIF >
    :data:`VIF_LIMIT` not already named in such a pair.

    Parameters
    ----------
    names : sequence of str
        The derivatives of the columns of ``X``.
    X : numpy.ndarray of shape (N, n)
        The regressor columns of one fit.

    Returns
    -------
    list of DerivativeWarning
        Of kind "correlated"; empty when every column stands apart.
    """
    keep = _varying(names, X)
    if len(keep) < 2:
        return []
    columns = np.asarray(X, dtype=float)[:, keep]
    kept = [names[j] for j in keep]
    R = np.corrcoef(columns, rowvar=False)
    out, paired = [], set()
    for a in range(len(kept)):
        for b in range(a + 1, len(kept)):
            if abs(R[a, b]) > CORRELATION_LIMIT:
                paired |= {kept[a], kept[b]}
                out.append(DerivativeWarning(
                    "correlated", (kept[a], kept[b]),
                    f"{kept[a]} and {kept[b]}: regressors correlated at {R[a, b]:+.3f} in "
                    "this flight; their derivatives trade against each other"))
    for name, vif in zip(kept, variance_inflation(columns), strict=True):
        if vif > VIF_LIMIT and name not in paired:
            out.append(DerivativeWarning(
                "correlated", (name,),
                f"{name}: variance inflation factor {vif:.3g} (> {VIF_LIMIT:g}); its "
                "regressor is nearly a combination of the others in this flight"))
    return out


def unexcited_derivatives(names: Sequence[str], X: np.ndarray, estimate: np.ndarray,
                          sigma: np.ndarray) -> list[DerivativeWarning]:
    """Warnings for derivatives the flight does not determine.

    A regressor that does not vary, or a standard error above
    :data:`RELATIVE_SIGMA_LIMIT` of the estimate. The constant term is not a direction of
    excitation and is left out.

    Parameters
    ----------
    names : sequence of str
        The derivatives of the columns of ``X``.
    X : numpy.ndarray of shape (N, n)
        The regressor columns of one fit.
    estimate : numpy.ndarray of shape (n,)
        The fit's estimates.
    sigma : numpy.ndarray of shape (n,)
        Their standard errors.

    Returns
    -------
    list of DerivativeWarning
        Of kind "unexcited".
    """
    varying = set(_varying(names, X))
    out = []
    for j, name in enumerate(names):
        if name.endswith("_0"):
            continue
        if j not in varying:
            out.append(DerivativeWarning(
                "unexcited", (name,), f"{name}: its regressor does not vary in this flight; "
                "the derivative is not identified"))
        elif sigma[j] > RELATIVE_SIGMA_LIMIT * abs(estimate[j]):
            out.append(DerivativeWarning(
                "unexcited", (name,),
                f"{name} = {estimate[j]:.3g} +- {sigma[j]:.2g} (sigma / |estimate| = "
                f"{_ratio(sigma[j], estimate[j]):.2g}): the flight does not pin it down"))
    return out


def _ratio(sigma: float, estimate: float) -> float:
    return sigma / abs(estimate) if estimate != 0 else float("inf")


def derivative_warnings(catalog: Mapping[str, float], final: Mapping[str, CoefficientFit]
                        ) -> list[DerivativeWarning]:
    """Implausible catalog values, then implausible, correlated and unexcited identified
    derivatives of every final fit (the effects' own columns are not range-checked).

    Parameters
    ----------
    catalog : Mapping
        The aircraft's derivatives, by name (``CL_alpha`` ...).
    final : Mapping
        Coefficient -> its final fit
        (:attr:`~drake_uav.identification.discovery.result.DiscoveryResult.final`).

    Returns
    -------
    list of DerivativeWarning
        A catalog value's message starts with ``catalog:``.
    """
    out = [dataclasses.replace(w, message=f"catalog: {w.message}")
           for w in implausible_derivatives(catalog)]
    for fit in final.values():
        r = fit.result
        out += implausible_derivatives(dict(zip(fit.names, r.estimate.tolist(), strict=True)),
                                       dict(zip(fit.names, r.sigma.tolist(), strict=True)))
        if fit.training_design is not None:
            out += correlated_regressors(fit.names, fit.training_design)
            out += unexcited_derivatives(fit.names, fit.training_design, r.estimate, r.sigma)
    return out
