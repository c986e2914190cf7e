"""PX4 ULog (``.ulg``) logs into a FlightLog with canonical channels, through pyulog.

Default mapping (see docs/flight_logs.md; "opt." marks an optional stream, dropped
with a warning when it is sparse or has gaps, instead of cutting the log):

========================  ==============================  ==============================
topic                     fields                          channels
========================  ==============================  ==============================
sensor_combined           accelerometer_m_s2[0..2]        imu_ax imu_ay imu_az (time base)
(instance > 0:            gyro_rad[0..2]                  imu_p imu_q imu_r
sensor_accel, sensor_gyro x y z)
vehicle_attitude          q[0..3] (w, x, y, z)            att_roll att_pitch att_yaw
vehicle_local_position    x y / z / vx vy / vz (NED),     gps_pn gps_pe / gps_pd /
(opt.)                    valid where xy_valid / z_valid  gps_vn gps_ve / gps_vd
                          / v_xy_valid / v_z_valid
airspeed_validated (or    true_airspeed_m_s (or           pitot_airspeed, valid where
airspeed) (opt.*)         indicated_airspeed_m_s)         finite and >= 0
differential_pressure     differential_pressure_pa        pitot_qbar
(opt.)                    (or ..._filtered_pa)
vehicle_air_data (opt.)   baro_alt_meter                  baro_alt
actuator_controls_1/0,    see :mod:`drake_uav.io.px4_actuators`  cmd_*
actuator_servos/motors
wind (or wind_estimate)   windspeed_north, _east          est_wind_n est_wind_e
(opt.)
rpm (opt.)                indicated_frequency_rpm         motor_speed
battery_status (opt.)     voltage_v current_a             battery_status.voltage_v ...
esc_status (opt.)         esc[i].esc_rpm (rev/min),       esc_rpm_<i> (rad/s),
                          esc_voltage, esc_current,       esc_voltage_<i>, esc_current_<i>,
                          esc_temperature (deg C)         esc_temperature_<i> (K)
========================  ==============================  ==============================

Required: the IMU, the attitude and (but on a multicopter) the commands; *the
pitot too on a plane or VTOL when it is logged at 2 Hz or more with valid samples.
``vehicle_local_position`` is the PX4 estimator's GPS-aided solution, not the
raw receiver; its validity flags split it into four streams, so a missing
horizontal fix never shows as zero positions. The accelerometer's
``accelerometer_timestamp_relative`` offset (a fraction of a sample) is ignored.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from drake_uav.io.esc import esc_stream
from drake_uav.io.extras import (
    PX4_EXTRAS,
    extra_streams,
    parse_extra_fields,
    wanted_fields,
)
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.px4_actuators import ACTUATOR_TOPICS, actuator_plan, actuator_streams
from drake_uav.io.px4_metadata import MULTICOPTER_TYPES, px4_metadata
from drake_uav.io.px4_ulog import ULogFile, channel_stream
from drake_uav.io.streams import (
    MIN_IMU_RATE_HZ,
    ActuatorMapping,
    FieldSource,
    Stream,
    align_streams,
)
from drake_uav.model.rotations import quat_to_euler

__all__ = ["read_px4", "read_px4_metadata"]

_RPM = 2.0 * math.pi / 60.0
_MIN_OPTIONAL_RATE_HZ = 2.0
"""The validated airspeed is preferred unless logged slower than this [Hz]."""
_AIRSPEED_FIELDS = {"true": "true_airspeed_m_s", "indicated": "indicated_airspeed_m_s"}
_TOPICS = ("sensor_combined", "sensor_accel", "sensor_gyro", "vehicle_attitude",
           "vehicle_local_position", "airspeed", "airspeed_validated", "differential_pressure",
           "vehicle_air_data", "wind", "wind_estimate", "rpm", "esc_status",
           "vtol_vehicle_status",
           *ACTUATOR_TOPICS)
_IMU = {"imu_ax": "accelerometer_m_s2[0]", "imu_ay": "accelerometer_m_s2[1]",
        "imu_az": "accelerometer_m_s2[2]", "imu_p": "gyro_rad[0]", "imu_q": "gyro_rad[1]",
        "imu_r": "gyro_rad[2]"}
_POSITION = (("xy", {"gps_pn": "x", "gps_pe": "y"}), ("z", {"gps_pd": "z"}),
             ("v_xy", {"gps_vn": "vx", "gps_ve": "vy"}), ("v_z", {"gps_vd": "vz"}))
_QBAR_FIELDS = ("differential_pressure_pa", "differential_pressure_filtered_pa")


def _simple(log: ULogFile, topics, mapping: Mapping[str, str], instance: int = 0,
            scale: float = 1.0, **kwargs) -> Stream | None:
    """Stream of the first topic of ``topics`` present: channel <- scale * field."""
    topic = next((t for t in topics if log.has(t, instance)), None)
    if topic is None:
        return None
    time, f = log.get(topic, list(mapping.values()), instance)
    return channel_stream(topic, time, {c: scale * f[k] for c, k in mapping.items()}, mapping,
                          **kwargs)


def _imu(log: ULogFile, instance: int) -> tuple[Stream, Stream | None]:
    """(time base, gyro stream or None): ``sensor_combined`` for instance 0 (or the
    given multi-id where the log has no ``sensor_accel`` of it), else
    ``sensor_accel`` and ``sensor_gyro`` of multi-id ``instance``."""
    accel = log.has("sensor_accel", instance) and log.has("sensor_gyro", instance)
    if log.has("sensor_combined", instance) and (instance == 0 or not accel):
        return _simple(log, ["sensor_combined"], _IMU, instance), None
    if accel:
        return (_simple(log, ["sensor_accel"], {"imu_ax": "x", "imu_ay": "y", "imu_az": "z"},
                        instance),
                _simple(log, ["sensor_gyro"], {"imu_p": "x", "imu_q": "y", "imu_r": "z"},
                        instance))
    raise FlightLogError(
        f"{log.source}: no IMU of instance {instance}: multi-ids of sensor_combined "
        f"{log.instances('sensor_combined')}, sensor_accel {log.instances('sensor_accel')}, "
        f"sensor_gyro {log.instances('sensor_gyro')}; pick one with instance=")


def _attitude(log: ULogFile) -> Stream:
    if not log.has("vehicle_attitude"):
        raise FlightLogError(f"{log.source}: no vehicle_attitude messages (the attitude)")
    q_fields = [f"q[{i}]" for i in range(4)]
    time, f = log.get("vehicle_attitude", q_fields)
    q = np.column_stack([f[k] for k in q_fields])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    euler = np.asarray(quat_to_euler(q.T), float).reshape(3, -1)  # all samples at once
    names = ("att_roll", "att_pitch", "att_yaw")
    return channel_stream("vehicle_attitude", time, dict(zip(names, euler, strict=True)),
                          dict.fromkeys(names, "q"), angles=("att_roll", "att_yaw"))


def _position(log: ULogFile) -> list[Stream]:
    """vehicle_local_position as four optional streams, each valid where its flag is 1."""
    if not log.has("vehicle_local_position"):
        return []
    data = log.fields("vehicle_local_position")
    streams = []
    for group, mapping in _POSITION:
        time, f = log.get("vehicle_local_position", list(mapping.values()))
        flag = data.get(f"{group}_valid")
        streams.append(channel_stream(
            f"vehicle_local_position.{group}", time, {c: f[k] for c, k in mapping.items()},
            mapping, optional=True, valid=None if flag is None else flag != 0))
    return streams


def _airspeed(log: ULogFile, airspeed: str, winged: bool) -> Stream | None:
    """``pitot_airspeed`` from airspeed_validated (unless logged below 2 Hz where
    ``airspeed`` is not), else airspeed; negative or NaN samples invalid.

    Required on a plane or VTOL when logged at 2 Hz or more with valid samples:
    the pitot is the air data of fixed-wing work, so its holes (a negative
    airspeed on the ground) cut segments instead of dropping it; else optional.
    """
    topics = [t for t in ("airspeed_validated", "airspeed") if log.has(t)]
    if not topics:
        return None
    rates = [_rate(log.get(t, [])[0]) for t in topics]
    if len(topics) == 2 and rates[0] < _MIN_OPTIONAL_RATE_HZ <= rates[1]:
        topics.reverse()
        rates.reverse()
    field = _AIRSPEED_FIELDS[airspeed]
    time, f = log.get(topics[0], [field])
    value = f[field]
    valid = np.isfinite(value) & (value >= 0)
    required = winged and rates[0] >= _MIN_OPTIONAL_RATE_HZ and bool(valid.any())
    return channel_stream(topics[0], time, {"pitot_airspeed": value},
                          {"pitot_airspeed": field}, optional=not required, valid=valid)


def _pitot_qbar(log: ULogFile) -> Stream | None:
    """``pitot_qbar`` [Pa] from the first differential-pressure field the log has."""
    if not log.has("differential_pressure"):
        return None
    data = log.fields("differential_pressure")
    field = next((f for f in _QBAR_FIELDS if f in data), _QBAR_FIELDS[0])
    return _simple(log, ["differential_pressure"], {"pitot_qbar": field}, optional=True)


def _air_and_position_streams(log: ULogFile, airspeed: str, winged: bool
                              ) -> list[Stream | None]:
    """The streams of the default mapping but the IMU, attitude and commands (module
    docstring; all optional but a usable pitot on a plane or VTOL); None for a topic
    the log does not have."""
    return [
        *_position(log),
        _airspeed(log, airspeed, winged),
        _pitot_qbar(log),
        _simple(log, ["vehicle_air_data"], {"baro_alt": "baro_alt_meter"}, optional=True),
        _simple(log, ["wind", "wind_estimate"],
                {"est_wind_n": "windspeed_north", "est_wind_e": "windspeed_east"},
                optional=True),
        _simple(log, ["rpm"], {"motor_speed": "indicated_frequency_rpm"}, scale=_RPM,
                optional=True),
    ]


def _rate(time: np.ndarray) -> float:
    """Median rate [Hz] of sample times (0 for fewer than 2)."""
    return 1.0 / float(np.median(np.diff(time))) if time.size > 1 else 0.0


def read_px4(path: str | Path, *, actuators: ActuatorMapping | str | None = None,
             airspeed: str = "true", extra: Mapping[str, FieldSource] | None = None,
             instance: int = 0, max_gap: float = 0.5, allow_truncated: bool = True,
             deflections: Mapping[str, float] | None = None,
             extra_channels: Sequence[str] = ()) -> FlightLog:
    """Reads a PX4 ``.ulg`` log into a FlightLog (canonical channels).

    Args:
        path: the ``.ulg`` file.
        actuators: an :class:`ActuatorMapping`; ``"controls"`` (the control group:
            ``actuator_controls_1`` on a VTOL, ``actuator_controls_0`` on a plane,
            else actuator_servos/actuator_motors); ``"outputs"`` (actuator_outputs
            PWM through the PWM_MAIN_* parameters); None: as "controls", falling
            back to outputs (see :mod:`drake_uav.io.px4_actuators`).
        airspeed: "true" or "indicated": which airspeed becomes ``pitot_airspeed``.
        extra: more channels from other topics, e.g. ``{"vane_alpha":
            FieldSource("vane_angles", "alpha", "rad")}`` (required streams).
        instance: the IMU: 0 is ``sensor_combined`` (the IMU the estimator uses);
            k > 0 is ``sensor_accel`` + ``sensor_gyro`` multi-id k (or
            ``sensor_combined`` multi-id k where the log has it). Every other
            topic is read at multi-id 0.
        max_gap: longest interval between two messages of a required topic before
            the log is cut into segments [s].
        allow_truncated: keep the data before a cut (with a warning) instead of raising.
        deflections: surface ("elevator", "aileron", "rudder") -> full deflection
            [rad] at a demand of 1 or a full servo throw (the aircraft's limits);
            25 deg unless given. Not used with an ``ActuatorMapping``.
        extra_channels: more fields as extra channels, ``"topic.field"`` (multi-id 0,
            unit ``1``: a ULog carries no units), beside the default
            :data:`~drake_uav.io.extras.PX4_EXTRAS`.

    Metadata: ``vehicle_type``, ``firmware``, ``flight_modes``, ``vtol_state``
    (VTOLs), ``imu_rate_hz``, ``parameters``, ``actuators`` and the alignment's
    ``segments``, ``dropped_streams`` and ``streams``.

    Raises:
        FlightLogError: not a ULog file, truncated before any data (or at all with
            ``allow_truncated=False``), no IMU or attitude, no actuator topic for a
            plane or VTOL, time not increasing, non-finite valid values, or no
            segment where every required stream has data; names the file.
    """
    path = Path(path)
    if airspeed not in _AIRSPEED_FIELDS:
        raise ValueError(f"airspeed: 'true' or 'indicated', got {airspeed!r}")
    extra = {name: source.validate() for name, source in (extra or {}).items()}
    named = parse_extra_fields(extra_channels)
    topics = sorted({*_TOPICS, *(s.message for s in extra.values()),
                     *(t for t, _, _ in PX4_EXTRAS), *(t for t, _ in named),
                     *([actuators.message] if isinstance(actuators, ActuatorMapping) else [])})
    log = ULogFile(path, topics, allow_truncated)
    metadata = {"format": "PX4 ULog", "instance": instance, "airspeed": airspeed,
                **px4_metadata(log)}
    base, gyro = _imu(log, instance)
    metadata["imu_rate_hz"] = round(_rate(base.time), 3)
    if metadata["imu_rate_hz"] < MIN_IMU_RATE_HZ:
        warnings.warn(f"{log.source}: IMU ({base.name} multi-id {instance}) logged at "
                      f"{metadata['imu_rate_hz']:.3g} Hz, below {MIN_IMU_RATE_HZ:g} Hz: "
                      "fast dynamics are aliased", stacklevel=3)
    mav_type = metadata["vehicle_type"]["mav_type"]
    sources, metadata["actuators"] = actuator_plan(log, actuators, mav_type, deflections)
    streams = [gyro, _attitude(log), *actuator_streams(log, sources),
               *_air_and_position_streams(log, airspeed, mav_type not in MULTICOPTER_TYPES),
               *_esc_streams(log), *_extra_streams(log, extra, instance)]
    streams += _logged_extras(log, named,
                              {base.name, *(s.name for s in streams if s is not None)})
    return align_streams(base, [s for s in streams if s is not None], source=log.source,
                         max_gap=max_gap, metadata=metadata)


def read_px4_metadata(path: str | Path, *, allow_truncated: bool = True,
                      deflections: Mapping[str, float] | None = None) -> dict:
    """What a ``.ulg`` log says about the vehicle, without reading its streams.

    Returns the metadata keys of :func:`read_px4` that need no IMU:
    ``vehicle_type``, ``firmware``, ``flight_modes`` (``vtol_state`` for a VTOL),
    ``parameters``, ``parameter_changes`` and ``actuators`` (the mapping the
    reader would use by default).
    """
    log = ULogFile(Path(path), sorted({"vtol_vehicle_status", *ACTUATOR_TOPICS}),
                   allow_truncated)
    metadata = px4_metadata(log)
    _, metadata["actuators"] = actuator_plan(log, None, metadata["vehicle_type"]["mav_type"],
                                             deflections)
    return metadata


_ESC_FIELDS = {"rpm": "esc_rpm", "voltage": "esc_voltage", "current": "esc_current",
               "temperature": "esc_temperature"}


def _esc_streams(log: ULogFile) -> list[Stream]:
    """One optional stream per ESC of ``esc_status`` (multi-id 0): ESC i for i below the
    largest ``esc_count``, valid where i < ``esc_count`` (:mod:`drake_uav.io.esc`)."""
    if not log.has("esc_status"):
        return []
    data = log.fields("esc_status")
    count = data.get("esc_count")
    if count is None or count.size == 0:
        return []
    streams = []
    for i in range(int(np.max(count))):
        fields = {q: f"esc[{i}].{f}" for q, f in _ESC_FIELDS.items() if f"esc[{i}].{f}" in data}
        if not fields:
            break
        time, raw = log.get("esc_status", list(fields.values()))
        streams.append(esc_stream(f"esc_status.esc{i}", i, time,
                                  {q: raw[f] for q, f in fields.items()},
                                  {q: f"esc_status.{f}" for q, f in fields.items()},
                                  valid=count > i))
    return streams


def _extra_streams(log: ULogFile, extra: Mapping[str, FieldSource], instance: int
                   ) -> list[Stream]:
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


def _logged_extras(log: ULogFile, named: Sequence[tuple[str, str]], taken: set[str]
                   ) -> list[Stream]:
    """Optional streams of the default extra channels the log has and of the ``named``
    (topic, field) pairs (FlightLogError naming one the log lacks), multi-id 0."""
    wanted = wanted_fields(PX4_EXTRAS, named,
                           lambda topic, field: log.has(topic) and field in log.fields(topic),
                           lambda topic, field: None, log.source)
    return extra_streams(wanted, lambda topic, fields: log.get(topic, fields), taken)
