"""Designed excitation inputs for flight-test identification.

Signals (plain functions of a time array and frozen dataclasses that call them):

* :func:`doublet`: +A for ``width`` seconds, then -A for ``width``.
* :func:`three_two_one_one`: +A, -A, +A, -A for 3, 2, 1, 1 times ``unit_width``.
* :func:`multisine`: sum of harmonics of 1/period, ``A_k cos(2 pi k t / T + phi_k)``.
  :func:`schroeder_phases` gives Schroeder's low-peak-factor phases;
  :func:`low_peak_factor_phases` refines them by iterative clipping (keeping the
  harmonic amplitudes) and shifts the signal so it starts at zero, as in
  Morelli's multiple-input design (Klein & Morelli 2006).
* :func:`orthogonal_multisines`: several surfaces excited at once with disjoint
  harmonic sets, mutually orthogonal over each period, so one manoeuvre
  separates the effect of each surface.
* :class:`Turn`: a steady turn, flown by moving the heading the autopilot holds
  (a *reference* channel, :data:`REFERENCES`, rather than a surface).

Times are in seconds, frequencies in Hz; amplitudes are in the unit of their
channel (rad for elevator, aileron and rudder, a 0..1 fraction for throttle; for a
reference, rad or m or m/s, :data:`REFERENCES`). :class:`ExcitationSource` adds the
signals to the trim controls (or to zero reference offsets) and holds the result at a
fixed sample period (the autopilot's output rate).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, Self

import numpy as np
from pydrake.systems.framework import LeafSystem

__all__ = [
    "SURFACES",
    "REFERENCES",
    "doublet",
    "three_two_one_one",
    "multisine",
    "schroeder_phases",
    "low_peak_factor_phases",
    "relative_peak_factor",
    "Doublet",
    "ThreeTwoOneOne",
    "Multisine",
    "Turn",
    "orthogonal_multisines",
    "excitation_controls",
    "ExcitationSource",
]

SURFACES = ("elevator", "aileron", "rudder", "throttle")
"""Control channels in the order of the plant's ``controls`` input."""
REFERENCES = ("pitch", "altitude", "heading", "airspeed")
"""Reference channels: offsets [rad, m, rad, m/s] added to what the safety pilot's holds
keep (:class:`~drake_uav.systems.safety_pilot.SafetyPilot`, input ``reference_offsets``).
A signal on one of them is flown by the holds, not by a surface."""


def _positive(name: str, value: float) -> None:
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(f"{name}: must be positive and finite, got {value}")


def _finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{name}: must be finite, got {value}")


def _check_surface(surface: str, channels: Sequence[str] = SURFACES + REFERENCES) -> int:
    if surface not in channels:
        raise ValueError(f"surface: unknown channel {surface!r}; use one of {tuple(channels)}")
    return tuple(channels).index(surface)


def _pulses(t, start: float, widths: Sequence[float], signs: Sequence[float]) -> np.ndarray:
    """Piecewise-constant train: sign_i on [edge_i, edge_i + width_i), zero elsewhere."""
    t = np.asarray(t, float)
    out = np.zeros_like(t)
    edge = start
    for width, sign in zip(widths, signs, strict=True):
        out = np.where((t >= edge) & (t < edge + width), sign, out)
        edge += width
    return out


# Pulse-train shapes: pulse widths in units of the signal's width, and pulse signs.
_DOUBLET = ((1.0, 1.0), (1.0, -1.0))
_THREE_TWO_ONE_ONE = ((3.0, 2.0, 1.0, 1.0), (1.0, -1.0, 1.0, -1.0))


def _pulse_train(t, shape, amplitude: float, unit_width: float, start: float) -> np.ndarray:
    units, signs = shape
    return amplitude * _pulses(t, start, tuple(n * unit_width for n in units), signs)


def doublet(t, amplitude: float, width: float, start: float = 0.0) -> np.ndarray:
    """Doublet: ``+amplitude`` on [start, start + width), ``-amplitude`` for the next ``width``."""
    return _pulse_train(t, _DOUBLET, amplitude, width, start)


