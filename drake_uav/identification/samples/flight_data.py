"""From a FlightLog to regression-ready samples (the first step of the main job).

The log must use the canonical measured channels below (the readers in
:mod:`drake_uav.io` map ArduPilot, PX4 and CSV logs onto them):

==================  ===========================================  ========
purpose             channels                                     unit
==================  ===========================================  ========
specific force      ``imu_ax imu_ay imu_az``                     m/s^2
body rates          ``imu_p imu_q imu_r``                        rad/s
attitude            ``att_roll att_pitch att_yaw``               rad
airspeed            ``pitot_airspeed``                           m/s
flow angles         ``vane_alpha vane_beta``                     rad
surfaces, throttle  ``cmd_elevator cmd_aileron cmd_rudder``      rad
                    ``cmd_throttle``                             1
height (optional)   ``baro_alt``                                 m
GPS (optional)      ``gps_vn gps_ve gps_vd``                     m/s
                    ``gps_pn gps_pe gps_pd`` (local NED)         m
==================  ===========================================  ========

The GPS velocity and position, when the log holds them, are carried into
``AeroSamples.signals`` under their channel names
(:data:`~drake_uav.identification.samples.aero_samples.GPS_VELOCITY`,
:data:`~drake_uav.identification.samples.aero_samples.GPS_POSITION`), the directions of the
vector effects that need them (against the ground velocity, towards a point): drawn as
straight lines between the fixes (:func:`gps_signals`), each triple left out when the log
lacks a channel of it or its fixes do not cover the airborne span. The receiver's latency
is not known from a log and not corrected: the position lags by it times the ground speed
(2.5 m for 0.1 s at 25 m/s).

Every other measured channel of the log is an extra channel
(:func:`~drake_uav.io.extras.extra_channels`: a tension, a battery voltage, an ESC's
speed): it is carried into ``AeroSamples.signals["logged:<channel>"]`` with its unit
and its noise (read from the data like the sensors', or declared), drawn as straight
lines between its samples when it was held like a slow sensor, and smoothed like the
regressors; :func:`usable_extras` leaves out, with a note, one that is constant, not
finite or changes too rarely to regress on.

The channels are checked (no NaN, no gap longer than ``max_gap``), brought onto a
uniform grid and passed to the coefficient isolation. A log sampled an integer number of
times faster than the grid is averaged over runs of that many samples, its commands
alike (:mod:`~drake_uav.identification.samples.decimation`), so that no sample's information is
dropped; another log is interpolated onto the grid. Commands are taken
as held from their time stamp to the next one (zero-order hold), which places
them differently for forces and moments (:func:`held_commands`): a sensor
sample sees the command in effect at its instant, the last one issued strictly
before it (a command stamped with the same time acts only after the sample);
the angular accelerations come from rate increments, which integrate the held
commands over the sample intervals. Every issued command is taken as logged
(held until the next logged one): a log thinned after the flight has lost the
commands in between, and nothing in it tells when they were issued.

Sensor noise matters to the errors-in-variables corrections of the discovery
loop. It is read from the data (:func:`raw_noise_variance`: the white floor of
each raw channel's spectrum, :mod:`drake_uav.estimation.sensor_noise`), or taken
from the sensor specs the caller declares (``sensor_noise_std``). Nothing else
of the log's metadata is read: a simulated flight records its true sensor noise
and command rate there, which a real log never holds.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping

import numpy as np

from drake_uav.estimation.channel_checks import check_channels
from drake_uav.estimation.sensor_noise import noise_floor_variance
from drake_uav.estimation.signals import HELD_FRACTION, fresh_samples, unheld
from drake_uav.identification.samples.aero_samples import (
    GPS_POSITION,
    GPS_VELOCITY,
    SHAFT_SPEED,
    AeroSamples,
    Signal,
)
from drake_uav.identification.samples.aero_samples import logged as logged_key
from drake_uav.identification.samples.decimation import (
    bin_means,
    binned_channels,
    decimation_factor,
)
from drake_uav.identification.samples.isolation import isolate_coefficients
from drake_uav.io.extras import extra_channels
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import logged_rate
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["REQUIRED_CHANNELS", "samples_from_log", "gridded_log", "isolated_samples",
           "GriddedLog", "check_gaps", "raw_noise_variance",
           "native_noise_variance", "white_noise_variance", "held_commands", "usable_extras",
           "MIN_EXTRA_CHANGES", "gps_signals", "GPS_MAX_GAP"]

SPECIFIC_FORCE = ("imu_ax", "imu_ay", "imu_az")
RATES = ("imu_p", "imu_q", "imu_r")
ATTITUDE = ("att_roll", "att_pitch", "att_yaw")
AIR_DATA = ("pitot_airspeed", "vane_alpha", "vane_beta")
CONTROLS = ("cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle")
HEIGHT = "baro_alt"

REQUIRED_CHANNELS = SPECIFIC_FORCE + RATES + ATTITUDE + AIR_DATA + CONTROLS
"""Measured channels the main job needs."""

GPS_MAX_GAP = 1.0
"""[s]: the longest time without a GPS fix a triple is drawn across, between fixes and at
the ends of the airborne span (five fixes of a 5 Hz receiver)."""


_NOISE_SOURCES = dict(zip(
    ("airspeed", "alpha", "beta", "p", "q", "r", "ax", "ay", "az"),
    AIR_DATA + RATES + SPECIFIC_FORCE, strict=True))

MIN_EXTRA_CHANGES = 20
"""An extra channel whose value changes fewer times than this over the log is too sparse
to regress on (a flag, a mode, a battery level logged once a minute)."""


def usable_extras(log: FlightLog, exclude=()) -> tuple[dict[str, str], tuple[str, ...]]:
    """The extra channels of ``log`` the main job tests, and why the others are left out.

    A channel is left out when it is not finite, constant, or changes fewer than
    :data:`MIN_EXTRA_CHANGES` times.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    exclude : iterable of str
        Channels that are not extra here (the flow angles in use).

    Returns
    -------
    usable : dict of str to str
        Channel -> unit of each usable extra channel.
    notes : tuple of str
        One note per extra channel left out.
    """
    usable, notes = {}, []
    for name, unit in extra_channels(log, exclude).items():
        values = log[name]
        changes = int(np.count_nonzero(np.diff(values)))
        if not np.all(np.isfinite(values)):
            why = "it has samples that are not finite"
        elif changes == 0:
            why = f"it is constant ({values[0]:.6g})"
        elif changes < MIN_EXTRA_CHANGES:
            why = f"too sparse: its value changes {changes} times (< {MIN_EXTRA_CHANGES})"
        else:
            usable[name] = unit
            continue
        notes.append(f"extra channel {name} [{unit}] left out: {why}")
    return usable, tuple(notes)


def white_noise_variance(values: np.ndarray, rate_hz: float,
                         commands: np.ndarray | None = None, averaged: int = 1) -> float:
    """Variance of the white-noise floor of a uniformly sampled signal.

    Of the mean of ``averaged`` consecutive samples; the commands' coherent part is set
    aside (:func:`~drake_uav.estimation.sensor_noise.noise_floor_variance`).

    Parameters
    ----------
    values : numpy.ndarray of shape (n,)
        The signal.
    rate_hz : float
        Its sample rate [Hz].
    commands : numpy.ndarray of shape (n, m), optional
        The logged commands on the same samples.
    averaged : int
        Number of consecutive samples averaged.

    Returns
    -------
    float
        The variance [unit^2].
    """
    return noise_floor_variance(values, rate_hz, commands, averaged)


def raw_noise_variance(log: FlightLog, declared: Mapping[str, float] | None = None,
                       air_density: float | None = None, averaged: int = 1) -> dict[str, float]:
    """Noise variance of the raw channels the isolation needs, by isolation name.

    ``declared`` wins where it names a channel; the airspeed's may also come from a
    declared ``pitot_qbar`` [Pa], carried through ``Va = sqrt(2 q / rho)`` at the log's
    median airspeed. The other channels' noise is read from the data
    (:func:`white_noise_variance`, the log's commands set aside) at the rate the channel
    was logged (:func:`native_noise_variance`).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    declared : Mapping[str, float], optional
        Log channel -> standard deviation [channel unit], the user's sensor specs.
    air_density : float, optional
        [kg/m^3], for a declared ``pitot_qbar``.
    averaged : int
        With ``averaged`` > 1, the variance of the means of that many consecutive samples.

    Returns
    -------
    dict of str to float
        Isolation source (``airspeed``, ``alpha``, ..., ``az``) -> variance [unit^2].
    """
    std = _declared_std(log, declared or {}, air_density)
    return {name: (std[channel] ** 2 if channel in std
                   else native_noise_variance(log, channel, averaged))
            for name, channel in _NOISE_SOURCES.items()}


def _at_rate(noise: dict[str, float], log: FlightLog, rate_hz: float,
             sources: dict[str, str] = _NOISE_SOURCES) -> dict[str, float]:
    """Noise variances (by the names of ``sources``: name -> log channel) as white noise on
    the ``rate_hz`` grid the isolation smooths.

    A channel logged at r < ``rate_hz`` [Hz] has independent errors only every 1/r s:
    over the smoothing window its error averages down r/``rate_hz`` times less than
    white noise on the grid would. White noise on the grid with the same density
    below r/2 has the variance scaled by ``rate_hz``/r.
    """
    out = dict(noise)
    for name, channel in sources.items():
        logged = logged_rate(log, channel)
        if logged is not None and 0 < logged < rate_hz:
            out[name] = noise[name] * rate_hz / logged
    return out


def _extra_noise(log: FlightLog, extras, declared: Mapping[str, float] | None,
                 rate_hz: float, averaged: int = 1) -> dict[str, float]:
    """Raw noise variance of each extra channel on the ``rate_hz`` grid, by its
    ``logged:<channel>`` name: the declared standard deviation where there is one, else
    the white floor read from the data (:func:`native_noise_variance`; of the means of
    ``averaged`` samples)."""
    sources = {logged_key(c): c for c in extras}
    declared = declared or {}
    noise = {name: (float(declared[c]) ** 2 if c in declared
                    else native_noise_variance(log, c, averaged))
             for name, c in sources.items()}
    return _at_rate(noise, log, rate_hz, sources)


def _shaft_speed_noise(log: FlightLog, declared: Mapping[str, float] | None, rate_hz: float,
                       averaged: int) -> dict[str, float]:
    """``{"motor_speed": variance}``: the propeller shaft speed's noise for the thrust fit
    (:func:`~drake_uav.identification.propulsion.identify_thrust`), declared or read at
    the rate it was logged, as white noise on the ``rate_hz`` grid. Empty without a shaft
    speed, or when its floor cannot be read at that rate (an ESC's few hertz, whose band
    the flight's own motion fills): the thrust fit then reads it on the grid."""
    if "motor_speed" not in log:
        return {}
    declared = declared or {}
    variance = (float(declared["motor_speed"]) ** 2 if "motor_speed" in declared
                else native_noise_variance(log, "motor_speed", averaged))
    if not variance > 0.0:
        return {}
    return _at_rate({"motor_speed": variance}, log, rate_hz, {"motor_speed": "motor_speed"})


def native_noise_variance(log: FlightLog, channel: str, averaged: int = 1) -> float:
    """White-noise variance of ``channel`` at the rate it was logged.

    A channel logged slower than the log's time base was interpolated onto it,
    which averages neighbouring samples and hides their noise. It is taken back to
    its own rate (every k-th sample); of the k phases, the one with the highest
    floor lies closest to the logged samples and gives the estimate (a mean of the log's
    samples holds ``averaged / k`` of its own).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    channel : str
        The channel.
    averaged : int
        With ``averaged`` > 1, of the mean of that many consecutive samples of the log
        (:mod:`~drake_uav.identification.samples.decimation`).

    Returns
    -------
    float
        The variance [unit^2].
    """
    rate = 1.0 / float(np.median(np.diff(log.time)))
    logged = logged_rate(log, channel)
    step = 1 if logged is None else max(1, int(round(rate / logged)))
    values, commands = log[channel], log.stack(CONTROLS)
    if step == 1:
        return white_noise_variance(values, rate, commands, averaged)
    own = max(1, int(round(averaged / step)))  # its own samples in a mean of the log's
    return max(white_noise_variance(values[j::step], rate / step, commands[j::step], own)
               for j in range(step))


def _specs_for(declared: Mapping[str, float] | None,
               flow_channels: tuple[str, str]) -> Mapping[str, float] | None:
    """The declared specs that apply: the vanes' only when the flow angles are the vanes'."""
    if declared is None or tuple(flow_channels) == AIR_DATA[1:]:
        return declared
    return {k: v for k, v in declared.items() if k not in AIR_DATA[1:]}


def _declared_std(log: FlightLog, declared: Mapping[str, float],
                  air_density: float | None) -> dict[str, float]:
    """Declared standard deviations of the isolation's channels (see :func:`raw_noise_variance`)."""
    std = {channel: float(declared[channel]) for channel in _NOISE_SOURCES.values()
           if channel in declared}
    if "pitot_airspeed" not in std and "pitot_qbar" in declared and air_density:
        airspeed = float(np.median(log["pitot_airspeed"]))
        std["pitot_airspeed"] = float(declared["pitot_qbar"]) / (air_density * airspeed)
    return std


def _air_data_unheld(log: FlightLog, extras=()) -> FlightLog:
    """``log`` with held air data, height and ``extras`` (a 10 Hz pitot held on a faster
    log) drawn as straight lines between their samples, as they were measured."""
    return log.with_measured({n: unheld(log.time, log[n]) for n in (*AIR_DATA, HEIGHT, *extras)
                              if n in log})


def _on_grid(log: FlightLog, rate_hz: float, factor: int):
    """``log`` on the isolation's ``rate_hz`` [Hz] grid, with its held commands there (at
    the instants, over the intervals: :func:`held_commands`).

    A log ``factor`` times faster is averaged over runs of ``factor`` samples
    (:mod:`~drake_uav.identification.samples.decimation`), and so are the commands, taken at the
    raw instants and over the grid step each raw instant starts; another log is
    interpolated onto the grid. Misplacing held commands by half a hold period would leave
    a spurious actuator delay (or lead) in the residual: forces and moments each get their
    own alignment. The yaw comes unwrapped, so that neither a mean nor an interpolation
    spans the +-pi wrap.
    """
    log = log.with_measured({"att_yaw": np.unwrap(log["att_yaw"])})
    if factor == 1:
        uniform = log.resample(rate_hz=rate_hz)
        return uniform, *held_commands(log.time, log.stack(CONTROLS), uniform.time)
    uniform = bin_means(log, factor, rate_hz)
    rows = len(uniform.time) * factor
    commands = held_commands(log.time, log.stack(CONTROLS), log.time, span=1.0 / rate_hz)
    return uniform, *(c[:rows].reshape(-1, factor, c.shape[1]).mean(axis=1) for c in commands)


def _averaged_specs(declared: Mapping[str, float] | None, averaged: tuple[str, ...],
                    factor: int) -> Mapping[str, float] | None:
    """The declared standard deviations of single samples as those of the means of
    ``factor`` samples for the channels ``averaged`` (white noise: ``1 / sqrt(factor)``)."""
    if declared is None or factor == 1:
        return declared
    return {c: float(std) / np.sqrt(factor) if c in averaged else std
            for c, std in declared.items()}


def _renamed(log: FlightLog, sources: dict[str, str]) -> FlightLog:
    """``log`` with channels ``sources`` values copied under their keys' names."""
    log.require(*sources.values())
    return log.with_measured({name: log[source] for name, source in sources.items()},
                             {name: log.unit(source) for name, source in sources.items()})


def held_commands(stamps: np.ndarray, values: np.ndarray, time: np.ndarray,
                  hold_period: float | None = None,
                  span: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Held commands on the sample times ``time``: at the instants, and over the intervals.

    The commands are issued every ``hold_period`` from the first stamp and held until the
    next issue (default: the log's step, every command logged); commands issued between
    two logged ones (a log thinned after the flight) are interpolated.

    Parameters
    ----------
    stamps : numpy.ndarray of shape (N,)
        Times the commands were logged [s].
    values : numpy.ndarray of shape (N, m)
        The logged commands.
    time : numpy.ndarray of shape (n,)
        Sample times [s].
    hold_period : float, optional
        Period of the command issues [s].
    span : float, optional
        Averaging span [s] of the second result (default: the sample intervals).

    Returns
    -------
    instant : numpy.ndarray of shape (n, m)
        The command in effect at each instant, the last one issued strictly before it (a
        sample and a command with the same stamp: the sample comes first).
    average : numpy.ndarray of shape (n, m)
        The average of the held commands over ``[time_k, time_(k+1))`` (the last row over
        one more step), what the rate increments integrate; with ``span``, over
        ``[time_k, time_k + span)``.
    """
    stamps = np.asarray(stamps, dtype=float)
    values = np.asarray(values, dtype=float)
    time = np.asarray(time, dtype=float)
    step = float(np.median(np.diff(stamps)))
    if hold_period is not None and hold_period < step * (1.0 - 1e-6):
        issued = stamps[0] + hold_period * np.arange(
            int(np.floor((stamps[-1] - stamps[0]) / hold_period + 1e-6)) + 1)
        values = np.column_stack([np.interp(issued, stamps, v) for v in values.T])
        stamps = issued
    tolerance = 1e-6 * float(np.median(np.diff(stamps)))
    index = np.clip(np.searchsorted(stamps, time - tolerance, side="left") - 1,
                    0, len(stamps) - 1)
    # Integral of the held commands from the first stamp, at any time.
    area = np.vstack([np.zeros(values.shape[1]),
                      np.cumsum(values[:-1] * np.diff(stamps)[:, None], axis=0)])

    def integral(t):
        i = np.clip(np.searchsorted(stamps, t, side="right") - 1, 0, len(stamps) - 1)
        return area[i] + values[i] * (t - stamps[i])[:, None]

    if span is not None:
        return values[index], (integral(time + span) - integral(time)) / span
    edges = np.append(time, 2.0 * time[-1] - time[-2])
    averages = np.diff(integral(edges), axis=0) / np.diff(edges)[:, None]
    return values[index], averages


def gps_signals(log: FlightLog, time: np.ndarray) -> dict[str, np.ndarray]:
    """The GPS velocity [m/s] and position [m] of ``log`` on the sample times ``time``.

    Each triple (:data:`GPS_VELOCITY`, :data:`GPS_POSITION`) is drawn as straight lines
    between its fixes (extended along the first and last pair's slope at the ends), and
    left out when the log lacks one of its channels or its fixes leave more than
    :data:`GPS_MAX_GAP` of ``time``'s span uncovered. A fix is a sample where a channel of
    the triple changes (the log holds a slow receiver's values until the next one), with
    finite values that are not all zero (a receiver without a fix writes zeros or nothing).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    time : numpy.ndarray of shape (n,)
        Sample times [s].

    Returns
    -------
    dict of str to numpy.ndarray
        Channel name -> (n,) values.
    """
    out = {}
    for names in (GPS_VELOCITY, GPS_POSITION):
        if not all(n in log for n in names):
            continue
        values = np.column_stack([np.asarray(log[n], dtype=float) for n in names])
        fixes = _fixes(values)
        stamps = np.asarray(log.time, dtype=float)[fixes]
        if _covers(stamps, time[0], time[-1]):
            out.update({n: _between_fixes(stamps, values[fixes, i], time)
                        for i, n in enumerate(names)})
    return out


def _fixes(values: np.ndarray) -> np.ndarray:
    """Indices of the fixes of a GPS triple (N, 3) (see :func:`gps_signals`)."""
    new = fresh_samples(values)
    if np.count_nonzero(new) > HELD_FRACTION * len(values):
        new[:] = True
    valid = np.all(np.isfinite(values), axis=1) & np.any(values != 0.0, axis=1)
    return np.flatnonzero(new & valid)


def _covers(stamps: np.ndarray, start: float, end: float) -> bool:
    """Fixes at ``stamps`` [s] leave no more than :data:`GPS_MAX_GAP` of [start, end]
    without one, at the ends and between them."""
    if stamps.size < 2 or stamps[0] - start > GPS_MAX_GAP or end - stamps[-1] > GPS_MAX_GAP:
        return False
    overlapping = (stamps[1:] > start) & (stamps[:-1] < end)
    return bool(np.all(np.diff(stamps)[overlapping] <= GPS_MAX_GAP))


def _between_fixes(stamps: np.ndarray, values: np.ndarray, time: np.ndarray) -> np.ndarray:
    """``values`` at the fixes ``stamps`` as straight lines on ``time``, the first and last
    lines extended beyond the fixes."""
    out = np.interp(time, stamps, values)
    for outside, a, b in ((time < stamps[0], 0, 1), (time > stamps[-1], -2, -1)):
        slope = (values[b] - values[a]) / (stamps[b] - stamps[a])
        out[outside] = values[a] + slope * (time[outside] - stamps[a])
    return out


def check_gaps(log: FlightLog, max_gap: float) -> None:
    """Check that no time step of ``log`` is longer than ``max_gap``.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    max_gap : float
        Longest allowed step [s].

    Raises
    ------
    FlightLogError
        At the first longer step, naming its time.
    """
    step = np.diff(log.time)
    bad = np.flatnonzero(step > max_gap)
    if bad.size:
        i = int(bad[0])
        raise FlightLogError(
            f"time: gap of {step[i]:.3g} s between samples {i} and {i + 1} "
            f"(t = {log.time[i]:.6g} s), longer than the allowed {max_gap:g} s")


@dataclasses.dataclass(frozen=True)
class GriddedLog:
    """A checked flight log on the samples' uniform time grid, ready for the isolation.

    Made by :func:`gridded_log`; the thrust identification
    (:func:`~drake_uav.identification.propulsion.thrust_from_gridded_log`) reads it too.

    Attributes
    ----------
    log : FlightLog
        The airborne channels on the grid (block means of the decimated samples).
    controls : numpy.ndarray of shape (N, 4)
        Elevator, aileron, rudder [rad] and throttle [0..1] as the forces see them.
    moment_controls : numpy.ndarray of shape (N, 4)
        The same controls as the moment coefficients see them.
    signals : dict of str to numpy.ndarray
        Attitude [rad], height [m] and the GPS triples, by :attr:`AeroSamples.signals` name.
    noise_variance : dict of str to float
        Raw white-noise variance of the isolation's sources, the extra channels and, where
        logged, ``motor_speed`` (the propeller's shaft speed, for the thrust fit).
    extras : Mapping[str, str]
        The extra channels carried into the samples (channel -> unit).
    """

    log: FlightLog
    controls: np.ndarray
    moment_controls: np.ndarray
    signals: dict[str, np.ndarray]
    noise_variance: dict[str, float]
    extras: Mapping[str, str]


def samples_from_log(log: FlightLog, params: FixedWingParams, rate_hz: float = 50.0,
                     max_gap: float = 0.5, min_airspeed: float = 5.0,
                     flow_channels: tuple[str, str] = ("vane_alpha", "vane_beta"),
                     sensor_noise_std: dict[str, float] | None = None,
                     extras: Mapping[str, str] | None = None) -> AeroSamples:
    """Regression samples (measured coefficients and regressors) from a flight log.

    With the thrust of the aircraft's propulsion model: :func:`gridded_log` followed by
    :func:`isolated_samples`; the main job puts its thrust identification between the two
    (:func:`~drake_uav.identification.pipeline.identify`).

    Parameters
    ----------
    log : FlightLog
        The flight log, channels in SI units (module docstring).
    params : FixedWingParams
        The aircraft.
    rate_hz : float
        Rate of the samples [Hz].
    max_gap : float
        Longest allowed time between two samples [s].
    min_airspeed : float
        Samples below this airspeed [m/s] are cut from the ends of the log.
    flow_channels : tuple of str
        The channels holding the angle of attack and sideslip [rad].
    sensor_noise_std : dict, optional
        Log channel -> declared noise standard deviation [channel unit].
    extras : Mapping, optional
        Extra channels (channel -> unit) carried into the samples.

    Returns
    -------
    AeroSamples
        The measured coefficients and their regressors on the grid.

    Raises
    ------
    FlightLogError
        As :func:`gridded_log`, or when the isolation refuses the data.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde(), rate_hz=50.0)
    >>> sorted(samples.coefficients)
    ['CD', 'CL', 'CY', 'Cl', 'Cm', 'Cn']
    >>> float(samples.time[1] - samples.time[0])
    0.02
    """
    return isolated_samples(gridded_log(log, params, rate_hz, max_gap, min_airspeed,
                                        flow_channels, sensor_noise_std, extras), params)


def gridded_log(log: FlightLog, params: FixedWingParams, rate_hz: float = 50.0,
                max_gap: float = 0.5, min_airspeed: float = 5.0,
                flow_channels: tuple[str, str] = ("vane_alpha", "vane_beta"),
                sensor_noise_std: dict[str, float] | None = None,
                extras: Mapping[str, str] | None = None) -> GriddedLog:
    """The airborne part of a flight log, checked and on a uniform grid, with the noise
    of its channels.

    The eight parameters are the independent settings of the data preparation, each
    with its default; they are not grouped further because each caller sets a few.

    Parameters
    ----------
    log : FlightLog
        The flight log, channels in SI units (module docstring).
    params : FixedWingParams
        The aircraft (its physical ranges and air density).
    rate_hz : float
        Rate of the grid [Hz]; faster logs are block-averaged down to it.
    max_gap : float
        Longest allowed time between two samples [s].
    min_airspeed : float
        Samples below this airspeed [m/s] (on the ground, take-off roll) are cut from
        the ends of the log.
    flow_channels : tuple of str
        The channels holding the angle of attack and sideslip [rad] (vanes, or an
        estimate).
    sensor_noise_std : dict, optional
        Log channel -> standard deviation [channel unit] the user declares; the noise of
        the channels left out is read from the data (:func:`raw_noise_variance`).
    extras : Mapping, optional
        Extra channels (channel -> unit) carried into the samples (module docstring);
        None takes :func:`usable_extras` of ``log``.

    Returns
    -------
    GriddedLog
        The channels on the grid, the controls as forces and moments see them, the
        signals and the noise variances.

    Raises
    ------
    FlightLogError
        Naming a missing channel, a non-finite sample, a gap, an airspeed never above
        ``min_airspeed`` or a physically impossible channel
        (:class:`~drake_uav.estimation.channel_checks.ImplausibleChannelError`).

    Notes
    -----
    The GPS velocity and position join the signals where the log holds them
    (:func:`gps_signals`). The channels are first checked against their physical ranges
    over the samples above ``min_airspeed``
    (:func:`~drake_uav.estimation.channel_checks.check_channels`): glitches are drawn
    over with a warning (``warnings.warn``), an impossible channel stops.
    """
    if tuple(flow_channels) != ("vane_alpha", "vane_beta"):
        log = _renamed(log, dict(zip(("vane_alpha", "vane_beta"), flow_channels, strict=True)))
    log.require(*REQUIRED_CHANNELS)
    check_gaps(log, max_gap)
    checked = check_channels(log, params, log["pitot_airspeed"] >= min_airspeed)
    for note in checked.notes:
        warnings.warn(note, stacklevel=2)
    log = checked.log
    if extras is None:
        extras = usable_extras(log, exclude=flow_channels)[0]
    log.require(*extras)
    factor = decimation_factor(log.time, rate_hz)
    declared = _averaged_specs(sensor_noise_std, binned_channels(log, rate_hz), factor)
    noise = _at_rate(raw_noise_variance(log, _specs_for(declared, flow_channels), params.rho,
                                        averaged=factor), log, rate_hz)
    extra_noise = _extra_noise(log, extras, declared, rate_hz, factor)
    noise |= _shaft_speed_noise(log, declared, rate_hz, factor)
    airborne = np.flatnonzero(log["pitot_airspeed"] >= min_airspeed)
    if airborne.size < 2:
        raise FlightLogError(
            f"pitot_airspeed: never above {min_airspeed} m/s; no airborne data to identify")
    whole = log
    log = _air_data_unheld(log.slice(log.time[airborne[0]], log.time[airborne[-1]]), extras)
    uniform, controls, moment_controls = _on_grid(log, rate_hz, factor)
    signals = {Signal.ROLL: uniform["att_roll"], Signal.PITCH: uniform["att_pitch"],
               Signal.YAW: uniform["att_yaw"]}
    if HEIGHT in uniform:
        signals[Signal.HEIGHT] = uniform[HEIGHT]
    signals.update(gps_signals(whole, uniform.time))
    return GriddedLog(uniform, controls, moment_controls, signals, {**noise, **extra_noise},
                      extras)


def isolated_samples(grid: GriddedLog, params: FixedWingParams,
                     thrust: Mapping[str, object] | None = None) -> AeroSamples:
    """The measured coefficients of a gridded log
    (:func:`~drake_uav.identification.samples.isolation.isolate_coefficients`).

    Parameters
    ----------
    grid : GriddedLog
        The log on its grid (:func:`gridded_log`).
    params : FixedWingParams
        The aircraft.
    thrust : Mapping, optional
        An identified thrust: ``thrust`` [N], ``thrust_airspeed_slope`` [N/(m/s)] and
        ``thrust_correction_terms``, from the shaft speed with ``thrust_speed_slope`` and
        ``shaft_speed``, whose noise then enters the samples (declared, or read at its
        native rate, :func:`gridded_log`; else on the grid)
        (:func:`~drake_uav.identification.propulsion.thrust_from_gridded_log`); None keeps
        the catalog's propulsion model.

    Returns
    -------
    AeroSamples

    Raises
    ------
    FlightLogError
        When the isolation refuses the data (its message).
    """
    uniform = grid.log
    try:
        return isolate_coefficients(
            params, uniform.time, uniform.stack(SPECIFIC_FORCE), uniform.stack(RATES),
            uniform.stack(AIR_DATA), grid.controls, signals=grid.signals,
            raw_noise_variance={k: v for k, v in grid.noise_variance.items()
                                if k != SHAFT_SPEED or "shaft_speed" in (thrust or {})},
            moment_controls=grid.moment_controls,
            logged={c: (uniform[c], unit) for c, unit in grid.extras.items()},
            **(thrust or {}))
    except ValueError as err:
        raise FlightLogError(str(err)) from None
