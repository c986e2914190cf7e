"""A simulated fixed-wing flight as a PX4 1.14 ULog ``.ulg``.

:func:`write_px4_log` writes what PX4 v1.14 would log of the flight, its ground
segment and its take-off (:func:`drake_uav.io.realistic_logs.extend_flight`):

======================  ========  =======================================================
topic                   rate      content
======================  ========  =======================================================
sensor_combined         50 Hz     gyro_rad, accelerometer_m_s2 (body FRD)
vehicle_attitude        50 Hz     q (w, x, y, z), body FRD -> NED
vehicle_local_position  10 Hz     x y z vx vy vz about the EKF origin (set at the GPS
                                  fix); xy_valid = v_xy_valid = 0 before the fix
vehicle_gps_position    5 Hz      lat/lon 1e-7 deg, alt mm; fix_type 0 until the fix, 3
airspeed                10 Hz     indicated/true airspeed (negative on the ground when the
                                  pressure is)
differential_pressure   1 Hz      differential_pressure_pa (sparse on purpose: optional)
wind                    1 Hz      windspeed_north/east estimate (sparse on purpose)
vehicle_air_data        10 Hz     baro_alt_meter (above mean sea level)
actuator_servos         100 Hz    control[0..3] left aileron, right aileron, elevator,
                                  rudder, -1..1 (PX4: trailing edge up / right positive)
actuator_motors         100 Hz    control[0] throttle 0..1, unused motors NaN
actuator_outputs        10 Hz     PWM [us] through PWM_MAIN_*; 0 on every output before
                                  arming
vehicle_status          1 Hz      nav_state MANUAL (0) on the ground, AUTO_TAKEOFF (17),
                                  STAB (15) in the flight; arming_state; vehicle_type 2
rpm                     10 Hz     only when the flight has ``motor_speed`` (``profile.shaft_speed``
                                  "rpm")
esc_status              10 Hz     instead of rpm with ``profile.shaft_speed`` "esc": esc_count 1,
                                  esc[0].esc_rpm, voltage and current 0, temperature 40 deg C
======================  ========  =======================================================

Parameters: MAV_TYPE 1 (fixed wing), CA_AIRFRAME 1, CA_SV_CS_COUNT 4 with CA_SV_CS0..3_TYPE
1, 2, 3, 4 (left aileron, right aileron, elevator, rudder) and their torques,
PWM_MAIN_FUNC1 101 (motor 1), PWM_MAIN_FUNC2..5 201..204 (servos 1..4),
PWM_MAIN_MIN/MAX 1100/1900 us, PWM_MAIN_DIS 0, PWM_MAIN_REV bit 4 (the rudder output
reversed). A servo control of +-1 is the aircraft's limit deflection of that surface.
Info: ver_sw_release v1.14.3 (0x010E03FF), sys_name PX4. No truth channel, no vane
angle, no simulation metadata goes into the file.
"""

from __future__ import annotations

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
from drake_uav.io.writers import ULogWriter
from drake_uav.model.geodesy import geodetic_from_ned
from drake_uav.model.rotations import euler_to_quat
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["write_px4_log", "VER_SW_RELEASE", "SERVO_TYPES", "PWM_REVERSED_OUTPUT"]

VER_SW_RELEASE = 0x010E03FF
_ESC_REPORT = ("uint64_t timestamp;int32_t esc_rpm;float esc_voltage;float esc_current;"
               "float esc_temperature;uint16_t failures;int8_t esc_errorcount;uint8_t esc_address")
"""The nested ``esc_report`` of ``esc_status`` (PX4 1.14)."""
"""PX4 v1.14.3, release build (major, minor, patch, type 0xFF)."""
SERVO_TYPES = (1, 2, 3, 4)
"""CA_SV_CS0..3_TYPE: left aileron, right aileron, elevator, rudder."""
PWM_REVERSED_OUTPUT = 5
"""MAIN output (1-based) whose PWM is reversed (PWM_MAIN_REV bit 4): the rudder."""
_NAV = {"MANUAL": 0, "STAB": 15, "AUTO_TAKEOFF": 17}

