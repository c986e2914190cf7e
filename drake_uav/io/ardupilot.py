"""ArduPilot DataFlash (``.bin``) logs into a FlightLog with canonical channels.

pymavlink's ``DFReader_binary`` indexes the file (message formats from the FMT
messages, byte offset of every message); each needed message type is then
decoded in one vectorised step (numpy structured view of all its messages) with
pymavlink's format table and multipliers (a 30-minute log with two IMUs at
400 Hz, 81 MB, reads in under 2 s). Time is ``TimeUS / 1e6`` [s since boot].

Default mapping (instance 0 of multi-instance messages; see docs/flight_logs.md):

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
RCOU       C1 C2 C3 C4               :class:`ActuatorMapping`        cmd_*
XKF2/NKF2  VWN VWE                   m/s                             est_wind_n est_wind_e
RPM        rpm1 (or RPM)             rev/min -> rad/s                motor_speed
=========  ========================  ==============================  =====================

GPS samples without a 3-D fix (Status < 3) are dropped. The origin of the local
positions is the EKF origin (``ORGN`` with Type 0), else the first fix; they use
the WGS-84 radii of curvature at the origin (flat earth, good to a few km).
Vane angles are not standard ArduPilot messages: map them with ``extra``
(e.g. from ``CUR2``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from pymavlink.DFReader import FORMAT_TO_STRUCT, DFReader_binary

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import CHANNELS, ActuatorMapping, FieldSource, Stream, align_streams

__all__ = ["read_ardupilot"]

_HEAD = (0xA3, 0x95, 0x80)  # every DataFlash log starts with a FMT message
_TRAILING_SLACK = 528
"""Bytes at the end of a log that may be block padding (pymavlink's allowance)."""
_EARTH_A, _EARTH_E2 = 6378137.0, 6.69437999014e-3  # WGS-84 semi-major axis [m], e^2
_RPM = 2.0 * math.pi / 60.0  # rev/min -> rad/s
_DEG = math.pi / 180.0


class _Index(DFReader_binary):
    """pymavlink's DataFlash index (formats, message offsets) without its clock.

    Every message this module uses carries ``TimeUS``, so the clock search,
    which parses the whole log message by message when there is no GPS, is skipped.
    """

    def init_clock(self):
        self.clock = None


def _dtype(fmt) -> np.dtype:
    """numpy dtype of the payload of DataFlash format ``fmt`` (pymavlink's table)."""
    fields = []
    for column, char in zip(fmt.columns, fmt.format, strict=True):
        code = FORMAT_TO_STRUCT[char][0]
        fields.append((column, f"S{code[:-1]}" if code.endswith("s") else f"<{code}"))
    return np.dtype(fields)


class _DataFlash:
    """A DataFlash file: its formats, message offsets and vectorised decoding."""

    def __init__(self, path: Path, allow_truncated: bool):
        self.source = str(path)
        self.data = np.fromfile(path, dtype=np.uint8)
        if self.data.size < 3 or tuple(self.data[:3]) != _HEAD:
            raise FlightLogError(f"{path}: not an ArduPilot DataFlash log (no FMT message at "
                                 "the start of the file)")
        try:
            index = _Index(str(path))
        except Exception as err:  # pymavlink raises bare Exceptions on malformed formats
            raise FlightLogError(f"{path}: unreadable DataFlash log ({err})") from None
        try:
            self.formats = {f.name: f for f in index.formats.values()}
            self.offsets = {name: np.asarray(index.offsets[f.type], np.int64)
                            for name, f in self.formats.items()}
        finally:
            index.close()
        self._check_coverage(allow_truncated)

    def _check_coverage(self, allow_truncated: bool) -> None:
        """Truncated last message, unparsed tail, skipped corrupt bytes (pymavlink resyncs)."""
        size, end, covered, where = self.data.size, 0, 0, None
        for name, offsets in self.offsets.items():
            if not offsets.size:
                continue
            length = self.formats[name].len
            last = int(offsets[-1])
            if last + length > size:
                message = (f"{self.source}: truncated file: the last {name} message (byte "
                           f"{last}) needs {length} bytes, {size - last} remain")
                if not allow_truncated:
                    raise FlightLogError(message + " (allow_truncated=True drops it)")
                warnings.warn(message + "; dropped", stacklevel=4)
                self.offsets[name] = offsets = offsets[:-1]
                if not offsets.size:
                    continue
                last = int(offsets[-1])
            covered += offsets.size * length
            if last + length > end:
                end, where = last + length, name
        if size - end > _TRAILING_SLACK:
            message = (f"{self.source}: the {size - end} bytes from byte {end} on (after the "
                       f"last complete message, {where}) could not be parsed: corrupt or "
                       "truncated log")
            if not allow_truncated:
                raise FlightLogError(message)
            warnings.warn(message + "; ignored", stacklevel=4)
        if covered < end:
            warnings.warn(f"{self.source}: {end - covered} bytes of corrupt data skipped",
                          stacklevel=4)

    def has(self, name: str) -> bool:
        return name in self.formats and self.offsets[name].size > 0

    def fields(self, name: str) -> list[str]:
        return list(self.formats[name].columns)

    def read(self, name: str, fields: list[str], instance_column: str | None = None,
             instance: int | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        """(time [s], field -> values) of message ``name`` (multipliers applied), keeping
        the messages whose ``instance_column`` equals ``instance`` when the message has
        that column; None when there is no such message."""
        if not self.has(name):
            return None
        fmt = self.formats[name]
        missing = [f for f in ("TimeUS", *fields) if f not in fmt.colhash]
        if missing:
            raise FlightLogError(f"{self.source}: message {name} has no field {missing[0]} "
                                 f"(fields: {', '.join(fmt.columns)})")
        dtype = _dtype(fmt)
        if dtype.itemsize != fmt.len - 3:
            raise FlightLogError(f"{self.source}: FMT of {name} gives length {fmt.len}, its "
                                 f"format '{fmt.format}' needs {dtype.itemsize + 3}")
        windows = np.lib.stride_tricks.sliding_window_view(self.data, dtype.itemsize)
        records = windows[self.offsets[name] + 3].view(dtype)[:, 0]
        if instance is not None and instance_column in fmt.colhash:
            records = records[records[instance_column] == instance]
            if records.size == 0:
                return None
        out = {}
        for field in fields:
            values = records[field].astype(float)
            mult = fmt.msg_mults[fmt.colhash[field]]
            if mult is not None:
                # Divide by the inverse of a fractional multiplier, as pymavlink does:
                # 1234 / 100 is exact to the last bit where 1234 * 0.01 is not.
                values = values / (1.0 / mult) if 0.0 < mult < 1.0 else values * mult
            out[field] = values
        return records["TimeUS"].astype(float) / 1e6, out


def _stream(name, time, channels, fields: Mapping[str, str], **kwargs) -> Stream:
    """A stream of canonical channels; ``fields``: channel -> field of message ``name``."""
    return Stream(name, time, channels, {n: CHANNELS[n][0] for n in channels},
                  fields={c: f"{name}.{f}" for c, f in fields.items()}, **kwargs)


def _simple(log: _DataFlash, name: str, mapping: Mapping[str, str], column: str | None = None,
            instance: int | None = None, scale: float = 1.0, **kwargs) -> Stream | None:
    """Stream of message ``name`` with channel <- scale * field, or None when absent."""
    got = log.read(name, list(mapping.values()), column, instance)
    if got is None:
        return None
    time, f = got
    return _stream(name, time, {c: scale * f[k] for c, k in mapping.items()}, mapping,
                   **kwargs)


def _gps(log: _DataFlash, instance: int) -> tuple[Stream, list[float]] | None:
    got = log.read("GPS", ["Status", "Spd", "GCrs", "VZ", "Lat", "Lng", "Alt"], "I", instance)
    if got is None:
        return None
    time, f = got
    fix = f["Status"] >= 3
    if not np.any(fix):
        warnings.warn(f"{log.source}: no GPS message with a 3-D fix (Status >= 3); no GPS "
                      "channels", stacklevel=3)
        return None
    time, f = time[fix], {k: v[fix] for k, v in f.items()}
    course = np.radians(f["GCrs"])
    lat0, lon0, alt0 = (float(f[k][0]) for k in ("Lat", "Lng", "Alt"))
    origin = log.read("ORGN", ["Type", "Lat", "Lng", "Alt"])
    if origin is not None and np.any(origin[1]["Type"] == 0):
        ekf = int(np.flatnonzero(origin[1]["Type"] == 0)[0])
        lat0, lon0, alt0 = (float(origin[1][k][ekf]) for k in ("Lat", "Lng", "Alt"))
    s2 = 1.0 - _EARTH_E2 * math.sin(math.radians(lat0)) ** 2
    r_north = _EARTH_A * (1.0 - _EARTH_E2) / s2 ** 1.5
    r_east = _EARTH_A / math.sqrt(s2) * math.cos(math.radians(lat0))
    channels = {
        "gps_pn": np.radians(f["Lat"] - lat0) * r_north,
        "gps_pe": np.radians(f["Lng"] - lon0) * r_east,
        "gps_pd": -(f["Alt"] - alt0),
        "gps_vn": f["Spd"] * np.cos(course),
        "gps_ve": f["Spd"] * np.sin(course),
        "gps_vd": f["VZ"],
    }
    fields = dict(zip(channels, ("Lat", "Lng", "Alt", "Spd", "Spd", "VZ"), strict=True))
    return _stream("GPS", time, channels, fields), [lat0, lon0, alt0]


def read_ardupilot(path: str | Path, *, actuators: ActuatorMapping | None = None,
                   extra: Mapping[str, FieldSource] | None = None, instance: int = 0,
                   max_gap: float = 0.5, allow_truncated: bool = False) -> FlightLog:
    """Reads an ArduPilot DataFlash ``.bin`` log into a FlightLog (canonical channels).

    Args:
        path: the ``.bin`` file.
        actuators: output -> command mapping (default :meth:`ActuatorMapping.ardupilot`).
        extra: more channels, e.g. vanes: ``{"vane_alpha": FieldSource("CUR2", "Volt",
            "rad", scale=..., offset=...)}``.
        instance: instance of IMU, GPS, ARSP, BARO, RPM (field ``I``) and EKF core
            of XKF2/NKF2 (field ``C``); messages without it are left out, except
            the IMU (the time base), which must have it.
        max_gap: longest allowed interval between two messages of a stream [s].
        allow_truncated: drop an incomplete last message (with a warning) instead
            of raising.

    Raises:
        FlightLogError: not a DataFlash log, truncated, no IMU messages, a stream
            with a gap, time not increasing or non-finite values; names the file.
    """
    path = Path(path)
    actuators = (actuators or ActuatorMapping.ardupilot()).validate()
    extra = {name: source.validate() for name, source in (extra or {}).items()}
    log = _DataFlash(path, allow_truncated)
    imu = {"imu_ax": "AccX", "imu_ay": "AccY", "imu_az": "AccZ",
           "imu_p": "GyrX", "imu_q": "GyrY", "imu_r": "GyrZ"}
    base = _simple(log, "IMU", imu, "I", instance)
    if base is None:
        raise FlightLogError(f"{log.source}: no IMU messages with I = {instance} (the time "
                             "base)")
    metadata = {"format": "ArduPilot DataFlash", "instance": instance,
                "actuators": actuators.describe()}
    streams = [
        _simple(log, "ATT", {"att_roll": "Roll", "att_pitch": "Pitch", "att_yaw": "Yaw"},
                scale=_DEG, angles=("att_roll", "att_yaw")),
        _simple(log, "ARSP", {"pitot_airspeed": "Airspeed", "pitot_qbar": "DiffPress"}, "I",
                instance),
        _simple(log, "BARO", {"baro_alt": "Alt"}, "I", instance),
        _simple(log, "XKF2" if log.has("XKF2") else "NKF2",
                {"est_wind_n": "VWN", "est_wind_e": "VWE"}, "C", instance),
    ]
    commands = actuators.channels()
    got = log.read(actuators.message, [m.field for m in commands.values()])
    if got is not None:
        time, f = got
        streams.append(_stream(actuators.message, time,
                               {c: m.apply(f[m.field]) for c, m in commands.items()},
                               {c: m.field for c, m in commands.items()}, hold=True))
    if log.has("RPM"):
        field = "rpm1" if "rpm1" in log.fields("RPM") else "RPM"
        streams.append(_simple(log, "RPM", {"motor_speed": field}, "I", instance, _RPM))
    gps = _gps(log, instance)
    if gps is not None:
        streams.append(gps[0])
        metadata["gps_origin_lat_lon_alt"] = gps[1]
    streams += _extra_streams(log, extra)
    return align_streams(base, [s for s in streams if s is not None], source=log.source,
                         max_gap=max_gap, metadata=metadata)


def _extra_streams(log: _DataFlash, extra: Mapping[str, FieldSource]) -> list[Stream]:
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
