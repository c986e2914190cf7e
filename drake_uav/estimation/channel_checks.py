"""Physically impossible input: each channel against its physical range and its redundant
channels, before any fit (docs/compatibility.md, "Physically impossible input").

=================================  ===================  =====================================
channels                           physical range       why
=================================  ===================  =====================================
``vane_alpha vane_beta``           +-pi/2 rad           a flow angle beyond +-90 deg is
``ahrs_alpha ahrs_beta``                                flight backwards, not a fixed wing's
                                                        identification flight
``att_roll``                       +-pi rad             the Euler roll angle's own range
``att_pitch``                      +-pi/2 rad           the Euler pitch angle's own range
``imu_p imu_q imu_r``              +-2000 deg/s         the largest full scale of the gyros
                                                        of autopilots
``imu_ax imu_ay imu_az``           +-16 g               the largest full scale of the
                                                        accelerometers of autopilots, beyond
                                                        a small airframe's strength
``cmd_elevator cmd_aileron         +-pi/2 rad           no surface deflects 90 deg
cmd_rudder``
``pitot_airspeed``                 0 to                 the aircraft's catalog: its
                                   :func:`max_airspeed` power-on vertical dive, at most
``pitot_qbar``                     0 to its dynamic     the speed of sound
                                   pressure
=================================  ===================  =====================================

:func:`check_channels` reads a log over its airborne rows. Out-of-range samples that are
*glitches* (each run shorter than :data:`GLITCH_DURATION`, together at most
:data:`GLITCH_SHARE` of the rows), and airspeed samples that jump off the line between
their neighbours faster than the aircraft accelerates (:data:`MAX_AIRSPEED_RATE`), are
drawn as a straight line between their neighbours,
with a note naming the channel and the times; anything more stops with
:class:`ImplausibleChannelError`, one line naming the file, the channel and the likely
cause ("vane_alpha looks like degrees"). The pitot airspeed is also checked against the
GPS ground speed: they differ by the wind, and no aircraft is flown in a wind faster than
it can fly. :func:`check_calibration` stops on a calibration estimate of the
data-compatibility check far outside what a calibration can be (:data:`GROSS_CALIBRATION`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np
from scipy import optimize, stats

from drake_uav.estimation.signals import HELD_FRACTION, fresh_samples
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import AeroCondition, CoefficientModel
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["ImplausibleChannelError", "ChannelRange", "PHYSICAL_RANGES", "SPEED_OF_SOUND",
           "GLITCH_DURATION", "GLITCH_SHARE", "MAX_AIRSPEED_RATE", "SPIKE_SIGMAS",
           "GROSS_CALIBRATION", "CheckedLog",
           "max_airspeed", "channel_ranges", "check_channels", "check_calibration"]


class ImplausibleChannelError(FlightLogError):
    """A channel is physically impossible (a wrong unit, a wrong channel, a failed sensor):
    the message names the channel and the likely cause."""


@dataclasses.dataclass(frozen=True)
class ChannelRange:
    """The values a channel can physically hold [its unit]."""

    low: float
    high: float
    unit: str
    reason: str


_G = 9.80665
PHYSICAL_RANGES: dict[str, ChannelRange] = {
    **{c: ChannelRange(-math.pi / 2, math.pi / 2, "rad", "a flow angle beyond +-90 deg")
       for c in ("vane_alpha", "vane_beta", "ahrs_alpha", "ahrs_beta")},
    "att_roll": ChannelRange(-math.pi, math.pi, "rad", "the Euler roll angle's range"),
    "att_pitch": ChannelRange(-math.pi / 2, math.pi / 2, "rad",
                              "the Euler pitch angle's range"),
    **{c: ChannelRange(-math.radians(2000.0), math.radians(2000.0), "rad/s",
                       "the largest full scale of autopilot gyros, 2000 deg/s")
       for c in ("imu_p", "imu_q", "imu_r")},
    **{c: ChannelRange(-16.0 * _G, 16.0 * _G, "m/s^2",
                       "the largest full scale of autopilot accelerometers, 16 g")
       for c in ("imu_ax", "imu_ay", "imu_az")},
    **{c: ChannelRange(-math.pi / 2, math.pi / 2, "rad", "a surface deflection of 90 deg")
       for c in ("cmd_elevator", "cmd_aileron", "cmd_rudder")},
}
"""Physical ranges of the channels that do not depend on the aircraft (module docstring);
:func:`channel_ranges` adds the airspeed's."""

