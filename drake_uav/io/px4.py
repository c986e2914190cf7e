"""PX4 ULog (``.ulg``) logs into a FlightLog with canonical channels, through pyulog.

pyulog reads only the topics needed (its message filter) into numpy arrays.
Time is ``timestamp_sample`` where a topic has it (the sensor sample time), else
``timestamp`` (publication time), in us since boot -> s.

Default mapping (multi-instance 0; see docs/flight_logs.md):

========================  ==============================  ==============================
topic                     fields                          channels
========================  ==============================  ==============================
sensor_combined           accelerometer_m_s2[0..2]        imu_ax imu_ay imu_az (time base)
sensor_combined           gyro_rad[0..2]                  imu_p imu_q imu_r
vehicle_attitude          q[0..3] (w, x, y, z)            att_roll att_pitch att_yaw
vehicle_local_position    x y z, vx vy vz (NED)           gps_pn..gps_pd, gps_vn..gps_vd
airspeed                  true_airspeed_m_s (or           pitot_airspeed
(or airspeed_validated)   indicated_airspeed_m_s)
differential_pressure     differential_pressure_pa        pitot_qbar
                          (or ..._filtered_pa)
vehicle_air_data          baro_alt_meter                  baro_alt
actuator_controls_0 or    control[0..3] or output[0..3]   cmd_* (:class:`ActuatorMapping`)
actuator_outputs
wind (or wind_estimate)   windspeed_north, _east          est_wind_n est_wind_e
rpm                       indicated_frequency_rpm         motor_speed
========================  ==============================  ==============================

``vehicle_local_position`` is the PX4 estimator's GPS-aided solution, not the
raw receiver; the accelerometer's ``accelerometer_timestamp_relative`` offset
(a fraction of a sample) is ignored.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from pyulog import ULog
from pyulog.core import ULogException

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import CHANNELS, ActuatorMapping, FieldSource, Stream, align_streams
from drake_uav.model.rotations import quat_to_euler

__all__ = ["read_px4"]

_RPM = 2.0 * math.pi / 60.0
_AIRSPEED_FIELDS = {"true": "true_airspeed_m_s", "indicated": "indicated_airspeed_m_s"}
_TOPICS = ("sensor_combined", "vehicle_attitude", "vehicle_local_position", "airspeed",
           "airspeed_validated", "differential_pressure", "vehicle_air_data",
           "actuator_controls_0", "actuator_outputs", "wind", "wind_estimate", "rpm")


class _ShortReads(io.BufferedReader):
    """A file that remembers the first read returning fewer bytes than asked.

    pyulog stops quietly where a file is cut; a clean end of file shows only as
    an empty 3-byte header read, anything else short is a truncated message.
    """

    short: tuple[int, int, int] | None = None  # (position, asked, got)

    def read(self, size=-1, _read=io.BufferedReader.read):
        data = _read(self, size)
        got = len(data)
        if got < size and (got or size != 3) and self.short is None:
            self.short = (self.tell() - got, size, got)
        return data


class _ULog:
    """The topics of a ULog file as (time [s], fields) per (topic, multi-id)."""

    def __init__(self, path: Path, topics: list[str], allow_truncated: bool):
        self.source = str(path)
        raw = io.FileIO(path, "r")
        handle = _ShortReads(raw)
        try:
            ulog = ULog(handle, message_name_filter_list=topics)
        except ULogException as err:
            raise FlightLogError(f"{path}: not a PX4 ULog file ({err})") from None
        finally:
            handle.close()
        if handle.short is not None:
            position, asked, got = handle.short
            message = (f"{path}: truncated file: a message at byte {position} needs {asked} "
                       f"bytes, {got} remain")
            if not allow_truncated:
                raise FlightLogError(message + " (allow_truncated=True drops it)")
            warnings.warn(message + "; dropped", stacklevel=4)
        elif ulog.file_corruption:
            warnings.warn(f"{path}: corrupt data skipped by the ULog parser", stacklevel=4)
        self.data = {(d.name, d.multi_id): d.data for d in ulog.data_list}

    def has(self, topic: str, instance: int = 0) -> bool:
        return (topic, instance) in self.data

    def fields(self, topic: str, instance: int = 0) -> dict[str, np.ndarray]:
        return self.data[(topic, instance)]

    def get(self, topic: str, fields: list[str], instance: int = 0
            ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(time [s], field -> float values) of one topic instance."""
        data = self.fields(topic, instance)
        missing = [f for f in fields if f not in data]
        if missing:
            raise FlightLogError(f"{self.source}: topic {topic} has no field {missing[0]} "
                                 f"(fields: {', '.join(data)})")
        stamp = data.get("timestamp_sample")
        if stamp is None or not np.all(stamp):
            stamp = data["timestamp"]
        return stamp.astype(float) / 1e6, {f: data[f].astype(float) for f in fields}


