"""Scalar helpers that work for float, AutoDiffXd and symbolic Expression.

Plain Python floats take a fast path (the model functions run inside
simulation loops); other scalar types go through :mod:`pydrake.math`.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import max as _drake_max
from pydrake.math import min as _drake_min
from pydrake.math import sqrt as _drake_sqrt

__all__ = ["smax", "smin", "clamp", "ssqrt", "as_list"]


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


def ssqrt(value):
    """Square root for any Drake scalar type and, elementwise, for float arrays (a model
    evaluated on a whole flight's samples)."""
    if isinstance(value, float | np.floating) or (isinstance(value, np.ndarray)
                                                  and value.dtype.kind == "f"):
        return np.sqrt(value)
    return _drake_sqrt(value)


def as_list(values) -> list:
    """Python list of the entries (float arithmetic on lists beats numpy scalars)."""
    return values.tolist() if isinstance(values, np.ndarray) else list(values)
