"""What to fly next: a manoeuvre that separates effects a flight could not tell apart.

When two candidate effects explain a coefficient almost equally well on a flight (a near
tie, :mod:`~drake_uav.identification.assessment.near_ties`), their regressor columns moved
together on it. A flight that separates them moves the part of one column that the other
(and the baseline's columns) cannot reproduce: the *distinguishing column*. The design,
plant-agnostic (it sees candidates' columns and input channels only):

1. **Sensitivity.** For each input channel, a probe multisine on that channel alone is flown
   on the model (``simulate``); on it, each rival's columns are regressed on the other's
   and the baseline's (:func:`distinguishing_energy`), and the residual's mean square,
   weighted by the rival's squared size over its squared residual on the flown data, per
   unit probe amplitude squared, is the channel's sensitivity [1 / input unit^2].
2. **Inputs.** The channels whose sensitivity reaches :data:`SELECTED_SHARE` of the best are
   the ones that separate the rivals; they get their full amplitude limit, the others the
   flight moved :data:`BACKGROUND_SHARE` of theirs, so the new flight still identifies the
   baseline; the rest stay at trim.
3. **Signals.** Mutually orthogonal low-peak-factor multisines on those channels (Morelli
   2003; :func:`~drake_uav.systems.excitation.orthogonal_multisines`), peaks within the
   limits. Given a turn rate, the manoeuvre is also predicted flown in a steady turn
   (:class:`~drake_uav.systems.excitation.Turn`: the heading the autopilot holds turns
   through the manoeuvre), which moves what depends on the heading and the attitude (a
   force fixed in the NED frame against one fixed in the body); the turn is kept when it
   separates more pairs than the straight manoeuvre.
4. **Predicted separation.** The designed manoeuvre is flown on the model and, for each
   rival taken as the truth with the size the flight gave it, the share of its gain the
   other would reach (:func:`rival_share`: the near-tie rule's own measure, a tie from
   90 %) and the expected partial F-statistic of its columns against the other's
   (:func:`expected_f`), next to the same figures on the flown data, and the largest
   canonical correlation of the two column sets after the baseline
   (:func:`column_correlation`) on both.

:func:`propose_manoeuvre` does this for the fixed-wing main job's result
(:class:`~drake_uav.identification.pipeline.IdentificationRun`): it flies the model with
the identified derivatives at the flight's airspeed (the probes in still air, the
prediction in light turbulence), and :func:`write_command_csv` writes the commands a user
can fly.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize, stats

from drake_uav.diagrams.identification_flight import fly
from drake_uav.identification.assessment.near_ties import NEAR_TIE_MARGIN
from drake_uav.identification.discovery.coefficient_design import baseline_names
from drake_uav.identification.discovery.effects import effect_library
from drake_uav.identification.discovery.vector_effects import vector_effect_library
from drake_uav.identification.pipeline import IdentificationRun
from drake_uav.identification.propulsion import thrust_correction_columns
from drake_uav.identification.samples.flight_data import samples_from_log
from drake_uav.identification.statistics.residuals import effective_sample_size
from drake_uav.model.coefficients import regressor_matrix
from drake_uav.model.propeller import THROTTLE_TERMS
from drake_uav.systems.excitation import (
    REFERENCES,
    SURFACES,
    Multisine,
    Turn,
    excitation_controls,
    orthogonal_multisines,
)
from drake_uav.vehicles.fixed_wing import GRAVITY, FixedWingParams
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["InputChannel", "Rivals", "Separation", "ManoeuvreDesign", "FIXED_WING_CHANNELS",
           "SELECTED_SHARE", "BACKGROUND_SHARE", "MOVED_SHARE", "TURN_BANK",
           "DECISION_LEVEL", "DECISION_POWER", "decisive_f",
           "distinguishing_energy",
           "column_correlation", "expected_f", "rival_share", "design_manoeuvre",
           "propose_manoeuvre", "turn_bank", "command_csv", "write_command_csv", "read_command_csv",
           "COMMAND_CSV"]

SELECTED_SHARE = 0.25
"""A channel whose sensitivity reaches this share of the best channel's separates the
rivals and is flown at its full limit."""
BACKGROUND_SHARE = 0.5
"""Share of its limit a channel that does not separate the rivals is flown at, when the
flown data moved it (it keeps the baseline's derivatives identified on the new flight)."""
MOVED_SHARE = 0.1
"""A channel moved on the flown data when its standard deviation exceeds this share of its
limit (an airspeed hold's throttle, within about 0.01, did not)."""
DECISION_LEVEL = 0.01
"""Significance level of the test a designed manoeuvre must let decide."""
DECISION_POWER = 0.8
"""Probability the designed manoeuvre must give that test of deciding."""
TURN_BANK = math.radians(15.0)
"""Bank [rad] of the steady turn :func:`propose_manoeuvre` considers: its rate is the one
this bank gives at the flight's airspeed (a circle in about a minute at 25 m/s), held over
the whole manoeuvre, within the safety pilot's roll limit."""


@dataclasses.dataclass(frozen=True)
class InputChannel:
    """An input the manoeuvre may move about its trim.

    Attributes
    ----------
    name : str
        The channel: a surface of :data:`~drake_uav.systems.excitation.SURFACES`, or a
        reference of :data:`~drake_uav.systems.excitation.REFERENCES` the autopilot's
        holds fly (``heading`` for a turn).
    unit : str
        Its unit in the command file (``rad``, or ``1`` for a throttle fraction).
    limit : float
        Largest deviation from trim allowed [unit], the peak of its multisine.
    """

    name: str
    unit: str
    limit: float

    def __post_init__(self):
        if self.name not in SURFACES + REFERENCES:
            raise ValueError(f"channel: unknown input {self.name!r}; use one of "
                             f"{SURFACES + REFERENCES}")
        if not (self.limit > 0 and math.isfinite(self.limit)):
            raise ValueError(f"channel {self.name}: limit must be positive and finite, "
                             f"got {self.limit}")


FIXED_WING_CHANNELS = (InputChannel("elevator", "rad", math.radians(3.0)),
                       InputChannel("aileron", "rad", math.radians(3.0)),
                       InputChannel("rudder", "rad", math.radians(3.0)),
                       InputChannel("throttle", "1", 0.15))
"""Default limits of the fixed-wing channels: 3 deg on each surface (the campaign flies
2-3 deg), 0.15 of full throttle."""

Columns = Callable[[Any], np.ndarray]
"""``columns(samples) -> (N, k)`` regressor columns of one candidate or of the baseline."""


@dataclasses.dataclass(frozen=True)
class Rivals:
    """Two candidates of one quantity to separate, and the baseline they are tested on.

    Attributes
    ----------
    quantity : str
        The quantity (coefficient) they act on.
    first, second : str
        Their names (from a near tie: the effect the flight accepted first, then its rivals
        in the order the tie lists them).
    first_columns, second_columns, base_columns : callable
        :data:`Columns` of each candidate and of the baseline.
    """

    quantity: str
    first: str
    second: str
    first_columns: Columns
    second_columns: Columns
    base_columns: Columns


def _matrix(name: str, x, n: int | None = None) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    x = x[:, None] if x.ndim == 1 else x
    if x.ndim != 2 or x.shape[0] < 3 or not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: need finite columns of shape (N, k) with N >= 3, "
                         f"got shape {x.shape}")
    if n is not None and x.shape[0] != n:
        raise ValueError(f"{name}: has {x.shape[0]} rows, the other columns {n}")
    return x


