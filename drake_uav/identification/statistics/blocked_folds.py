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
    """Boundaries of ``k`` contiguous blocked folds over ``n`` samples."""
    return tuple(int(e) for e in np.linspace(0, n, k + 1).astype(int))


def squared_errors(z: np.ndarray, prediction: np.ndarray, theta, C_xx, c_xz
                   ) -> tuple[float, float]:
    """Observed squared error of ``prediction`` and the same without its regressor-noise part
    (the noise moments ``C_xx, c_xz`` of the same rows).

    Comparing models by the error without it scores how well they predict the true
    coefficient, so a column that merely stands in for a noisy regressor (a cleaner proxy)
    gains nothing.
    """
    r = z - prediction
    observed = float(r @ r)
    return observed, observed - noise_error_energy(theta, C_xx, c_xz)


def held_out_errors(blocks: BlockMoments, z: np.ndarray,
                    predict: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """(2, K): observed and noise-corrected held-out squared error of each blocked fold,
    fitted on the others; ``predict(theta)`` (K, n) -> (N, K) predictions of every fit."""
    theta = solve_normal_equations(*blocks.held_in())
    prediction = predict(theta)
    edges: Sequence[int] = blocks.edges
    return np.array([squared_errors(z[a:b], prediction[a:b, k], theta[k], blocks.noise_xx[k],
                                    blocks.noise_xz[k])
                     for k, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True))]).T