def _stream(name, time, channels, fields, **kwargs) -> Stream:
    return Stream(name, time, channels, {n: CHANNELS[n][0] for n in channels},
                  fields={c: f"{name}.{f}" for c, f in fields.items()}, **kwargs)


def _simple(log: _ULog, topics, mapping: Mapping[str, str], instance: int,
            scale: float = 1.0) -> Stream | None:
    """Stream of the first topic of ``topics`` present: channel <- scale * field."""
    topic = next((t for t in topics if log.has(t, instance)), None)
    if topic is None:
        return None
    time, f = log.get(topic, list(mapping.values()), instance)
    return _stream(topic, time, {c: scale * f[k] for c, k in mapping.items()}, mapping)


def _attitude(log: _ULog, instance: int) -> Stream:
    q_fields = [f"q[{i}]" for i in range(4)]
    time, f = log.get("vehicle_attitude", q_fields, instance)
    q = np.column_stack([f[k] for k in q_fields])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    euler = np.array([quat_to_euler(row) for row in q]).reshape(-1, 3)
    names = ("att_roll", "att_pitch", "att_yaw")
    return _stream("vehicle_attitude", time, dict(zip(names, euler.T, strict=True)),
                   dict.fromkeys(names, "q"), angles=("att_roll", "att_yaw"))


_IMU = {"imu_ax": "accelerometer_m_s2[0]", "imu_ay": "accelerometer_m_s2[1]",
        "imu_az": "accelerometer_m_s2[2]", "imu_p": "gyro_rad[0]", "imu_q": "gyro_rad[1]",
        "imu_r": "gyro_rad[2]"}
_POSITION = {"gps_pn": "x", "gps_pe": "y", "gps_pd": "z",
             "gps_vn": "vx", "gps_ve": "vy", "gps_vd": "vz"}
_QBAR_FIELDS = ("differential_pressure_pa", "differential_pressure_filtered_pa")


def _pitot_qbar(log: _ULog, instance: int) -> Stream | None:
    """``pitot_qbar`` [Pa] from the first differential-pressure field the log has."""
    if not log.has("differential_pressure", instance):
        return None
    data = log.fields("differential_pressure", instance)
    field = next((f for f in _QBAR_FIELDS if f in data), _QBAR_FIELDS[0])
    return _simple(log, ["differential_pressure"], {"pitot_qbar": field}, instance)


def _actuator_stream(log: _ULog, actuators: ActuatorMapping, instance: int) -> Stream | None:
    """The ``cmd_*`` channels (held between messages), or None without the topic."""
    if not log.has(actuators.message, instance):
        return None
    commands = actuators.channels()
    time, f = log.get(actuators.message, [m.field for m in commands.values()], instance)
    return _stream(actuators.message, time,
                   {c: m.apply(f[m.field]) for c, m in commands.items()},
                   {c: m.field for c, m in commands.items()}, hold=True)


def _default_streams(log: _ULog, actuators: ActuatorMapping, airspeed: str,
                     instance: int) -> list[Stream | None]:
    """The streams of the default mapping (module docstring) but the IMU time base;
    None for a topic the log does not have."""
    return [
        _attitude(log, instance) if log.has("vehicle_attitude", instance) else None,
        _simple(log, ["vehicle_local_position"], _POSITION, instance),
        _simple(log, ["airspeed", "airspeed_validated"],
                {"pitot_airspeed": _AIRSPEED_FIELDS[airspeed]}, instance),
        _pitot_qbar(log, instance),
        _simple(log, ["vehicle_air_data"], {"baro_alt": "baro_alt_meter"}, instance),
        _actuator_stream(log, actuators, instance),
        _simple(log, ["wind", "wind_estimate"],
                {"est_wind_n": "windspeed_north", "est_wind_e": "windspeed_east"}, instance),
        _simple(log, ["rpm"], {"motor_speed": "indicated_frequency_rpm"}, instance,
                scale=_RPM),
    ]