_TOPICS = {
    "sensor_combined": "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
    "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;"
    "uint32_t accelerometer_integral_dt;uint8_t accelerometer_clipping;uint8_t gyro_clipping;"
    "uint8_t accel_calibration_count;uint8_t gyro_calibration_count",
    "vehicle_attitude": "uint64_t timestamp;uint64_t timestamp_sample;float[4] q;"
    "float[4] delta_q_reset;uint8_t quat_reset_counter",
    "vehicle_local_position": "uint64_t timestamp;uint64_t timestamp_sample;"
    "uint64_t ref_timestamp;double ref_lat;double ref_lon;float x;float y;float z;float vx;"
    "float vy;float vz;float z_deriv;float heading;float ref_alt;float eph;float epv;"
    "bool xy_valid;bool z_valid;bool v_xy_valid;bool v_z_valid;bool xy_global;bool z_global;"
    "bool dead_reckoning",
    "vehicle_gps_position": "uint64_t timestamp;uint64_t timestamp_sample;uint64_t time_utc_usec;"
    "uint32_t device_id;int32_t lat;int32_t lon;int32_t alt;int32_t alt_ellipsoid;"
    "float s_variance_m_s;float c_variance_rad;float eph;float epv;float hdop;float vdop;"
    "float vel_m_s;float vel_n_m_s;float vel_e_m_s;float vel_d_m_s;float cog_rad;"
    "uint8_t fix_type;bool vel_ned_valid;uint8_t satellites_used",
    "airspeed": "uint64_t timestamp;uint64_t timestamp_sample;float indicated_airspeed_m_s;"
    "float true_airspeed_m_s;float air_temperature_celsius;float confidence",
    "differential_pressure": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;"
    "float differential_pressure_pa;float temperature;uint32_t error_count",
    "wind": "uint64_t timestamp;uint64_t timestamp_sample;float windspeed_north;"
    "float windspeed_east;float variance_north;float variance_east;float tas_innov;"
    "float tas_innov_var;float beta_innov;float beta_innov_var",
    "vehicle_air_data": "uint64_t timestamp;uint64_t timestamp_sample;uint32_t baro_device_id;"
    "float baro_alt_meter;float baro_temp_celcius;float baro_pressure_pa;float rho;"
    "uint8_t calibration_count",
    "actuator_servos": "uint64_t timestamp;uint64_t timestamp_sample;float[8] control",
    "actuator_motors": "uint64_t timestamp;uint64_t timestamp_sample;float[12] control;"
    "uint16_t reversible_flags",
    "actuator_outputs": "uint64_t timestamp;uint32_t noutputs;float[16] output",
    "vehicle_status": "uint64_t timestamp;uint64_t armed_time;uint64_t takeoff_time;"
    "uint64_t nav_state_timestamp;uint8_t arming_state;uint8_t nav_state;"
    "uint8_t vehicle_type;bool is_vtol;bool is_vtol_tailsitter;bool in_transition_mode;"
    "bool in_transition_to_fw;bool failsafe;uint8_t system_type;uint8_t system_id;"
    "uint8_t component_id",
    "rpm": "uint64_t timestamp;float indicated_frequency_rpm;float estimated_accurancy_rpm",
    "esc_status": "uint64_t timestamp;uint16_t counter;uint8_t esc_count;"
    "uint8_t esc_connectiontype;uint8_t esc_online_flags;uint8_t esc_armed_flags;"
    "esc_report[8] esc",
}


def _parameters(w: ULogWriter) -> None:
    """MAV_TYPE, control allocation (CA_*) and output (PWM_MAIN_*) parameters."""
    values: dict[str, int | float] = {"MAV_TYPE": 1, "SYS_AUTOSTART": 2100, "CA_AIRFRAME": 1,
                                      "CA_SV_CS_COUNT": len(SERVO_TYPES), "FW_ARSP_MODE": 0,
                                      "SYS_HAS_NUM_ASPD": 1, "IMU_GYRO_RATEMAX": 400}
    torques = ({"TRQ_R": -0.5}, {"TRQ_R": 0.5}, {"TRQ_P": 1.0}, {"TRQ_Y": 1.0})
    for i, (kind, torque) in enumerate(zip(SERVO_TYPES, torques, strict=True)):
        values[f"CA_SV_CS{i}_TYPE"] = kind
        values.update({f"CA_SV_CS{i}_{k}": v for k, v in torque.items()})
    for n in range(1, 9):
        function = 101 if n == 1 else 200 + n - 1 if n <= 1 + len(SERVO_TYPES) else 0
        values.update({f"PWM_MAIN_FUNC{n}": function, f"PWM_MAIN_MIN{n}": 1100,
                       f"PWM_MAIN_MAX{n}": 1900, f"PWM_MAIN_DIS{n}": 0,
                       f"PWM_MAIN_FAIL{n}": 0})
    values["PWM_MAIN_REV"] = 1 << (PWM_REVERSED_OUTPUT - 1)
    for name, value in values.items():
        w.parameter(name, value)


