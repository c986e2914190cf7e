"""ArduPilot DataFlash (``.bin``) logs into a FlightLog with canonical channels.

The file is decoded by :class:`~drake_uav.io.dataflash.DataFlash` (one
vectorised step per message type). Default mapping (instance 0; see
docs/flight_logs.md):

=========  ========================  ==============================  =====================
message    fields                    conversion                      channels
=========  ========================  ==============================  =====================
IMU        AccX AccY AccZ            m/s^2                           imu_ax imu_ay imu_az
IMU        GyrX GyrY GyrZ            rad/s                           imu_p imu_q imu_r
ATT        Roll Pitch Yaw            deg -> rad, yaw to [-pi, pi)    att_roll att_pitch att_yaw
GPS        Spd GCrs VZ               vn = Spd cos GCrs, ...          gps_vn gps_ve gps_vd
GPS        Lat Lng Alt               local NED about the origin      gps_pn gps_pe gps_pd
ARSP       Airspeed DiffPress        m/s, Pa                         pitot_airspeed pitot_qbar
BARO       Alt                       m                               baro_alt
RCOU       C<n> (SERVOn_FUNCTION)    SERVOn_MIN/MAX/TRIM/REVERSED    cmd_*
XKF2/NKF2  VWN VWE                   m/s                             est_wind_n est_wind_e
RPM        rpm1 rpm2 (or RPM per I)  rev/min -> rad/s (< 0 invalid)  motor_speed motor_speed_2
AOA        AOA SSA                   deg -> rad (AHRS estimate)      ahrs_alpha ahrs_beta
BAT        Volt Curr                 V, A (extra channels)           BAT.Volt BAT.Curr
ESC        RPM Volt Curr Temp        rpm->rad/s, V, A, degC->K       esc_rpm_<i>, esc_voltage_<i>,
(ESC1..8)  per Instance i                                            esc_current_<i>, ... (extra)
=========  ========================  ==============================  =====================

IMU, ATT and RCOU are required streams: a gap or a hole of invalid samples
cuts the log into segments. The others are optional: sparse or gappy, they are
dropped with a warning. Invalid samples: GPS without a 3-D fix, negative
airspeed, a servo PWM of 0 or outside its SERVOn_MIN..MAX (+- 50 us). The
instance of IMU, GPS, BARO and ARSP is the ``I`` field (4.1 and later) or a
separate message (IMU2, IMU3, GPS2, BAR2, BAR3, ASP2; 4.0 and earlier).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from drake_uav.io.ardupilot_params import imu_position, mode_name, servo_mapping, vehicle_type
from drake_uav.io.dataflash import DataFlash
from drake_uav.io.esc import esc_stream
from drake_uav.io.extras import (
    AHRS_CHANNELS,
    ARDUPILOT_EXTRAS,
    extra_streams,
    parse_extra_fields,
    wanted_fields,
)
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import (
    CHANNELS,
    MIN_IMU_RATE_HZ,
    ActuatorMapping,
    FieldSource,
    Stream,
    align_streams,
)
from drake_uav.model.geodesy import ned_from_geodetic

__all__ = ["AHRS_CHANNELS", "read_ardupilot", "read_ardupilot_metadata"]

_RPM = 2.0 * math.pi / 60.0  # rev/min -> rad/s
_DEG = math.pi / 180.0
_INSTANCE_MESSAGES = {"IMU": ("IMU", "IMU2", "IMU3"), "GPS": ("GPS", "GPS2"),
                      "BARO": ("BARO", "BAR2", "BAR3"), "ARSP": ("ARSP", "ASP2"),
                      "XKF2": ("XKF2",), "NKF2": ("NKF2", "NKF7"), "RPM": ("RPM",)}
"""Message -> the messages of instances 0, 1, ... in logs without an instance field."""
_INSTANCE_COLUMNS = {"XKF2": "C", "NKF2": "C"}
_LOG_BITMASK_IMU = 128  # MASK_LOG_IMU of ArduPlane and ArduCopter


def _instance_source(log: DataFlash, message: str, instance: int) -> tuple[str, str | None]:
    """(message, instance column or None) holding ``instance`` of ``message``:
    the message itself with its ``I``/``C`` field, else the separate message of
    that instance (IMU2, ...); ("", None) when the log has neither."""
    column = _INSTANCE_COLUMNS.get(message, "I")
    if log.has(message) and column in log.formats[message].colhash:
        return message, column
    names = _INSTANCE_MESSAGES.get(message, (message,))
    if instance < len(names) and log.has(names[instance]):
        return names[instance], None
    return "", None


def _stream(name, time, channels, fields: Mapping[str, str], units=None, **kwargs) -> Stream:
    """A stream of canonical channels; ``fields``: channel -> field of message ``name``."""
    units = units or {n: CHANNELS[n][0] for n in channels}
    return Stream(name, time, channels, units,
                  fields={c: f"{name}.{f}" for c, f in fields.items()}, **kwargs)


def _simple(log: DataFlash, message: str, mapping: Mapping[str, str], instance: int | None = None,
            scale: float = 1.0, **kwargs) -> Stream | None:
    """Stream of ``message`` (instance ``instance``, None: every message) with channel
    <- scale * field, or None when absent."""
    name, column = (message, None) if instance is None else _instance_source(log, message,
                                                                               instance)
    if not name:
        return None
    got = log.read(name, list(mapping.values()), column, instance)
    if got is None:
        return None
    time, f = got
    return _stream(name, time, {c: scale * f[k] for c, k in mapping.items()}, mapping,
                   **kwargs)


def _missing_instance(log: DataFlash, message: str, instance: int) -> str:
    """"no IMU messages with I = 2 ...; the log has I = 0, 1" (what exists), for errors."""
    if log.has(message) and "I" in log.formats[message].colhash:
        got = np.unique(log.records(message)["I"]).tolist()
        return (f"no {message} messages with I = {instance} (the time base); the log has "
                f"I = {', '.join(map(str, got))}")
    names = _INSTANCE_MESSAGES[message]
    wanted = names[instance] if instance < len(names) else f"{message} instance {instance}"
    present = " and ".join(n for n in names if log.has(n))
    return f"no {wanted} messages (the time base); the log has {present} messages"


def _imu(log: DataFlash, instance: int, params: Mapping[str, float]) -> Stream:
    """The IMU stream of ``instance`` (the time base); FlightLogError naming what exists."""
    imu = {"imu_ax": "AccX", "imu_ay": "AccY", "imu_az": "AccZ",
           "imu_p": "GyrX", "imu_q": "GyrY", "imu_r": "GyrZ"}
    for name in ("IMU", "ATT"):
        if log.has(name):
            log.check_time(name)
    base = _simple(log, "IMU", imu, instance)
    if base is not None:
        return base
    if not any(log.has(n) for n in _INSTANCE_MESSAGES["IMU"]):
        bitmask = params.get("LOG_BITMASK")
        why = ("" if bitmask is None or int(bitmask) & _LOG_BITMASK_IMU else
               f": recorded without IMU logging (LOG_BITMASK = {bitmask:g} lacks the IMU bit "
               f"{_LOG_BITMASK_IMU}; set it to log the IMU)")
        raise FlightLogError(f"{log.source}: no IMU messages (the time base){why}")
    raise FlightLogError(f"{log.source}: {_missing_instance(log, 'IMU', instance)}")


def _gps(log: DataFlash, instance: int) -> tuple[Stream, list[float]] | None:
    """The GPS stream (samples without a 3-D fix invalid) and the NED origin, or None."""
    name, column = _instance_source(log, "GPS", instance)
    got = log.read(name, ["Status", "Spd", "GCrs", "VZ", "Lat", "Lng", "Alt"], column,
                   instance) if name else None
    if got is None:
        return None
    time, f = got
    fix = f["Status"] >= 3
    if not np.any(fix):
        warnings.warn(f"{log.source}: no {name} message with a 3-D fix (Status >= 3); no GPS "
                      "channels", stacklevel=3)
        return None
    first = int(np.flatnonzero(fix)[0])
    origin = [float(f[k][first]) for k in ("Lat", "Lng", "Alt")]
    orgn = log.read("ORGN", ["Type", "Lat", "Lng", "Alt"])
    if orgn is not None and np.any(orgn[1]["Type"] == 0):
        ekf = int(np.flatnonzero(orgn[1]["Type"] == 0)[0])
        origin = [float(orgn[1][k][ekf]) for k in ("Lat", "Lng", "Alt")]
    pn, pe, pd = ned_from_geodetic(f["Lat"], f["Lng"], f["Alt"], origin)
    course = np.radians(f["GCrs"])
    channels = {"gps_pn": pn, "gps_pe": pe, "gps_pd": pd, "gps_vn": f["Spd"] * np.cos(course),
                "gps_ve": f["Spd"] * np.sin(course), "gps_vd": f["VZ"]}
    fields = dict(zip(channels, ("Lat", "Lng", "Alt", "Spd", "Spd", "VZ"), strict=True))
    return _stream(name, time, channels, fields, valid=fix, optional=True), origin


def _airspeed(log: DataFlash, instance: int) -> Stream | None:
    """The pitot stream; a negative airspeed (ground, sensor offset) is an invalid sample."""
    stream = _simple(log, "ARSP", {"pitot_airspeed": "Airspeed", "pitot_qbar": "DiffPress"},
                     instance, optional=True)
    if stream is None:
        return None
    return Stream(stream.name, stream.time, stream.channels, stream.units, fields=stream.fields,
                  valid=~(stream.channels["pitot_airspeed"] < 0.0), optional=True)


def _optional_streams(log: DataFlash, instance: int) -> list[Stream | None]:
    """Barometer, EKF wind, RPM and ArduPlane's AHRS flow angles (optional streams)."""
    streams = [_simple(log, "BARO", {"baro_alt": "Alt"}, instance, optional=True),
               _simple(log, "XKF2" if log.has("XKF2") else "NKF2",
                       {"est_wind_n": "VWN", "est_wind_e": "VWE"}, instance, optional=True)]
    if log.has("RPM"):  # one message for both sensors (rpm1, rpm2), or one per sensor (I)
        fields = log.fields("RPM")
        one = "rpm1" in fields
        streams.append(_rpm_stream(log, "motor_speed", "rpm1" if one else "RPM", instance))
        if "rpm2" in fields or ("I" in fields and instance != 1):
            streams.append(_rpm_stream(log, "motor_speed_2", "rpm2" if one else "RPM",
                                       instance if one else 1))
    if log.has("AOA"):
        streams.append(_simple(log, "AOA", {"ahrs_alpha": "AOA", "ahrs_beta": "SSA"}, None,
                               _DEG, units={c: u for c, (u, _) in AHRS_CHANNELS.items()},
                               optional=True))
    return streams


