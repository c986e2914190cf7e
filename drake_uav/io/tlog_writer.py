"""A FlightLog as a MAVLink telemetry log (``.tlog``), as a ground station records ArduPlane.

:func:`write_tlog` sends the log's canonical channels as the MAVLink messages ArduPlane
streams (encoded by pymavlink), each stream at its own rate, so that a flight can be
turned into the telemetry a ground station would have recorded of it: to test what the
analysis says on a low-rate log, or to hand a simulated flight to tools that read
``.tlog`` files. Each value sent is the log's latest sample at the send time (the
autopilot sends what it has), with the resolution of the MAVLink field (1 mG, 1 mrad/s,
1 us of PWM, 1 cm/s, 1e-7 deg).

===================  ==========================  ============================================
stream (``rates``)   message                     from
===================  ==========================  ============================================
``imu``              RAW_IMU (mG, mrad/s)        imu_ax .. imu_r
``attitude``         ATTITUDE                    att_roll att_pitch att_yaw
``commands``         SERVO_OUTPUT_RAW            cmd_aileron (servo 1), cmd_elevator (2),
                                                 cmd_throttle (3), cmd_rudder (4): the
                                                 SERVOn parameters sent as PARAM_VALUE
``air``              VFR_HUD, SCALED_PRESSURE    pitot_airspeed, cmd_throttle; pitot_qbar
``position``         GLOBAL_POSITION_INT         gps_pn .. gps_vd about ``origin``
``esc``              ESC_TELEMETRY_1_TO_4 ..     esc_rpm_<i> .. esc_temperature_<i>
``rpm``              RPM                         motor_speed
(1 Hz)               HEARTBEAT                   ``mav_type``, ArduPilot, mode ``custom_mode``
===================  ==========================  ============================================

A stream whose channels the log lacks is not sent. Times: ``time_boot_ms`` / ``time_usec``
are the log's times; each message arrives ``link_delay`` later on a clock starting at
``epoch`` [s since 1970].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from drake_uav.io.ardupilot_params import servo_mapping
from drake_uav.io.esc import CELSIUS_TO_KELVIN, RPM_TO_RAD_S, esc_channels
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.streams import ActuatorChannel
from drake_uav.model.geodesy import geodetic_from_ned

__all__ = ["SERVO_PARAMETERS", "TLOG_STREAMS", "write_tlog"]

TLOG_STREAMS = ("imu", "attitude", "commands", "air", "position", "esc", "rpm")
"""The streams :func:`write_tlog` sends, each at its own rate."""

SERVO_PARAMETERS: dict[str, float] = {
    **{f"SERVO{n}_{key}": value for n in (1, 2, 3, 4)
       for key, value in (("MIN", 1000.0), ("MAX", 2000.0), ("TRIM", 1500.0),
                          ("REVERSED", 0.0))},
    "SERVO1_FUNCTION": 4.0, "SERVO2_FUNCTION": 19.0, "SERVO3_FUNCTION": 70.0,
    "SERVO4_FUNCTION": 21.0, "SERVO3_TRIM": 1000.0,
}
"""The ArduPlane servo layout written: 1 aileron, 2 elevator, 3 throttle, 4 rudder,
1000..2000 us, surfaces trimmed at 1500 us."""

_G = 9.80665
_ARDUPILOT = 3
_MAV_STATE_ACTIVE = 4
_REAL32 = 9  # MAV_PARAM_TYPE_REAL32


def _pwm(channel: ActuatorChannel, command: np.ndarray) -> np.ndarray:
    """The PWM [us] that ``channel`` reads as ``command`` (the inverse of its mapping)."""
    demand = np.asarray(command, float) / channel.full_value
    low = channel.full_low if channel.full_low is not None else 2 * channel.neutral - \
        channel.full
    raw = np.where(demand >= 0.0, channel.neutral + demand * (channel.full - channel.neutral),
                   channel.neutral + demand * (channel.neutral - low))
    return np.rint(raw)


def _at(log: FlightLog, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(send times [s], indices of the log's latest samples at them) of a stream sent at
    ``rate_hz`` [Hz] from the log's first sample on."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rates: a rate must be positive and finite, got {rate_hz}")
    t = log.time
    grid = t[0] + np.arange(int(math.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1) / rate_hz
    return grid, np.clip(np.searchsorted(t, grid + 1e-9, side="right") - 1, 0, t.size - 1)


def _us(t: float) -> int:
    """A time [s] as MAVLink's time_usec (the boot clock; 0 before it starts)."""
    return max(0, int(round(t * 1e6)))