def _columns(base, first, second) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The baseline's and both rivals' columns, checked to be finite and of one length."""
    first = _matrix("first", first)
    return _matrix("base", base, len(first)), first, _matrix("second", second, len(first))


def _parameters(theta, first: np.ndarray) -> np.ndarray:
    """``theta`` as one finite value per column of ``first``."""
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    if theta.shape != (first.shape[1],) or not np.all(np.isfinite(theta)):
        raise ValueError(f"theta: need {first.shape[1]} finite values, got {theta}")
    return theta


def _residual(x: np.ndarray, on: np.ndarray) -> np.ndarray:
    """``x`` minus its least-squares fit on ``on`` and a constant."""
    design = np.column_stack([np.ones(len(on)), on])
    return x - design @ np.linalg.lstsq(design, x, rcond=None)[0]


def distinguishing_energy(base, first, second) -> tuple[float, float]:
    """Mean squares of the parts of each rival's columns the other cannot reproduce.

    Parameters
    ----------
    base, first, second : array_like
        (N, k) columns (or (N,)) of the baseline and of the two rivals.

    Returns
    -------
    tuple of float
        (first against second and the baseline, second against first and the baseline),
        mean squares [column unit^2].

    Raises
    ------
    ValueError
        For columns that are not finite or whose lengths differ.
    """
    base, first, second = _columns(base, first, second)
    return (float(np.mean(_residual(first, np.column_stack([base, second])) ** 2)
                  * first.shape[1]),
            float(np.mean(_residual(second, np.column_stack([base, first])) ** 2)
                  * second.shape[1]))


def column_correlation(base, first, second) -> float:
    """Largest canonical correlation of two candidates' columns after the baseline's fit.

    1: some combination of one is a combination of the other (no flight of this input
    tells them apart); 0: they move independently.

    Parameters
    ----------
    base, first, second : array_like
        (N, k) columns of the baseline and of the two rivals.

    Returns
    -------
    float
        In [0, 1].

    Raises
    ------
    ValueError
        For columns that are not finite or whose lengths differ.
    """
    base, first, second = _columns(base, first, second)
    a, b = _residual(first, base), _residual(second, base)
    qa, qb = np.linalg.qr(a)[0], np.linalg.qr(b)[0]
    if not (np.any(np.abs(a) > 0) and np.any(np.abs(b) > 0)):
        return 0.0
    return float(min(np.linalg.svd(qa.T @ qb, compute_uv=False)[0], 1.0))


def expected_f(theta, sigma: float, first, second, base, independent_share: float = 1.0
               ) -> float:
    """Expected partial F-statistic of ``first`` added to the baseline and ``second``.

    With ``first`` the truth with parameters ``theta`` and white residuals of standard
    deviation ``sigma``, the partial F-statistic of its q columns has expectation
    ``1 + lambda / q``, ``lambda = |P theta|^2 / sigma^2`` the non-centrality, P the part of
    its columns the others cannot reproduce, scaled by ``independent_share`` (effective
    over nominal sample size of the residual: correlated residuals carry less).

    Parameters
    ----------
    theta : array_like
        (q,) the first candidate's parameters [quantity unit / column unit].
    sigma : float
        Residual standard deviation [quantity unit].
    first, second, base : array_like
        (N, k) columns.
    independent_share : float
        Effective over nominal sample size, in (0, 1].

    Returns
    -------
    float
        The expected F-statistic (1: no evidence either way).

    Raises
    ------
    ValueError
        For a non-positive ``sigma``, a ``theta`` of the wrong size or bad columns.
    """
    base, first, second = _columns(base, first, second)
    theta = _parameters(theta, first)
    if not (sigma > 0 and math.isfinite(sigma)):
        raise ValueError(f"sigma: must be positive and finite, got {sigma}")
    part = _residual(first, np.column_stack([base, second])) @ theta
    return 1.0 + float(part @ part) / sigma**2 * independent_share / theta.size


@functools.cache
def decisive_f(columns: int) -> float:
    """Expected partial F-statistic at which a test of ``columns`` columns decides.

    The expectation ``1 + lambda / q`` whose non-centrality ``lambda`` gives the test at
    the :data:`DECISION_LEVEL` level :data:`DECISION_POWER` power (large-sample
    chi-square approximation of the F-statistic): a pair whose expected F stays below it
    is likely to stay tied however the columns differ (Cohen's usual 80 % power).

    Parameters
    ----------
    columns : int
        The number of columns q tested (at least 1).

    Returns
    -------
    float
        The expected F-statistic (about 12.7 for one column).

    Raises
    ------
    ValueError
        For fewer than one column.
    """
    if columns < 1:
        raise ValueError(f"columns: need at least one, got {columns}")
    critical = stats.chi2.ppf(1.0 - DECISION_LEVEL, columns)
    lam = optimize.brentq(lambda x: stats.ncx2.sf(critical, columns, x) - DECISION_POWER,
                          1e-9, 1e4)
    return 1.0 + lam / columns


def rival_share(theta, first, second, base) -> float:
    """The share of ``first``'s gain that ``second`` reaches when ``first`` is the truth.

    With ``first`` the truth with parameters ``theta``, the baseline leaves its term's part
    ``r0`` unexplained and the baseline with ``second`` leaves ``r1``; the rival explains
    ``1 - |r1|^2 / |r0|^2`` of what the truth explains (the squared correlation, for single
    columns). The near-tie rule names the rival when this reaches ``1 - NEAR_TIE_MARGIN``.

    Parameters
    ----------
    theta : array_like
        (q,) the first candidate's parameters.
    first, second, base : array_like
        (N, k) columns.

    Returns
    -------
    float
        In [0, 1] (0 also when the baseline already explains the first's term).

    Raises
    ------
    ValueError
        For a ``theta`` of the wrong size or bad columns.
    """
    base, first, second = _columns(base, first, second)
    theta = _parameters(theta, first)
    r0 = _residual(first, base) @ theta
    r1 = _residual(first, np.column_stack([base, second])) @ theta
    total = float(r0 @ r0)
    return 0.0 if total <= 0.0 else float(np.clip(1.0 - (r1 @ r1) / total, 0.0, 1.0))


@dataclasses.dataclass(frozen=True)
class Separation:
    """Predicted separation of one pair of rivals.

    Attributes
    ----------
    rivals : Rivals
        The pair.
    correlation_flown, correlation_designed : float
        :func:`column_correlation` on the flown data and on the designed manoeuvre.
    f_flown, f_designed : tuple of float
        Expected F-statistic of (first against second, second against first), each taken
        as the truth with its size on the flown data, on the flown data and on the designed
        manoeuvre (:func:`expected_f`).
    share_flown, share_designed : tuple of float
        The share of each rival's gain the other would reach, each taken as the truth
        (:func:`rival_share`), on the flown data and on the designed manoeuvre.
    f_decisive : tuple of float
        The expected F-statistic each way round at which the test decides
        (:func:`decisive_f` of each rival's number of columns).
    """

    rivals: Rivals
    correlation_flown: float
    correlation_designed: float
    f_flown: tuple[float, float]
    f_designed: tuple[float, float]
    share_flown: tuple[float, float]
    share_designed: tuple[float, float]
    f_decisive: tuple[float, float]

    @property
    def resolves(self) -> bool:
        """The designed manoeuvre is predicted to end the near tie: whichever rival is true,
        the other reaches less than ``1 - NEAR_TIE_MARGIN`` of its gain (the columns part)
        and the expected F-statistic reaches :attr:`f_decisive` (the noise lets the flight
        see it)."""
        return (max(self.share_designed) < 1.0 - NEAR_TIE_MARGIN
                and all(f >= need for f, need in zip(self.f_designed, self.f_decisive,
                                                      strict=True)))

    def summary(self) -> dict:
        """JSON-ready figures of the pair."""
        return {"quantity": self.rivals.quantity, "first": self.rivals.first,
                "second": self.rivals.second,
                "correlation": {"flown": self.correlation_flown,
                                "designed": self.correlation_designed},
                "expected_f": {"first_true": {"flown": self.f_flown[0],
                                              "designed": self.f_designed[0]},
                               "second_true": {"flown": self.f_flown[1],
                                               "designed": self.f_designed[1]}},
                "rival_share": {"first_true": {"flown": self.share_flown[0],
                                               "designed": self.share_designed[0]},
                                "second_true": {"flown": self.share_flown[1],
                                                "designed": self.share_designed[1]}},
                "decisive_f": {"first_true": self.f_decisive[0],
                               "second_true": self.f_decisive[1]},
                "resolves": self.resolves}

    def sentence(self) -> str:
        """One line for the report."""
        r = self.rivals
        verdict = ("separates them" if self.resolves else
                   "does not separate them: a near tie is expected to remain")
        return (f"`{r.first}` against `{r.second}` on {r.quantity}: the rival reaches "
                f"{max(self.share_flown):.0%} of the true one's gain flown, "
                f"{max(self.share_designed):.0%} designed; column correlation "
                f"{self.correlation_flown:.3f} flown, {self.correlation_designed:.3f} "
                f"designed; expected F {min(self.f_flown):.1f} over the flown flight, "
                f"{min(self.f_designed):.1f} over the manoeuvre (each the worse of the two "
                f"ways round; it grows with the length flown; {max(self.f_decisive):.1f} "
                f"decides, a test at {DECISION_LEVEL:.0%} with {DECISION_POWER:.0%} power): "
                f"the manoeuvre {verdict}.")


@dataclasses.dataclass(frozen=True)
class ManoeuvreDesign:
    """A designed manoeuvre and what it is predicted to separate.

    Attributes
    ----------
    signals : tuple of Multisine or Turn
        The orthogonal multisines, one per surface [channel unit], and the
        :class:`~drake_uav.systems.excitation.Turn` of the heading when the manoeuvre is
        flown in a turn.
    channels : tuple of InputChannel
        The channels flown, in the order of ``signals`` (the others stay at trim).
    selected : tuple of str
        The channels that separate the rivals (flown at their limit).
    sensitivity : dict of str to float
        Each channel's sensitivity: :func:`distinguishing_energy` of each rival times its
        squared parameters over its squared residual (its F-statistic's growth per sample),
        per unit amplitude squared, summed over the pairs and both ways round
        [1 / channel unit^2].
    separations : tuple of Separation
        The predicted separation of each pair.
    duration : float
        Length of the manoeuvre [s].
    trim : dict of str to float
        Each channel's trim command the signals are added to [channel unit] (0 for the
        heading: its column is the change from the heading at the start).
    """

    signals: tuple[Multisine | Turn, ...]
    channels: tuple[InputChannel, ...]
    selected: tuple[str, ...]
    sensitivity: dict[str, float]
    separations: tuple[Separation, ...]
    duration: float
    trim: dict[str, float]

    @property
    def turn(self) -> Turn | None:
        """The steady turn the manoeuvre is flown in, or None (straight)."""
        return next((s for s in self.signals if isinstance(s, Turn)), None)

    def summary(self) -> dict:
        """JSON-ready summary (``summary.json``'s ``what_to_fly_next``)."""
        turn = self.turn
        return {"duration_s": self.duration, "selected_inputs": list(self.selected),
                "trim": self.trim,
                "turn_rate_deg_s": None if turn is None else math.degrees(turn.rate),
                "sensitivity": self.sensitivity,
                "peaks": {s.surface: float(np.max(np.abs(s(np.linspace(s.start, s.end, 4001)))))
                          for s in self.signals},
                "separations": [s.summary() for s in self.separations]}


def _pair_figures(rivals: Rivals, samples) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (_matrix("base", rivals.base_columns(samples)),
            _matrix(rivals.first, rivals.first_columns(samples)),
            _matrix(rivals.second, rivals.second_columns(samples)))


def _sizes(rivals: Rivals, y, flown) -> tuple[tuple, tuple]:
    """Each rival's parameters and residual figures when it alone is fitted to ``y``."""
    base, first, second = _pair_figures(rivals, flown)
    out = []
    for own in (first, second):
        design = np.column_stack([np.ones(len(y)), base, own])
        theta, *_ = np.linalg.lstsq(design, y, rcond=None)
        e = y - design @ theta
        out.append((theta[-own.shape[1]:], float(np.std(e)),
                    effective_sample_size(e) / len(e)))
    return tuple(out)


def design_manoeuvre(simulate: Callable[[Sequence[Multisine], float], Any],
                     pairs: Sequence[tuple[Rivals, np.ndarray]], flown,
                     channels: Sequence[InputChannel], *, trim: Mapping[str, float],
                     background: Sequence[str] | None = None, duration: float = 60.0,
                     period: float = 20.0, band: tuple[float, float] = (0.1, 1.5),
                     turn_rate: float | None = None,
                     predict: Callable[[Sequence, float], Any] | None = None
                     ) -> ManoeuvreDesign:
    """Designs the manoeuvre that separates each pair of rivals and predicts how well.

    Parameters
    ----------
    simulate : callable
        ``simulate(signals, duration) -> samples``: flies the model with the signals
        added to trim and returns what the candidates' :data:`Columns` read.
    pairs : sequence of (Rivals, numpy.ndarray)
        Each pair with the measured quantity (N,) on the flown data.
    flown : Any
        The flown samples (what the columns read).
    channels : sequence of InputChannel
        The inputs the manoeuvre may move, with their limits.
    trim : mapping of str to float
        Each channel's trim command [its unit] (the command file adds the signals to it).
    background : sequence of str, optional
        The channels that do not separate the rivals but are still flown, at
        :data:`BACKGROUND_SHARE` of their limit (the inputs the baseline needs; None: every
        channel). The others are held at trim.
    duration : float
        Length of the manoeuvre [s], at least one ``period``.
    period : float
        Period of the multisines [s].
    band : tuple of float
        Frequency band (f_min, f_max) [Hz] of the multisines.
    turn_rate : float, optional
        Rate [rad/s] of a steady turn (:class:`~drake_uav.systems.excitation.Turn` on the
        ``heading`` reference, over the whole manoeuvre) to predict the manoeuvre with as
        well; the turn is kept when more pairs are predicted separated with it than
        without (:attr:`Separation.resolves`). None: straight only.
    predict : callable, optional
        Flies the designed manoeuvre for the predicted separation, as ``simulate`` does
        (None: ``simulate``). The probes measure what each input moves; the prediction
        should see what the next flight will, gusts included (:func:`propose_manoeuvre`
        flies it in light turbulence).

    Returns
    -------
    ManoeuvreDesign
        The signals and the predicted separations.

    Raises
    ------
    ValueError
        For no pair, no channel, a channel named twice, a channel without a trim, a
        duration shorter than the period or a turn rate that is zero or not finite.
    """
    if not pairs:
        raise ValueError("pairs: need at least one pair of rivals to separate")
    channels = tuple(channels)
    names = [c.name for c in channels]
    if not channels or len(set(names)) != len(names):
        raise ValueError(f"channels: need at least one channel, each once, got {names}")
    missing = [n for n in names if n not in trim or not math.isfinite(trim[n])]
    if missing:
        raise ValueError(f"trim: no finite trim command for {', '.join(missing)}; give one "
                         "per channel")
    if not (duration >= period > 0):
        raise ValueError(f"duration: {duration} s must be at least one period ({period} s)")
    if turn_rate is not None and not (math.isfinite(turn_rate) and turn_rate != 0.0):
        raise ValueError(f"turn_rate: must be finite and non-zero, got {turn_rate}")
    start = 1.0
    sizes = [_sizes(rivals, y, flown) for rivals, y in pairs]
    sensitivity = {}
    for channel in channels:
        probe = orthogonal_multisines([channel.name], period, channel.limit, band, start)
        samples = simulate(probe, start + period)
        sensitivity[channel.name] = sum(
            float(np.dot([np.sum(t**2) / s**2 for t, s, _ in size],
                         distinguishing_energy(*_pair_figures(rivals, samples))))
            for (rivals, _), size in zip(pairs, sizes, strict=True)) / channel.limit**2
    best = max(sensitivity.values())
    selected = tuple(n for n in names if best > 0 and sensitivity[n] >= SELECTED_SHARE * best)
    background = names if background is None else background
    flown_channels = tuple(c for c in channels if c.name in selected or c.name in background)
    peaks = [c.limit if c.name in selected else BACKGROUND_SHARE * c.limit
             for c in flown_channels]
    signals = orthogonal_multisines([c.name for c in flown_channels], period, peaks, band,
                                    start, cycles=(duration - start) / period)
    trims = {c.name: float(trim[c.name]) for c in flown_channels}
    predict = simulate if predict is None else predict
    separations = _separations(pairs, sizes, flown, predict(signals, duration))
    if turn_rate is not None:
        turn = Turn(turn_rate, duration - start, start)
        turning = _separations(pairs, sizes, flown, predict((*signals, turn), duration))
        if sum(s.resolves for s in turning) > sum(s.resolves for s in separations):
            signals, separations = (*signals, turn), turning
            flown_channels += (InputChannel("heading", "rad", abs(turn(turn.end))),)
            trims["heading"] = 0.0
    return ManoeuvreDesign(tuple(signals), flown_channels, selected, sensitivity,
                           separations, duration, trims)


def _separations(pairs, sizes, flown, designed) -> tuple[Separation, ...]:
    """Each pair's :class:`Separation` between the flown and the designed samples."""
    separations = []
    for (rivals, _), ((t1, s1, n1), (t2, s2, n2)) in zip(pairs, sizes, strict=True):
        figures = {}
        for key, samples in (("flown", flown), ("designed", designed)):
            base, first, second = _pair_figures(rivals, samples)
            figures[key] = (column_correlation(base, first, second),
                            (expected_f(t1, s1, first, second, base, n1),
                             expected_f(t2, s2, second, first, base, n2)),
                            (rival_share(t1, first, second, base),
                             rival_share(t2, second, first, base)))
        decisive = (decisive_f(len(np.atleast_1d(t1))), decisive_f(len(np.atleast_1d(t2))))
        separations.append(Separation(rivals, figures["flown"][0], figures["designed"][0],
                                      figures["flown"][1], figures["designed"][1],
                                      figures["flown"][2], figures["designed"][2], decisive))
    return tuple(separations)


def _effect_columns(name: str, params: FixedWingParams, quantity: str) -> Columns | None:
    """A named effect's columns on ``quantity`` (its non-zero ones), or None for a name the
    libraries do not hold (a data-driven product, a logged channel) or one whose direction
    the library leaves to a search (a force towards a point the data locate)."""
    effect = {e.name: e for e in [*effect_library(), *vector_effect_library()]}.get(name)
    if effect is None or getattr(effect, "unit_vectors", True) is None:
        return None
    candidate = effect.candidate(params)

    def columns(samples):
        X = np.column_stack(list(candidate.columns(samples, quantity).values()))
        return X[:, np.any(X != 0, axis=0)]
    return columns


def _base_columns(params: FixedWingParams, quantity: str) -> Columns:
    """The job's baseline of ``quantity``: the catalog's terms and, on C_D, the correction
    terms of a thrust identified from the flight (when the samples carry them)."""
    names = baseline_names(params, quantity)

    def columns(samples):
        view = samples.aligned(quantity)
        X = regressor_matrix(names, view.condition, params.b, params.c)
        thrust = thrust_correction_columns(view) if quantity == "CD" else {}
        return np.column_stack([X, *thrust.values()])
    return columns


def turn_bank(turn: Turn, airspeed: float) -> float:
    """Bank [rad] of a steady coordinated turn at ``turn.rate`` and ``airspeed`` [m/s]."""
    return math.atan(airspeed * abs(turn.rate) / GRAVITY)


def _identified_model(run: IdentificationRun) -> FixedWingParams:
    """The catalog model with the derivatives the run identified."""
    known = run.params.derivatives
    return run.params.with_derivatives(**{
        n: float(fit.result.estimate[i]) for fit in run.discovery.final.values()
        for i, n in enumerate(fit.names) if n in known})


def propose_manoeuvre(run: IdentificationRun, *,
                      channels: Sequence[InputChannel] = FIXED_WING_CHANNELS,
                      duration: float = 60.0, propulsion: str = "data", turn: bool = True,
                      turbulence: str | None = "light", seed: int = 0,
                      sensors: SensorSuiteParams | None = None) -> ManoeuvreDesign | None:
    """The manoeuvre that separates the near ties of a main-job result, or None.

    Every pair of the members of a near tie (the accepted effect and its rivals: they all
    explain the coefficient almost equally well) is designed for, where both are named
    effects of the libraries
    (:func:`~drake_uav.identification.discovery.effects.effect_library`,
    :func:`~drake_uav.identification.discovery.vector_effects.vector_effect_library`, on the
    tied coefficient);
    the model is the catalog aircraft with the identified derivatives, trimmed at the
    flight's median airspeed, flown with ``sensors`` (the probes in still air, the
    predicted separation in ``turbulence``). The baseline the
    rivals are tested against is the job's: on C_D it holds the correction terms of a thrust
    identified from the flight where the job identified one, and on a manoeuvre that moves
    the throttle (the job then identifies the thrust): a throttle input that only moves what
    the job reads as thrust separates nothing (``propulsion="catalog"``: the next flight's
    thrust is known, the throttle separates what scales with it).

    Parameters
    ----------
    run : IdentificationRun
        The main job's result.
    channels : sequence of InputChannel
        The inputs and their limits (:data:`FIXED_WING_CHANNELS`).
    duration : float
        Length of the manoeuvre [s].
    propulsion : str
        How the next flight's job will know the thrust, as the job's option: "data" (it
        identifies the thrust from a throttle that moves on its own), "catalog" (the thrust
        is known: a declared propeller, a logged motor speed).
    turn : bool
        Also predict the manoeuvre flown in a steady turn (at the rate a :data:`TURN_BANK`
        bank gives at the flight's airspeed, over the whole manoeuvre), and keep it where
        it separates more pairs.
    turbulence : str or None
        Turbulence the prediction flies the designed manoeuvre in (the level of
        :func:`~drake_uav.diagrams.identification_flight.fly`; None: still air). Gusts
        move the rivals' columns together as the next flight's will; the probes that pick
        the inputs fly in still air.
    seed : int
        Seed of the prediction's turbulence.
    sensors : SensorSuiteParams, optional
        The sensors the model is flown with. None: research-grade ones
        (:meth:`~drake_uav.vehicles.sensors.SensorSuiteParams.research_grade`), so that the
        columns carry little noise: noise in the channels the columns are computed from
        moves two rivals' columns apart without telling them apart, and noisier sensors
        would predict separations the next flight does not give.

    Returns
    -------
    ManoeuvreDesign or None
        None when the run has no near tie between named effects.

    Raises
    ------
    ValueError
        For an unknown ``propulsion``.
    """
    if propulsion not in ("data", "catalog"):
        raise ValueError(f"propulsion: {propulsion!r} unknown; use 'data' or 'catalog'")
    params = run.params
    pairs = []
    for tie in run.near_ties:
        k = tie.winner.coefficient
        members = [(e.effect, _effect_columns(e.effect, params, k))
                   for e in (tie.winner, *tie.alternatives)]
        members = [(name, columns) for name, columns in members if columns is not None]
        y = np.asarray(run.samples.coefficients[k], dtype=float)
        pairs += [(Rivals(k, a, b, first, second, _base_columns(params, k)), y)
                  for (a, first), (b, second) in itertools.combinations(members, 2)]
    if not pairs:
        return None
    model = _identified_model(run)
    airspeed = float(np.median(run.samples.condition.airspeed))
    suite = SensorSuiteParams.research_grade(model.rho) if sensors is None else sensors

    def simulate(signals, length, gusts=None):
        log = fly(model, turbulence=gusts, excitation=tuple(signals), duration=length,
                  airspeed=airspeed, seed=seed, sensors=suite)
        samples = samples_from_log(log, model)
        if propulsion == "data" and any(s.surface == "throttle" for s in signals):
            # The job identifies the thrust from a throttle that moves on its own.
            samples = dataclasses.replace(samples, thrust_correction_terms=THROTTLE_TERMS)
        return samples

    condition = run.samples.condition
    trim = {"elevator": condition.elevator, "aileron": condition.aileron,
            "rudder": condition.rudder, "throttle": run.samples.throttle}
    moved = [c.name for c in channels
             if np.std(trim[c.name]) > MOVED_SHARE * c.limit]
    turn_rate = GRAVITY * math.tan(TURN_BANK) / airspeed
    return design_manoeuvre(simulate, pairs, run.samples, channels, duration=duration,
                            trim={c.name: float(np.median(trim[c.name])) for c in channels},
                            background=moved, turn_rate=turn_rate if turn else None,
                            predict=functools.partial(simulate, gusts=turbulence))


COMMAND_CSV = "next_manoeuvre.csv"
"""Name of the command file in the main job's report folder."""
COMMAND_HEADER = ("# time [s], then one column per input named <input>_<unit>: its command "
                  "(trim + manoeuvre) in that unit (rad for a surface, 1 for a throttle fraction "
                  "of full; heading_rad: the heading to hold, as its change from the heading "
                  "at the start)")


def command_csv(design: ManoeuvreDesign, rate_hz: float = 50.0) -> str:
    """The manoeuvre as a command sequence a user can fly, as CSV text.

    A first comment line says what the columns are; then ``time_s`` and
    ``<channel>_<unit>`` (``elevator_rad``, ``throttle_1``): each channel's trim plus its
    multisine, at ``rate_hz`` from 0 to the manoeuvre's end; a manoeuvre flown in a turn
    has ``heading_rad`` too, the heading the autopilot is to hold, as its change from the
    heading at the start.

    Parameters
    ----------
    design : ManoeuvreDesign
        The manoeuvre.
    rate_hz : float
        Rate of the rows [Hz].

    Returns
    -------
    str
        The CSV text.

    Raises
    ------
    ValueError
        For a non-positive rate.
    """
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise ValueError(f"rate_hz: must be positive and finite, got {rate_hz}")
    t = np.arange(round(design.duration * rate_hz) + 1) / rate_hz
    names = SURFACES + REFERENCES
    controls = excitation_controls(t, [design.trim.get(s, 0.0) for s in names],
                                   design.signals, names)
    out = io.StringIO()
    out.write(COMMAND_HEADER + "\n")
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["time_s", *(f"{c.name}_{c.unit}" for c in design.channels)])
    for i, ti in enumerate(t):
        writer.writerow([f"{ti:.4f}", *(f"{controls[i, names.index(c.name)]:.6g}"
                                        for c in design.channels)])
    return out.getvalue()


def write_command_csv(path: str | Path, design: ManoeuvreDesign, rate_hz: float = 50.0
                      ) -> Path:
    """Writes :func:`command_csv` to ``path``; returns the path.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    design : ManoeuvreDesign
        The manoeuvre.
    rate_hz : float
        Rate of the rows [Hz].

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    path.write_text(command_csv(design, rate_hz))
    return path


def read_command_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Reads a command sequence written by :func:`write_command_csv`.

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    dict of str to numpy.ndarray
        Column name (``time_s``, ``elevator_rad``, ...) -> values.

    Raises
    ------
    ValueError
        When the file has no ``time_s`` column or a value is not a number.
    """
    path = Path(path)
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    rows = list(csv.reader(lines))
    if not rows or "time_s" not in rows[0]:
        raise ValueError(f"{path}: no 'time_s' column; write it with write_command_csv")
    try:
        values = np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
    except ValueError as error:
        raise ValueError(f"{path}: a command is not a number ({error})") from None
    return {name: values[:, i] for i, name in enumerate(rows[0])}