def _rpm_stream(log: DataFlash, channel: str, field: str, instance: int) -> Stream | None:
    """An RPM sensor's optional stream [rad/s], a negative speed invalid (ArduPilot logs
    -1 rev/min for an unhealthy sensor): ``motor_speed`` (the first sensor, or instance
    ``instance``) or ``motor_speed_2`` (the second sensor)."""
    stream = _simple(log, "RPM", {channel: field}, instance, _RPM, units={channel: "rad/s"})
    if stream is None or (channel == "motor_speed_2"
                          and not np.any(stream.channels[channel] > 0.0)):
        return None  # a second sensor that never reads a speed is not fitted
    name = stream.name if channel == "motor_speed" else f"{stream.name}.{field}[1]"
    return Stream(name, stream.time, stream.channels, stream.units, fields=stream.fields,
                  valid=stream.channels[channel] >= 0.0, optional=True,
                  trims=channel == "motor_speed")  # the second is an extra channel


def _actuator_stream(log: DataFlash, actuators: ActuatorMapping) -> Stream | None:
    """The ``cmd_*`` channels (held between messages; required), or None without the
    message. A sample is invalid when any output is outside its valid range or, for
    the PWM messages RCOU/RCIN, 0 (output not driven)."""
    commands = actuators.channels()
    got = log.read(actuators.message, sorted({m.field for m in commands.values()}))
    if got is None or not commands:
        return None
    time, f = got
    valid = np.ones(time.size, bool)
    for m in commands.values():
        valid &= m.valid(f[m.field])
        if actuators.message in ("RCOU", "RCIN"):
            valid &= f[m.field] > 0.0
    return _stream(actuators.message, time,
                   {c: m.apply(f[m.field]) for c, m in commands.items()},
                   {c: m.field for c, m in commands.items()}, hold=True, valid=valid)