def _status(w: ULogWriter, ids: dict, flight: ExtendedFlight) -> None:
    """vehicle_status at 1 Hz and at every change; logged text of the events."""
    ph = flight.phases
    times = np.union1d(flight.time[flight.indices(1.0)],
                       [ph.arm_s, ph.takeoff_s, ph.flight_s])
    nav = np.select([times >= ph.flight_s, times >= ph.takeoff_s],
                    [_NAV["STAB"], _NAV["AUTO_TAKEOFF"]], _NAV["MANUAL"])
    changed = np.select([times >= ph.flight_s, times >= ph.takeoff_s], [ph.flight_s,
                        ph.takeoff_s], times[0])
    us = np.round(times * 1e6).astype(np.uint64)
    armed = times >= ph.arm_s
    w.data("vehicle_status", ids["vehicle_status"], timestamp=us,
           armed_time=np.where(armed, round(ph.arm_s * 1e6), 0),
           takeoff_time=np.where(times >= ph.takeoff_s, round(ph.takeoff_s * 1e6), 0),
           nav_state_timestamp=np.round(changed * 1e6), arming_state=np.where(armed, 2, 1),
           nav_state=nav, vehicle_type=2, system_type=1, system_id=1, component_id=1)
    for time, text in ((ph.gps_fix_s, "[ekf2] GPS checks passed"),
                       (ph.arm_s, "[commander] Armed by RC"),
                       (ph.takeoff_s, "[navigator] Takeoff to 100.0 meters above home"),
                       (ph.flight_s, "[navigator] Takeoff complete")):
        w.text(round(time * 1e6), text)


def _inertial(w: ULogWriter, ids: dict, flight: ExtendedFlight) -> None:
    """sensor_combined and vehicle_attitude at the IMU rate."""
    i = flight.indices(flight.profile.imu_rate_hz)
    ch, us = flight.channels, flight.time_us(i)
    period = round(1e6 / flight.profile.imu_rate_hz)
    w.data("sensor_combined", ids["sensor_combined"], timestamp=us,
           gyro_rad=np.column_stack([ch[f"imu_{k}"][i] for k in "pqr"]),
           gyro_integral_dt=period, accelerometer_integral_dt=period,
           accelerometer_m_s2=np.column_stack([ch[f"imu_a{k}"][i] for k in "xyz"]))
    euler = np.array([ch["att_roll"][i], ch["att_pitch"][i], ch["att_yaw"][i]])
    w.data("vehicle_attitude", ids["vehicle_attitude"], timestamp=us + np.uint64(300),
           timestamp_sample=us, q=euler_to_quat(euler).T)