SPEED_OF_SOUND = 340.0
"""[m/s] at sea level (ISA): no propeller aircraft flies near it, and the pitot's
incompressible relation fails well before."""
GLITCH_DURATION = 0.5
"""[s]: the longest run of out-of-range samples drawn over as a glitch, the longest gap the
main job accepts in a stream (``samples_from_log(max_gap=0.5)``)."""
GLITCH_SHARE = 0.01
"""Share of a channel's rows out of range beyond which the channel is wrong, not glitchy."""
MAX_AIRSPEED_RATE = 17.0 * _G
"""[m/s^2]: the fastest the airspeed changes, the accelerometers' largest full scale (16 g)
plus gravity; a sample further from the line between its neighbours than this over the
interval, plus :data:`SPIKE_SIGMAS` times the sensor noise, is a spike."""
SPIKE_SIGMAS = 5.0
"""A spike stands this many standard deviations of the sensor noise (the robust spread of
the samples' distances from the line between their neighbours) beyond what the aircraft
can do: about one false spike in two million samples of Gaussian noise."""

_UNIT_SLIPS = {"rad": (math.degrees(1.0), "degrees"), "rad/s": (math.degrees(1.0), "deg/s")}
"""Unit -> (factor, name) of the unit a channel in that unit is often logged in by mistake."""


def max_airspeed(params: FixedWingParams) -> float:
    """The highest airspeed [m/s] ``params`` can fly: its terminal speed in a vertical dive
    at full throttle, where the drag ``rho V^2 S C_D,min / 4`` equals the weight plus the
    thrust (none once the propeller stops pulling), at most :data:`SPEED_OF_SOUND`.

    ``C_D,min`` is the catalog's least drag coefficient over the angle of attack (the other
    signals zero), halved because a flight may find the drag lower than the catalog's; a
    catalog without a positive drag floor gives the speed of sound.
    """
    alpha = np.linspace(-math.pi / 2, math.pi / 2, 721)
    zeros = np.zeros_like(alpha)
    drag = CoefficientModel(params.derivatives).coefficient(
        "CD", AeroCondition(zeros + 1.0, alpha, zeros, zeros, zeros, zeros), params.b, params.c)
    floor = 0.5 * float(np.min(np.broadcast_to(drag, alpha.shape)))

    def excess_drag(speed: float) -> float:
        thrust = float(params.propulsion.thrust_torque(speed, params.limits.throttle_max,
                                                       params.rho)[0])
        return (float(dynamic_pressure(speed, params.rho)) * params.S * floor
                - params.mass * params.gravity - max(thrust, 0.0))

    if floor <= 0.0 or excess_drag(SPEED_OF_SOUND) <= 0.0:
        return SPEED_OF_SOUND
    return float(optimize.brentq(excess_drag, 0.0, SPEED_OF_SOUND, xtol=1e-6))


def channel_ranges(params: FixedWingParams) -> dict[str, ChannelRange]:
    """:data:`PHYSICAL_RANGES` with the airspeed and dynamic pressure bounded by
    :func:`max_airspeed` of ``params``."""
    top = max_airspeed(params)
    why = ("the speed of sound" if top == SPEED_OF_SOUND
           else "the aircraft's power-on vertical dive")
    return {**PHYSICAL_RANGES,
            "pitot_airspeed": ChannelRange(0.0, top, "m/s", why),
            "pitot_qbar": ChannelRange(0.0, float(dynamic_pressure(top, params.rho)), "Pa",
                                       why)}


@dataclasses.dataclass(frozen=True)
class CheckedLog:
    """A log whose channels passed :func:`check_channels`, glitches drawn over."""

    log: FlightLog
    notes: tuple[str, ...]
    """One line per channel whose glitches were removed (the channel, the times)."""


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


def _cause(values: np.ndarray, bounds: ChannelRange) -> str:
    """The likely cause of a channel wholly out of its range, in a few words."""
    slip = _UNIT_SLIPS.get(bounds.unit)
    if slip is not None and np.all((values / slip[0] >= bounds.low)
                                   & (values / slip[0] <= bounds.high)):
        return f"looks like {slip[1]}"
    return "is not physical (a wrong unit, a wrong channel or a failed sensor)"


def _outside(bounds: ChannelRange) -> str:
    """"outside +-1.571 rad" or "outside 0 to 131.8 m/s"."""
    if bounds.low == -bounds.high:
        return f"outside +-{bounds.high:.4g} {bounds.unit}"
    return f"outside {bounds.low:.4g} to {bounds.high:.4g} {bounds.unit}"


def _prefix(source: str | None) -> str:
    return f"{source}: " if source else ""