def _resolve_actuators(log: DataFlash, actuators, params: Mapping[str, float],
                       deflections: Mapping[str, float]) -> tuple[ActuatorMapping | None, dict]:
    """The mapping to use and its metadata (``"source"`` plus the mapping)."""
    if isinstance(actuators, ActuatorMapping):
        return actuators.validate(), {"source": "given", **actuators.describe()}
    if actuators == "aetr":
        mapping = ActuatorMapping.ardupilot_aetr(**deflections)
        if not log.has("AETR"):
            raise FlightLogError(f"{log.source}: actuators='aetr' but the log has no AETR "
                                 "messages")
        return mapping, {"source": "AETR demands", **mapping.describe()}
    if actuators not in (None, "servo"):
        raise ValueError(f"actuators: an ActuatorMapping, 'servo' or 'aetr', got {actuators!r}")
    if not any(k.startswith("SERVO") and k.endswith("_FUNCTION") for k in params):
        if actuators == "servo":
            raise FlightLogError(f"{log.source}: actuators='servo' but the log has no "
                                 "SERVOn_FUNCTION parameters")
        mapping = ActuatorMapping.ardupilot(**deflections)
        warnings.warn(f"{log.source}: no SERVOn parameters in the log; RCOU read with the "
                      "default mapping (C1 aileron, C2 elevator, C3 throttle, C4 rudder, "
                      "1500 +- 500 us)", stacklevel=3)
        return mapping, {"source": "default (no SERVOn parameters)", **mapping.describe()}
    mapping, notes = servo_mapping(params, deflections, log.source)
    for note in notes:
        warnings.warn(f"{log.source}: {note}", stacklevel=3)
    if mapping is None:
        return None, {"source": "SERVOn parameters", "message": None,
                      "note": "no aileron, elevator, rudder or throttle servo"}
    return mapping, {"source": "SERVOn parameters", **mapping.describe()}


