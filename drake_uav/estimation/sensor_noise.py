"""Sensor noise floors read from the flight data alone.

The white noise of a sensor channel has a flat spectrum ``a`` [unit^2/Hz] up to
the Nyquist frequency; the flight signal beneath it does not fade there in
turbulence. The gusts of a discrete turbulence model change every step, so the
accelerations and air data they drive behave like a random walk at high
frequencies, whose spectrum is ``b / sin^2(pi f / fs)`` (the spectrum of a
discrete integrator of white noise); what the aircraft's inertia filters once
more falls like ``c / sin^4(pi f / fs)``. A logger that averages or interpolates
adjacent samples (an autopilot's light filtering, a channel re-timed between samples)
colours the noise: white noise through a two-tap filter has the spectrum
``A cos^2(pi f / fs) + B sin^2(pi f / fs)``, ``A = B`` when it is white, ``B = 0`` for
the mean of two samples, whose floor vanishes at the Nyquist frequency. The floor is
fitted as those two shapes, with the signal's two, by non-negative least squares on
the upper part of the Welch spectrum (Welch 1967), weighted by the fitted spectrum (the
scatter of a Welch estimate is proportional to its value); the noise variance per
sample is ``(A + B) fs / 4`` (``a fs / 2`` for a white floor ``a``). A constant floor
alone reads the mean of two samples as noiseless, and the errors-in-variables
correction then leaves their noise in the fit.

A signal the autopilot's commands drive (the thrust of a throttle that moves
every step) has neither shape. The part of the channel's spectrum that is
coherent with the logged commands is removed first (the conditioned spectrum,
Bendat & Piersol 2010, ch. 7); the commands are exact, so this removes signal,
not noise -- unless the autopilot feeds the channel back into its commands
(a rate damper: the gyro noise is then in the commands too, and the
conditioned spectrum loses most of its floor). The floor is therefore the
conditioned fit's, unless it is below :data:`FEEDBACK_RATIO` of the plain
fit's: then the channel is taken as fed back and the plain fit is kept.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls
from scipy.signal import get_window
from scipy.stats import f as f_distribution

__all__ = ["cross_spectral_density", "conditioned_spectrum", "white_floor",
           "noise_floor_variance"]

SEGMENT = 256
"""Welch segment length [samples] (Hann window, half overlap)."""
LOWEST_FIT_FRACTION = 0.2
"""The floor is fitted above this fraction of the Nyquist frequency."""
FEEDBACK_RATIO = 0.25
"""A conditioned floor below this fraction of the plain one marks a channel the
commands feed back: conditioning removed its noise, not only signal."""
COLOURED_LEVEL = 1e-3
"""Significance level at which a two-tap (coloured) noise floor replaces a white one."""
SIGNAL_SHAPES = (2, 4)
"""Powers ``k`` of the signal's shapes ``sin(pi f / fs)^-k``: random walk, its integral."""


