"""A fast log onto the isolation's slower grid, keeping every sample's information.

A log sampled ``m`` times faster than the isolation's grid (a 100 Hz IMU and air data for
the 50 Hz grid) holds ``m`` independent sensor errors per grid step. Interpolating onto
the grid keeps one of them and throws the others away. :func:`bin_means` averages each
run of ``m`` consecutive samples instead (a box filter of one grid step, then every
``m``-th value): white noise falls ``m``-fold in variance, the rigid-body band below
~5 Hz loses at most 1.2 % (100 Hz onto 50 Hz), and every channel sees one and the same filter,
so a coefficient and its regressors keep their relation on the means (up to the second
order of the variation inside a step). The commands get the same average in
:func:`~drake_uav.identification.samples.flight_data.samples_from_log`: the command in effect
at each raw instant for the forces, and its average over the step each raw instant
starts for the moments (the rate increments between two means integrate over those).

Channels the log says were recorded no faster than the grid (``metadata["streams"]`` of
the autopilot readers) hold no extra samples; they are interpolated at the means' times.
"""

from __future__ import annotations

import numpy as np

from drake_uav.io.flight_log import FlightLog
from drake_uav.io.streams import logged_rate

__all__ = ["decimation_factor", "bin_means", "binned_channels"]

UNIFORM_TOLERANCE = 1e-3
"""Largest deviation of a log's sample interval from its median, as a share of it, for the
time base to count as uniform."""


def decimation_factor(time: np.ndarray, rate_hz: float) -> int:
    """The integer factor by which a uniform log is faster than the sample rate wanted.

    Parameters
    ----------
    time : numpy.ndarray of shape (N,)
        Sample times [s].
    rate_hz : float
        The rate wanted [Hz].

    Returns
    -------
    int
        ``m >= 2`` when ``time`` is uniform at ``m`` times ``rate_hz``, else 1 (the log is
        then resampled onto the grid).
    """
    steps = np.diff(np.asarray(time, dtype=float))
    if steps.size == 0:
        return 1
    step = float(np.median(steps))
    if step <= 0 or np.max(np.abs(steps - step)) > UNIFORM_TOLERANCE * step:
        return 1
    ratio = 1.0 / (step * rate_hz)
    factor = int(round(ratio))
    return factor if factor >= 2 and abs(ratio - factor) < UNIFORM_TOLERANCE else 1


def binned_channels(log: FlightLog, rate_hz: float) -> tuple[str, ...]:
    """The channels of ``log`` that :func:`bin_means` averages.

    All but those the log says were recorded no faster than ``rate_hz``.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    rate_hz : float
        The rate wanted [Hz].

    Returns
    -------
    tuple of str
        The channel names.
    """
    return tuple(n for n in log.names
                 if (r := logged_rate(log, n)) is None or r > rate_hz * (1 + UNIFORM_TOLERANCE))


def bin_means(log: FlightLog, factor: int, rate_hz: float) -> FlightLog:
    """``log`` with each run of ``factor`` consecutive samples replaced by its mean.

    Time is averaged too, the mean times put on the uniform grid that fits them best where
    the log's clock jitters (the samples left over at the end are dropped). Channels logged
    no faster than ``rate_hz`` (:func:`binned_channels`) are interpolated at the means'
    times instead. A wrapped angle (the yaw) is averaged unwrapped and wrapped again.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    factor : int
        Number of samples per mean.
    rate_hz : float
        The rate of the result [Hz].

    Returns
    -------
    FlightLog
        The decimated log, with the units and metadata of ``log``.
    """
    n = (len(log.time) // factor) * factor
    time = log.time[:n].reshape(-1, factor).mean(axis=1)
    steps = np.diff(time)
    if steps.size and np.ptp(steps) > 1e-9 * np.median(steps):
        # The means jitter as the log's clock does (a microsecond clock: about 1e-6 s); the
        # derivatives downstream need one exact interval, so they stand on the uniform grid
        # that fits their times best.
        k = np.arange(len(time))
        time = np.polynomial.polynomial.Polynomial.fit(k, time, 1).convert()(k)
    averaged = set(binned_channels(log, rate_hz))

    def reduce(name: str) -> np.ndarray:
        values = np.asarray(log[name], dtype=float)
        if name not in averaged:
            return np.interp(time, log.time, values)
        unwrapped = np.unwrap(values) if log.unit(name) == "rad" else values
        means = unwrapped[:n].reshape(-1, factor).mean(axis=1)
        if unwrapped is values or np.array_equal(unwrapped, values):
            return means
        return (means + np.pi) % (2.0 * np.pi) - np.pi

    return FlightLog(time, {c: reduce(c) for c in log.measured_names},
                     {c: reduce(c) for c in log.truth_names}, log.units, log.metadata)
