"""Is a fitted coefficient model complete? Its equation error against the sensor noise.

A model that lacks nothing leaves an equation error the sensor noise explains: its mean
square is the noise floor (:mod:`~drake_uav.identification.assessment.noise_floor`), on the samples
the fit saw and on those it did not. When no candidate effect passes but the error is
well above the floor, or higher on the held-out tail than on the training part, the model
is incomplete: something the candidates do not describe moves the coefficient (a
derivative that drifts, an effect of a signal no candidate uses). :func:`assess` says
where: the ratio to the floor, the flight segments where the residual is largest and the
logged signals it correlates with over the whole flight (the in-sample residual of the
training part, then the held-out one: a slow drift shows as the contrast between the
two, which the held-out tail alone, centred, would hide).

The rule (:class:`AdequacyRule`). Let ``m`` be the mean square of the residual over a part
of the flight and ``f`` the mean of its noise variance there (the floor squared). Under a
complete model ``m - f`` is zero up to

* the sampling error of ``m``: ``sqrt(var(r^2) / N_eff)``, ``N_eff`` the effective sample
  size of ``r^2`` (the residual of smoothed data is correlated over the smoothing window,
  :func:`~drake_uav.identification.statistics.residuals.effective_sample_size`);
* the error of ``f`` itself: the noise variances are read from the data, each to a few per
  cent (:attr:`AdequacyRule.floor_uncertainty` of ``f``).

The held-out tail is **above the floor** when ``m_h / f_h - 1`` exceeds
:attr:`AdequacyRule.sigmas` times the combined relative standard error, and by at least
:attr:`AdequacyRule.min_excess` (a ratio of RMS 1.1 or less is no finding, whatever its
significance). The training and held-out parts **differ** when the held-out ratio
``m_h / f_h`` exceeds the training one ``m_t / f_t`` by the same number of their
combined sampling errors (the floor's error is common to both and cancels) and by the same
minimum. Either makes the model incomplete for that coefficient.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from drake_uav.identification.statistics.residuals import effective_sample_size

__all__ = ["AdequacyRule", "Adequacy", "assess", "coefficient_symbol"]


@dataclasses.dataclass(frozen=True)
class AdequacyRule:
    """Thresholds of the incompleteness finding (module docstring).

    Attributes
    ----------
    sigmas : float
        Standard errors an excess must reach.
    floor_uncertainty : float
        Relative standard error of the floor's mean square (noise variances read from the
        data).
    min_excess : float
        Smallest excess of a mean-square ratio over 1 (or over the training ratio) that
        counts: 0.21 is an RMS 1.1 times the floor.
    min_share_of_variation : float
        Smallest excess RMS (the error the noise does not explain) that counts, as a share
        of the coefficient's standard deviation over the flight: what the evidence rule asks
        of an effect's contribution.
    windows : int
        Equal windows the flight is cut into to say where the residual is largest.
    top_signals : int
        Signals the held-out residual correlates with most that are named.
    """

    sigmas: float = 4.0
    floor_uncertainty: float = 0.1
    min_excess: float = 0.21
    min_share_of_variation: float = 0.01
    windows: int = 10
    top_signals: int = 3


@dataclasses.dataclass(frozen=True)
class Adequacy:
    """One coefficient's equation error against its noise floor (module docstring).

    Attributes
    ----------
    coefficient : str
        The coefficient.
    ratio : float
        Held-out RMS / noise floor [-].
    train_ratio : float
        Training RMS / its noise floor [-].
    above_floor : bool
        The held-out error is significantly above the floor.
    differs : bool
        The held-out ratio is significantly above the training ratio.
    limit : float
        Held-out RMS ratio above which the error is significantly above the floor [-].
    train_limit : float
        Held-out RMS ratio above which it differs significantly from the training one [-].
    segments : tuple of (float, float, float)
        ``(start, end [s], RMS / floor)`` of the flight segments where the residual is
        largest, largest first.
    correlations : tuple of (str, float)
        ``(signal, correlation)`` the residual correlates with most over the flight.
    """

    coefficient: str
    ratio: float
    train_ratio: float
    above_floor: bool
    differs: bool
    limit: float
    train_limit: float = float("inf")
    segments: tuple[tuple[float, float, float], ...] = ()
    correlations: tuple[tuple[str, float], ...] = ()

    @property
    def incomplete(self) -> bool:
        """True when the noise does not explain the error (either test)."""
        return self.above_floor or self.differs

    @property
    def explanation(self) -> str:
        """One line: how far above the floor, where, and with what it correlates."""
        parts = [f"held-out error {self.ratio:.2g}x the noise floor"]
        if self.differs:
            parts[0] += f" against {self.train_ratio:.2g}x on the training part"
        if self.segments:
            parts.append("largest at " + ", ".join(f"{a:.0f}-{b:.0f} s"
                                                   for a, b, _ in self.segments))
        if self.correlations:
            parts.append("correlates with " + ", ".join(f"{s} ({c:.2f})"
                                                        for s, c in self.correlations))
        return ", ".join(parts)

    def summary(self) -> dict:
        """JSON-ready fields of the adequacy (a ratio without a floor is None).

        Returns
        -------
        dict
            The ratios, limits, decisions, segments and correlations.
        """

        def finite(value: float) -> float | None:
            return value if np.isfinite(value) else None

        return {"ratio": finite(self.ratio), "train_ratio": finite(self.train_ratio),
                "above_floor": self.above_floor, "differs": self.differs,
                "limit": finite(self.limit), "train_limit": finite(self.train_limit),
                "incomplete": self.incomplete,
                "segments_s": [list(s) for s in self.segments],
                "correlations": [list(c) for c in self.correlations]}


def coefficient_symbol(coefficient: str) -> str:
    """The symbol of a coefficient name: ``"CD"`` -> ``"C_D"``.

    Parameters
    ----------
    coefficient : str
        The name.

    Returns
    -------
    str
        The symbol.
    """
    return f"{coefficient[0]}_{coefficient[1:]}"


@dataclasses.dataclass(frozen=True)
class _Part:
    """A part of the flight: residual, noise variance per sample and the statistics."""

    time: np.ndarray
    residual: np.ndarray
    variance: np.ndarray

    @property
    def ratio(self) -> float:
        """Mean square over floor squared."""
        return float(np.mean(self.residual**2) / np.mean(self.variance))

    @property
    def sampling_error(self) -> float:
        """Standard error of :attr:`ratio` from the residual's own scatter."""
        square = self.residual**2
        n_eff = effective_sample_size(square - square.mean())
        return float(np.std(square) / np.sqrt(n_eff) / np.mean(self.variance))


