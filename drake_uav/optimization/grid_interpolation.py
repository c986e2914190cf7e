"""Multilinear interpolation of values stored on a regular grid, vectorised in numpy.

The run-time half of a reachable tube: a membership query must cost microseconds and
must not import the solver that computed the values (JAX). ``scipy``'s
``RegularGridInterpolator`` does the same arithmetic but validates and re-derives the
grid on every call, which dominates for one or a few query points
(``benchmarks/bench_tubes.py`` measures both).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

__all__ = ["RegularGridValues"]


class RegularGridValues:
    """Values on a regular grid, evaluated by multilinear interpolation.

    Parameters
    ----------
    values : numpy.ndarray
        Values at the nodes, shape ``(n_1, ..., n_d)``, every ``n_k >= 2``.
    lower, upper : sequence of float
        First and last node coordinates per dimension.

    Raises
    ------
    ValueError
        ``values`` has a dimension with fewer than two nodes, ``lower``/``upper`` do
        not match its dimensions, or ``upper <= lower``.
    """

    def __init__(self, values: np.ndarray, lower, upper):
        values = np.ascontiguousarray(values, dtype=float)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        d = values.ndim
        if self.lower.shape != (d,) or self.upper.shape != (d,):
            raise ValueError(f"lower/upper need {d} entries (one per grid dimension), got "
                             f"{self.lower.shape} and {self.upper.shape}")
        if any(n < 2 for n in values.shape):
            raise ValueError(f"values need at least 2 nodes per dimension, got {values.shape}")
        if not np.all(self.upper > self.lower):
            raise ValueError(f"upper must exceed lower, got {self.lower} and {self.upper}")
        self.values = values
        self.shape = np.array(values.shape)
        self.spacing = (self.upper - self.lower) / (self.shape - 1)
        self._flat = values.ravel()
        strides = np.array(values.strides) // values.itemsize
        corners = np.array(list(itertools.product((0, 1), repeat=d)), dtype=np.intp)
        self._offsets = corners @ strides
        self._strides = strides
        self._axes = list(zip(self.lower.tolist(), self.spacing.tolist(), values.shape,
                              strides.tolist(), strict=True))

    @property
    def coordinates(self) -> tuple[np.ndarray, ...]:
        """Node coordinates per dimension."""
        return tuple(np.linspace(lo, hi, n)
                     for lo, hi, n in zip(self.lower, self.upper, self.shape, strict=True))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Interpolated values at ``points`` (N, d); points beyond the grid are clamped to it.

        Returns an array (N,).
        """
        position = (points - self.lower) / self.spacing
        cell = np.clip(np.floor(position).astype(np.intp), 0, self.shape - 2)
        t = np.clip(position - cell, 0.0, 1.0)
        corners = self._flat[(cell @ self._strides)[:, None] + self._offsets]
        # Corners are ordered with the first dimension slowest: halve them dimension by
        # dimension with a linear blend.
        for k in range(t.shape[1]):
            half = corners.shape[1] // 2
            tk = t[:, k:k + 1]
            corners = corners[:, :half] + tk * (corners[:, half:] - corners[:, :half])
        return corners[:, 0]

    def at(self, point) -> tuple[float, float]:
        """Value at one point (d floats) and its distance beyond the grid in cells (0 inside).

        The same interpolation as calling the object, in float arithmetic: a few
        microseconds instead of the per-call cost of numpy on tiny arrays.
        """
        base, blend, beyond = 0, [], 0.0
        for x, (lo, step, n, stride) in zip(point, self._axes, strict=True):
            position = (x - lo) / step
            beyond = max(beyond, -position, position - (n - 1))
            cell = min(max(math.floor(position), 0), n - 2)
            blend.append(min(max(position - cell, 0.0), 1.0))
            base += cell * stride
        corners = self._flat[self._offsets + base].tolist()
        for t in blend:
            half = len(corners) // 2
            corners = [a + t * (b - a) for a, b in zip(corners[:half], corners[half:],
                                                       strict=True)]
        return corners[0], beyond

    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        """Largest distance beyond the grid over the dimensions, in grid cells (0 inside)."""
        below = (self.lower - points) / self.spacing
        above = (points - self.upper) / self.spacing
        return np.maximum(np.maximum(below, above).max(axis=1), 0.0)
