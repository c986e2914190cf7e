"""A simulated fixed-wing flight as an ArduPlane 4.5 DataFlash ``.bin`` log.

:func:`write_ardupilot_log` writes what ArduPlane would log of the flight, its ground
segment and its take-off (:func:`drake_uav.io.realistic_logs.extend_flight`), with
ArduPlane 4.x message layouts (as pymavlink reads them):

=========  ========  ================================================================
message    rate      content
=========  ========  ================================================================
PARM       start     SERVO1..14 FUNCTION/MIN/MAX/TRIM/REVERSED and a few others
MSG        events    firmware string "ArduPlane V4.5.7 (...)", GPS, EKF, arming
MODE       changes   MANUAL (0) on the ground, TAKEOFF (13), FBWA (5) in the flight
ARM, EV    arming    ArmState 1, event 10 (armed)
IMU        50 Hz     instance I = 0; rad/s, m/s^2
ATT        50 Hz     centidegrees (Roll, Pitch int16; Yaw uint16 0..36000)
GPS        5 Hz      Status 1 (no fix, Lat = Lng = 0) until the fix, then 3; Lat/Lng 1e-7 deg
ORGN       once      EKF origin (Type 0) and home (Type 1) after the fix
ARSP       10 Hz     Airspeed >= 0 (ArduPilot takes the root of abs(pressure)), DiffPress
BARO       10 Hz     Alt above the boot altitude
RCOU       100 Hz    PWM of every output through the SERVOn parameters; 0 before arming
AETR       100 Hz    demands: Ail, Elev, Rudd -4500..4500 (roll right, pitch up, yaw right),
                     Thr 0..100
XKF2       1 Hz      wind estimate VWN, VWE (sparse on purpose: an optional stream)
RPM        10 Hz     only when the flight has ``motor_speed`` (``profile.shaft_speed``
                     "rpm")
ESC        10 Hz     instead of RPM with ``profile.shaft_speed`` "esc": Instance 0, RPM,
                     Volt and Curr 0 (an ESC without those sensors), Temp 40 deg C
=========  ========  ================================================================

Servos: SERVO1 aileron (4), SERVO2 elevator (19, REVERSED = 1), SERVO3 throttle (70),
SERVO4 rudder (21), SERVO5..14 disabled (0); MIN/MAX 1100/1900 us (+-400 us),
TRIM 1500 (throttle 1100). A demand of +-4500 (full throw MAX - TRIM or TRIM - MIN)
is the aircraft's limit deflection of that surface. No truth channel, no vane angle,
no simulation metadata goes into the file.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import FlightLog
from drake_uav.io.realistic_logs import (
    ORIGIN,
    ExtendedFlight,
    LogProfile,
    WrittenLog,
    extend_flight,
    save_log,
)
from drake_uav.io.writers import DataFlashWriter
from drake_uav.model.geodesy import geodetic_from_ned
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["write_ardupilot_log", "ArduPilotServo", "SERVOS", "FIRMWARE", "servo_pwm"]

FIRMWARE = "ArduPlane V4.5.7 (2ea2e5ba)"
"""The firmware string of the MSG message at the start of the log."""
_BLOCK = 4096  # SD-card block [bytes]
_FUNCTION = {"aileron": 4, "elevator": 19, "rudder": 21, "throttle": 70}
_MODES = {"MANUAL": 0, "FBWA": 5, "TAKEOFF": 13}


@dataclasses.dataclass(frozen=True)
class ArduPilotServo:
    """One servo output's parameters (SERVOn_FUNCTION/MIN/MAX/TRIM/REVERSED)."""

    function: str | None
    """"aileron", "elevator", "rudder", "throttle" or None (disabled, function 0)."""
    min: int = 1100
    max: int = 1900
    trim: int = 1500
    reversed: bool = False

    def parameters(self, n: int) -> dict[str, float]:
        return {f"SERVO{n}_FUNCTION": float(_FUNCTION.get(self.function, 0)),
                f"SERVO{n}_MIN": float(self.min), f"SERVO{n}_MAX": float(self.max),
                f"SERVO{n}_TRIM": float(self.trim),
                f"SERVO{n}_REVERSED": float(self.reversed)}