def _position(w: ULogWriter, ids: dict, flight: ExtendedFlight) -> None:
    """vehicle_local_position (validity flags) and vehicle_gps_position."""
    ch, ph = flight.channels, flight.phases
    k = int(np.searchsorted(flight.time, ph.gps_fix_s))
    origin = np.array([ch["gps_pn"][k], ch["gps_pe"][k], ch["gps_pd"][k]])
    ref = geodetic_from_ned(*origin, ORIGIN)
    i = flight.indices(flight.profile.position_rate_hz)
    fixed = flight.gps_fixed()[i]
    local = {axis: np.where(fixed, ch[f"gps_p{axis}"][i] - origin[j], 0.0)
             for j, axis in enumerate("ne")}
    w.data("vehicle_local_position", ids["vehicle_local_position"],
           timestamp=flight.time_us(i) + np.uint64(500), timestamp_sample=flight.time_us(i),
           ref_timestamp=np.where(fixed, round(ph.gps_fix_s * 1e6), 0),
           ref_lat=np.where(fixed, ref[0], 0.0), ref_lon=np.where(fixed, ref[1], 0.0),
           ref_alt=np.where(fixed, ref[2], 0.0), x=local["n"], y=local["e"],
           z=-ch["baro_alt"][i], vx=np.where(fixed, ch["gps_vn"][i], 0.0),
           vy=np.where(fixed, ch["gps_ve"][i], 0.0), vz=ch["gps_vd"][i],
           z_deriv=ch["gps_vd"][i], heading=ch["att_yaw"][i], eph=np.where(fixed, 1.0, 999.0),
           epv=2.0, xy_valid=fixed, z_valid=1, v_xy_valid=fixed, v_z_valid=1,
           xy_global=fixed, z_global=fixed, dead_reckoning=0)
    i = flight.indices(flight.profile.gps_rate_hz)
    fixed = flight.gps_fixed()[i]
    lat, lon, alt = geodetic_from_ned(ch["gps_pn"][i], ch["gps_pe"][i], ch["gps_pd"][i],
                                      ORIGIN)
    vn, ve, vd = ch["gps_vn"][i], ch["gps_ve"][i], ch["gps_vd"][i]
    w.data("vehicle_gps_position", ids["vehicle_gps_position"], timestamp=flight.time_us(i),
           timestamp_sample=flight.time_us(i), device_id=11_010_051,
           lat=np.where(fixed, np.round(lat * 1e7), 0), lon=np.where(fixed, np.round(lon * 1e7), 0),
           alt=np.where(fixed, np.round(alt * 1e3), 0),
           alt_ellipsoid=np.where(fixed, np.round((alt + 48.0) * 1e3), 0),
           eph=np.where(fixed, 0.9, 99.0), epv=np.where(fixed, 1.4, 99.0), hdop=0.8, vdop=1.1,
           vel_m_s=np.where(fixed, np.hypot(vn, ve), 0.0), vel_n_m_s=np.where(fixed, vn, 0.0),
           vel_e_m_s=np.where(fixed, ve, 0.0), vel_d_m_s=np.where(fixed, vd, 0.0),
           cog_rad=np.arctan2(ve, vn), fix_type=np.where(fixed, 3, 0), vel_ned_valid=fixed,
           satellites_used=np.where(fixed, 14, 3))


def _air_data(w: ULogWriter, ids: dict, flight: ExtendedFlight) -> None:
    """airspeed, the 1 Hz differential_pressure and wind, vehicle_air_data and rpm or
    esc_status."""
    ch, p = flight.channels, flight.profile
    i = flight.indices(p.airspeed_rate_hz)
    w.data("airspeed", ids["airspeed"], timestamp=flight.time_us(i) + np.uint64(200),
           timestamp_sample=flight.time_us(i), indicated_airspeed_m_s=ch["pitot_airspeed"][i],
           true_airspeed_m_s=ch["pitot_airspeed"][i], air_temperature_celsius=25.0,
           confidence=1.0)
    i = flight.indices(p.optional_rate_hz)
    w.data("differential_pressure", ids["differential_pressure"], timestamp=flight.time_us(i),
           timestamp_sample=flight.time_us(i), device_id=9_502_987,
           differential_pressure_pa=ch["pitot_qbar"][i], temperature=25.0)
    north, east = flight.wind_estimate()
    w.data("wind", ids["wind"], timestamp=flight.time_us(i), timestamp_sample=flight.time_us(i),
           windspeed_north=north[i], windspeed_east=east[i], variance_north=0.5,
           variance_east=0.5)
    i = flight.indices(p.baro_rate_hz)
    alt = ch["baro_alt"][i]
    w.data("vehicle_air_data", ids["vehicle_air_data"], timestamp=flight.time_us(i),
           timestamp_sample=flight.time_us(i), baro_device_id=4_325_393,
           baro_alt_meter=ORIGIN[2] + alt, baro_temp_celcius=25.0,
           baro_pressure_pa=95_500.0 - flight.params.rho * flight.params.gravity * alt,
           rho=flight.params.rho)
    topic = _shaft_speed_topic(flight)
    if topic is not None:
        i = flight.indices(p.shaft_speed_rate_hz)
        rpm = ch["motor_speed"][i] * 60.0 / (2.0 * np.pi)
        if topic == "rpm":
            w.data("rpm", ids["rpm"], timestamp=flight.time_us(i),
                   indicated_frequency_rpm=rpm, estimated_accurancy_rpm=10.0)
        else:
            report = np.zeros((i.size, 8))
            report[:, 0] = np.round(rpm)
            nested = {"esc.timestamp": flight.time_us(i)[:, None], "esc.esc_rpm": report,
                      "esc.esc_temperature": 40.0}
            w.data("esc_status", ids["esc_status"], timestamp=flight.time_us(i),
                   counter=np.arange(i.size) % 65536, esc_count=1, esc_connectiontype=6,
                   esc_online_flags=1, esc_armed_flags=1, **nested)


