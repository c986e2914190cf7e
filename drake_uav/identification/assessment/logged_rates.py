"""What a log's native rates can support: terms that need bandwidth the log lacks.

A reader puts every stream of a log on one time base and the isolation resamples that onto
its grid (50 Hz by default), so every channel *looks* sampled at the grid's rate. What a
channel can carry is set by the rate it was logged at (``metadata["streams"]``,
:func:`~drake_uav.io.streams.logged_rate`), not by the grid: a telemetry log (MAVLink
``.tlog``) or a ground-station export holds the IMU at a few Hz and the commands at less.
A term built on such a channel is fitted on samples the grid filled in between the logged
ones; the fit then reads the filling as physics (a held command lags by up to its period,
which the fits take for a servo delay). This module decides, from the native rates
alone, which terms a log can support, and says for each one it cannot what rate it
would need. It knows channel names and rates only, nothing of the vehicle: the caller
names each term's channels (:class:`RateNeed`).

The rules, each from what the term is fitted on:

* **Band terms** (control and damping derivatives, alpha-dot, rate coupling, a lever arm:
  a term whose information is the channel's variation over the flight's dynamics) are
  fitted on the band the isolation passes, its Savitzky-Golay smoothing's -3 dB frequency
  ``f_b`` (:func:`analysis_band`; 4.9 Hz for the 0.2 s window on the 50 Hz grid). An
  interpolated channel logged at ``f_s`` passes a frequency ``f`` with the gain
  ``sinc^2(f / f_s)`` of linear interpolation; it carries the band when that gain at
  ``f_b`` is no worse than the isolation's own there, ``1 / sqrt(2)``: ``f_s >= f_b /
  0.319`` (15.5 Hz on the default grid, :func:`interpolated_rate`), or the grid's rate
  where that is lower (a channel at the grid's rate is not interpolated).
* **Held channels** (the commands: the autopilot holds each output until it writes the
  next) are exact on the grid only when logged at least once per grid step. Logged at a
  period ``T`` longer than the step, the held value lags the one the aircraft flew by a
  time spread over ``[0, T)`` (``T / 2`` on average), which the fits cannot tell from a
  servo delay. A band term on a held channel needs the grid's rate.
* **Timing terms** (time delays and time skews) are resolved to one grid step ``dt``; a
  channel logged at a period ``T > dt`` hides a lag (held) or a timing uncertainty
  (interpolated) of up to ``T``, larger than the resolution: every channel of a timing
  term needs the grid's rate.

Nothing here is tuned: ``f_b`` is the isolation's, ``1 / sqrt(2)`` the -3 dB point that
defines it, and the grid step the job's own. A channel whose rate the log does not
record (a single time base: simulated logs, Parquet, one-time CSV) is at the log's rate.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Iterable, Mapping

import numpy as np
from scipy.optimize import brentq
from scipy.signal import freqz, savgol_coeffs

from drake_uav.identification.samples.regressor_noise import ISOLATION_WINDOW
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.streams import logged_rate

__all__ = ["BAND", "TIMING", "RateNeed", "RateLimit", "LoggedRates", "analysis_band",
           "interpolated_rate", "logged_rates", "native_rates"]

BAND = "band"
"""Kind of a term fitted on its channels' variation over the analysis band."""
TIMING = "timing"
"""Kind of a term that is a time (a delay, a skew)."""

_HALF_POWER = 1.0 / math.sqrt(2.0)
"""Gain at the -3 dB point: the edge of a band by its usual definition."""
_POLYORDER = 3
"""Polynomial order of the isolation's Savitzky-Golay filters (cubic)."""


def analysis_band(grid_rate_hz: float, window: float = ISOLATION_WINDOW) -> float:
    """The band the isolation passes: its smoothing's -3 dB frequency [Hz].

    The isolation smooths every signal with a cubic Savitzky-Golay filter of ``window``
    on the grid (:mod:`~drake_uav.identification.samples.isolation`); the coefficients
    and their regressors hold what passes it.

    Parameters
    ----------
    grid_rate_hz : float
        The grid's rate [Hz].
    window : float
        The filter's length [s].

    Returns
    -------
    float
        The frequency [Hz] where the filter's gain first falls to ``1 / sqrt(2)``; the
        grid's Nyquist frequency where it never does, or where the window holds too few
        samples for the filter.
    """
    length = int(round(window * grid_rate_hz)) | 1
    if length <= _POLYORDER:
        return grid_rate_hz / 2.0
    frequency, response = freqz(savgol_coeffs(length, _POLYORDER), worN=8192, fs=grid_rate_hz)
    below = np.flatnonzero(np.abs(response) < _HALF_POWER)
    return float(frequency[below[0]]) if below.size else grid_rate_hz / 2.0


