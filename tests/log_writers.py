"""Minimal writers of ArduPilot DataFlash (``.bin``) and PX4 ULog (``.ulg``) files.

Written from the published file layouts, independently of the readers, so the
reader tests check the readers against the format rather than against themselves.

* DataFlash: every message is ``0xA3 0x95 <type>`` followed by its packed fields
  (little-endian). Type 128 is ``FMT`` (Type B, Length B, Name 4s, Format 16s,
  Columns 64s) and defines the other types. Scaled integer formats: ``c``/``C``
  int16/uint16 x 0.01, ``e``/``E`` int32/uint32 x 0.01, ``L`` int32 x 1e-7.
* ULog: a 16-byte header (``ULog`` magic, version, start time in us), then
  messages ``uint16 size, uint8 type, payload``: ``B`` flag bits, ``F`` formats,
  ``I`` info, then ``A`` subscriptions and ``D`` data (``uint16 msg_id`` + fields).
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

# DataFlash format character -> (numpy dtype, multiplier of the stored integer).
_DF_TYPES = {
    "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None),
    "i": ("<i4", None), "I": ("<u4", None), "q": ("<i8", None), "Q": ("<u8", None),
    "f": ("<f4", None), "d": ("<f8", None), "M": ("u1", None),
    "n": ("S4", None), "N": ("S16", None), "Z": ("S64", None),
    "c": ("<i2", 100.0), "C": ("<u2", 100.0), "e": ("<i4", 100.0), "E": ("<u4", 100.0),
    "L": ("<i4", 1e7),
}

_FMT_TYPE = 0x80


class DataFlashWriter:
    """Collects DataFlash messages and writes them (definitions first, then by time)."""

    def __init__(self):
        self._formats: dict[str, tuple[int, str, tuple[str, ...], np.dtype]] = {}
        self._definitions: list[bytes] = []
        self._blocks: list[tuple[np.ndarray, np.ndarray]] = []  # (time_us, rows of bytes)

    def define(self, name: str, fmt: str, columns: str) -> None:
        """Declares message ``name`` with format characters ``fmt`` and comma-separated columns."""
        cols = tuple(columns.split(","))
        assert len(cols) == len(fmt) <= 16 and len(columns) <= 64, (name, fmt, cols)
        type_id = _FMT_TYPE + 1 + len(self._formats)
        dtype = np.dtype([("h1", "u1"), ("h2", "u1"), ("type", "u1")]
                         + [(c, _DF_TYPES[f][0]) for c, f in zip(cols, fmt, strict=True)])
        self._formats[name] = (type_id, fmt, cols, dtype)
        self._definitions.append(
            struct.pack("<BBBBB4s16s64s", 0xA3, 0x95, _FMT_TYPE, type_id, dtype.itemsize,
                        name.encode(), fmt.encode(), columns.encode()))

    def add(self, name: str, at=None, **columns) -> None:
        """Adds messages of ``name``: each column is a scalar or an array (physical units).

        The messages go into the file in the order of ``at`` [us] (default: TimeUS).
        """
        type_id, fmt, cols, dtype = self._formats[name]
        n = max(np.size(v) for v in columns.values())
        rows = np.zeros(n, dtype)
        rows["h1"], rows["h2"], rows["type"] = 0xA3, 0x95, type_id
        for col, f in zip(cols, fmt, strict=True):
            if col not in columns:
                continue
            values = np.broadcast_to(columns[col], (n,))
            mult = _DF_TYPES[f][1]
            if mult is not None:
                values = np.round(np.asarray(values, float) * mult)
            rows[col] = values
        order = columns.get("TimeUS", 0) if at is None else at
        time_us = np.broadcast_to(np.asarray(order, np.uint64), (n,))
        self._blocks.append((time_us, rows.view(np.uint8).reshape(n, dtype.itemsize)))

    def to_bytes(self) -> bytes:
        times = np.concatenate([t for t, _ in self._blocks])
        rows = [r for _, block in self._blocks for r in block]
        order = np.argsort(times, kind="stable")
        return b"".join(self._definitions) + b"".join(rows[i].tobytes() for i in order)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_bytes(self.to_bytes())
        return path


# ULog field type -> numpy dtype.
_ULOG_TYPES = {
    "int8_t": "i1", "uint8_t": "u1", "int16_t": "<i2", "uint16_t": "<u2",
    "int32_t": "<i4", "uint32_t": "<u4", "int64_t": "<i8", "uint64_t": "<u8",
    "float": "<f4", "double": "<f8", "bool": "u1", "char": "Ortiz & Gutierrez 2009",
}


def _ulog_message(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


class ULogWriter:
    """Collects ULog formats, subscriptions and data; writes them in timestamp order."""

    def __init__(self, start_us: int = 0):
        self._start_us = start_us
        self._definitions: list[bytes] = []
        self._topics: dict[str, np.dtype] = {}
        self._subscriptions: list[bytes] = []
        self._blocks: list[tuple[np.ndarray, np.ndarray]] = []
        self._next_id = 0

    def format(self, name: str, fields: str) -> None:
        """Declares topic ``name`` with fields ``"uint64_t timestamp;float[3] x;..."``."""
        parts = []
        for item in filter(None, fields.split(";")):
            type_str, field = item.split()
            size = 0
            if "[" in type_str:
                type_str, size = type_str[:-1].split("[")
                size = int(size)
            parts.append((field, _ULOG_TYPES[type_str], (size,) if size else ()))
        self._topics[name] = np.dtype([("msg_id", "<u2"), *parts])
        self._definitions.append(_ulog_message("F", f"{name}:{fields}".encode()))

    def info(self, key: str, value: str) -> None:
        """Adds a string info message (``char[len] key``)."""
        type_key = f"char[{len(value)}] {key}".encode()
        self._definitions.append(
            _ulog_message("I", bytes([len(type_key)]) + type_key + value.encode()))

    def subscribe(self, name: str, multi_id: int = 0) -> int:
        """Adds an ``A`` message for topic ``name``; returns its message id."""
        msg_id = self._next_id
        self._next_id += 1
        self._subscriptions.append(
            _ulog_message("A", struct.pack("<BH", multi_id, msg_id) + name.encode()))
        return msg_id

    def data(self, name: str, msg_id: int, **columns) -> None:
        """Adds ``D`` messages of topic ``name``; ``timestamp`` [us] is required."""
        dtype = self._topics[name]
        n = len(columns["timestamp"])
        rows = np.zeros(n, dtype)
        rows["msg_id"] = msg_id
        for key, value in columns.items():
            rows[key] = value
        header = np.zeros(n, [("size", "<u2"), ("type", "u1")])
        header["size"], header["type"] = dtype.itemsize, ord("D")
        packed = np.concatenate([header.view(np.uint8).reshape(n, 3),
                                 rows.view(np.uint8).reshape(n, dtype.itemsize)], axis=1)
        self._blocks.append((np.asarray(columns["timestamp"], np.uint64), packed))

    def to_bytes(self) -> bytes:
        header = b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", self._start_us)
        flags = _ulog_message("B", bytes(16) + bytes(24))
        times = np.concatenate([t for t, _ in self._blocks])
        rows = [r for _, block in self._blocks for r in block]
        order = np.argsort(times, kind="stable")
        return (header + flags + b"".join(self._definitions) + b"".join(self._subscriptions)
                + b"".join(rows[i].tobytes() for i in order))

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_bytes(self.to_bytes())
        return path


# ------------------------------------------------- canonical FlightLog -> native logs
_EARTH_A, _EARTH_E2 = 6378137.0, 6.69437999014e-3  # WGS-84
ORIGIN = (47.0, 8.0, 500.0)
"""Latitude, longitude [deg], altitude [m] of the NED origin in the converted logs."""
FULL_DEFLECTION = math.radians(25.0)
"""Surface deflection at full PWM / full normalised demand in the converted logs [rad]."""


def _lat_lon_alt(log):
    """Latitude, longitude [deg] and altitude [m] of ``gps_pn/pe/pd`` about :data:`ORIGIN`."""
    lat0 = math.radians(ORIGIN[0])
    s2 = 1.0 - _EARTH_E2 * math.sin(lat0) ** 2
    r_north = _EARTH_A * (1.0 - _EARTH_E2) / s2 ** 1.5
    r_east = _EARTH_A / math.sqrt(s2) * math.cos(lat0)
    return (ORIGIN[0] + np.degrees(log["gps_pn"] / r_north),
            ORIGIN[1] + np.degrees(log["gps_pe"] / r_east),
            ORIGIN[2] - log["gps_pd"])


def dataflash_from_log(log, path, max_deflection: float = FULL_DEFLECTION) -> Path:
    """An ArduPilot ``.bin`` of a FlightLog with the canonical channels (one rate).

    Vanes go to a ``VANE`` message (fields ``AoA``, ``SSA`` in deg); surfaces to
    RCOU C1 aileron, C2 elevator (PWM above trim = nose-up = negative elevator),
    C3 throttle (1100..1900), C4 rudder (PWM above trim = negative rudder), with
    ``max_deflection`` [rad] (default 25 deg) at +-500 us.
    """
    w = DataFlashWriter()
    w.define("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH")
    w.define("ATT", "QccccCCffB",
             "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    w.define("GPS", "QBBIHBcLLeffff",
             "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw")
    w.define("ARSP", "QBffcffBBffB",
             "TimeUS,I,Airspeed,DiffPress,Temp,RawPress,Offset,U,H,Hp,TR,Pri")
    w.define("BARO", "QBffcfIffB", "TimeUS,I,Alt,Press,Temp,CRt,SMS,Offset,GndTemp,Health")
    w.define("RCOU", "QHHHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6,C7,C8")
    w.define("VANE", "Qff", "TimeUS,AoA,SSA")
    w.define("ORGN", "QBLLe", "TimeUS,Type,Lat,Lng,Alt")
    us = np.round(log.time * 1e6).astype(np.uint64)
    w.add("IMU", TimeUS=us, I=0, AccX=log["imu_ax"], AccY=log["imu_ay"], AccZ=log["imu_az"],
          GyrX=log["imu_p"], GyrY=log["imu_q"], GyrZ=log["imu_r"], T=25.0, GH=1, AH=1)
    w.add("ATT", TimeUS=us, Roll=np.degrees(log["att_roll"]), Pitch=np.degrees(log["att_pitch"]),
          Yaw=np.degrees(log["att_yaw"]) % 360.0)
    lat, lon, alt = _lat_lon_alt(log)
    w.add("ORGN", TimeUS=us[:1], Type=0, Lat=ORIGIN[0], Lng=ORIGIN[1], Alt=ORIGIN[2])
    w.add("GPS", TimeUS=us, I=0, Status=3, NSats=12, Lat=lat, Lng=lon, Alt=alt,
          Spd=np.hypot(log["gps_vn"], log["gps_ve"]),
          GCrs=np.degrees(np.arctan2(log["gps_ve"], log["gps_vn"])) % 360.0, VZ=log["gps_vd"])
    w.add("ARSP", TimeUS=us, I=0, Airspeed=log["pitot_airspeed"], DiffPress=log["pitot_qbar"],
          Temp=15.0, H=1)
    w.add("BARO", TimeUS=us, I=0, Alt=log["baro_alt"], Press=101325.0, Health=1)
    pwm = 500.0 / max_deflection
    w.add("RCOU", TimeUS=us, C1=np.round(1500 + pwm * log["cmd_aileron"]),
          C2=np.round(1500 - pwm * log["cmd_elevator"]),
          C3=np.round(1100 + 800 * log["cmd_throttle"]),
          C4=np.round(1500 - pwm * log["cmd_rudder"]))
    w.add("VANE", TimeUS=us, AoA=np.degrees(log["vane_alpha"]), SSA=np.degrees(log["vane_beta"]))
    return w.save(path)


def ulog_from_log(log, path) -> Path:
    """A PX4 ``.ulg`` of a FlightLog with the canonical channels (one rate).

    Attitude as a quaternion, positions and velocities in ``vehicle_local_position``,
    surfaces as normalised ``actuator_controls_0`` (roll, pitch, yaw demand in
    -1..1 for 25 deg, throttle 0..1), vanes in a ``vane_angles`` topic [rad].
    """
    from drake_uav.model.rotations import euler_to_quat

    w = ULogWriter()
    w.info("sys_name", "PX4")
    w.format("sensor_combined", "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
             "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;"
             "uint32_t accelerometer_integral_dt")
    w.format("vehicle_attitude", "uint64_t timestamp;uint64_t timestamp_sample;float[4] q")
    w.format("vehicle_local_position", "uint64_t timestamp;uint64_t timestamp_sample;"
             "float x;float y;float z;float vx;float vy;float vz")
    w.format("airspeed", "uint64_t timestamp;uint64_t timestamp_sample;"
             "float indicated_airspeed_m_s;float true_airspeed_m_s;float confidence")
    w.format("differential_pressure", "uint64_t timestamp;uint64_t timestamp_sample;"
             "uint32_t device_id;float differential_pressure_pa;float temperature")
    w.format("vehicle_air_data", "uint64_t timestamp;uint64_t timestamp_sample;"
             "float baro_alt_meter;float baro_pressure_pa")
    w.format("actuator_controls_0", "uint64_t timestamp;uint64_t timestamp_sample;float[8] control")
    w.format("vane_angles", "uint64_t timestamp;float alpha;float beta")
    us = np.round(log.time * 1e6).astype(np.uint64)
    max_deflection = FULL_DEFLECTION
    q = np.array([euler_to_quat(e) for e in log.stack(["att_roll", "att_pitch", "att_yaw"])])
    control = np.zeros((len(log), 8))
    control[:, 0] = log["cmd_aileron"] / max_deflection
    control[:, 1] = -log["cmd_elevator"] / max_deflection
    control[:, 2] = -log["cmd_rudder"] / max_deflection
    control[:, 3] = log["cmd_throttle"]
    columns = {
        "sensor_combined": dict(
            gyro_rad=log.stack(["imu_p", "imu_q", "imu_r"]),
            accelerometer_m_s2=log.stack(["imu_ax", "imu_ay", "imu_az"])),
        "vehicle_attitude": dict(timestamp_sample=us, q=q),
        "vehicle_local_position": dict(
            timestamp_sample=us, x=log["gps_pn"], y=log["gps_pe"], z=log["gps_pd"],
            vx=log["gps_vn"], vy=log["gps_ve"], vz=log["gps_vd"]),
        "airspeed": dict(timestamp_sample=us, true_airspeed_m_s=log["pitot_airspeed"],
                         indicated_airspeed_m_s=log["pitot_airspeed"], confidence=1.0),
        "differential_pressure": dict(timestamp_sample=us,
                                      differential_pressure_pa=log["pitot_qbar"]),
        "vehicle_air_data": dict(timestamp_sample=us, baro_alt_meter=log["baro_alt"]),
        "actuator_controls_0": dict(timestamp_sample=us, control=control),
        "vane_angles": dict(alpha=log["vane_alpha"], beta=log["vane_beta"]),
    }
    for topic, values in columns.items():
        w.data(topic, w.subscribe(topic), timestamp=us, **values)
    return w.save(path)
