"""MAVLink telemetry logs (``.tlog``) into a FlightLog with canonical channels, through pymavlink.

A ground station (Mission Planner, QGroundControl, MAVProxy) records every MAVLink message
it receives from the aircraft, each behind the 8-byte time it arrived. Telemetry streams
are slow (a few Hz to a few tens of Hz, as the stream rates were set) and lose messages
on a weak link: the log's ``metadata["streams"]`` gives each stream's native rate so the
analysis can say what the log cannot support. Default mapping (ArduPilot and PX4; "opt."
marks an optional stream):

======================  ==============================  ==================================
message                 fields                          channels
======================  ==============================  ==================================
HIGHRES_IMU, else       xacc yacc zacc (m/s^2 or mG),   imu_ax imu_ay imu_az (time base)
SCALED_IMU, else        xgyro ygyro zgyro (rad/s or     imu_p imu_q imu_r
RAW_IMU                 mrad/s)
ATTITUDE                roll pitch yaw                  att_roll att_pitch att_yaw
SERVO_OUTPUT_RAW        servo<n>_raw (SERVOn_* params   cmd_* (ArduPilot; held)
                        from PARAM_VALUE)
VFR_HUD (opt.)          airspeed; throttle (%)          pitot_airspeed; cmd_throttle when
                                                        no servo gives it (winged)
SCALED_PRESSURE (opt.)  press_diff (hPa)                pitot_qbar (when not all zero)
GLOBAL_POSITION_INT     lat lon alt, vx vy vz           gps_pn gps_pe gps_pd, gps_vn ...
(opt.)                  (valid where lat, lon != 0)     (NED about the first fix)
WIND (opt., ArduPilot)  direction (from), speed         est_wind_n est_wind_e
RPM (opt., ArduPilot)   rpm1                            motor_speed
ESC_TELEMETRY_1_TO_4    rpm, voltage (cV), current      esc_rpm_<i>, esc_voltage_<i>, ...
.. _9_TO_12 (opt.)      (cA), temperature (deg C)       (:mod:`drake_uav.io.esc`)
SYS_STATUS (opt.)       voltage_battery (mV),           SYS_STATUS.voltage_battery (V),
                        current_battery (cA)            SYS_STATUS.current_battery (A)
HEARTBEAT               type, autopilot, custom_mode    metadata vehicle_type, flight_modes
======================  ==============================  ==================================

Time: a message's own autopilot time where it has one (``time_boot_ms``; ``time_usec``
when it agrees with the boot clock within 1 s), else its arrival time moved onto the
autopilot's boot clock by the median offset of the ``time_boot_ms`` messages (arrival
times jitter with the link). Only the aircraft's messages are read: the source (system,
component) of an autopilot HEARTBEAT, component 1 first, then the one sending the most
IMU messages (``metadata["system_component"]``). A message repeated or arriving out of order
(time not above the stream's latest) is dropped and counted in ``metadata["out_of_order"]``;
damaged bytes are skipped (``metadata["skipped_bytes"]``).
``VFR_HUD.airspeed`` is the autopilot's airspeed, its sensor's when it uses one (ArduPilot
sends an estimate otherwise). RC_CHANNELS (the pilot's sticks) and other messages are read
only when named in ``extra_channels`` (``"RC_CHANNELS.chan3_raw"``).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from drake_uav.io.ardupilot_params import imu_position, mode_name, servo_mapping
from drake_uav.io.esc import esc_stream
from drake_uav.io.extras import extra_streams, parse_extra_fields, wanted_fields
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.px4_metadata import MAV_TYPE_NAMES, MULTICOPTER_TYPES
from drake_uav.io.streams import (
    CHANNELS,
    MIN_IMU_RATE_HZ,
    ActuatorMapping,
    Stream,
    align_streams,
)
from drake_uav.model.geodesy import ned_from_geodetic

__all__ = ["TLOG_EXTRAS", "read_tlog"]

_G = 9.80665
_RPM = math.pi / 30.0
_IMUS = {"HIGHRES_IMU": (1.0, 1.0), "SCALED_IMU": (_G / 1000.0, 1e-3),
         "RAW_IMU": (_G / 1000.0, 1e-3)}
"""IMU message -> (accelerometer factor to m/s^2, gyro factor to rad/s), in preference order."""
_ESC_BLOCKS = {"ESC_TELEMETRY_1_TO_4": 0, "ESC_TELEMETRY_5_TO_8": 4,
               "ESC_TELEMETRY_9_TO_12": 8}
_DEFAULT_MESSAGES = {"HEARTBEAT", "PARAM_VALUE", "ATTITUDE", "SERVO_OUTPUT_RAW", "VFR_HUD",
                     "SCALED_PRESSURE", "GLOBAL_POSITION_INT", "WIND", "RPM", "SYS_STATUS", *_IMUS,
                     *_ESC_BLOCKS}
_AUTOPILOT_INVALID = 8  # MAV_AUTOPILOT_INVALID: a ground station, a gimbal, ...
_AUTOPILOT_COMPONENT = 1  # MAV_COMP_ID_AUTOPILOT1
_STAMP = 8  # bytes of a record's arrival time
_MAVLINK1, _MAVLINK2 = 0xFE, 0xFD
_ARDUPILOT, _PX4 = 3, 12
_CLOCK_AGREEMENT_S = 1.0
"""A message's ``time_usec`` is on the boot clock when it is within this of the arrival
time moved onto the boot clock [s] (median over the message's samples)."""


@dataclasses.dataclass
class _Messages:
    """The aircraft's messages of one type: arrival times [s] and the decoded messages."""

    arrival: list[float] = dataclasses.field(default_factory=list)
    items: list = dataclasses.field(default_factory=list)


def _frame_length(data: bytes, pos: int) -> int:
    """Length [bytes] of the MAVLink 1 or 2 frame at ``pos``, or 0 when none starts there."""
    if pos + 2 > len(data):
        return 0
    marker, payload = data[pos], data[pos + 1]
    if marker == _MAVLINK1:
        return 8 + payload
    if marker == _MAVLINK2 and pos + 3 <= len(data):
        return 12 + payload + (13 if data[pos + 2] & 1 else 0)  # signed: 13 more bytes
    return 0


def _decode(path: Path, wanted: set[str]) -> tuple[dict[str, dict], int]:
    """(type -> (system, component) -> _Messages, bytes skipped).

    A ``.tlog`` is a sequence of records: the arrival time (8 bytes, big-endian, us since
    1970) and one MAVLink 1 or 2 frame. Where no record decodes (a bad checksum, a message
    this dialect does not know, bytes that are no frame) the reader moves on one byte and
    tries again, so that it finds the next record after damaged bytes.
    """
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    data = path.read_bytes()
    parser = dialect.MAVLink(None)
    found: dict[str, dict] = {}
    bad, pos = 0, 0
    while pos + _STAMP + 8 <= len(data):
        arrival = int.from_bytes(data[pos:pos + _STAMP], "big") / 1e6
        length = _frame_length(data, pos + _STAMP)
        end = pos + _STAMP + length
        if length == 0 or end > len(data):
            bad, pos = bad + 1, pos + 1
            continue
        try:
            message = parser.decode(bytearray(data[pos + _STAMP:end]))
        except Exception:  # pymavlink raises several types on a frame it cannot decode
            bad, pos = bad + 1, pos + 1
            continue
        pos = end
        kind = message.get_type()
        if kind not in wanted:
            continue
        source = (message.get_srcSystem(), message.get_srcComponent())
        group = found.setdefault(kind, {}).setdefault(source, _Messages())
        group.arrival.append(arrival)
        group.items.append(message)
    if not found and bad:
        raise FlightLogError(f"{path}: not a MAVLink telemetry log (no message decoded in "
                             f"{len(data)} bytes)")
    return found, bad


def _aircraft(found: dict[str, dict], source: str) -> tuple[tuple[int, int], object | None]:
    """(system, component) of the aircraft and its first HEARTBEAT (None without one): of
    the sources of an autopilot HEARTBEAT, component 1 (the autopilot's) first, then the
    one sending the most IMU messages, then the first heard; without one, the source of
    the most IMU messages."""
    counts = Counter()
    for kind in _IMUS:
        for key, group in found.get(kind, {}).items():
            counts[key] += len(group.items)
    first = None
    for key, group in found.get("HEARTBEAT", {}).items():
        for arrival, beat in zip(group.arrival, group.items, strict=True):
            rank = (key[1] != _AUTOPILOT_COMPONENT, -counts[key], arrival)
            if beat.autopilot != _AUTOPILOT_INVALID and (first is None or rank < first[0]):
                first = (rank, key, beat)
    if first is not None:
        return first[1], first[2]
    if not counts:
        raise FlightLogError(f"{source}: no MAVLink IMU messages (HIGHRES_IMU, SCALED_IMU or "
                             "RAW_IMU) and no autopilot HEARTBEAT: not a telemetry log of an "
                             "aircraft")
    return counts.most_common(1)[0][0], None


class _Telemetry:
    """The aircraft's messages as numpy fields on the autopilot's boot clock."""

    def __init__(self, found: dict[str, dict], aircraft: tuple[int, int], source: str):
        self.source = source
        self.messages = {kind: groups[aircraft] for kind, groups in found.items()
                         if aircraft in groups}
        self.out_of_order: dict[str, int] = {}
        boot = [(np.array([m.time_boot_ms for m in g.items], float) / 1e3
                 - np.asarray(g.arrival)) for kind, g in self.messages.items()
                if g.items and "time_boot_ms" in g.items[0].get_fieldnames()]
        offsets = np.concatenate(boot) if boot else np.zeros(0)
        self.offset = float(np.median(offsets)) if offsets.size else 0.0

    def has(self, kind: str) -> bool:
        return kind in self.messages and bool(self.messages[kind].items)

    def fieldnames(self, kind: str) -> list[str]:
        return list(self.messages[kind].items[0].get_fieldnames()) if self.has(kind) else []

    def unit(self, kind: str, field: str) -> str | None:
        if not self.has(kind):
            return None
        units = getattr(self.messages[kind].items[0], "fieldunits_by_name", {})
        return units.get(field.split("[")[0])  # an array's element: the array's unit

    def get(self, kind: str, fields: Sequence[str], keep=None
            ) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        """(time [s], field -> float values) of the messages ``keep(message)`` accepts;
        an array field ``rpm[2]`` gives one element. None without such messages."""
        group = self.messages.get(kind)
        if group is None:
            return None
        index = [i for i, m in enumerate(group.items) if keep is None or keep(m)]
        if not index:
            return None
        items = [group.items[i] for i in index]
        arrival = np.asarray(group.arrival, float)[index]
        time = self._clock(items, arrival)
        values = {f: np.array([_field(m, f) for m in items], float) for f in fields}
        ahead = np.concatenate([[True], time[1:] > np.maximum.accumulate(time)[:-1]])
        if not ahead.all():
            self.out_of_order[kind] = int(np.count_nonzero(~ahead))
        return time[ahead], {f: v[ahead] for f, v in values.items()}

    def _clock(self, items: list, arrival: np.ndarray) -> np.ndarray:
        """Sample times [s] on the boot clock (module docstring)."""
        names = items[0].get_fieldnames()
        moved = arrival + self.offset
        if "time_boot_ms" in names:
            return np.array([m.time_boot_ms for m in items], float) / 1e3
        if "time_usec" in names:
            own = np.array([m.time_usec for m in items], float) / 1e6
            if abs(float(np.median(own - moved))) < _CLOCK_AGREEMENT_S:
                return own
        return moved


def _field(message, field: str) -> float:
    """A numeric field; ``name[i]`` is element i of an array field (NaN when absent)."""
    name, _, rest = field.partition("[")
    value = getattr(message, name, math.nan)
    if rest:
        try:
            value = value[int(rest.rstrip("]"))]
        except (IndexError, TypeError, ValueError):
            return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _stream(name, got, channels: Mapping[str, np.ndarray], fields: Mapping[str, str],
            **kwargs) -> Stream:
    """A stream of canonical channels from ``got`` = (time, ...)."""
    return Stream(name, got[0], dict(channels), {c: CHANNELS[c][0] for c in channels},
                  fields={c: f"{name}.{f}" for c, f in fields.items()}, **kwargs)


def _imu(tel: _Telemetry) -> Stream:
    kind = next((k for k in _IMUS if tel.has(k)), None)
    if kind is None:
        raise FlightLogError(f"{tel.source}: no IMU messages (HIGHRES_IMU, SCALED_IMU or "
                             "RAW_IMU) from the aircraft; stream them to the ground station "
                             "(SR*_RAW_SENS on ArduPilot)")
    accel, gyro = _IMUS[kind]
    fields = {"imu_ax": "xacc", "imu_ay": "yacc", "imu_az": "zacc", "imu_p": "xgyro",
              "imu_q": "ygyro", "imu_r": "zgyro"}
    keep = (lambda m: getattr(m, "id", 0) == 0) if "id" in tel.fieldnames(kind) else None
    got = tel.get(kind, list(fields.values()), keep)
    scale = {c: accel if c.startswith("imu_a") else gyro for c in fields}
    return _stream(kind, got, {c: scale[c] * got[1][f] for c, f in fields.items()}, fields)


def _simple(tel: _Telemetry, kind: str, fields: Mapping[str, str], scale=None, keep=None,
            valid=None, **kwargs) -> Stream | None:
    """channel <- scale[channel] * field of ``kind``; ``valid(values)`` marks samples."""
    got = tel.get(kind, list(fields.values()), keep) if tel.has(kind) else None
    if got is None:
        return None
    scale = scale or {}
    values = {c: scale.get(c, 1.0) * got[1][f] for c, f in fields.items()}
    return _stream(kind, got, values, fields,
                   valid=None if valid is None else valid(got[1]), **kwargs)


def _position(tel: _Telemetry) -> tuple[list[Stream], list[float] | None]:
    """GLOBAL_POSITION_INT as position and velocity streams about the first fix."""
    fields = ["lat", "lon", "alt", "vx", "vy", "vz"]
    got = tel.get("GLOBAL_POSITION_INT", fields) if tel.has("GLOBAL_POSITION_INT") else None
    if got is None:
        return [], None
    time, f = got
    lat, lon, alt = f["lat"] / 1e7, f["lon"] / 1e7, f["alt"] / 1e3
    fixed = (f["lat"] != 0) | (f["lon"] != 0)
    if not fixed.any():
        return [], None
    i = int(np.argmax(fixed))
    origin = [float(lat[i]), float(lon[i]), float(alt[i])]
    pn, pe, pd = ned_from_geodetic(lat, lon, alt, origin)
    pos = {"gps_pn": "lat", "gps_pe": "lon", "gps_pd": "alt"}
    vel = {"gps_vn": "vx", "gps_ve": "vy", "gps_vd": "vz"}
    name = "GLOBAL_POSITION_INT"
    return [_stream(name, got, {"gps_pn": pn, "gps_pe": pe, "gps_pd": pd}, pos, valid=fixed,
                    optional=True),
            _stream(f"{name}.v", got, {c: f[k] / 100.0 for c, k in vel.items()}, vel,
                    valid=fixed, optional=True)], origin


def _air_streams(tel: _Telemetry) -> list[Stream | None]:
    """Airspeed, differential pressure, wind estimate and RPM (optional streams)."""
    streams = [_simple(tel, "VFR_HUD", {"pitot_airspeed": "airspeed"}, optional=True,
                       valid=lambda f: f["airspeed"] >= 0.0)]
    qbar = _simple(tel, "SCALED_PRESSURE", {"pitot_qbar": "press_diff"}, {"pitot_qbar": 100.0},
                   optional=True)
    if qbar is not None and np.any(qbar.channels["pitot_qbar"] != 0.0):
        streams.append(qbar)
    got = tel.get("WIND", ["direction", "speed"]) if tel.has("WIND") else None
    if got is not None:  # direction the wind comes from
        direction, speed = np.radians(got[1]["direction"]), got[1]["speed"]
        streams.append(_stream("WIND", got, {"est_wind_n": -speed * np.cos(direction),
                                             "est_wind_e": -speed * np.sin(direction)},
                               {"est_wind_n": "direction", "est_wind_e": "speed"},
                               optional=True))
    streams.append(_simple(tel, "RPM", {"motor_speed": "rpm1"}, {"motor_speed": _RPM},
                           optional=True, valid=lambda f: f["rpm1"] >= 0.0))
    return streams


def _esc_streams(tel: _Telemetry) -> list[Stream]:
    """One optional stream per ESC of the ESC_TELEMETRY messages that reports anything."""
    streams = []
    units = {"rpm": 1.0, "voltage": 0.01, "current": 0.01, "temperature": 1.0}
    for kind, first in _ESC_BLOCKS.items():
        if not tel.has(kind):
            continue
        for j in range(4):
            fields = {q: f"{q}[{j}]" for q in units}
            time, raw = tel.get(kind, list(fields.values()))
            if not (np.any(raw[fields["rpm"]] != 0) or np.any(raw[fields["voltage"]] != 0)):
                continue
            streams.append(esc_stream(f"{kind}.esc{first + j}", first + j, time,
                                      {q: units[q] * raw[f] for q, f in fields.items()},
                                      {q: f"{kind}.{f}" for q, f in fields.items()}))
    return streams


def _parameters(tel: _Telemetry) -> dict[str, float]:
    """The parameters the ground station received (PARAM_VALUE; the last value of each)."""
    out = {}
    for message in tel.messages.get("PARAM_VALUE", _Messages()).items:
        name = str(getattr(message, "param_id", "")).rstrip("\x00")
        value = float(getattr(message, "param_value", math.nan))
        if name and math.isfinite(value):
            out[name] = value
    return out


def _vehicle(tel: _Telemetry, heartbeat) -> dict:
    """vehicle_type, firmware and flight_modes (ArduPilot mode names) from HEARTBEAT."""
    if heartbeat is None:
        return {"firmware": "", "flight_modes": []}
    mav_type, autopilot = int(heartbeat.type), int(heartbeat.autopilot)
    firmware = ""
    if autopilot == _ARDUPILOT:
        firmware = ("ArduCopter" if mav_type in MULTICOPTER_TYPES
                    else "ArduPlane" if mav_type in MAV_TYPE_NAMES else "")
    elif autopilot == _PX4:
        firmware = "PX4"
    modes: list[list] = []
    got = tel.get("HEARTBEAT", ["custom_mode"])
    if got is not None and firmware.startswith("Ardu"):
        for t, mode in zip(got[0], got[1]["custom_mode"], strict=True):
            name = mode_name(firmware, int(mode))
            if not modes or modes[-1][1] != name:
                modes.append([float(t), name])
    return {"firmware": firmware, "flight_modes": modes,
            "vehicle_type": {"mav_type": mav_type,
                             "name": MAV_TYPE_NAMES.get(mav_type, f"MAV_TYPE {mav_type}")}}


def _servo_fields(mapping: ActuatorMapping) -> ActuatorMapping:
    """An RCOU mapping (fields ``C<n>``) read from SERVO_OUTPUT_RAW (``servo<n>_raw``)."""
    renamed = {name: None if channel is None else
               dataclasses.replace(channel, field=f"servo{channel.field[1:]}_raw")
               for name, channel in ((c, getattr(mapping, c)) for c in
                                     ("elevator", "aileron", "rudder", "throttle"))}
    return ActuatorMapping("SERVO_OUTPUT_RAW", **renamed)


def _actuators(tel: _Telemetry, actuators, params, deflections, vehicle: dict
               ) -> tuple[ActuatorMapping | None, dict]:
    """The commands' mapping and its metadata: given, the SERVOn parameters (ArduPilot),
    or ArduPilot's default servo layout with a warning; None on a multicopter or PX4."""
    if isinstance(actuators, ActuatorMapping):
        return actuators.validate(), {"source": "given", **actuators.describe()}
    if actuators is not None:
        raise ValueError(f"actuators: an ActuatorMapping or None, got {actuators!r}")
    mav_type = (vehicle.get("vehicle_type") or {}).get("mav_type")
    if mav_type in MULTICOPTER_TYPES:
        return None, {"source": "none: a multicopter has no control surfaces"}
    if vehicle.get("firmware") == "PX4":
        warnings.warn(f"{tel.source}: surface commands of a PX4 telemetry log are not mapped; "
                      "pass actuators=ActuatorMapping('SERVO_OUTPUT_RAW', ...)", stacklevel=4)
        return None, {"source": "none: PX4 (pass an ActuatorMapping)"}
    if any(k.startswith("SERVO") and k.endswith("_FUNCTION") for k in params):
        mapping, notes = servo_mapping(params, deflections, tel.source)
        for note in notes:
            warnings.warn(f"{tel.source}: {note}", stacklevel=4)
        if mapping is None:
            return None, {"source": "SERVOn parameters", "message": None}
        mapping = _servo_fields(mapping)
        return mapping, {"source": "SERVOn parameters", **mapping.describe()}
    mapping = _servo_fields(ActuatorMapping.ardupilot(**deflections))
    warnings.warn(f"{tel.source}: no SERVOn parameters in the telemetry log; "
                  "SERVO_OUTPUT_RAW read with the default mapping (servo 1 aileron, 2 "
                  "elevator, 3 throttle, 4 rudder, 1500 +- 500 us)", stacklevel=4)
    return mapping, {"source": "default (no SERVOn parameters)", **mapping.describe()}


def _command_streams(tel: _Telemetry, mapping: ActuatorMapping | None, winged: bool
                     ) -> list[Stream]:
    """The ``cmd_*`` channels (held; required), and on a winged aircraft ``cmd_throttle``
    from VFR_HUD's throttle (%) when no servo gives it."""
    streams = []
    commands = mapping.channels() if mapping is not None else {}
    if commands:
        port = (lambda m: getattr(m, "port", 0) == 0) if mapping.message == \
            "SERVO_OUTPUT_RAW" else None
        got = tel.get(mapping.message, sorted({m.field for m in commands.values()}), port) \
            if tel.has(mapping.message) else None
        if got is None:
            warnings.warn(f"{tel.source}: no {mapping.message} messages: no surface "
                          "commands", stacklevel=4)
        else:
            f = got[1]
            valid = np.ones(got[0].size, bool)
            for m in commands.values():
                valid &= m.valid(f[m.field]) & (f[m.field] > 0.0)
            streams.append(_stream(mapping.message, got,
                                   {c: m.apply(f[m.field]) for c, m in commands.items()},
                                   {c: m.field for c, m in commands.items()}, hold=True,
                                   valid=valid))
    if winged and "cmd_throttle" not in commands and tel.has("VFR_HUD"):
        got = tel.get("VFR_HUD", ["throttle"])
        streams.append(_stream("VFR_HUD.throttle", got,
                               {"cmd_throttle": got[1]["throttle"] / 100.0},
                               {"cmd_throttle": "throttle"}, hold=True))
    return streams


TLOG_EXTRAS = (("SYS_STATUS", "voltage_battery", "mV"), ("SYS_STATUS", "current_battery", "cA"))
"""(message, field, unit) of the extra channels a ``.tlog`` gives by default: the battery
voltage and current (the channels ``SYS_STATUS.voltage_battery`` [V],
``SYS_STATUS.current_battery`` [A])."""
_NOT_MEASURED = {("SYS_STATUS", "voltage_battery"): 65535.0,
                 ("SYS_STATUS", "current_battery"): -1.0}
"""The value MAVLink sends for a quantity the autopilot does not measure."""


def _extras(tel: _Telemetry, named: Sequence[str], taken: set[str]) -> list[Stream]:
    """Optional streams of the default extra channels the log has (:data:`TLOG_EXTRAS`)
    and of the ``named`` ``MESSAGE.field`` ones (unit from the MAVLink definition where
    the FlightLog knows it, else the raw number); a value sent for "not measured" is an
    invalid sample, and a field that is never measured no channel; ``taken``: the names
    of the other streams."""

    def read(kind, fields):
        got = tel.get(kind, fields)
        if got is None:
            return None
        time, values = got
        return time, {f: np.where(values[f] == _NOT_MEASURED.get((kind, f), np.nan), np.nan,
                                  values[f]) for f in fields}

    wanted = wanted_fields(TLOG_EXTRAS, parse_extra_fields(named),
                           lambda k, f: f.split("[")[0] in tel.fieldnames(k), tel.unit,
                           tel.source)
    for (kind, field), sentinel in _NOT_MEASURED.items():  # a quantity never measured
        got = tel.get(kind, [field]) if field in wanted.get(kind, {}) else None
        if got is not None and np.all(got[1][field] == sentinel):
            del wanted[kind][field]
    return extra_streams({k: f for k, f in wanted.items() if f}, read, taken)


def read_tlog(path: str | Path, *, actuators: ActuatorMapping | None = None,
              deflections: Mapping[str, float] | None = None, max_gap: float = 1.0,
              extra_channels: Sequence[str] = ()) -> FlightLog:
    """Reads a MAVLink telemetry log (``.tlog``) into a FlightLog (canonical channels).

    Args:
        path: the ``.tlog`` file.
        actuators: an :class:`ActuatorMapping` of a MAVLink message's fields (e.g.
            ``SERVO_OUTPUT_RAW``, ``servo2_raw``); None: ArduPilot's SERVOn parameters
            the log holds (PARAM_VALUE), else ArduPilot's default servo layout with a
            warning; none on a multicopter or a PX4 log.
        deflections: surface ("elevator", "aileron", "rudder") -> full deflection [rad] at
            the servo's MAX (or MIN) PWM; 25 deg unless given.
        max_gap: longest interval between two messages of a required stream before the log
            is cut into segments [s]; 1 s by default, as telemetry links drop messages.
        extra_channels: more fields as extra channels, ``"MESSAGE.field"``.

    Metadata: ``format``, ``vehicle_type`` (from HEARTBEAT), ``firmware``, ``flight_modes``
    (ArduPilot), ``parameters``, ``imu_position`` (ArduPilot's ``INS_POS1_X/Y/Z`` when
    received), ``actuators``, ``imu_rate_hz``, ``clock_offset_s`` (boot
    time minus arrival time), ``out_of_order`` (messages dropped per type),
    ``gps_origin_lat_lon_alt`` and the alignment's ``streams`` with each native rate.

    Raises:
        FlightLogError: not a MAVLink log, no IMU or ATTITUDE messages from the aircraft,
            bad SERVOn parameters, non-finite values, no segment where every required
            stream has data; names the file.
    """
    path = Path(path)
    source = str(path)
    deflections = {**dict.fromkeys(("elevator", "aileron", "rudder"), math.radians(25.0)),
                   **(deflections or {})}
    named = list(extra_channels)
    wanted = {*_DEFAULT_MESSAGES, *(m for m, _ in parse_extra_fields(named))}
    found, bad = _decode(path, wanted)
    aircraft, heartbeat = _aircraft(found, source)
    tel = _Telemetry(found, aircraft, source)
    base = _imu(tel)
    attitude = _simple(tel, "ATTITUDE", {"att_roll": "roll", "att_pitch": "pitch",
                                          "att_yaw": "yaw"}, angles=("att_roll", "att_yaw"))
    if attitude is None:
        raise FlightLogError(f"{source}: no ATTITUDE messages from the aircraft (the attitude)")
    params = _parameters(tel)
    vehicle = _vehicle(tel, heartbeat)
    mapping, described = _actuators(tel, actuators, params, deflections, vehicle)
    position, origin = _position(tel)
    winged = (vehicle.get("vehicle_type") or {}).get("mav_type") not in MULTICOPTER_TYPES
    streams = [attitude, *_command_streams(tel, mapping, winged), *_air_streams(tel), *position,
               *_esc_streams(tel)]
    streams += _extras(tel, named, {base.name, *(s.name for s in streams if s is not None)})
    imu_rate = 1.0 / float(np.median(np.diff(base.time))) if base.time.size > 1 else 0.0
    if round(imu_rate, 3) < MIN_IMU_RATE_HZ:
        warnings.warn(f"{source}: IMU ({base.name}) telemetry at {imu_rate:.3g} Hz, below "
                      f"{MIN_IMU_RATE_HZ:g} Hz: fast dynamics are aliased", stacklevel=3)
    metadata = {"format": "MAVLink telemetry", "system_component": list(aircraft), **vehicle,
                "parameters": params, "actuators": described,
                "imu_rate_hz": round(imu_rate, 6), "clock_offset_s": tel.offset,
                "out_of_order": tel.out_of_order, "skipped_bytes": bad,
                **(imu_position(params, 0) if vehicle["firmware"].startswith("Ardu") else {})}
    if origin is not None:
        metadata["gps_origin_lat_lon_alt"] = origin
    return align_streams(base, [s for s in streams if s is not None], source=source,
                         max_gap=max_gap, metadata=metadata)
