"""Isolation formulas: the measured aerodynamic coefficients from flight signals.

The derivative of a sampled signal by a Savitzky-Golay filter (the angular
accelerations of the moment equations; Vaiopoulos 2017, sec. 5.5).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

__all__ = ["differentiate"]


def differentiate(time: np.ndarray, values: np.ndarray, window: float = 0.2,
                  polyorder: int = 3, deriv: int = 1) -> np.ndarray:
    """Time derivative of uniformly sampled ``values`` (along axis 0) by Savitzky-Golay.

    ``window`` is the filter length [s]; ``deriv=0`` gives the smoothed signal
    itself. Raises ``ValueError`` for non-uniform sampling or a window shorter
    than the polynomial needs.
    """
    time = np.asarray(time, dtype=float)
    dt = np.diff(time)
    if len(time) < 3 or np.any(dt <= 0):
        raise ValueError("differentiate: time must be strictly increasing with >= 3 samples")
    step = float(np.median(dt))
    if np.max(np.abs(dt - step)) > 1e-6 * max(step, 1e-12) + 1e-9:
        raise ValueError("differentiate: samples must be uniform in time (resample first)")
    length = int(round(window / step)) | 1
    if length <= polyorder:
        raise ValueError(
            f"differentiate: window {window} s holds {length} samples, needs > {polyorder}")
    length = min(length, len(time) - (1 - len(time) % 2))
    return savgol_filter(values, length, polyorder, deriv=deriv, delta=step, axis=0,
                         mode="interp")