def _vehicle_metadata(log: DataFlash, params: Mapping[str, float]) -> dict:
    """firmware, flight_modes, vehicle_type (when known) and vtol_state (quadplanes)."""
    firmware = ""
    for message, field in (("VER", "FWS"), ("MSG", "Message")):
        got = log.strings(message, field)
        found = [t for t in (got[1] if got else []) if t.startswith(("Ardu", "Rover", "Blimp"))]
        if found:
            firmware = found[0]
            break
    kind = vehicle_type(firmware, params)
    modes = []
    got = (log.read("MODE", ["ModeNum"])
           if log.has("MODE") and "ModeNum" in log.fields("MODE") else None)
    if got is not None:
        modes = [[float(t), mode_name(firmware, int(m))]
                 for t, m in zip(got[0], got[1]["ModeNum"], strict=True)]
    meta = {"firmware": firmware, "flight_modes": modes}
    if kind is None:  # unknown: left out rather than guessed
        return meta
    meta["vehicle_type"] = kind
    if 19 <= kind["mav_type"] <= 24:
        # ArduPlane's Q modes hover on the lift motors; the others fly on the wing.
        meta["vtol_state"] = [[t, "mc" if name.startswith("Q") else "fw"] for t, name in modes]
    return meta


def read_ardupilot(path: str | Path, *, actuators: ActuatorMapping | str | None = None,
                   extra: Mapping[str, FieldSource] | None = None, instance: int = 0,
                   max_gap: float = 0.5, allow_truncated: bool = True,
                   deflections: Mapping[str, float] | None = None,
                   segment: tuple[float, float] | None = None,
                   extra_channels: Sequence[str] = ()) -> FlightLog:
    """Reads an ArduPilot DataFlash ``.bin`` log into a FlightLog (canonical channels).

    Args:
        path: the ``.bin`` file.
        actuators: None (the log's SERVOn parameters, else
            :meth:`ActuatorMapping.ardupilot` with a warning), ``"servo"`` (the
            SERVOn parameters or an error), ``"aetr"`` (the AETR demand message)
            or an :class:`ActuatorMapping`.
        extra: more channels, e.g. vanes: ``{"vane_alpha": FieldSource("CUR2", "Volt",
            "rad", scale=..., offset=...)}``.
        instance: instance of IMU, GPS, ARSP, BARO, RPM and EKF core of XKF2/NKF2;
            an optional message without it is left out, the IMU must have it.
        max_gap: longest interval between two messages of a stream [s] before a
            required stream cuts the log or an optional one is dropped.
        allow_truncated: drop a half-written last record (SD-card logs) with a
            warning; False raises instead.
        deflections: surface ("elevator", "aileron", "rudder") -> full deflection
            [rad] at the servo's MAX (or MIN) PWM or full demand; 25 deg by default.
        segment: (t0, t1) [s since boot] to read, None: the whole log. Optional
            streams are judged inside it (a GPS fixed before ``t0`` is kept).
        extra_channels: more fields as extra channels, ``"MESSAGE.Field"`` (first
            instance, unit from the log's FMTU where it is known, else ``1``), beside
            the default :data:`~drake_uav.io.extras.ARDUPILOT_EXTRAS`.

    Raises:
        FlightLogError: not a DataFlash log, corrupt, a TimeMS log (unsupported
            firmware), no IMU instance ``instance``, bad SERVOn parameters, no
            segment where every required stream has valid data; names the file.
    """
    path = Path(path)
    deflections = _deflections(deflections)
    extra = {name: source.validate() for name, source in (extra or {}).items()}
    log = DataFlash(path, allow_truncated)
    params = log.parameters()
    base = _imu(log, instance, params)
    mapping, described = _resolve_actuators(log, actuators, params, deflections)
    metadata = {"format": "ArduPilot DataFlash", "instance": instance, "actuators": described,
                **_vehicle_metadata(log, params), "imu_rate_hz": _imu_rate(log, base),
                "parameters": params, **imu_position(params, instance)}
    streams = [_simple(log, "ATT", {"att_roll": "Roll", "att_pitch": "Pitch", "att_yaw": "Yaw"},
                       scale=_DEG, angles=("att_roll", "att_yaw")),
               _airspeed(log, instance), *_optional_streams(log, instance)]
    if mapping is not None:
        streams.append(_actuator_stream(log, mapping))
        if streams[-1] is None:
            warnings.warn(f"{log.source}: no {mapping.message} messages: no cmd_* channels",
                          stacklevel=2)
    gps = _gps(log, instance)
    if gps is not None:
        streams.append(gps[0])
        metadata["gps_origin_lat_lon_alt"] = gps[1]
    streams += _esc_streams(log) + _extra_streams(log, extra)
    streams += _logged_extras(log, extra_channels,
                              {base.name, *(s.name for s in streams if s is not None)})
    return align_streams(base, [s for s in streams if s is not None], source=log.source,
                         max_gap=max_gap, metadata=metadata, span=segment)