def check_channels(log: FlightLog, params: FixedWingParams, rows: np.ndarray | None = None,
                   source: str | None = None) -> CheckedLog:
    """``log`` with each channel checked against its physical range
    (:func:`channel_ranges`) over ``rows`` (bool, the airborne samples; default all) and the
    pitot airspeed against the GPS ground speed (module docstring).

    Returns the log with its glitches drawn over and a note for each channel that had any.
    Raises :class:`ImplausibleChannelError`, one line starting with ``source`` (the file)
    and naming the channel, its values and the likely cause, for a channel out of range
    beyond glitches or an airspeed the GPS contradicts by more than the aircraft can fly.
    """
    rows = np.ones(len(log), bool) if rows is None else np.asarray(rows, bool)
    if not rows.any():
        return CheckedLog(log, ())
    repaired, notes = {}, []
    for channel, bounds in channel_ranges(params).items():
        if channel not in log.measured_names:
            continue
        values = np.asarray(log[channel], float)
        out = rows & ((values < bounds.low) | (values > bounds.high))
        if not out.any():
            continue
        runs = _runs(out)
        longest = max(log.time[b] - log.time[a] for a, b in runs)
        seen = values[rows]
        if longest > GLITCH_DURATION or out.sum() > GLITCH_SHARE * rows.sum():
            ground = _ground_speed(log, rows) if channel.startswith("pitot_") else None
            raise ImplausibleChannelError(
                f"{_prefix(source)}{channel} {_cause(seen, bounds)}: {seen.min():.3g} to "
                f"{seen.max():.3g} {bounds.unit} in flight, {out.sum()} of {rows.sum()} "
                f"samples {_outside(bounds)} ({bounds.reason})"
                + ("" if ground is None else f"; the GPS ground speed is {ground:.3g} m/s")
                + "; fix the unit or the channel of the log")
        good = ~out
        values = values.copy()
        values[out] = np.interp(log.time[out], log.time[good], values[good])
        repaired[channel] = values
        times = ", ".join(f"{log.time[a]:.2f} s" for a, _ in runs[:5])
        notes.append(f"{channel}: {int(out.sum())} sample(s) {_outside(bounds)} "
                     f"({bounds.reason}) removed as glitches at {times}"
                     f"{' ...' if len(runs) > 5 else ''}; drawn as a straight line between "
                     "their neighbours")
    checked = log.with_measured(repaired) if repaired else log
    if "pitot_airspeed" in checked:
        spikes = rows & _isolated_spikes(checked.time, checked["pitot_airspeed"])
        if spikes.any():
            values = np.array(checked["pitot_airspeed"], float)
            values[spikes] = np.interp(checked.time[spikes], checked.time[~spikes],
                                       values[~spikes])
            checked = checked.with_measured({"pitot_airspeed": values})
            at = checked.time[spikes]
            notes.append(f"pitot_airspeed: {spikes.sum()} isolated spike(s), a jump faster "
                         f"than the aircraft accelerates ({MAX_AIRSPEED_RATE / _G:.0f} g), "
                         "removed at " + ", ".join(f"{t:.2f} s" for t in at[:5])
                         + (" ..." if len(at) > 5 else "") + "; drawn as a straight line "
                         "between their neighbours")
    _check_ground_speed(checked, params, rows, source)
    return CheckedLog(checked, tuple(notes))


