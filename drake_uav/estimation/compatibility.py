"""Data compatibility before fitting: calibration errors read from the redundancy of the
sensors, reported as named effects (:mod:`~drake_uav.estimation.compatibility_result`).

The IMU, the attitude, the GPS, the barometer and the air data measure the same motion
several times over. Flight-path reconstruction checks them against each other
(Klein & Morelli 2006, ch. 10) and estimates what makes them disagree:

===========================  ======================================  =================
effect                       relation                                channels
===========================  ======================================  =================
``gyro_bias_p/q/r``          Euler-angle kinematics vs the gyro      ``imu_p/q/r``
``attitude_time_skew``       the same, the attitude shifted          ``att_*``
``accelerometer_bias_x/y/z`` GPS velocity changes vs the             ``imu_ax/ay/az``
                             accelerometer in NED plus gravity
``gps_time_skew``            the same, the GPS shifted (beyond the   ``gps_*``
                             receiver latency)
``baro_bias``                barometric vs GPS altitude              ``baro_alt``
``command_time_skew``        commands vs the angular accelerations   ``cmd_*``
``airspeed_scale_factor``    pitot vs the wind triangle              ``pitot_*``
``vane_alpha_offset`` ...    vanes vs the wind triangle              ``vane_alpha/beta``
``air_data_time_skew``       air data vs the kinematic air data      ``pitot_*, vane_*``
===========================  ======================================  =================

The relations are in :mod:`~drake_uav.estimation.compatibility_kinematics` and
:mod:`~drake_uav.estimation.compatibility_air_data`, the fits and their standard errors
(time-block sandwich for correlated residuals) in
:mod:`~drake_uav.estimation.compatibility_fits`. Only measured channels are read, never
the log's metadata. The stages run in the table's order, each on the
channels the earlier ones corrected (a significant skew or bias is removed before the
next relation uses the channel).

A command skew is corrected only when it is negative (the response cannot precede the
command) or longer than ``max_actuator_delay``: a shorter one cannot be told from a
servo delay, which belongs to the aircraft and is left to the model. Either way the
air-data stage reads the commands at the time the aircraft responds to them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from drake_uav.estimation.channel_checks import check_calibration
from drake_uav.estimation.compatibility_air_data import (
    air_data_skew,
    heading_spread,
    kinematic_air_data,
    vane_scale_fit,
    wind_fit,
)
from drake_uav.estimation.compatibility_fits import ParameterFit, fresh_times
from drake_uav.estimation.compatibility_kinematics import (
    Strapdown,
    attitude_fit,
    baro_fit,
    command_fit,
    reconstructed_velocity,
    velocity_fit,
)
from drake_uav.estimation.compatibility_result import (
    SIGNIFICANCE,
    CalibrationEffect,
    CompatibilityResult,
    read_later,
)
from drake_uav.estimation.gps import DEFAULT_GPS_LATENCY
from drake_uav.io.flight_log import FlightLog, FlightLogError

__all__ = ["check_compatibility", "DEFAULT_TOLERANCES", "MIN_HEADING_SPREAD",
           "MAX_UNSEEN_SHARE", "CalibrationEffect", "CompatibilityResult"]

DEFAULT_TOLERANCES: dict[str, float] = {
    "gyro_bias": math.radians(0.1),
    "accelerometer_bias": 0.05,
    "airspeed_scale_factor": 0.02,
    "vane_offset": math.radians(0.5),
    "vane_scale_factor": 0.05,
    "baro_bias": 2.0,
    "air_data_time_skew": 0.01,
}
"""Practical tolerances in SI units (rad/s, m/s^2, -, rad, -, m, s). The skews of the GPS,
the attitude and the commands are tolerated up to one sample period of their channels,
the air data's up to the larger of that and ``air_data_time_skew`` (the estimate carries
a few milliseconds of gust bias). Reasons and figures: docs/compatibility.md."""

MIN_HEADING_SPREAD = 0.05
"""Heading spread (circular variance) below which the airspeed scale factor and the
sideslip offset are not fitted: they are confounded with the wind along and across a
straight track (0.05 is a swing of about +-30 deg)."""
MAX_UNSEEN_SHARE = 0.25
"""Share of the kinematic flow angle's variation a vane may miss (gusts) for its scale
factor to be observable: the attenuation bias grows with it."""
WINDOW = 1.0
"""Window [s] of the kinematic relations."""
MIN_DOF = 4
"""Fewest degrees of freedom (time blocks - 1) of an observable effect: with fewer blocks
the standard error itself is too uncertain to test against."""
WIND_INTERVAL = 300.0
"""Longest time [s] one constant wind is fitted over."""

_IMU = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r")
_ATTITUDE = ("att_roll", "att_pitch", "att_yaw")
_GPS_VELOCITY = ("gps_vn", "gps_ve", "gps_vd")
_GPS = ("gps_pn", "gps_pe", "gps_pd", *_GPS_VELOCITY)
_AIR = {"airspeed": ("pitot_airspeed", "pitot_qbar"), "alpha": ("vane_alpha",),
        "beta": ("vane_beta",)}
_COMMANDS = {"elevator": "cmd_elevator", "aileron": "cmd_aileron", "rudder": "cmd_rudder"}


@dataclasses.dataclass
class _Check:
    """The measured channels as the stages correct them, and what they found."""

    log: FlightLog
    gravity: float
    tolerances: dict[str, float]
    gps_latency: float
    max_skew: float
    significance: float
    max_actuator_delay: float
    channels: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    effects: list[CalibrationEffect] = dataclasses.field(default_factory=list)
    notes: list[str] = dataclasses.field(default_factory=list)
    gps_delay: float = 0.0
    command_skew: float = 0.0
    """How much later [s] the aircraft responds to the logged commands (a servo delay or a
    logging skew), when the command stage estimated it."""
    accel_bias: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.time = self.log.time
        self.channels = {n: np.array(self.log[n]) for n in self.log.measured_names}

    def has(self, *names: str) -> bool:
        return all(n in self.channels for n in names)

    def stack(self, names) -> np.ndarray:
        return np.column_stack([self.channels[n] for n in names])

    def period(self, names) -> float:
        """Median interval [s] between new samples of a channel group."""
        fresh = fresh_times(self.time, self.stack(names))
        return float(np.median(np.diff(self.time[fresh]))) if len(fresh) > 1 else math.inf

    def add(self, name: str, channels, value: float, sigma: float, dof: int, unit: str,
            tolerance: float, explanation: str, *, nominal: float = 0.0,
            observable: bool = True, note: str = "", correctable: bool = True,
            drives: bool = False) -> CalibrationEffect:
        if observable and not (math.isfinite(sigma) and sigma > 0.0):
            observable, note = False, "degenerate: a channel held constant"
        elif observable and dof < MIN_DOF:
            observable, note = False, (f"{dof + 1} time blocks: too short a record for the "
                                       "correlation of its residuals")
        elif observable and not sigma <= tolerance:
            observable, note = False, "the data do not determine it to its tolerance"
        effect = CalibrationEffect(
            name, tuple(channels), float(value), float(sigma), int(dof), unit, nominal,
            float(tolerance), explanation, observable=observable, note=note,
            correctable=correctable, significance=self.significance, drives=drives)
        self.effects.append(effect)
        return effect

    def add_fit(self, name: str, fit: ParameterFit, parameter: str, channels, unit: str,
                tolerance: float, explanation: str, **kw) -> CalibrationEffect:
        return self.add(name, channels, fit.value(parameter), fit.sigma(parameter), fit.dof,
                        unit, tolerance, explanation, **kw)

    def subtract(self, channel: str, value: float) -> None:
        self.channels[channel] = self.channels[channel] - value

    def read_later(self, names, tau: float) -> None:
        """Channels ``names`` (those present) read ``tau`` [s] later."""
        for n in names:
            if n in self.channels:
                self.channels[n] = read_later(self.time, self.channels[n], tau,
                                              angle=self.log.unit(n) == "rad")


def _attitude_stage(c: _Check) -> None:
    fit = attitude_fit(c.time, c.stack(_IMU[3:]), c.stack(_ATTITUDE), window=WINDOW,
                       max_skew=c.max_skew)
    for axis, channel in zip("pqr", _IMU[3:], strict=True):
        effect = c.add_fit(f"gyro_bias_{axis}", fit, f"bias_{axis}", (channel,), "rad/s",
                           c.tolerances["gyro_bias"], f"constant error of the {axis} gyro "
                           "(attitude kinematics against the gyro)")
        if effect.applied:
            c.subtract(channel, effect.estimate)
    effect = c.add_fit("attitude_time_skew", fit, "skew", _ATTITUDE, "s",
                       c.period(_ATTITUDE), "the attitude lags the IMU by this time")
    if effect.applied:
        c.read_later(_ATTITUDE, effect.estimate)


def _gps_stage(c: _Check) -> None:
    strapdown = Strapdown.from_samples(c.time, c.stack(_IMU[:3]), c.stack(_ATTITUDE), c.gravity)
    fit = velocity_fit(c.time, strapdown, c.stack(_GPS_VELOCITY), window=WINDOW,
                       max_skew=c.max_skew)
    c.accel_bias = fit.estimate[:3].copy()
    for i, (axis, channel) in enumerate(zip("xyz", _IMU[:3], strict=True)):
        effect = c.add_fit(f"accelerometer_bias_{axis}", fit, f"bias_{axis}", (channel,),
                           "m/s^2", c.tolerances["accelerometer_bias"],
                           f"constant error of the {axis} accelerometer (GPS velocity "
                           "changes against the accelerometer in NED plus gravity)")
        if effect.applied:
            c.subtract(channel, effect.estimate)
            c.accel_bias[i] = 0.0
    delay = fit.value("skew")
    effect = c.add("gps_time_skew", _GPS, delay - c.gps_latency, fit.sigma("skew"), fit.dof,
                   "s", c.period(_GPS_VELOCITY), "the GPS lags the IMU by this time beyond "
                   f"the receiver latency ({c.gps_latency:.3g} s; measured delay "
                   f"{delay:.3f} s)")
    c.gps_delay = delay
    if effect.applied:
        c.read_later(_GPS, effect.estimate)
        c.gps_delay = c.gps_latency


def _baro_stage(c: _Check) -> None:
    fit = baro_fit(c.time, c.channels["baro_alt"], c.channels["gps_pd"], c.gps_delay, 10.0)
    tolerance = c.tolerances["baro_bias"]
    c.add_fit("baro_bias", fit, "bias", ("baro_alt",), "m", tolerance,
              "barometric altitude minus GPS altitude", correctable=False,
              note="the barometer keeps its own reference (sea level, or the ground at "
                   "power-up)" if abs(fit.value("bias")) > tolerance else "")


def _wind_segments(time: np.ndarray) -> np.ndarray:
    """Wind segment of each sample: a new one at every time gap and every
    :data:`WIND_INTERVAL`."""
    step = np.diff(time)
    gap = np.concatenate([[0], np.cumsum(step > 5.0 * np.median(step))])
    start = np.concatenate([[0], np.flatnonzero(np.diff(gap)) + 1])
    since = time - time[start][gap]
    return np.unique(gap * 100000 + (since // WIND_INTERVAL).astype(int),
                     return_inverse=True)[1]


_RESPONSE = {"airspeed": ("imu_ax", "cmd_throttle"), "alpha": ("imu_az", "cmd_elevator"),
             "beta": ("imu_ay", "cmd_rudder", "cmd_aileron")}
"""Signals that move with each air-data channel at once (those logged are used): the
specific force along the force the channel's flow angle or airspeed changes, which sees
a gust when the air data do, and the commands that move that specific force directly
(thrust, the surfaces' own lift and side force). Without the commands the specific force
leads the flow angle by the surfaces' share and biases the skew by about +0.015 s. The
specific force also enters over the dynamic pressure (:meth:`_AirData._response`): a
flow angle moves the force per dynamic pressure at once, while a throttle that moves the
airspeed moves the force with no change of the flow angle, through the speed dynamics;
with the force alone the skew comes out late on flights that move the throttle, with both
far less."""


class _AirData:
    """The wind-triangle stage: the reconstructed flight path against the air data."""

    def __init__(self, c: _Check):
        self.c = c
        strapdown = Strapdown.from_samples(c.time, c.stack(_IMU[:3]), c.stack(_ATTITUDE),
                                           c.gravity)
        self.velocity = reconstructed_velocity(c.time, strapdown, c.stack(_GPS_VELOCITY),
                                               c.accel_bias, c.gps_delay)
        self.rows = strapdown.rows
        self.segment = _wind_segments(c.time)
        self.spread = heading_spread(c.channels["att_yaw"])
        self.turning = self.spread >= MIN_HEADING_SPREAD
        self.names = [k for k, (channel, *_) in _AIR.items() if c.has(channel)]
        self.free = ((["airspeed_scale"] if self.turning else []) + ["alpha_offset"] * c.has(
            "vane_alpha") + ["beta_offset"] * (c.has("vane_beta") and self.turning))

    def measured(self) -> dict[str, np.ndarray]:
        return {k: self.c.channels[_AIR[k][0]] for k in self.names}

    def fit(self, fixed: Mapping[str, float] | None = None) -> ParameterFit:
        return wind_fit(self.c.time, self.velocity, self.rows, self.measured(), self.segment,
                        self.free, fixed)

    def kinematic(self, fit: ParameterFit) -> dict[str, np.ndarray]:
        winds = fit.estimate[: 2 * (int(self.segment.max()) + 1)].reshape(-1, 2)[self.segment]
        wind = np.column_stack([winds, np.zeros(len(winds))])
        return dict(zip(("airspeed", "alpha", "beta"),
                        kinematic_air_data(self.velocity, self.rows, wind), strict=True))

    def skew(self, kinematic: Mapping[str, np.ndarray]) -> None:
        """The skew of the air data, timed on the vanes when there are any: they see the
        surfaces and gusts at once, while the airspeed follows the thrust through the speed
        dynamics (with a servo delay the airspeed relation alone was biased by -0.04 to
        -0.06 s on simulated flights, the vanes by under 0.004 s). All the air-data
        channels are corrected together."""
        c = self.c
        timed = [k for k in self.names if k != "airspeed"] or self.names
        response = {k: self._response(k, kinematic["airspeed"]) for k in timed}
        fit = air_data_skew(c.time, {k: kinematic[k] for k in timed},
                            {k: self.c.channels[_AIR[k][0]] for k in timed}, response,
                            c.max_skew)
        channels = [n for k in self.names for n in _AIR[k] if c.has(n)]
        effect = c.add_fit("air_data_time_skew", fit, "skew", channels, "s",
                           max(c.period(channels[:1]), c.tolerances["air_data_time_skew"]),
                           "the air data lag the IMU by this time")
        if effect.applied:
            c.read_later(channels, effect.estimate)

    def _response(self, quantity: str, airspeed: np.ndarray) -> np.ndarray:
        """(N, m) response signals of the air-data ``quantity`` (:data:`_RESPONSE`, those
        logged), then its specific force over the dynamic pressure relative to its mean,
        ``(airspeed / mean)^-2`` at the IMU's time (``airspeed``, the kinematic one [m/s])."""
        signals = [self._responding(n) for n in _RESPONSE[quantity] if self.c.has(n)]
        force = _RESPONSE[quantity][0]
        if self.c.has(force):
            signals.append(self.c.channels[force] * (airspeed / np.mean(airspeed)) ** -2)
        return np.column_stack(signals)

    def _responding(self, channel: str) -> np.ndarray:
        """A response signal; a command at the time the aircraft responds to it."""
        values = self.c.channels[channel]
        if channel.startswith("cmd_") and self.c.command_skew:
            return read_later(self.c.time, values, -self.c.command_skew)
        return values

    def scales(self, kinematic: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Vane scale-factor effects; the applied ones as fixed values of the final fit."""
        c, fixed = self.c, {}
        for k in ("alpha", "beta"):
            if k not in self.names:
                continue
            fit, share = vane_scale_fit(c.time, kinematic[k], c.channels[_AIR[k][0]])
            seen = share <= MAX_UNSEEN_SHARE
            effect = c.add_fit(
                f"vane_{k}_scale_factor", fit, "scale", _AIR[k], "1",
                c.tolerances["vane_scale_factor"], f"the {k} vane reads this times the "
                "kinematic flow angle", nominal=1.0, observable=seen,
                note="" if seen else f"the vane does not follow the kinematic flow angle "
                f"(unexplained share {share:.2g}; gusts)")
            if effect.applied:
                fixed[f"{k}_scale"] = effect.estimate
        return fixed

    def levels(self, fit: ParameterFit) -> None:
        """Airspeed scale factor and vane offsets of the final fit; the winds as notes."""
        c = self.c
        confounded = (f"heading spread {self.spread:.3f} < {MIN_HEADING_SPREAD}: confounded "
                      "with the wind along and across the track")
        entries = [("airspeed_scale_factor", "airspeed_scale", "airspeed", "1",
                    c.tolerances["airspeed_scale_factor"], 1.0,
                    "the pitot reads this times the airspeed of the wind triangle")]
        entries += [(f"vane_{k}_offset", f"{k}_offset", k, "rad", c.tolerances["vane_offset"],
                     0.0, f"the {k} vane reads this much more than the kinematic angle "
                     "(mean vertical wind taken as zero)") for k in ("alpha", "beta")]
        for name, parameter, key, unit, tolerance, nominal, text in entries:
            if key not in self.names:
                continue
            if parameter in fit.names:
                effect = c.add_fit(name, fit, parameter, _AIR[key], unit, tolerance, text,
                                   nominal=nominal)
                for channel in _AIR[key] if effect.applied else ():
                    if c.has(channel):
                        power = (2.0 if channel == "pitot_qbar" else 1.0) * (nominal == 1.0)
                        c.channels[channel] = (c.channels[channel] / effect.estimate**power
                                               if power else c.channels[channel] - effect.estimate)
            else:
                c.add(name, _AIR[key], math.nan, math.inf, 1, unit, tolerance, text,
                      nominal=nominal, observable=False, note=confounded)
        for s in range(int(self.segment.max()) + 1):
            c.notes.append(f"wind (segment {s}): north {fit.value(f'wind_n_{s}'):+.2f}, "
                           f"east {fit.value(f'wind_e_{s}'):+.2f} m/s" if self.turning else
                           f"wind (segment {s}): not observable: heading spread "
                           f"{self.spread:.3f} < {MIN_HEADING_SPREAD}, the wind across the "
                           "track trades with a heading error and the sideslip vane's offset; "
                           "the fit's value is not a wind measurement")


def _air_data_stage(c: _Check) -> None:
    stage = _AirData(c)
    kinematic = stage.kinematic(stage.fit())
    stage.skew(kinematic)
    fixed = stage.scales(kinematic)
    stage.levels(stage.fit(fixed))


def _command_stage(c: _Check) -> None:
    imu = {n[4:]: c.channels[n] for n in _IMU}
    commands = {k: c.channels[v] for k, v in _COMMANDS.items() if c.has(v)}
    fit = command_fit(c.time, imu, commands, max_skew=c.max_skew)
    if fit is None:
        return
    skew, period = fit.value("skew"), float(np.median(np.diff(c.time)))
    late = 0.0 <= skew <= c.max_actuator_delay
    effect = c.add_fit("command_time_skew", fit, "skew", list(_COMMANDS.values()), "s",
                       period, "the angular accelerations follow the commands by this time",
                       correctable=not late, drives=True,
                       note=f"a delay up to {c.max_actuator_delay:g} s may be the servos' (a "
                            "model effect), left to the model" if late and skew > period else "")
    if effect.observable:
        c.command_skew = skew


def check_compatibility(log: FlightLog, params, *, gps_latency: float = DEFAULT_GPS_LATENCY,
                        tolerances: Mapping[str, float] | None = None,
                        max_skew: float = 5.0, significance: float = SIGNIFICANCE,
                        max_actuator_delay: float = 0.25) -> CompatibilityResult:
    """Calibration errors of ``log`` from the redundancy of its measured channels.

    Args:
        log: the flight; needs ``imu_*`` and ``att_*``, and uses what it has of
            ``gps_*``, ``baro_alt``, ``pitot_airspeed`` (and ``pitot_qbar``),
            ``vane_alpha``, ``vane_beta`` and ``cmd_*``.
        params: the aircraft (its ``gravity`` [m/s^2]).
        gps_latency: receiver latency [s] the downstream estimators assume: the GPS
            skew is reported, and corrected, beyond it.
        tolerances: practical tolerances overriding :data:`DEFAULT_TOLERANCES`.
        max_skew: skews are searched within +-max_skew [s] (at most a quarter of the log).
        significance: two-sided p-value threshold.
        max_actuator_delay: command skews in [0, this] [s] are reported, not corrected.

    Raises :class:`~drake_uav.io.flight_log.FlightLogError` naming a missing IMU or
    attitude channel, or a log too short to check;
    :class:`~drake_uav.estimation.channel_checks.ImplausibleChannelError` for an airspeed
    scale factor, vane scale factor or vane offset far outside what a calibration can be
    (:data:`~drake_uav.estimation.channel_checks.GROSS_CALIBRATION`: a wrong unit, channel
    or sensor, which a correction would hide).
    """
    for name in (*_IMU, *_ATTITUDE):
        if name not in log.measured_names:
            raise FlightLogError(f"compatibility check: missing measured channel '{name}'")
    if log.duration < 8.0 * WINDOW or len(log) < 100:
        raise FlightLogError(f"compatibility check: {log.duration:.1f} s and {len(log)} "
                             f"samples; need at least {8 * WINDOW:g} s and 100 samples")
    check = _Check(log, float(params.gravity), {**DEFAULT_TOLERANCES, **(tolerances or {})},
                   gps_latency, min(max_skew, 0.25 * log.duration), significance,
                   max_actuator_delay)
    _run(_attitude_stage, check, "attitude and gyro")
    if check.has(*_GPS_VELOCITY):
        _run(_gps_stage, check, "accelerometer and GPS")
        if check.has("baro_alt", "gps_pd"):
            _run(_baro_stage, check, "baro")
    _run(_command_stage, check, "commands")
    if check.has(*_GPS_VELOCITY):
        if check.has("pitot_airspeed"):
            _run(_air_data_stage, check, "air data")
        else:
            check.notes.append("air data not checked: no pitot_airspeed channel")
    else:
        check.notes.append("accelerometer, GPS, baro and air data not checked: no GPS "
                           "velocity channels (gps_vn, gps_ve, gps_vd)")
    check_calibration(check.effects, significance)
    return CompatibilityResult(tuple(check.effects), tuple(check.notes))


def _run(stage, check: _Check, what: str) -> None:
    """Runs one stage; data it cannot fit (a channel held constant, a singular relation)
    leave a note instead of stopping the check."""
    with np.errstate(all="ignore"):
        try:
            stage(check)
        except (np.linalg.LinAlgError, ValueError) as err:
            check.notes.append(f"{what} not checked: the data do not determine the "
                               f"relation ({err})")