SERVOS = (ArduPilotServo("aileron"), ArduPilotServo("elevator", reversed=True),
          ArduPilotServo("throttle", trim=1100), ArduPilotServo("rudder"),
          *(ArduPilotServo(None) for _ in range(10)))
"""SERVO1..14 of the written logs."""


def servo_pwm(servo: ArduPilotServo, demand: np.ndarray) -> np.ndarray:
    """PWM [us] of a normalised demand: surfaces -1..1 (ArduPilot's +-4500), throttle 0..1.

    As ArduPilot's servo output: a reversed servo negates the demand; a surface's
    positive demand spans TRIM..MAX, a negative one TRIM..MIN; throttle spans MIN..MAX.
    Rounded to whole microseconds.
    """
    if servo.function == "throttle":
        span = np.clip(demand, 0.0, 1.0) * (servo.max - servo.min)
        return np.round(servo.max - span if servo.reversed else servo.min + span)
    x = -demand if servo.reversed else demand
    throw = np.where(x > 0.0, servo.max - servo.trim, servo.trim - servo.min)
    return np.round(servo.trim + np.clip(x, -1.0, 1.0) * throw)


def _parameters(flight: ExtendedFlight) -> dict[str, float]:
    """The PARM messages: servos, airspeed sensor, EKF, logging and trim settings."""
    out = {"FORMAT_VERSION": 16.0, "SYSID_THISMAV": 1.0, "Q_ENABLE": 0.0,
           "SCHED_LOOP_RATE": 50.0, "LOG_BITMASK": 65535.0, "AHRS_EKF_TYPE": 3.0,
           "EK3_ENABLE": 1.0, "ARSPD_TYPE": 1.0, "ARSPD_USE": 1.0, "ARSPD_RATIO": 2.0,
           "TRIM_ARSPD_CM": float(round(100 * np.median(
               np.abs(flight.channels["pitot_airspeed"][flight.time >= flight.phases.flight_s])))),
           "THR_MAX": 100.0, "THR_MIN": 0.0, "INS_GYRO_FILTER": 20.0,
           "RPM1_TYPE": 2.0 if _shaft_speed_message(flight) == "RPM" else 0.0}
    for n, servo in enumerate(SERVOS, start=1):
        out.update(servo.parameters(n))
    return out


def _shaft_speed_message(flight: ExtendedFlight) -> str | None:
    """``RPM``, ``ESC`` or None: the message of the flight's ``motor_speed``."""
    if "motor_speed" not in flight.channels:
        return None
    return "RPM" if flight.profile.shaft_speed == "rpm" else "ESC"


def _define(w: DataFlashWriter, shaft_speed: str | None) -> None:
    """The FMT messages (ArduPlane 4.x layouts)."""
    w.define("PARM", "QNff", "TimeUS,Name,Value,Default")
    w.define("MSG", "QZ", "TimeUS,Message")
    w.define("MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn")
    w.define("ARM", "QBIBB", "TimeUS,ArmState,ArmChecks,Forced,Method")
    w.define("EV", "QB", "TimeUS,Id")
    w.define("IMU", "QBffffffIIfBBHH",
             "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz")
    w.define("ATT", "QccccCCCCB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,"
             "ErrYaw,AEKF")
    w.define("GPS", "QBBIHBcLLeffffB",
             "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw,U")
    w.define("ORGN", "QBLLe", "TimeUS,Type,Lat,Lng,Alt")
    w.define("ARSP", "QBffcffBBfB",
             "TimeUS,I,Airspeed,DiffPress,Temp,RawPress,Offset,U,H,Hfp,Pri")
    w.define("BARO", "QBffcfIffB", "TimeUS,I,Alt,Press,Temp,CRt,SMS,Offset,GndTemp,Health")
    w.define("RCOU", "QHHHHHHHHHHHHHH", "TimeUS," + ",".join(f"C{i}" for i in range(1, 15)))
    w.define("AETR", "Qffffff", "TimeUS,Ail,Elev,Thr,Rudd,Flap,SS")
    w.define("XKF2", "QBccccchhhhhhfff",
             "TimeUS,C,AX,AY,AZ,VWN,VWE,MN,ME,MD,MX,MY,MZ,IDX,IDY,IS")
    if shaft_speed == "RPM":
        w.define("RPM", "QBf", "TimeUS,I,RPM")
    elif shaft_speed == "ESC":
        w.define("ESC", "QBffffcfcf", "TimeUS,Instance,RPM,RawRPM,Volt,Curr,Temp,CTot,MotTemp,"
                 "Err")