def _ms(t: float) -> int:
    """A time [s] as MAVLink's time_boot_ms."""
    return max(0, int(round(t * 1e3)))


def _int(values, low: float, high: float) -> np.ndarray:
    """Values rounded to integers inside a MAVLink field's range."""
    return np.clip(np.rint(values), low, high).astype(np.int64)


def write_tlog(log: FlightLog, path: str | Path, *, rates: Mapping[str, float] | None = None,
               deflections: Mapping[str, float] | None = None,
               origin: tuple[float, float, float] = (47.0, 8.0, 500.0), mav_type: int = 1,
               custom_mode: int = 0, link_delay: float = 0.02,
               epoch: float = 1.7e9, parameters: Mapping[str, float] | None = None) -> Path:
    """Writes ``log`` as a MAVLink 2 telemetry log of ArduPlane (module docstring).

    Args:
        log: the flight (canonical channels; those it lacks are not sent).
        path: the ``.tlog`` file to write.
        rates: stream (:data:`TLOG_STREAMS`) -> send rate [Hz]; a stream not named is sent
            at every sample of the log.
        deflections: surface ("elevator", "aileron", "rudder") -> deflection [rad] at full
            servo throw; 25 deg unless given (the reader's default).
        origin: latitude, longitude [deg], altitude [m] of the log's NED origin.
        mav_type: MAV_TYPE of the HEARTBEAT (1: fixed wing).
        custom_mode: ArduPilot mode number of the HEARTBEAT (0: MANUAL).
        link_delay: arrival time after the autopilot's time [s].
        epoch: arrival time of the log's time 0 [s since 1970].
        parameters: more parameters to send as PARAM_VALUE (``INS_POS1_X``, ...), beside
            :data:`SERVO_PARAMETERS`.

    Returns:
        The path written.

    Raises:
        ValueError: an unknown stream in ``rates`` or a rate that is not positive.
    """
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    rates = dict(rates or {})
    unknown = sorted(set(rates) - set(TLOG_STREAMS))
    if unknown:
        raise ValueError(f"rates: unknown stream(s) {', '.join(unknown)} (known: "
                         f"{', '.join(TLOG_STREAMS)})")
    deflections = {**dict.fromkeys(("elevator", "aileron", "rudder"), math.radians(25.0)),
                   **(deflections or {})}
    link = dialect.MAVLink(None, srcSystem=1, srcComponent=1)
    records: list[tuple[float, int, bytes]] = []

    def send(t: float, message) -> None:
        records.append((t + link_delay, len(records), message))

    def indices(stream: str) -> list[tuple[float, int]]:
        """(send time [s], sample index) of each message of ``stream``."""
        if stream not in rates:
            return list(zip(log.time.tolist(), range(log.time.size), strict=True))
        return list(zip(*_at(log, rates[stream]), strict=True))

    for t in _at(log, 1.0)[0]:
        send(t, link.heartbeat_encode(mav_type, _ARDUPILOT, 0, custom_mode,
                                         _MAV_STATE_ACTIVE))
    sent = {**SERVO_PARAMETERS, **(parameters or {})}
    for i, (name, value) in enumerate(sent.items()):
        send(log.time[0], link.param_value_encode(name.encode(), value, _REAL32, len(sent), i))
    has = set(log.names)
    if {"imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r"} <= has:
        acc = [_int(log[c] * 1000.0 / _G, -32768, 32767) for c in ("imu_ax", "imu_ay", "imu_az")]
        gyro = [_int(log[c] * 1000.0, -32768, 32767) for c in ("imu_p", "imu_q", "imu_r")]
        for t, k in indices("imu"):
            send(t, link.raw_imu_encode(_us(t), *(int(a[k]) for a in acc),
                                           *(int(g[k]) for g in gyro), 0, 0, 0, 0, 0))
    if {"att_roll", "att_pitch", "att_yaw"} <= has:
        for t, k in indices("attitude"):
            send(t, link.attitude_encode(_ms(t), log["att_roll"][k],
                                            log["att_pitch"][k], log["att_yaw"][k], 0, 0, 0))
    _commands(log, send, indices("commands"), deflections, link, has)
    _air(log, send, indices("air"), link, has, origin)
    _position(log, send, indices("position"), link, has, origin)
    _esc(log, send, indices("esc"), link)
    if "motor_speed" in has:
        for t, k in indices("rpm"):
            send(t, link.rpm_encode(log["motor_speed"][k] / RPM_TO_RAD_S, -1.0))
    records.sort(key=lambda r: (r[0], r[1]))
    out = bytearray()
    for arrival, _, message in records:
        out += int(round((epoch + arrival) * 1e6)).to_bytes(8, "big")
        out += message.pack(link)
        link.seq = (link.seq + 1) % 256
    path = Path(path)
    path.write_bytes(bytes(out))
    return path


