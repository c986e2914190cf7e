"""Blocked K-fold held-out errors of bias-compensated fits.

The evidence that the discovery loop (:mod:`~drake_uav.identification.discovery.loop`) and the
parsimony of its baseline (:mod:`~drake_uav.identification.discovery.parsimony`) read: the training
part of the flight cut into ``K`` contiguous blocks, each predicted by the fit on the others
(:class:`~.errors_in_variables.BlockMoments`), every error also given
without its regressor-noise part.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from drake_uav.identification.statistics.errors_in_variables import (
    BlockMoments,
    noise_error_energy,
    solve_normal_equations,
)

__all__ = ["fold_edges", "squared_errors", "held_out_errors"]


def fold_edges(n: int, k: int) -> tuple[int, ...]:
    """Boundaries of ``k`` contiguous blocked folds over ``n`` samples.

    Parameters
    ----------
    n : int
        Number of samples.
    k : int
        Number of folds.

    Returns
    -------
    tuple of int
        k + 1 boundaries from 0 to n: fold i holds samples ``edges[i]:edges[i + 1]``.
    """
    return tuple(int(e) for e in np.linspace(0, n, k + 1).astype(int))


def squared_errors(z: np.ndarray, prediction: np.ndarray, theta, C_xx, c_xz
                   ) -> tuple[float, float]:
    """Observed squared error of ``prediction``, and the same without its regressor-noise part.

    Comparing models by the error without it scores how well they predict the true
    coefficient, so a column that merely stands in for a noisy regressor (a cleaner proxy)
    gains nothing.

    Parameters
    ----------
    z : numpy.ndarray of shape (N,)
        Observation.
    prediction : numpy.ndarray of shape (N,)
        The model's prediction of ``z``.
    theta : numpy.ndarray of shape (n,)
        The parameters that made the prediction.
    C_xx : numpy.ndarray of shape (n, n)
        Expected regressor-noise moment ``dX^T dX`` of the same rows.
    c_xz : numpy.ndarray of shape (n,)
        Expected ``dX^T dz`` of the same rows.

    Returns
    -------
    observed : float
        ``|z - prediction|^2``, in the unit of z squared.
    corrected : float
        ``observed`` minus its expected regressor-noise part.
    """
    r = z - prediction
    observed = float(r @ r)
    return observed, observed - noise_error_energy(theta, C_xx, c_xz)


def held_out_errors(blocks: BlockMoments, z: np.ndarray,
                    predict: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Observed and noise-corrected held-out squared error of each blocked fold.

    Each fold is predicted by the fit on all the others (blocked cross-validation).

    Parameters
    ----------
    blocks : BlockMoments
        Per-block moments of the design.
    z : numpy.ndarray of shape (N,)
        Observation.
    predict : callable
        ``predict(theta)`` maps the (K, n) fits to the (N, K) predictions of every fit.

    Returns
    -------
    numpy.ndarray of shape (2, K)
        Row 0 the observed, row 1 the noise-corrected squared error of each fold.
    """
    theta = solve_normal_equations(*blocks.held_in())
    prediction = predict(theta)
    edges: Sequence[int] = blocks.edges
    return np.array([squared_errors(z[a:b], prediction[a:b, k], theta[k], blocks.noise_xx[k],
                                    blocks.noise_xz[k])
                     for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True))]).T