def cross_spectral_density(columns: np.ndarray, rate_hz: float, segment: int = SEGMENT
                           ) -> tuple[np.ndarray, np.ndarray, int]:
    """One-sided Welch cross-spectral densities of the columns of ``columns`` (n, m).

    Hann segments of ``segment`` samples with half overlap, each segment's mean
    removed, scaled to [unit^2/Hz] like :func:`scipy.signal.welch`. Returns the
    frequencies [Hz] (nf,), the densities (nf, m, m) and the number of segments.
    """
    columns = np.asarray(columns, dtype=float)
    n = columns.shape[0]
    segment = min(segment, n)
    window = get_window("hann", segment)
    starts = range(0, n - segment + 1, max(segment // 2, 1))
    pieces = np.stack([columns[s:s + segment] - columns[s:s + segment].mean(axis=0)
                       for s in starts])
    spectra = np.fft.rfft(pieces * window[None, :, None], axis=1)
    density = np.einsum("kfi,kfj->fij", spectra, spectra.conj()) / len(pieces)
    density *= 2.0 / (rate_hz * (window @ window))
    density[0] /= 2.0
    if segment % 2 == 0:
        density[-1] /= 2.0
    return np.fft.rfftfreq(segment, 1.0 / rate_hz), density, len(pieces)


def conditioned_spectrum(values: np.ndarray, inputs: np.ndarray, rate_hz: float,
                         segment: int = SEGMENT) -> tuple[np.ndarray, np.ndarray] | None:
    """Spectrum of ``values`` (n,) less its part coherent with ``inputs`` (n, m).

    ``S_xx - S_xu S_uu^+ S_ux`` per frequency, scaled by ``K / (K - m)`` for the
    ``m`` degrees of freedom the linear fit takes from the ``K`` segments.
    Returns (frequencies [Hz], density), or None when the log has too few
    segments (``K <= 2 m``) for the inputs.
    """
    inputs = np.asarray(inputs, dtype=float).reshape(len(values), -1)
    inputs = inputs[:, np.ptp(inputs, axis=0) > 0]
    m = inputs.shape[1]
    frequency, density, count = cross_spectral_density(
        np.column_stack([values, inputs]), rate_hz, segment)
    if m == 0 or count <= 2 * m:
        return None
    coupling = density[:, 0, 1:]
    gain = np.linalg.pinv(density[:, 1:, 1:], rcond=1e-10, hermitian=True)
    explained = np.einsum("fi,fij,fj->f", coupling, gain, coupling.conj())
    return frequency, np.real(density[:, 0, 0] - explained) * count / (count - m)


def white_floor(frequency: np.ndarray, density: np.ndarray, rate_hz: float,
                lowest: float = LOWEST_FIT_FRACTION, averaged: int = 1) -> float:
    """Noise variance per sample [unit^2] of the noise floor of a one-sided spectrum
    (``averaged`` > 1: of the mean of that many consecutive samples, :func:`_mean_variance`).

    Fits ``a + b / s^2 + c / s^4`` (``s = sin(pi f / fs)``, all >= 0) to the ``density``
    [unit^2/Hz] between ``lowest`` times the Nyquist frequency and the Nyquist bin
    (excluded), weighted by the fitted spectrum (three passes), and the same with the
    two-tap floor ``A (1 - s^2) + B s^2`` in place of ``a``; the two-tap fit is taken when
    it is better at the :data:`COLOURED_LEVEL` of an F-test. Returns ``a fs / 2`` or
    ``(A + B) fs / 4``.
    """
    band = (frequency >= lowest * rate_hz / 2.0) & (frequency < rate_hz / 2.0)
    band[0] = False
    f, p = frequency[band], np.maximum(density[band], 0.0)
    if f.size < 3 + len(SIGNAL_SHAPES) or not np.any(p > 0):
        return 0.0
    s = np.sin(np.pi * f / rate_hz)
    signal_shapes = [s ** -k for k in SIGNAL_SHAPES]
    white, white_misfit = _weighted_fit(np.column_stack([np.ones_like(s), *signal_shapes]), p)
    coloured, coloured_misfit = _weighted_fit(
        np.column_stack([1.0 - s**2, s**2, *signal_shapes]), p)
    dof = f.size - 2 - len(SIGNAL_SHAPES)
    gain = (white_misfit - coloured_misfit) / max(coloured_misfit / dof, 1e-300)
    # The white floor is the two-tap one with A = B = a.
    coloured_floor = gain > f_distribution.isf(COLOURED_LEVEL, 1, dof)
    a, b = (coloured[0], coloured[1]) if coloured_floor else (white[0], white[0])
    if averaged > 1:
        return _mean_variance(a, b, rate_hz, averaged)
    return float((a + b) * rate_hz / 4.0)


def _mean_variance(a: float, b: float, rate_hz: float, averaged: int) -> float:
    """Variance [unit^2] of the mean of ``averaged`` consecutive samples of the noise of
    one-sided density ``a (1 - s^2) + b s^2`` (``s = sin(pi f / fs)``): its integral times
    the mean's power gain ``(sin(m pi f / fs) / (m sin(pi f / fs)))^2`` up to ``fs / 2``
    (the midpoint rule on 4096 bins)."""
    x = (np.arange(4096) + 0.5) / 4096 * np.pi / 2  # pi f / fs over (0, pi / 2)
    s = np.sin(x)
    gain = (np.sin(averaged * x) / (averaged * s)) ** 2
    return float(np.mean((a * (1.0 - s**2) + b * s**2) * gain) * rate_hz / 2.0)


def _weighted_fit(shapes: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative coefficients of ``shapes`` (n, k) fitted to ``p`` (n), weighted by the
    fitted spectrum (three passes), and the weighted sum of squared misfits."""
    tiny = 1e-6 * float(np.max(p))
    weight = 1.0 / np.maximum(p, tiny)
    for _ in range(3):
        coefficients, _ = nnls(shapes * weight[:, None], p * weight)
        weight = 1.0 / np.maximum(shapes @ coefficients, tiny)
    return coefficients, float(np.sum(((p - shapes @ coefficients) * weight) ** 2))


def noise_floor_variance(values: np.ndarray, rate_hz: float,
                         inputs: np.ndarray | None = None, averaged: int = 1) -> float:
    """White-noise variance per sample [unit^2] of a uniformly sampled channel (``averaged``
    > 1: of the mean of that many consecutive samples).

    ``values`` (n,) sampled at ``rate_hz`` [Hz]; ``inputs`` (n, m), the logged
    commands on the same samples, when known. The floor of the command-conditioned
    spectrum, or of the plain one for a channel the commands feed back (see the
    module text).
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size < 8:
        raise ValueError(f"noise_floor_variance: need a 1-D signal of at least 8 samples, "
                         f"got shape {values.shape}")
    if not (rate_hz > 0 and np.isfinite(rate_hz)):
        raise ValueError(f"noise_floor_variance: rate_hz must be positive, got {rate_hz}")
    frequency, density, _ = cross_spectral_density(values[:, None], rate_hz)
    floor = white_floor(frequency, density[:, 0, 0].real, rate_hz, averaged=averaged)
    if inputs is not None:
        conditioned = conditioned_spectrum(values, inputs, rate_hz)
        if conditioned is not None:
            without_commands = white_floor(*conditioned, rate_hz, averaged=averaged)
            if without_commands >= FEEDBACK_RATIO * floor:
                floor = without_commands
    return floor
