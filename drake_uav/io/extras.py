"""Extra channels: the measured signals a log holds beyond the canonical ones.

Any measured channel of a :class:`~drake_uav.io.flight_log.FlightLog` that is not
canonical (:data:`~drake_uav.io.streams.CHANNELS`) and not an autopilot's estimate of a
canonical quantity (:data:`ESTIMATED_CHANNELS`) is an *extra channel*: a tether tension,
a battery voltage or current, an ESC's shaft speed, a payload signal. It keeps its name
and its unit, and the main job tests it as a candidate explanation of the residual
(docs/main_job.md, "The effects").

* CSV: every column that is not canonical (``tension [N]``; a column without a unit,
  ``payload``, gets the unit ``1``).
* ArduPilot ``.bin`` and PX4 ``.ulg``: a small default set of physical signals when the
  log has them (:data:`ARDUPILOT_EXTRAS`, :data:`PX4_EXTRAS`: battery voltage and
  current), plus the fields the user names (``extra_channels=["BAT.Temp", ...]``,
  ``drake-uav identify --extra-channels``), as channels ``<message>.<field>`` (brackets
  of an array field dropped: ``esc_status.esc1.esc_power``). Every ESC's telemetry is
  read as ``esc_rpm_<i>``, ``esc_voltage_<i>``, ... (:mod:`drake_uav.io.esc`). They are
  optional streams: sparse or gappy, they are left out with a warning; a sample that is
  not finite is an invalid one; they never shorten the log (a battery logged from 0.3 s
  after the IMU holds its first value).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np

from drake_uav.io.csv_log import UNIT_VARIANTS, channel_name
from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError
from drake_uav.io.streams import CHANNELS, Stream

__all__ = ["AHRS_CHANNELS", "ESTIMATED_CHANNELS", "ARDUPILOT_EXTRAS", "PX4_EXTRAS",
           "extra_channels", "extra_channel_name", "parse_extra_fields", "logged_unit",
           "wanted_fields", "extra_streams"]

AHRS_CHANNELS = {
    "ahrs_alpha": ("rad", "angle of attack estimated by ArduPlane's AHRS (not a sensor)"),
    "ahrs_beta": ("rad", "sideslip angle estimated by ArduPlane's AHRS (not a sensor)"),
}
"""Channels of ArduPlane's logged ``AOA`` message: name -> (unit, meaning)."""

ESTIMATED_CHANNELS = {
    **AHRS_CHANNELS,
    "est_alpha": ("rad", "angle of attack estimated from IMU, attitude, GPS and pitot"),
    "est_beta": ("rad", "sideslip angle estimated from IMU, attitude, GPS and pitot"),
}
"""Measured channels that estimate a canonical quantity, never extra: name -> (unit,
meaning)."""

ARDUPILOT_EXTRAS = (("BAT", "Volt", "V"), ("BAT", "Curr", "A"))
"""(message, field, unit) of the extra channels a ``.bin`` log gives by default (first
instance)."""

PX4_EXTRAS = (("battery_status", "voltage_v", "V"), ("battery_status", "current_a", "A"))
"""(topic, field, unit) of the extra channels a ``.ulg`` log gives by default (multi-id 0)."""


def extra_channels(log: FlightLog, exclude: Iterable[str] = ()) -> dict[str, str]:
    """The extra measured channels of ``log`` (module docstring) -> unit, in log order;
    ``exclude`` leaves more names out (flow angles estimated from the log)."""
    skip = {*CHANNELS, *ESTIMATED_CHANNELS, *exclude}
    return {name: log.unit(name) for name in log.measured_names if name not in skip}


def extra_channel_name(message: str, field: str) -> str:
    """The channel name of a logged field: ``BAT.Volt``; brackets dropped
    (``esc_status.esc[0].esc_rpm`` -> ``esc_status.esc0.esc_rpm``), any other character
    a channel name cannot hold replaced (:func:`~drake_uav.io.csv_log.channel_name`)."""
    return channel_name(f"{message}.{field}".replace("[", "").replace("]", ""))


def parse_extra_fields(names: Sequence[str]) -> list[tuple[str, str]]:
    """``["BAT.Volt", "esc_status.esc[1].esc_rpm"]`` -> (message, field) pairs (split at
    the first dot); ValueError naming an entry without a message or a field."""
    out = []
    for name in names:
        message, _, field = str(name).strip().partition(".")
        if not message or not field:
            raise ValueError(f"extra_channels: {name!r} is not MESSAGE.FIELD (e.g. BAT.Volt)")
        out.append((message, field))
    return out


def logged_unit(unit: str | None) -> tuple[str, float]:
    """(unit of the channel, factor from the logged value) of a field logged in ``unit``:
    a variant of an SI unit is converted (``rpm`` -> ``rad/s``), a unit of the FlightLog
    registry kept, anything else (or None) kept as the raw number with unit ``1``."""
    if unit in UNIT_VARIANTS:
        return UNIT_VARIANTS[unit]
    if unit in UNITS:
        return unit, 1.0
    return "1", 1.0


def wanted_fields(defaults: Sequence[tuple[str, str, str]], named: Sequence[tuple[str, str]],
                  has: Callable[[str, str], bool], unit: Callable[[str, str], str | None],
                  source: str) -> dict[str, dict[str, str | None]]:
    """message -> field -> logged unit of the extra channels to read: the ``defaults``
    (message, field, unit) the log ``has``, then the ``named`` (message, field) pairs with
    the log's ``unit`` of them; FlightLogError naming ``source`` and a named field the log
    lacks."""
    wanted: dict[str, dict[str, str | None]] = {}
    for message, field, logged in defaults:
        if has(message, field):
            wanted.setdefault(message, {})[field] = logged
    for message, field in named:
        if not has(message, field):
            raise FlightLogError(f"{source}: no field {field} in {message} messages for the "
                                 f"extra channel {message}.{field}")
        wanted.setdefault(message, {}).setdefault(field, unit(message, field))
    return wanted


def extra_streams(wanted: Mapping[str, Mapping[str, str | None]],
                  read: Callable[[str, list[str]], tuple[np.ndarray, dict] | None],
                  taken: Iterable[str] = ()) -> list[Stream]:
    """One optional stream per message of ``wanted`` (message -> field -> logged unit or
    None), its fields as extra channels (:func:`extra_channel_name`, :func:`logged_unit`);
    ``read(message, fields)`` gives (time [s], field -> raw values) or None (the message
    left out). A sample with a non-finite value is invalid; the streams never trim the
    canonical channels' segments (:attr:`~drake_uav.io.streams.Stream.trims`). A stream is
    named after its message, ``<message>.extra`` where the reader's other streams
    (``taken``) have that name (an extra field of the IMU message)."""
    streams, taken = [], set(taken)
    for message, fields in wanted.items():
        got = read(message, list(fields))
        if got is None:
            continue
        time, raw = got
        values, units, sources = {}, {}, {}
        for field, logged in fields.items():
            channel = extra_channel_name(message, field)
            units[channel], factor = logged_unit(logged)
            values[channel], sources[channel] = factor * raw[field], f"{message}.{field}"
        valid = np.logical_and.reduce([np.isfinite(v) for v in values.values()])
        name = f"{message}.extra" if message in taken else message
        streams.append(Stream(name, time, values, units, fields=sources, valid=valid,
                              optional=True, trims=False))
    return streams