def _events(w: DataFlashWriter, flight: ExtendedFlight) -> None:
    """PARM, MSG, MODE, ARM and EV messages of the log's phases."""
    ph, us = flight.phases, lambda t: np.uint64(round(t * 1e6))
    start = us(flight.time[0])
    params = _parameters(flight)
    w.add("PARM", TimeUS=start, Name=np.array(list(params)), Value=np.array(list(params.values())),
          Default=np.array(list(params.values())))
    texts = [(start, FIRMWARE), (start, "ChibiOS: 6a85082c"),
             (start, "CubeOrange 003F0033 31395114 34363831"), (start, "RCOut: PWM:1-14"),
             (us(flight.time[0] + 3.0), "GPS 1: detected as u-blox at 230400 baud"),
             (us(ph.gps_fix_s + 2.0), "EKF3 IMU0 origin set"),
             (us(ph.arm_s), "Throttle armed"), (us(ph.flight_s), "Takeoff complete")]
    for time, text in texts:
        w.add("MSG", TimeUS=time, Message=text)
    for time, mode, reason in ((start, "MANUAL", 26), (us(ph.takeoff_s), "TAKEOFF", 2),
                               (us(ph.flight_s), "FBWA", 1)):
        w.add("MODE", TimeUS=time, Mode=_MODES[mode], ModeNum=_MODES[mode], Rsn=reason)
    w.add("ARM", TimeUS=us(ph.arm_s), ArmState=1, ArmChecks=0xFFFFFFFF, Forced=0, Method=0)
    w.add("EV", TimeUS=us(ph.arm_s), Id=10)


def _inertial(w: DataFlashWriter, flight: ExtendedFlight) -> None:
    """IMU and ATT at the IMU rate."""
    i = flight.indices(flight.profile.imu_rate_hz)
    ch, t = flight.channels, flight.time_us(i)
    w.add("IMU", TimeUS=t, I=0, GyrX=ch["imu_p"][i], GyrY=ch["imu_q"][i], GyrZ=ch["imu_r"][i],
          AccX=ch["imu_ax"][i], AccY=ch["imu_ay"][i], AccZ=ch["imu_az"][i], T=35.0, GH=1,
          AH=1, GHz=1000, AHz=1000)
    roll, pitch = np.degrees(ch["att_roll"][i]), np.degrees(ch["att_pitch"][i])
    yaw = np.degrees(ch["att_yaw"][i]) % 360.0
    w.add("ATT", TimeUS=t, DesRoll=roll, Roll=roll, DesPitch=pitch, Pitch=pitch, DesYaw=yaw,
          Yaw=yaw, ErrRP=0.02, ErrYaw=0.05, AEKF=3)