def _shaft_speed_topic(flight: ExtendedFlight) -> str | None:
    """``rpm``, ``esc_status`` or None: the topic of the flight's ``motor_speed``."""
    if "motor_speed" not in flight.channels:
        return None
    return "rpm" if flight.profile.shaft_speed == "rpm" else "esc_status"


def _actuators(w: ULogWriter, ids: dict, flight: ExtendedFlight) -> None:
    """actuator_servos, actuator_motors and the PWM of actuator_outputs."""
    i = flight.indices(flight.profile.command_rate_hz)
    aileron = flight.demand("aileron")
    servos = np.full((flight.time.size, 8), np.nan)
    servos[:, :4] = np.column_stack([-aileron, aileron, flight.demand("elevator"),
                                     flight.demand("rudder")])
    motors = np.full((flight.time.size, 12), np.nan)
    motors[:, 0] = np.clip(flight.channels["cmd_throttle"], 0.0, 1.0)
    w.data("actuator_servos", ids["actuator_servos"], timestamp=flight.time_us(i),
           timestamp_sample=flight.time_us(i), control=servos[i])
    w.data("actuator_motors", ids["actuator_motors"], timestamp=flight.time_us(i),
           timestamp_sample=flight.time_us(i), control=motors[i])
    i = flight.indices(flight.profile.position_rate_hz)
    pwm = np.zeros((i.size, 16))
    pwm[:, 0] = np.round(1100.0 + 800.0 * motors[i, 0])
    servo = servos[i, :4]
    servo[:, PWM_REVERSED_OUTPUT - 2] *= -1.0
    pwm[:, 1:5] = np.round(1500.0 + 400.0 * servo)
    pwm[~flight.armed()[i]] = 0.0
    w.data("actuator_outputs", ids["actuator_outputs"], timestamp=flight.time_us(i),
           noutputs=8, output=pwm)


def write_px4_log(log: FlightLog, path: str | Path, *, seed: int,
                  aircraft: str | FixedWingParams | None = None,
                  profile: LogProfile | None = None) -> WrittenLog:
    """Writes a simulated flight as a PX4 1.14 ``.ulg`` log (see the module); arguments
    and result as :func:`drake_uav.io.realistic_ardupilot.write_ardupilot_log`. With
    ``profile.truncate`` the last message keeps its first half."""
    flight = extend_flight(log, aircraft, profile, seed=seed)
    w = ULogWriter(start_us=int(flight.time_us(np.array([0]))[0]))
    for key, value in (("sys_name", "PX4"), ("ver_hw", "CUBEPILOT_CUBEORANGE"),
                       ("ver_sw", "b8e2fb5a6ab5a8d1a8bc3ff3a6a4d4a5fc34f9c2"),
                       ("sys_os_name", "NuttX"), ("ver_sw_release", VER_SW_RELEASE)):
        w.info(key, value)
    _parameters(w)
    ids = {}
    w.structure("esc_report", _ESC_REPORT)
    for topic, fields in _TOPICS.items():
        if topic not in ("rpm", "esc_status") or topic == _shaft_speed_topic(flight):
            w.format(topic, fields)
            ids[topic] = w.subscribe(topic)
    for part in (_status, _inertial, _position, _air_data, _actuators):
        part(w, ids, flight)
    return save_log(w, flight, path, None)