def _commands(log, send, index, deflections, link, has) -> None:
    """SERVO_OUTPUT_RAW of the ``cmd_*`` channels through :data:`SERVO_PARAMETERS`."""
    mapping, _ = servo_mapping(SERVO_PARAMETERS, deflections, "write_tlog")
    servos = {int(channel.field[1:]): (command, channel)
              for command, channel in mapping.channels().items() if command in has}
    if not servos:
        return
    pwm = {n: _int(_pwm(channel, log[command]), 0, 65535)
           for n, (command, channel) in servos.items()}
    for t, k in index:
        outputs = [int(pwm[n][k]) if n in pwm else 0 for n in range(1, 9)]
        send(t, link.servo_output_raw_encode(_us(t) % 2**32, 0, *outputs))


def _air(log, send, index, link, has, origin) -> None:
    """VFR_HUD (airspeed, throttle, altitude) and SCALED_PRESSURE (pitot_qbar)."""
    if "pitot_airspeed" in has:
        throttle = (_int(100.0 * log["cmd_throttle"], 0, 100) if "cmd_throttle" in has
                    else np.zeros(log.time.size, np.int64))
        alt = origin[2] - (log["gps_pd"] if "gps_pd" in has else 0.0 * log.time)
        for t, k in index:
            send(t, link.vfr_hud_encode(log["pitot_airspeed"][k], 0.0, 0, int(throttle[k]),
                                        float(alt[k]), 0.0))
    if "pitot_qbar" in has:
        for t, k in index:
            send(t, link.scaled_pressure_encode(_ms(t), 1013.25, log["pitot_qbar"][k] / 100.0,
                                                2000))


def _position(log, send, index, link, has, origin) -> None:
    """GLOBAL_POSITION_INT of gps_pn .. gps_vd."""
    names = ("gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve", "gps_vd")
    if not set(names) <= has:
        return
    lat, lon, alt = geodetic_from_ned(log["gps_pn"], log["gps_pe"], log["gps_pd"], origin)
    lat, lon = _int(np.asarray(lat) * 1e7, -2**31, 2**31 - 1), _int(np.asarray(lon) * 1e7,
                                                                     -2**31, 2**31 - 1)
    alt_mm = _int(np.asarray(alt) * 1e3, -2**31, 2**31 - 1)
    vel = [_int(log[c] * 100.0, -32768, 32767) for c in ("gps_vn", "gps_ve", "gps_vd")]
    for t, k in index:
        send(t, link.global_position_int_encode(
            _ms(t), int(lat[k]), int(lon[k]), int(alt_mm[k]),
            int(alt_mm[k] - round(origin[2] * 1e3)), *(int(v[k]) for v in vel), 0))


def _esc(log, send, index, link) -> None:
    """ESC_TELEMETRY_1_TO_4 (.. _9_TO_12) of the esc_* channels."""
    escs = esc_channels(log)
    blocks = sorted({i // 4 for i in escs if i < 12})
    zeros = np.zeros(log.time.size)

    def column(i, quantity, scale, offset=0.0):
        name = escs.get(i, {}).get(quantity)
        return zeros if name is None else (log[name] - offset) * scale

    for block in blocks:
        encode = getattr(link, f"esc_telemetry_{4 * block + 1}_to_{4 * block + 4}_encode")
        ids = range(4 * block, 4 * block + 4)
        temp = [_int(column(i, "temperature", 1.0, CELSIUS_TO_KELVIN), 0, 255) for i in ids]
        volt = [_int(column(i, "voltage", 100.0), 0, 65535) for i in ids]
        curr = [_int(column(i, "current", 100.0), 0, 65535) for i in ids]
        rpm = [_int(column(i, "rpm", 1.0 / RPM_TO_RAD_S), 0, 65535) for i in ids]
        for t, k in index:
            send(t, encode([int(x[k]) for x in temp], [int(x[k]) for x in volt],
                                     [int(x[k]) for x in curr], [0, 0, 0, 0],
                                     [int(x[k]) for x in rpm], [0, 0, 0, 0]))