def assess(coefficient: str, train: tuple[np.ndarray, np.ndarray, np.ndarray],
           test: tuple[np.ndarray, np.ndarray, np.ndarray],
           signals: Mapping[str, np.ndarray], scale: float,
           rule: AdequacyRule | None = None) -> Adequacy:
    """The adequacy of one coefficient's final fit (module docstring).

    Parameters
    ----------
    coefficient : str
        The coefficient.
    train : (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        ``(time [s], residual, noise variance per sample)`` of the training part
        (in-sample residual).
    test : (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The same of the held-out tail.
    signals : Mapping[str, numpy.ndarray]
        The logged signals on the training samples followed by the held-out ones, by name
        (``time`` is added).
    scale : float
        The coefficient's standard deviation over the flight.
    rule : AdequacyRule, optional
        The thresholds (None: the defaults).

    Returns
    -------
    Adequacy
        The adequacy (ratios inf when there is no floor).
    """
    rule = rule or AdequacyRule()
    fit, tail = _Part(*train), _Part(*test)
    floor = float(np.mean(tail.variance))
    if not (floor > 0.0 and np.mean(fit.variance) > 0.0):
        return Adequacy(coefficient, float("inf"), float("inf"), False, False, float("inf"))
    matters = (rule.min_share_of_variation * scale) ** 2 / floor
    excess = max(rule.sigmas * np.hypot(tail.sampling_error,
                                        rule.floor_uncertainty * tail.ratio),
                 rule.min_excess, matters)
    above = tail.ratio - 1.0 > excess
    gap = max(rule.sigmas * np.hypot(tail.sampling_error, fit.sampling_error),
              rule.min_excess * fit.ratio, matters)
    differs = tail.ratio - fit.ratio > gap
    adequacy = Adequacy(coefficient, float(np.sqrt(tail.ratio)), float(np.sqrt(fit.ratio)),
                        bool(above), bool(differs), float(np.sqrt(1.0 + excess)),
                        float(np.sqrt(fit.ratio + gap)))
    if not adequacy.incomplete:
        return adequacy
    return dataclasses.replace(
        adequacy, segments=_segments(fit, tail, rule, adequacy.limit),
        correlations=_correlations(np.concatenate([fit.residual, tail.residual]),
                                   {"time": np.concatenate([fit.time, tail.time]),
                                    **signals}, rule.top_signals))


def _segments(fit: _Part, tail: _Part, rule: AdequacyRule, limit: float
              ) -> tuple[tuple[float, float, float], ...]:
    """Runs of consecutive windows whose RMS ratio exceeds ``limit`` (the largest window
    alone when none does), largest peak first, at most two."""
    time = np.concatenate([fit.time, tail.time])
    square = np.concatenate([fit.residual, tail.residual]) ** 2
    variance = np.concatenate([fit.variance, tail.variance])
    chunks = np.array_split(np.arange(time.size), rule.windows)
    ratio = np.array([np.sqrt(square[c].mean() / variance[c].mean()) for c in chunks])
    runs, start = [], None
    for i, high in enumerate([*(ratio > limit), False]):
        if high and start is None:
            start = i
        elif not high and start is not None:
            runs.append((start, i))
            start = None
    if not runs:
        best = int(np.argmax(ratio))
        runs = [(best, best + 1)]
    runs.sort(key=lambda r: -ratio[r[0]:r[1]].max())
    return tuple((float(time[chunks[a][0]]), float(time[chunks[b - 1][-1]]),
                  float(ratio[a:b].max())) for a, b in runs[:2])


def _correlations(residual: np.ndarray, signals: Mapping[str, np.ndarray], top: int
                  ) -> tuple[tuple[str, float], ...]:
    """The ``top`` signals of largest absolute Pearson correlation with ``residual``
    (constant signals are left out)."""
    r = residual - residual.mean()
    out = []
    for name, values in signals.items():
        x = np.asarray(values, dtype=float) - np.mean(values)
        norm = float(np.sqrt((x @ x) * (r @ r)))
        if norm > 0.0:
            out.append((name, float(x @ r / norm)))
    out.sort(key=lambda c: -abs(c[1]))
    return tuple(out[:top])