def read_ardupilot_metadata(path: str | Path, *, allow_truncated: bool = True,
                            deflections: Mapping[str, float] | None = None) -> dict:
    """What a ``.bin`` log says about the vehicle, without reading its streams.

    Returns the metadata keys of :func:`read_ardupilot` that need no IMU:
    ``vehicle_type``, ``firmware``, ``flight_modes`` (``vtol_state`` for a
    quadplane), ``parameters``, ``actuators`` (the mapping the reader would use) and
    ``imu_position`` (of IMU instance 0) when the log sets it.
    """
    log = DataFlash(Path(path), allow_truncated)
    params = log.parameters()
    _, described = _resolve_actuators(log, None, params, _deflections(deflections))
    return {**_vehicle_metadata(log, params), "parameters": params, "actuators": described,
            **imu_position(params, 0)}


def _deflections(given: Mapping[str, float] | None) -> dict[str, float]:
    """Full surface deflections [rad]: 25 deg unless given."""
    return {**dict.fromkeys(("elevator", "aileron", "rudder"), math.radians(25.0)),
            **(given or {})}


def _imu_rate(log: DataFlash, base: Stream) -> float:
    """Median IMU logging rate [Hz]; warns below 100 Hz (too slow for identification)."""
    rate = 1.0 / float(np.median(np.diff(base.time))) if base.time.size > 1 else 0.0
    if round(rate, 3) < MIN_IMU_RATE_HZ:
        warnings.warn(f"{log.source}: {base.name} logged at {rate:.3g} Hz (< "
                      f"{MIN_IMU_RATE_HZ:g} Hz): fast manoeuvres are under-sampled; log the "
                      "IMU faster (INS_LOG_BAT_* or the IMU rate of LOG_BITMASK)", stacklevel=3)
    return round(rate, 6)