def interpolated_rate(band_hz: float) -> float:
    """The lowest native rate [Hz] at which a linearly interpolated channel carries
    ``band_hz``: its interpolation's gain ``sinc^2(f / f_s)`` at the band's edge is
    ``1 / sqrt(2)``, the isolation's own there.

    Parameters
    ----------
    band_hz : float
        The band's edge [Hz].

    Returns
    -------
    float
        The rate [Hz] (about 3.1 times ``band_hz``).
    """
    ratio = brentq(lambda x: np.sinc(x) ** 2 - _HALF_POWER, 1e-6, 0.99)
    return band_hz / ratio


def native_rates(log: FlightLog) -> dict[str, float]:
    """Each measured channel's native rate [Hz].

    The rate of the stream it was read from (:func:`~drake_uav.io.streams.logged_rate`),
    else the log's own median rate.

    Parameters
    ----------
    log : FlightLog
        The flight log.

    Returns
    -------
    dict of str to float
        Channel -> rate [Hz].
    """
    steps = np.diff(log.time)
    own = 1.0 / float(np.median(steps)) if steps.size else math.inf
    return {n: (r if (r := logged_rate(log, n)) is not None else own)
            for n in log.measured_names}


@dataclasses.dataclass(frozen=True)
class RateNeed:
    """A candidate term and the channels it is built from.

    Attributes
    ----------
    term : str
        Its name (``"Cl_p"``, ``"actuator_time_delay"``).
    what : str
        What it is, for the report (``"damping derivative"``).
    channels : tuple of str
        The log channels it is built from.
    kind : str
        :data:`BAND` or :data:`TIMING` (module docstring).
    """

    term: str
    what: str
    channels: tuple[str, ...]
    kind: str = BAND

    def __post_init__(self):
        if self.kind not in (BAND, TIMING):
            raise ValueError(f"RateNeed.kind: {BAND!r} or {TIMING!r}, got {self.kind!r}")