def _resolve_actuators(log: _ULog, actuators: ActuatorMapping | None,
                       instance: int) -> ActuatorMapping:
    """The given mapping, else PX4's controls mapping when the log has
    ``actuator_controls_0``, else its outputs mapping; validated."""
    if actuators is None:
        actuators = (ActuatorMapping.px4_controls() if log.has("actuator_controls_0", instance)
                     else ActuatorMapping.px4_outputs())
    actuators.validate()
    return actuators


def read_px4(path: str | Path, *, actuators: ActuatorMapping | None = None,
             airspeed: str = "true", extra: Mapping[str, FieldSource] | None = None,
             instance: int = 0, max_gap: float = 0.5,
             allow_truncated: bool = False) -> FlightLog:
    """Reads a PX4 ``.ulg`` log into a FlightLog (canonical channels).

    Args:
        path: the ``.ulg`` file.
        actuators: output -> command mapping; default :meth:`ActuatorMapping.px4_controls`
            when the log has ``actuator_controls_0``, else :meth:`ActuatorMapping.px4_outputs`.
        airspeed: "true" or "indicated": which airspeed becomes ``pitot_airspeed``.
        extra: more channels from other topics, e.g. ``{"vane_alpha":
            FieldSource("vane_angles", "alpha", "rad")}``.
        instance: multi-instance id of every topic.
        max_gap: longest allowed interval between two messages of a topic [s].
        allow_truncated: keep the data before a cut (with a warning) instead of raising.

    Raises:
        FlightLogError: not a ULog file, truncated, no ``sensor_combined``, a topic
            with a gap, time not increasing or non-finite values; names the file.
    """
    path = Path(path)
    if airspeed not in _AIRSPEED_FIELDS:
        raise ValueError(f"airspeed: 'true' or 'indicated', got {airspeed!r}")
    extra = {name: source.validate() for name, source in (extra or {}).items()}
    topics = sorted({*_TOPICS, *(s.message for s in extra.values()),
                     *([actuators.message] if actuators else [])})
    # Built here, not in a helper: its warnings' stacklevel points at read_px4's caller.
    log = _ULog(path, topics, allow_truncated)
    if not log.has("sensor_combined", instance):
        raise FlightLogError(f"{log.source}: no sensor_combined messages (the time base)")
    actuators = _resolve_actuators(log, actuators, instance)
    base = _simple(log, ["sensor_combined"], _IMU, instance)
    streams = _default_streams(log, actuators, airspeed, instance)
    streams += _extra_streams(log, extra, instance)
    metadata = {"format": "PX4 ULog", "instance": instance, "airspeed": airspeed,
                "actuators": actuators.describe()}
    return align_streams(base, [s for s in streams if s is not None], source=log.source,
                         max_gap=max_gap, metadata=metadata)


def _extra_streams(log: _ULog, extra: Mapping[str, FieldSource], instance: int) -> list[Stream]:
    """One stream per (topic, multi-id, hold) of the ``extra`` channels."""
    groups: dict[tuple, dict[str, FieldSource]] = {}
    for channel, src in extra.items():
        key = (src.message, instance if src.instance is None else src.instance, src.hold)
        groups.setdefault(key, {})[channel] = src
    streams = []
    for (topic, multi_id, hold), sources in groups.items():
        if not log.has(topic, multi_id):
            raise FlightLogError(f"{log.source}: no {topic} messages (multi-id {multi_id}) for "
                                 f"channel(s) {', '.join(sources)}")
        time, f = log.get(topic, sorted({s.field for s in sources.values()}), multi_id)
        streams.append(Stream(
            topic, time, {c: s.apply(f[s.field]) for c, s in sources.items()},
            {c: s.unit for c, s in sources.items()}, hold=hold,
            fields={c: f"{topic}.{s.field}" for c, s in sources.items()}))
    return streams
