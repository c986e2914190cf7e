"""Canonical FlightLogs as ArduPilot DataFlash (``.bin``) and PX4 ULog (``.ulg``) files.

The writers live in :mod:`drake_uav.io.writers` (re-exported here for the tests that
import them from this module); the converters below write every canonical channel
at one rate, vanes included, for reader tests. Realistic autopilot logs (ground
segment, late GPS, servo parameters, ...) come from :mod:`drake_uav.io.realistic_logs`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from drake_uav.io.writers import DataFlashWriter, ULogWriter
from drake_uav.model.geodesy import geodetic_from_ned

__all__ = ["DataFlashWriter", "ULogWriter", "px4_imu_writer", "ORIGIN", "FULL_DEFLECTION",
           "dataflash_from_log", "grouped_csv_from_log", "ulog_from_log"]

# ------------------------------------------------- canonical FlightLog -> native logs
ORIGIN = (47.0, 8.0, 500.0)
"""Latitude, longitude [deg], altitude [m] of the NED origin in the converted logs."""
FULL_DEFLECTION = math.radians(25.0)
"""Surface deflection at full PWM / full normalised demand in the converted logs [rad]."""


def _lat_lon_alt(log):
    """Latitude, longitude [deg] and altitude [m] of ``gps_pn/pe/pd`` about :data:`ORIGIN`."""
    return geodetic_from_ned(log["gps_pn"], log["gps_pe"], log["gps_pd"], ORIGIN)


def dataflash_from_log(log, path, max_deflection: float = FULL_DEFLECTION,
                       parameters: dict[str, float] | None = None) -> Path:
    """An ArduPilot ``.bin`` of a FlightLog with the canonical channels (one rate).

    Vanes go to a ``VANE`` message (fields ``AoA``, ``SSA`` in deg); surfaces to
    RCOU C1 aileron, C2 elevator (PWM above trim = nose-up = negative elevator),
    C3 throttle (1100..1900), C4 rudder (PWM above trim = negative rudder), with
    ``max_deflection`` [rad] (default 25 deg) at +-500 us. ``parameters`` go to PARM
    messages at the start.
    """
    w = DataFlashWriter()
    if parameters:
        w.define("PARM", "QNff", "TimeUS,Name,Value,Default")
        values = np.array(list(parameters.values()), dtype=float)
        w.add("PARM", TimeUS=np.uint64(round(log.time[0] * 1e6)),
              Name=np.array(list(parameters)), Value=values, Default=values)
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


def px4_imu_writer() -> ULogWriter:
    """A PX4 ULog writer with the IMU (``sensor_combined``) and attitude
    (``vehicle_attitude``) topics defined."""
    w = ULogWriter()
    w.info("sys_name", "PX4")
    w.format("sensor_combined", "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
             "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;"
             "uint32_t accelerometer_integral_dt")
    w.format("vehicle_attitude", "uint64_t timestamp;uint64_t timestamp_sample;float[4] q")
    return w


def ulog_from_log(log, path, parameters: dict[str, float] | None = None) -> Path:
    """A PX4 ``.ulg`` of a FlightLog with the canonical channels (one rate).

    Attitude as a quaternion, positions and velocities in ``vehicle_local_position``,
    surfaces as normalised ``actuator_controls_0`` (roll, pitch, yaw demand in
    -1..1 for 25 deg, throttle 0..1), vanes in a ``vane_angles`` topic [rad];
    ``parameters`` as the log's initial parameters.
    """
    from drake_uav.model.rotations import euler_to_quat

    w = px4_imu_writer()
    for name, value in (parameters or {}).items():
        w.parameter(name, value)
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


def grouped_csv_from_log(log, path, rates: dict[str, float]) -> Path:
    """A CSV of a FlightLog with a time column per group (the export layout of
    drake_uav.io.csv_log): ``time`` (the IMU and every channel but the commands and GPS),
    ``time_commands`` (cmd_*) and ``time_gps`` (gps_*), each group's samples every
    ``1 / rates[group]`` s (groups "imu", "commands", "gps"), shorter groups padded with
    empty cells."""
    groups = {"imu": [n for n in log.measured_names if not n.startswith(("cmd_", "gps_"))],
              "commands": [n for n in log.measured_names if n.startswith("cmd_")],
              "gps": [n for n in log.measured_names if n.startswith("gps_")]}
    step = 1.0 / float(np.median(np.diff(log.time)))
    header, columns = [], []
    for group, names in groups.items():
        if not names:
            continue
        index = np.arange(0, log.time.size, max(1, int(round(step / rates[group]))))
        header += ["time [s]" if group == "imu" else f"time_{group} [s]",
                   *(f"{n} [{log.unit(n)}]" for n in names)]
        columns += [log.time[index], *(log[n][index] for n in names)]
    rows = max(c.size for c in columns)
    lines = [",".join("" if i >= c.size else repr(float(c[i])) for c in columns)
             for i in range(rows)]
    path = Path(path)
    path.write_text(",".join(header) + "\n" + "\n".join(lines) + "\n")
    return path