def three_two_one_one(t, amplitude: float, unit_width: float, start: float = 0.0) -> np.ndarray:
    """3-2-1-1: alternating pulses of 3, 2, 1 and 1 ``unit_width`` [s], starting positive."""
    return _pulse_train(t, _THREE_TWO_ONE_ONE, amplitude, unit_width, start)


def multisine(t, period: float, harmonics, amplitudes, phases, start: float = 0.0,
              cycles: float = 1.0) -> np.ndarray:
    """Sum of ``A_k cos(2 pi k (t - start) / period + phi_k)`` on [start, start + cycles period).

    ``harmonics`` are integers k (frequency k / period [Hz]); zero outside the window.
    """
    t = np.asarray(t, float)
    tau = t - start
    k = np.asarray(harmonics, float)
    arg = np.multiply.outer(tau, 2.0 * np.pi * k / period) + np.asarray(phases, float)
    x = np.cos(arg) @ np.asarray(amplitudes, float)
    return np.where((tau >= 0) & (tau < cycles * period), x, 0.0)


def schroeder_phases(amplitudes) -> np.ndarray:
    """Schroeder phases ``phi_k = -2 pi sum_{i<k} (k - i) p_i`` (p_i: power fractions)."""
    a = np.asarray(amplitudes, float)
    p = a**2 / np.sum(a**2)
    k = np.arange(a.size)
    return np.array([-2.0 * np.pi * np.sum((kk - k[:kk]) * p[:kk]) for kk in k])


def relative_peak_factor(x) -> float:
    """(max - min) / (2 sqrt(2) rms): 1 for a single sinusoid."""
    x = np.asarray(x, float)
    return float((x.max() - x.min()) / (2.0 * math.sqrt(2.0) * math.sqrt(np.mean(x * x))))


