"""Scalar helpers that work for float, AutoDiffXd and symbolic Expression.

Plain Python floats take a fast path (the model functions run inside
simulation loops); other scalar types go through :mod:`pydrake.math`.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import max as _drake_max
from pydrake.math import min as _drake_min

__all__ = ["smax", "smin", "clamp", "as_list"]


def smax(a, b):
    """max(a, b) for any Drake scalar type."""
    if isinstance(a, float) and isinstance(b, float):
        return a if a > b else b
    return _drake_max(a, b)


def smin(a, b):
    """min(a, b) for any Drake scalar type."""
    if isinstance(a, float) and isinstance(b, float):
        return a if a < b else b
    return _drake_min(a, b)


def clamp(value, low: float, high: float):
    """``value`` limited to ``[low, high]``."""
    return smin(smax(value, low), high)


def as_list(values) -> list:
    """Python list of the entries (float arithmetic on lists beats numpy scalars)."""
    return values.tolist() if isinstance(values, np.ndarray) else list(values)