_ESC_FIELDS = {"rpm": "RPM", "voltage": "Volt", "current": "Curr", "temperature": "Temp"}


def _esc_streams(log: DataFlash) -> list[Stream]:
    """One optional stream per ESC: ``ESC`` messages per ``Instance`` (ESC[i]), or the
    separate ``ESC1`` .. ``ESC8`` messages of older firmware (:mod:`drake_uav.io.esc`)."""
    sources = []
    if log.has("ESC") and "Instance" in log.fields("ESC"):
        instances = np.unique(log.records("ESC")["Instance"]).astype(int)
        sources = [("ESC", "Instance", int(i), f"ESC[{int(i)}]") for i in instances]
    else:
        sources = [(f"ESC{n}", None, None, f"ESC{n}") for n in range(1, 9)
                   if log.has(f"ESC{n}")]
    streams = []
    for index, (message, column, instance, name) in enumerate(sources):
        fields = {q: f for q, f in _ESC_FIELDS.items() if f in log.fields(message)}
        got = log.read(message, list(fields.values()), column, instance) if fields else None
        if got is None:
            continue
        time, raw = got
        streams.append(esc_stream(name, index if instance is None else instance, time,
                                  {q: raw[f] for q, f in fields.items()},
                                  {q: f"{message}.{f}" for q, f in fields.items()}))
    return streams


def _extra_streams(log: DataFlash, extra: Mapping[str, FieldSource]) -> list[Stream]:
    """One stream per (message, instance, hold) of the ``extra`` channels."""
    groups: dict[tuple, dict[str, FieldSource]] = {}
    for channel, src in extra.items():
        groups.setdefault((src.message, src.instance, src.hold), {})[channel] = src
    streams = []
    for (message, instance, hold), sources in groups.items():
        column = ("I" if "I" in log.fields(message) else "C") if log.has(message) else None
        got = log.read(message, sorted({s.field for s in sources.values()}), column, instance)
        if got is None:
            which = "" if instance is None else f" with {column} = {instance}"
            raise FlightLogError(f"{log.source}: no {message} messages{which} for channel(s) "
                                 f"{', '.join(sources)}")
        time, f = got
        streams.append(Stream(
            message if instance is None else f"{message}[{instance}]", time,
            {c: s.apply(f[s.field]) for c, s in sources.items()},
            {c: s.unit for c, s in sources.items()}, hold=hold,
            fields={c: f"{message}.{s.field}" for c, s in sources.items()}))
    return streams


def _logged_extras(log: DataFlash, named: Sequence[str], taken: set[str]) -> list[Stream]:
    """Optional streams of the default extra channels the log has and of the ``named``
    fields (FlightLogError naming one the log lacks), one per message, first instance;
    ``taken``: the names of the reader's other streams."""

    def has(message, field):
        return log.has(message) and field in log.fields(message)

    def unit(message, field):  # the log's FMTU, when it has one
        fmt = log.formats[message]
        return fmt.units[fmt.colhash[field]] if fmt.units else None

    def read(message, fields):
        fmt = log.formats[message]
        column = fmt.instance_field or next((c for c in ("I", "Inst", "Instance")
                                             if c in fmt.colhash), None)
        return log.read(message, fields, column, None if column is None else 0)

    wanted = wanted_fields(ARDUPILOT_EXTRAS, parse_extra_fields(named), has, unit, log.source)
    return extra_streams(wanted, read, taken)