def _isolated_spikes(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Rows (bool) of the airspeed samples that stand alone off the line between their
    neighbours by more than the aircraft can accelerate over the interval
    (:data:`MAX_AIRSPEED_RATE`) plus :data:`SPIKE_SIGMAS` times the sensor noise; a held
    channel is judged on the samples it delivered."""
    values = np.asarray(values, float)
    fresh = np.flatnonzero(fresh_samples(values))
    if fresh.size > HELD_FRACTION * values.size:  # not held: every sample is its own
        fresh = np.arange(values.size)
    out = np.zeros(values.size, bool)
    if fresh.size < 5:
        return out
    t, v = np.asarray(time, float)[fresh], values[fresh]
    before, after = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    off = v[1:-1] - (v[:-2] + (v[2:] - v[:-2]) * before / (before + after))
    spread = 1.4826 * float(np.median(np.abs(off - np.median(off))))
    beyond = np.abs(off) > MAX_AIRSPEED_RATE * np.minimum(before, after) + SPIKE_SIGMAS * spread
    # An isolated spike also pulls its neighbours off their lines, by half as much.
    peak = np.abs(off) >= np.maximum(np.abs(np.roll(off, 1)), np.abs(np.roll(off, -1)))
    spikes = fresh[1:-1][beyond & peak]
    held_until = np.append(fresh[1:], values.size)
    for k in spikes:  # a held spike lasts until the next sample
        out[k:held_until[np.searchsorted(fresh, k)]] = True
    return out


def _check_ground_speed(log: FlightLog, params: FixedWingParams, rows: np.ndarray,
                        source: str | None) -> None:
    """Raises when the pitot airspeed and the GPS ground speed differ, in the median over
    ``rows``, by more than :func:`max_airspeed` (the wind they imply)."""
    ground = _ground_speeds(log, rows)
    if ground is None or "pitot_airspeed" not in log:
        return
    fixes = np.isfinite(ground) & (ground > 0.0)  # without a fix: zeros or nothing
    airspeed = np.asarray(log["pitot_airspeed"], float)[rows][fixes]
    difference = float(np.median(np.abs(airspeed - ground[fixes])))
    top = max_airspeed(params)
    if difference > top:
        raise ImplausibleChannelError(
            f"{_prefix(source)}pitot_airspeed disagrees with the GPS ground speed: median "
            f"{np.median(airspeed):.3g} m/s against {np.median(ground[fixes]):.3g} m/s, a "
            f"wind of {difference:.3g} m/s, faster than the aircraft can fly ({top:.0f} "
            "m/s); check the unit and channel of the airspeed and of the GPS velocity")


def _ground_speeds(log: FlightLog, rows: np.ndarray) -> np.ndarray | None:
    """GPS ground speed [m/s] over ``rows``; None without GPS velocity or any fix."""
    names = ("gps_vn", "gps_ve", "gps_vd")
    if not all(n in log for n in names):
        return None
    speed = np.linalg.norm(np.column_stack([log[n] for n in names]), axis=1)[rows]
    return speed if np.any(np.isfinite(speed) & (speed > 0.0)) else None


def _ground_speed(log: FlightLog, rows: np.ndarray) -> float | None:
    """Median GPS ground speed [m/s] over ``rows`` (fixes only); None without GPS."""
    speed = _ground_speeds(log, rows)
    return None if speed is None else float(np.median(speed[np.isfinite(speed) & (speed > 0)]))


GROSS_CALIBRATION: dict[str, tuple[float, float, str]] = {
    "airspeed_scale_factor": (2.0 / 3.0, 1.5, "a pitot's position error and the air "
                              "density of the altitude stay within 1/1.5 to 1.5"),
    **{f"vane_{k}_scale_factor": (0.5, 2.0, "the upwash at a vane stays within 0.5 to 2")
       for k in ("alpha", "beta")},
    **{f"vane_{k}_offset": (-math.radians(10.0), math.radians(10.0),
                            "a vane's mounting and the upwash offset it by under 10 deg")
       for k in ("alpha", "beta")},
}
"""Calibration effect -> (low, high, reason): the values a calibration can physically have.
An estimate beyond them (with the check's confidence) is a wrong unit, channel or sensor,
which a calibration would only hide."""

_SCALE_SLIPS = ((math.degrees(1.0), "degrees logged as radians"),
                (1.0 / 0.514444, "knots logged as m/s"), (3.6, "km/h logged as m/s"),
                (1.0 / 0.44704, "mph logged as m/s"))


def check_calibration(effects: Iterable, significance: float,
                      source: str | None = None) -> None:
    """Raises :class:`ImplausibleChannelError` for the first calibration effect (a
    :class:`~drake_uav.estimation.compatibility_result.CalibrationEffect`) whose estimate
    lies beyond its :data:`GROSS_CALIBRATION` range by more than its two-sided confidence
    interval at ``significance``.

    A scale factor the data do not determine (``observable`` False: gusts the vane follows
    and the kinematic angle misses) is biased towards zero, so only a too large one counts.
    """
    z = float(stats.norm.isf(significance / 2.0))
    for effect in effects:
        if effect.name not in GROSS_CALIBRATION or not (
                math.isfinite(effect.estimate) and math.isfinite(effect.sigma)):
            continue
        low, high, reason = GROSS_CALIBRATION[effect.name]
        attenuated = effect.nominal == 1.0 and not effect.observable
        above = effect.estimate - z * effect.sigma > high
        below = effect.estimate + z * effect.sigma < low and not attenuated
        if not (above or below):
            continue
        degrees = effect.unit == "rad"
        factor, unit = (math.degrees(1.0), " deg") if degrees else (1.0, "")
        cause = ("a wrong zero or a wrong channel, not a calibration" if effect.nominal == 0.0
                 else next((name for ratio, name in _SCALE_SLIPS
                            if abs(math.log(effect.estimate / ratio)) < 0.15),
                           "a wrong unit, a wrong channel or a failed sensor, not a calibration"))
        raise ImplausibleChannelError(
            f"{_prefix(source)}{', '.join(effect.channels[:1])}: {effect.name} "
            f"{effect.estimate * factor:.4g} +- {effect.sigma * factor:.2g}{unit}, far outside "
            f"{low * factor:.3g} to {high * factor:.3g}{unit} ({reason}): likely {cause}; "
            "fix the log's unit or channel")