def _gps(w: DataFlashWriter, flight: ExtendedFlight) -> None:
    """GPS from its detection 3 s into the log; no fix (Lat = Lng = 0) before the fix."""
    i = flight.indices(flight.profile.gps_rate_hz)
    i = i[flight.time[i] >= flight.time[0] + 3.0]
    ch, t = flight.channels, flight.time_us(i)
    fixed = flight.gps_fixed()[i]
    lat, lon, alt = geodetic_from_ned(ch["gps_pn"][i], ch["gps_pe"][i], ch["gps_pd"][i],
                                      ORIGIN)
    vn, ve = ch["gps_vn"][i], ch["gps_ve"][i]
    week_ms = (310_000_000 + t // 1000) % 604_800_000
    w.add("GPS", TimeUS=t, I=0, Status=np.where(fixed, 3, 1), GMS=week_ms, GWk=2395,
          NSats=np.where(fixed, 14, 3), HDop=np.where(fixed, 0.8, 99.99),
          Lat=np.where(fixed, lat, 0.0), Lng=np.where(fixed, lon, 0.0),
          Alt=np.where(fixed, alt, 0.0), Spd=np.where(fixed, np.hypot(vn, ve), 0.0),
          GCrs=np.where(fixed, np.degrees(np.arctan2(ve, vn)) % 360.0, 0.0),
          VZ=np.where(fixed, ch["gps_vd"][i], 0.0), U=1)
    k = int(np.searchsorted(flight.time, flight.phases.gps_fix_s + 2.0))
    origin = geodetic_from_ned(ch["gps_pn"][k], ch["gps_pe"][k], ch["gps_pd"][k], ORIGIN)
    for kind in (0, 1):
        w.add("ORGN", TimeUS=flight.time_us(np.array([k])), Type=kind, Lat=origin[0],
              Lng=origin[1], Alt=origin[2])


def _air_data(w: DataFlashWriter, flight: ExtendedFlight) -> None:
    """ARSP, BARO, the 1 Hz XKF2 wind estimate and RPM or ESC."""
    ch, p = flight.channels, flight.profile
    i = flight.indices(p.airspeed_rate_hz)
    w.add("ARSP", TimeUS=flight.time_us(i), I=0, Airspeed=np.abs(ch["pitot_airspeed"][i]),
          DiffPress=ch["pitot_qbar"][i], Temp=25.0, RawPress=ch["pitot_qbar"][i] + 1.7,
          Offset=1.7, U=1, H=1, Hfp=1.0, Pri=0)
    i = flight.indices(p.baro_rate_hz)
    alt = ch["baro_alt"][i]
    pressure = 95_500.0 - flight.params.rho * flight.params.gravity * alt  # hydrostatic
    w.add("BARO", TimeUS=flight.time_us(i), I=0, Alt=alt, Press=pressure, Temp=25.0,
          CRt=-ch["gps_vd"][i], SMS=flight.time_us(i) // 1000, GndTemp=25.0, Health=1)
    i = flight.indices(p.optional_rate_hz)
    north, east = flight.wind_estimate()
    w.add("XKF2", TimeUS=flight.time_us(i), C=0, VWN=north[i], VWE=east[i])
    message = _shaft_speed_message(flight)
    if message is not None:
        i = flight.indices(p.shaft_speed_rate_hz)
        rpm = ch["motor_speed"][i] * 60.0 / (2.0 * np.pi)
        if message == "RPM":
            w.add("RPM", TimeUS=flight.time_us(i), I=0, RPM=rpm)
        else:
            w.add("ESC", TimeUS=flight.time_us(i), Instance=0, RPM=rpm, RawRPM=rpm, Volt=0.0,
                  Curr=0.0, Temp=40, CTot=0.0, MotTemp=0, Err=0.0)


def _outputs(w: DataFlashWriter, flight: ExtendedFlight) -> None:
    """RCOU through the servo parameters (0 before arming) and the AETR demands."""
    i = flight.indices(flight.profile.command_rate_hz)
    demand = {s: flight.demand(s)[i] for s in ("aileron", "elevator", "rudder")}
    demand["throttle"] = np.clip(flight.channels["cmd_throttle"][i], 0.0, 1.0)
    armed = flight.armed()[i]
    pwm = {}
    for n, servo in enumerate(SERVOS, start=1):
        if servo.function is not None:
            pwm[f"C{n}"] = np.where(armed, servo_pwm(servo, demand[servo.function]), 0.0)
    t = flight.time_us(i)
    w.add("RCOU", TimeUS=t, **pwm)
    w.add("AETR", TimeUS=t, Ail=4500.0 * demand["aileron"], Elev=4500.0 * demand["elevator"],
          Thr=100.0 * demand["throttle"], Rudd=4500.0 * demand["rudder"])


def write_ardupilot_log(log: FlightLog, path: str | Path, *, seed: int,
                        aircraft: str | FixedWingParams | None = None,
                        profile: LogProfile | None = None) -> WrittenLog:
    """Writes a simulated flight as an ArduPlane 4.5 ``.bin`` log (see the module).

    Args:
        log: a simulated fixed-wing flight (:func:`drake_uav.diagrams.fly`).
        path: the ``.bin`` to write.
        seed: noise of the synthesised ground and take-off; the same seed gives the
            same bytes.
        aircraft: the aircraft flown (default the log's ``metadata["aircraft"]``).
        profile: timing and rates (default :class:`LogProfile`).

    Returns:
        The path and the phases in the log's time (s since boot).
    """
    flight = extend_flight(log, aircraft, profile, seed=seed)
    w = DataFlashWriter()
    _define(w, _shaft_speed_message(flight))
    for part in (_events, _inertial, _gps, _air_data, _outputs):
        part(w, flight)
    return save_log(w, flight, path, _BLOCK)