@dataclasses.dataclass(frozen=True)
class RateLimit:
    """A term the log cannot support: its slowest channel against the rate it needs.

    Attributes
    ----------
    term, what, kind : str
        As in :class:`RateNeed`.
    channel : str
        The channel that falls short (the one furthest below its need).
    native_rate_hz : float
        The rate it was logged at [Hz].
    needed_rate_hz : float
        The rate the term needs of it [Hz].
    reason : str
        The rule that sets the need, in one clause.
    """

    term: str
    what: str
    kind: str
    channel: str
    native_rate_hz: float
    needed_rate_hz: float
    reason: str

    def message(self) -> str:
        """The limit in one line.

        Returns
        -------
        str
            ``"Cl_p (damping derivative): not identifiable at the logged rates: imu_p
            logged at 10 Hz, needs 15.5 Hz (<reason>)"``.
        """
        return (f"{self.term} ({self.what}): not identifiable at the logged rates: "
                f"{self.channel} logged at {self.native_rate_hz:.3g} Hz, needs "
                f"{self.needed_rate_hz:.3g} Hz ({self.reason})")

    def summary(self) -> dict:
        """JSON-ready fields (``summary.json``'s ``not_identifiable_at_logged_rates``).

        Returns
        -------
        dict
            The attributes by name.
        """
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class LoggedRates:
    """A log's native rates and what they support on an analysis grid.

    Attributes
    ----------
    rates : Mapping[str, float]
        Channel -> native rate [Hz] (:func:`native_rates`).
    held : frozenset of str
        The channels held between samples (commands).
    grid_rate_hz : float
        The analysis grid's rate [Hz].
    band_hz : float
        The band the analysis fits on [Hz] (:func:`analysis_band`).
    """

    rates: Mapping[str, float]
    held: frozenset[str]
    grid_rate_hz: float
    band_hz: float

    def needed_rate(self, channel: str, kind: str) -> tuple[float, str]:
        """The rate a term of ``kind`` needs of ``channel`` (module docstring).

        Parameters
        ----------
        channel : str
            The channel.
        kind : str
            :data:`BAND` or :data:`TIMING`.

        Returns
        -------
        rate : float
            The rate needed [Hz].
        reason : str
            The rule that sets it, in one clause.
        """
        if kind == TIMING:
            return self.grid_rate_hz, (f"a time is resolved to one step of the "
                                       f"{self.grid_rate_hz:g} Hz grid; a coarser channel "
                                       "hides a lag of up to its period")
        if channel in self.held:
            return self.grid_rate_hz, ("a held command logged less than once per grid step "
                                       "lags the one flown by up to its period, which reads "
                                       "as a delay")
        # A channel logged at the grid's rate is on the grid: nothing is interpolated.
        return min(interpolated_rate(self.band_hz), self.grid_rate_hz), (
            f"linear interpolation must pass the {self.band_hz:.2g} Hz band the isolation "
            "fits on at -3 dB")

    def nyquist(self, channels: Iterable[str]) -> float:
        """The lowest native Nyquist frequency of ``channels``.

        No spectrum of a signal built from them means anything above it.

        Parameters
        ----------
        channels : iterable of str
            The channels (those the log does not hold are left out).

        Returns
        -------
        float
            Half the lowest native rate [Hz]; half the grid's rate when none is in the log.
        """
        rates = [self.rates[c] for c in channels if c in self.rates]
        return min([*rates, self.grid_rate_hz]) / 2.0

    def limit(self, need: RateNeed) -> RateLimit | None:
        """Why the log cannot support ``need``.

        A channel the log does not hold is not judged here (the term is not testable for
        another reason).

        Parameters
        ----------
        need : RateNeed
            The term and its channels.

        Returns
        -------
        RateLimit or None
            The channel furthest below its need (the first of them on a tie); None when
            every channel is fast enough.
        """
        short = []
        for channel in need.channels:
            if channel not in self.rates:
                continue
            needed, reason = self.needed_rate(channel, need.kind)
            rate = self.rates[channel]
            # Rates are medians of a logger's clock: 0.1 % below the need is the same rate.
            if rate < needed * (1.0 - 1e-3):
                short.append((rate / needed, channel, rate, needed, reason))
        if not short:
            return None
        _, channel, rate, needed, reason = min(short, key=lambda s: s[0])
        return RateLimit(need.term, need.what, need.kind, channel, rate, needed, reason)

    def limits(self, needs: Iterable[RateNeed]) -> tuple[RateLimit, ...]:
        """The needs the log cannot support.

        Parameters
        ----------
        needs : iterable of RateNeed
            The terms.

        Returns
        -------
        tuple of RateLimit
            One per term the log cannot support, in the order given.
        """
        return tuple(limit for need in needs if (limit := self.limit(need)) is not None)


def logged_rates(log: FlightLog, grid_rate_hz: float = 50.0, *,
                 held: Collection[str] | None = None,
                 window: float = ISOLATION_WINDOW) -> LoggedRates:
    """The native rates of ``log`` judged against an analysis grid (module docstring).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    grid_rate_hz : float
        The analysis grid's rate [Hz].
    held : collection of str, optional
        The channels held between samples (None: the ``cmd_*`` channels, the commands).
    window : float
        The isolation's smoothing window [s].

    Returns
    -------
    LoggedRates

    Raises
    ------
    ValueError
        For a grid rate that is not positive and finite.

    Examples
    --------
    >>> import numpy as np
    >>> from drake_uav.io.flight_log import FlightLog
    >>> t = np.arange(0.0, 10.0, 0.1)                       # a 10 Hz log
    >>> log = FlightLog(t, {"imu_p": 0 * t, "cmd_aileron": 0 * t},
    ...                 units={"imu_p": "rad/s", "cmd_aileron": "rad"})
    >>> rates = logged_rates(log)
    >>> limit = rates.limit(RateNeed("Cl_p", "damping derivative", ("imu_p",)))
    >>> limit.channel, round(limit.native_rate_hz, 1), round(limit.needed_rate_hz, 1)
    ('imu_p', 10.0, 15.5)
    >>> rates.limit(RateNeed("actuator_time_delay", "time delay", ("cmd_aileron",), TIMING))
    ... # doctest: +ELLIPSIS
    RateLimit(term='actuator_time_delay', ..., needed_rate_hz=50.0, ...)
    """
    if not (math.isfinite(grid_rate_hz) and grid_rate_hz > 0.0):
        raise ValueError(f"grid_rate_hz: a positive rate [Hz], got {grid_rate_hz!r}")
    rates = native_rates(log)
    held = frozenset(n for n in rates if n.startswith("cmd_")) if held is None else \
        frozenset(held)
    return LoggedRates(rates, held, float(grid_rate_hz), analysis_band(grid_rate_hz, window))