def _one_period(harmonics: np.ndarray, amplitudes: np.ndarray, phases, n: int) -> np.ndarray:
    """One period of the multisine on ``n`` uniform samples (inverse real FFT)."""
    spectrum = np.zeros(n // 2 + 1, complex)
    spectrum[harmonics] = 0.5 * n * amplitudes * np.exp(1j * np.asarray(phases))
    return np.fft.irfft(spectrum, n)


def low_peak_factor_phases(harmonics, amplitudes, iterations: int = 300,
                           samples: int | None = None) -> np.ndarray:
    """Phases giving a low relative peak factor, with the signal starting at zero.

    Starts from :func:`schroeder_phases`, then repeats: synthesise one period,
    clip it below its peak (levels cycling through 95, 90 and 80 %), keep the
    phases of the clipped signal's harmonics and restore the amplitudes. The
    best phases found are finally shifted in time so that the signal is zero,
    rising, at t = 0 (a time shift leaves the peak factor unchanged).
    """
    k = np.asarray(harmonics, int)
    a = np.asarray(amplitudes, float)
    if k.size == 0 or k.size != a.size:
        raise ValueError("harmonics: need one amplitude per harmonic, at least one harmonic")
    if np.any(k < 1) or np.unique(k).size != k.size:
        raise ValueError(f"harmonics: must be distinct positive integers, got {k.tolist()}")
    n = samples or int(2 ** math.ceil(math.log2(max(256, 32 * int(k.max())))))
    phases = schroeder_phases(a)
    best, best_rpf = phases, relative_peak_factor(_one_period(k, a, phases, n))
    levels = (0.95, 0.9, 0.8)
    for i in range(iterations):
        x = _one_period(k, a, phases, n)
        c = levels[i % len(levels)] * np.max(np.abs(x))
        phases = np.angle(np.fft.rfft(np.clip(x, -c, c))[k])
        rpf = relative_peak_factor(_one_period(k, a, phases, n))
        if rpf < best_rpf:
            best, best_rpf = phases, rpf
    return _shift_to_zero_crossing(k, a, best, n)


def _shift_to_zero_crossing(k: np.ndarray, a: np.ndarray, phases: np.ndarray,
                            n: int) -> np.ndarray:
    """Phases of the same signal delayed so it starts at an upward zero crossing."""
    x = _one_period(k, a, phases, n)
    up = np.flatnonzero((x[:-1] <= 0) & (x[1:] > 0))
    i = int(up[0]) if up.size else int(np.argmin(np.abs(x)))
    # Linear interpolation of the crossing between samples i and i + 1 (fraction of a period).
    frac = (i + (-x[i] / (x[i + 1] - x[i]) if up.size else 0.0)) / n
    shifted = phases + 2.0 * np.pi * k * frac
    # Newton steps on x(0) = sum a cos(phi) remove the interpolation error.
    for _ in range(3):
        value = np.sum(a * np.cos(shifted))
        slope = -np.sum(a * np.sin(shifted) * 2.0 * np.pi * k)
        shifted = shifted - 2.0 * np.pi * k * value / slope
    return np.mod(shifted + np.pi, 2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class _PulseTrain:
    """What a doublet and a 3-2-1-1 share: pulses whose widths are multiples of one width.

    Attributes:
        surface: control channel, one of :data:`SURFACES`.
        amplitude: pulse height [rad, or throttle fraction].

    Subclasses add their width field [s] (named by ``_WIDTH``) and ``start``
    [s], the time the first pulse begins; ``_SHAPE`` gives the pulse widths in
    units of that width and the pulse signs.
    """

    _SHAPE: ClassVar[tuple[tuple[float, ...], tuple[float, ...]]]
    _WIDTH: ClassVar[str]

    surface: str
    amplitude: float

    def validate(self) -> Self:
        """Raises ValueError naming the first invalid field; returns self."""
        _check_surface(self.surface)
        _finite("amplitude", self.amplitude)
        _positive(self._WIDTH, getattr(self, self._WIDTH))
        _finite("start", self.start)
        return self

    @property
    def end(self) -> float:
        """Time [s] after which the signal is zero."""
        return self.start + sum(self._SHAPE[0]) * getattr(self, self._WIDTH)

    def __call__(self, t) -> np.ndarray:
        return _pulse_train(t, self._SHAPE, self.amplitude, getattr(self, self._WIDTH), self.start)


@dataclass(frozen=True)
class Doublet(_PulseTrain):
    """A doublet on one surface (see :func:`doublet`): zero mean, so the aircraft stays near trim.

    Fields ``surface``, ``amplitude``, ``width`` (length of each of the two
    pulses [s]) and ``start`` [s].
    """

    _SHAPE = _DOUBLET
    _WIDTH = "width"

    width: float
    start: float = 0.0


@dataclass(frozen=True)
class ThreeTwoOneOne(_PulseTrain):
    """A 3-2-1-1 on one surface (see :func:`three_two_one_one`).

    Fields ``surface``, ``amplitude``, ``unit_width`` (length of the shortest
    pulse [s]; the signal lasts 7 units) and ``start`` [s]. Its pulses of 3, 2,
    1 and 1 units spread the input energy over a wider frequency band than a
    doublet of the same unit, so one manoeuvre excites slow and fast modes.
    """

    _SHAPE = _THREE_TWO_ONE_ONE
    _WIDTH = "unit_width"

    unit_width: float
    start: float = 0.0


@dataclass(frozen=True)
class Multisine:
    """A multisine on one surface (see :func:`multisine`).

    Attributes:
        surface: control channel name.
        period: fundamental period T [s]; harmonic k has frequency k / T [Hz].
        harmonics: harmonic numbers k.
        amplitudes: amplitude of each harmonic [rad, or throttle fraction].
        phases: phase of each harmonic [rad].
        start: time the signal starts [s].
        cycles: number of periods played.
    """

    surface: str
    period: float
    harmonics: tuple[int, ...]
    amplitudes: tuple[float, ...]
    phases: tuple[float, ...]
    start: float = 0.0
    cycles: float = 1.0

    def validate(self) -> Multisine:
        """Raises ValueError naming the first invalid field; returns self."""
        _check_surface(self.surface)
        _positive("period", self.period)
        k = np.asarray(self.harmonics)
        if k.size == 0 or np.any(k < 1) or np.unique(k).size != k.size:
            raise ValueError(f"harmonics: need distinct positive integers, got {self.harmonics}")
        if len(self.amplitudes) != k.size or len(self.phases) != k.size:
            raise ValueError("amplitudes: need one amplitude and one phase per harmonic")
        if not np.all(np.isfinite(self.amplitudes)) or np.any(np.asarray(self.amplitudes) < 0):
            raise ValueError(f"amplitudes: must be finite and >= 0, got {self.amplitudes}")
        _finite("start", self.start)
        _positive("cycles", self.cycles)
        return self

    @property
    def frequencies(self) -> np.ndarray:
        """Frequencies of the harmonics [Hz]."""
        return np.asarray(self.harmonics, float) / self.period

    @property
    def end(self) -> float:
        """Time [s] after which the signal is zero."""
        return self.start + self.cycles * self.period

    def __call__(self, t) -> np.ndarray:
        return multisine(t, self.period, self.harmonics, self.amplitudes, self.phases,
                         self.start, self.cycles)


@dataclass(frozen=True)
class Turn:
    """A steady turn: the heading reference turns at ``rate`` for ``duration``.

    The heading offset is ``rate (t - start)`` on [start, start + duration), then holds
    the heading reached (zero before ``start``). A signal of the ``heading`` reference
    channel: the safety pilot's heading hold banks the aircraft to follow it (at
    airspeed ``V`` a steady turn at ``rate`` needs a bank of ``atan(V rate / g)``).

    Attributes:
        rate: turn rate [rad/s], positive to the right (NED yaw).
        duration: how long the heading turns [s].
        start: time the turn starts [s].
    """

    surface: ClassVar[str] = "heading"
    rate: float
    duration: float
    start: float = 0.0

    def validate(self) -> Turn:
        """Raises ValueError naming the first invalid field; returns self."""
        if not (math.isfinite(self.rate) and self.rate != 0.0):
            raise ValueError(f"rate: must be finite and non-zero, got {self.rate}")
        _positive("duration", self.duration)
        _finite("start", self.start)
        return self

    @property
    def end(self) -> float:
        """Time [s] after which the heading offset holds."""
        return self.start + self.duration

    def __call__(self, t) -> np.ndarray:
        return self.rate * np.clip(np.asarray(t, float) - self.start, 0.0, self.duration)


Signal = Doublet | ThreeTwoOneOne | Multisine | Turn


def orthogonal_multisines(surfaces: Sequence[str], period: float, amplitudes,
                          band: tuple[float, float], start: float = 0.0,
                          cycles: float = 1.0) -> tuple[Multisine, ...]:
    """Mutually orthogonal low-peak-factor multisines, one per surface.

    The harmonics k of 1/period inside ``band`` = (f_min, f_max) [Hz] are dealt
    out in turn (surface i gets the i-th, (i+n)-th, ... harmonic), so the
    signals share no frequency and are orthogonal over every period. Each
    signal has a flat amplitude spectrum, phases from
    :func:`low_peak_factor_phases`, and is scaled so its peak equals its entry
    of ``amplitudes`` (one value per surface, or a single value for all).
    """
    surfaces = tuple(surfaces)
    for s in surfaces:
        _check_surface(s)
    if len(set(surfaces)) != len(surfaces):
        raise ValueError(f"surfaces: each surface at most once, got {surfaces}")
    _positive("period", period)
    peaks = np.broadcast_to(np.asarray(amplitudes, float), (len(surfaces),))
    if not np.all(np.isfinite(peaks)) or np.any(peaks <= 0):
        raise ValueError(f"amplitudes: must be positive, got {amplitudes}")
    f_min, f_max = band
    if not 0 < f_min < f_max:
        raise ValueError(f"band: need 0 < f_min < f_max [Hz], got {band}")
    k_all = np.arange(max(1, math.ceil(f_min * period - 1e-9)),
                      math.floor(f_max * period + 1e-9) + 1)
    if k_all.size < len(surfaces):
        raise ValueError(
            f"band: {band} Hz holds {k_all.size} harmonics of 1/{period} s, "
            f"fewer than the {len(surfaces)} surfaces; widen the band or lengthen the period"
        )
    out = []
    for i, surface in enumerate(surfaces):
        k = k_all[i :: len(surfaces)]
        unit = np.ones(k.size)
        phases = low_peak_factor_phases(k, unit)
        n = int(2 ** math.ceil(math.log2(max(1024, 64 * int(k.max())))))
        scale = peaks[i] / np.max(np.abs(_one_period(k, unit, phases, n)))
        out.append(Multisine(surface, period, tuple(int(v) for v in k),
                             tuple(scale * unit), tuple(phases), start, cycles).validate())
    return tuple(out)


def excitation_controls(t, trim_controls, signals: Sequence[Signal],
                        channels: Sequence[str] = SURFACES) -> np.ndarray:
    """Values (len(t), len(channels)) = trim + the sum of the signals on their channels.

    ``channels``: :data:`SURFACES` (the controls), :data:`REFERENCES` (the safety pilot's
    reference offsets, ``trim_controls`` zeros) or both; a signal on another channel
    raises ValueError."""
    t = np.atleast_1d(np.asarray(t, float))
    out = np.tile(np.asarray(trim_controls, float), (t.size, 1))
    for s in signals:
        out[:, _check_surface(s.surface, channels)] += s(t)
    return out


class ExcitationSource(LeafSystem):
    """Trim controls plus excitation signals, held at a fixed sample period.

    | port (out) | size | units                                                   |
    |------------|------|---------------------------------------------------------|
    | controls   | 4    | elevator, aileron, rudder [rad], throttle [0..1]        |

    With ``channels=REFERENCES`` (zero trim) it plays reference signals instead
    (:class:`Turn`): its output, named ``output`` (say ``reference_offsets``), holds
    pitch [rad], altitude [m], heading [rad] and airspeed [m/s] offsets for the
    safety pilot.

    The output is updated at t_k = k * sample_period with the value at t_k and
    held until t_(k+1) (no inputs; depends on the discrete state only). Samples
    are computed in vectorised blocks and memoised, so a periodic update costs a
    table look-up.
    """

    _BLOCK = 1024

    def __init__(self, trim_controls, signals: Sequence[Signal] = (),
                 sample_period: float = 0.01, channels: Sequence[str] = SURFACES,
                 output: str = "controls"):
        super().__init__()
        self.channels = tuple(channels)
        trim_controls = np.asarray(trim_controls, float)
        if (trim_controls.shape != (len(self.channels),)
                or not np.all(np.isfinite(trim_controls))):
            raise ValueError(f"trim_controls: need {len(self.channels)} finite values, got "
                             f"{trim_controls}")
        _positive("sample_period", sample_period)
        self.signals = tuple(s.validate() for s in signals)
        self.trim_controls = trim_controls
        self.sample_period = sample_period
        self._table = np.empty((0, len(self.channels)))
        xd = self.DeclareDiscreteState(self.controls_at(np.array([0.0]))[0])
        self.DeclarePeriodicDiscreteUpdateEvent(sample_period, 0.0, self._update)
        self.DeclareStateOutputPort(output, xd)

    def controls_at(self, t) -> np.ndarray:
        """Values (len(t), len(channels)) at times ``t`` [s], without the hold."""
        return excitation_controls(t, self.trim_controls, self.signals, self.channels)

    def _update(self, context, discrete_state) -> None:
        k = round(context.get_time() / self.sample_period)
        while k >= self._table.shape[0]:
            n0 = self._table.shape[0]
            t = (n0 + np.arange(self._BLOCK)) * self.sample_period
            self._table = np.vstack([self._table, self.controls_at(t)])
        discrete_state.set_value(self._table[k])
