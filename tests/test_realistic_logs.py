"""Realistic ArduPilot .bin and PX4 .ulg logs of a simulated flight.

The files are checked with the real tools (pymavlink's DFReader, pyulog) against the
layouts an autopilot writes, then read with drake_uav.io.read_log.
"""

import math
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader
from pyulog import ULog

from drake_uav.diagrams import fly
from drake_uav.io import FlightLog, read_log
from drake_uav.io.esc import with_motor_speed
from drake_uav.io.realistic_ardupilot import FIRMWARE, write_ardupilot_log
from drake_uav.io.realistic_logs import LogProfile, extend_flight
from drake_uav.io.realistic_px4 import VER_SW_RELEASE, write_px4_log
from drake_uav.io.streams import logged_rate

LIMIT = math.radians(25.0)  # the Aerosonde's surface limits: the full servo throw
REAL = Path(__file__).parent / "data"  # real logs (ArduPlane 4.2.3, PX4 1.15)


@pytest.fixture(scope="module")
def flight():
    return fly(duration=20.0, seed=4, disturbance=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0))


@pytest.fixture(scope="module")
def bin_log(flight, tmp_path_factory):
    return write_ardupilot_log(flight, tmp_path_factory.mktemp("ap") / "flight.bin", seed=1)


@pytest.fixture(scope="module")
def ulg_log(flight, tmp_path_factory):
    return write_px4_log(flight, tmp_path_factory.mktemp("px4") / "flight.ulg", seed=1)


def _dataflash(path) -> dict[str, list]:
    """Every message of a .bin by type, as pymavlink reads it."""
    reader = DFReader.DFReader_binary(str(path))
    messages: dict[str, list] = {}
    while (m := reader.recv_msg()) is not None:
        messages.setdefault(m.get_type(), []).append(m)
    return messages


def _rate(times) -> float:
    return 1.0 / float(np.median(np.diff(times)))


def _sim_command(flight, phases, times, name):
    """The simulated command in effect at log times ``times`` [s since boot]."""
    k = np.round((np.asarray(times) - phases.flight_s) / 0.01).astype(int)
    return flight[name][np.clip(k, 0, len(flight) - 1)]


# ---------------------------------------------------------------- ArduPilot .bin
def test_bin_messages_rates_and_events_as_arduplane_writes_them(bin_log):
    m, ph = _dataflash(bin_log.path), bin_log.phases
    assert set(m) == {"FMT", "PARM", "MSG", "MODE", "ARM", "EV", "IMU", "ATT", "GPS", "ORGN",
                      "ARSP", "BARO", "RCOU", "AETR", "XKF2"}  # no vanes, no truth
    rates = {k: _rate([x.TimeUS / 1e6 for x in m[k]]) for k in
             ("IMU", "ATT", "GPS", "ARSP", "RCOU", "XKF2")}
    assert rates == pytest.approx({"IMU": 50, "ATT": 50, "GPS": 5, "ARSP": 10, "RCOU": 100,
                                   "XKF2": 1}, rel=1e-3)
    assert {x.I for x in m["IMU"]} == {0}
    assert m["MSG"][0].Message == FIRMWARE
    assert [(x.TimeUS / 1e6, x.ModeNum) for x in m["MODE"]] == [
        (pytest.approx(4.8), 0), (pytest.approx(ph.takeoff_s), 13),
        (pytest.approx(ph.flight_s), 5)]
    assert m["ARM"][0].TimeUS / 1e6 == pytest.approx(ph.arm_s)
    fixes = [x for x in m["GPS"] if x.Status >= 3]
    assert fixes[0].TimeUS / 1e6 == pytest.approx(ph.gps_fix_s, abs=0.2)
    assert all(x.Lat == 0 and x.Status == 1 for x in m["GPS"] if x.TimeUS / 1e6 < ph.gps_fix_s)
    assert m["GPS"][0].TimeUS / 1e6 - 4.8 == pytest.approx(3.0)  # detected 3 s in


def test_bin_servo_parameters_and_pwm_zero_before_arming(bin_log):
    m, ph = _dataflash(bin_log.path), bin_log.phases
    params = {x.Name: x.Value for x in m["PARM"]}
    for n, function in ((1, 4), (2, 19), (3, 70), (4, 21), (5, 0)):
        assert params[f"SERVO{n}_FUNCTION"] == function
        assert (params[f"SERVO{n}_MIN"], params[f"SERVO{n}_MAX"]) == (1100, 1900)
    assert [params[f"SERVO{n}_REVERSED"] for n in (1, 2, 3, 4)] == [0, 1, 0, 0]
    assert params["SERVO3_TRIM"] == 1100 and params["Q_ENABLE"] == 0
    before = [x for x in m["RCOU"] if x.TimeUS / 1e6 < ph.arm_s]
    after = [x for x in m["RCOU"] if x.TimeUS / 1e6 >= ph.arm_s]
    assert before and all(x.C1 == x.C2 == x.C3 == x.C4 == x.C5 == 0 for x in before)
    assert all(1100 <= x.C2 <= 1900 and x.C5 == 0 for x in after)


def _surface_from_pwm(pwm, params, n):
    """Inverse of ArduPilot's servo output, written out independently for the test."""
    trim, low, high = (params[f"SERVO{n}_{k}"] for k in ("TRIM", "MIN", "MAX"))
    x = np.where(pwm >= trim, (pwm - trim) / (high - trim), (pwm - trim) / (trim - low))
    return -x if params[f"SERVO{n}_REVERSED"] else x


def test_bin_pwm_is_the_simulated_command_through_the_servo_parameters(bin_log, flight):
    m, ph = _dataflash(bin_log.path), bin_log.phases
    params = {x.Name: x.Value for x in m["PARM"]}
    rcou = [x for x in m["RCOU"] if x.TimeUS / 1e6 >= ph.flight_s]
    t = np.array([x.TimeUS / 1e6 for x in rcou])
    # Demands: roll right, pitch up, yaw right positive; full throw = the surface limit.
    for n, name, sign in ((1, "cmd_aileron", 1.0), (2, "cmd_elevator", -1.0),
                          (4, "cmd_rudder", -1.0)):
        pwm = np.array([getattr(x, f"C{n}") for x in rcou], float)
        surface = sign * LIMIT * _surface_from_pwm(pwm, params, n)
        error = surface - _sim_command(flight, ph, t, name)
        assert np.max(np.abs(error)) <= 0.5 * LIMIT / 400 + 1e-9  # half a microsecond
    throttle = (np.array([x.C3 for x in rcou]) - 1100.0) / 800.0
    assert np.max(np.abs(throttle - _sim_command(flight, ph, t, "cmd_throttle"))) < 1e-3
    aetr = [x for x in m["AETR"] if x.TimeUS / 1e6 >= ph.flight_s]
    elev = np.array([x.Elev for x in aetr]) / 4500.0 * -LIMIT
    assert np.allclose(elev, _sim_command(flight, ph, t, "cmd_elevator"), atol=1e-6)


def test_bin_ends_in_a_half_written_record_padded_to_a_block(bin_log):
    data = bin_log.path.read_bytes()
    assert len(data) % 4096 == 0
    reader = DFReader.DFReader_binary(str(bin_log.path))
    last, length = max((int(offsets[-1]), reader.formats[t].len)
                       for t, offsets in enumerate(reader.offsets) if offsets)
    assert last + length > len(data)  # the last record does not fit in the file
    assert data[-16:] == bytes(16)  # its missing half: zero padding


def test_bin_ground_segment_reads_gravity_and_no_airspeed(bin_log):
    m, ph = _dataflash(bin_log.path), bin_log.phases
    ground = [x for x in m["IMU"] if x.TimeUS / 1e6 < ph.takeoff_s]
    assert np.mean([x.AccZ for x in ground]) == pytest.approx(-9.81, abs=0.02)
    assert np.std([x.GyrY for x in ground]) < 0.01
    arsp = [x for x in m["ARSP"] if x.TimeUS / 1e6 < ph.takeoff_s]
    assert min(x.DiffPress for x in arsp) < 0.0 < max(x.DiffPress for x in arsp)
    assert all(0.0 <= x.Airspeed < 8.0 for x in arsp)


def test_bin_layouts_are_those_of_a_real_arduplane_log(bin_log):
    real = DFReader.DFReader_binary(str(REAL / "ardupilot_center_0003.bin"))
    real_formats = {f.name: (f.format, f.columns) for f in real.formats.values()}
    ours = DFReader.DFReader_binary(str(bin_log.path))
    shared = 0
    for f in ours.formats.values():
        if f.name == "PARM":  # ArduPlane 4.3+ adds the Default column to 4.2's QNf
            assert (f.format, f.columns) == ("QNff", ["TimeUS", "Name", "Value", "Default"])
        elif f.name in real_formats:
            assert (f.format, f.columns) == real_formats[f.name], f.name
            shared += 1
    assert shared >= 13


# ---------------------------------------------------------------- PX4 .ulg
def test_ulg_fields_are_those_of_a_real_px4_log(ulg_log):
    real = {d.name: {(f.field_name, f.type_str) for f in d.field_data}
            for d in ULog(str(REAL / "px4_sample_px4_events.ulg")).data_list}
    shared = 0
    for d in ULog(str(ulg_log.path)).data_list:
        fields = {(f.field_name, f.type_str) for f in d.field_data}
        if d.name == "vehicle_gps_position":  # PX4 1.14: int32 lat/lon (1e-7 deg), alt (mm)
            fields -= {("lat", "int32_t"), ("lon", "int32_t"), ("alt", "int32_t"),
                       ("alt_ellipsoid", "int32_t")}
        if d.name in real:
            assert fields <= real[d.name], (d.name, fields - real[d.name])
            shared += 1
    assert shared >= 8


def test_ulg_topics_parameters_and_info_as_px4_writes_them(ulg_log):
    ulog, ph = ULog(str(ulg_log.path)), ulg_log.phases
    data = {d.name: d.data for d in ulog.data_list}
    assert set(data) == {"sensor_combined", "vehicle_attitude", "vehicle_local_position",
                         "vehicle_gps_position", "airspeed", "differential_pressure", "wind",
                         "vehicle_air_data", "actuator_servos", "actuator_motors",
                         "actuator_outputs", "vehicle_status"}
    rates = {k: _rate(data[k]["timestamp"] / 1e6) for k in
             ("sensor_combined", "vehicle_attitude", "vehicle_gps_position", "airspeed",
              "differential_pressure", "wind", "actuator_servos")}
    assert rates == pytest.approx({"sensor_combined": 50, "vehicle_attitude": 50,
                                   "vehicle_gps_position": 5, "airspeed": 10,
                                   "differential_pressure": 1, "wind": 1,
                                   "actuator_servos": 100}, rel=1e-3)
    assert ulog.msg_info_dict["ver_sw_release"] == VER_SW_RELEASE
    p = ulog.initial_parameters
    assert p["MAV_TYPE"] == 1 and p["CA_SV_CS_COUNT"] == 4
    assert [p[f"CA_SV_CS{i}_TYPE"] for i in range(4)] == [1, 2, 3, 4]
    assert [p[f"PWM_MAIN_FUNC{n}"] for n in range(1, 7)] == [101, 201, 202, 203, 204, 0]
    assert (p["PWM_MAIN_MIN2"], p["PWM_MAIN_MAX2"], p["PWM_MAIN_REV"]) == (1100, 1900, 16)
    status = data["vehicle_status"]
    changes = np.flatnonzero(np.diff(status["nav_state"])) + 1
    assert list(status["nav_state"][np.r_[0, changes]]) == [0, 17, 15]
    assert status["timestamp"][changes] / 1e6 == pytest.approx([ph.takeoff_s, ph.flight_s])
    assert set(status["vehicle_type"]) == {2}


def test_ulg_validity_pwm_zero_before_arming_and_negative_ground_airspeed(ulg_log, flight):
    ulog, ph = ULog(str(ulg_log.path)), ulg_log.phases
    data = {d.name: d.data for d in ulog.data_list}
    position = data["vehicle_local_position"]
    t = position["timestamp_sample"] / 1e6
    assert not np.any(position["xy_valid"][t < ph.gps_fix_s])
    assert np.all(position["xy_valid"][t >= ph.gps_fix_s]) and np.all(position["z_valid"])
    outputs = data["actuator_outputs"]
    before = outputs["timestamp"] / 1e6 < ph.arm_s
    pwm = np.column_stack([outputs[f"output[{i}]"] for i in range(16)])
    assert np.all(pwm[before] == 0) and np.all(pwm[~before, :5] >= 1100)
    airspeed = data["airspeed"]
    ground = airspeed["timestamp_sample"] / 1e6 < ph.takeoff_s
    assert np.min(airspeed["indicated_airspeed_m_s"][ground]) < 0.0
    servos = data["actuator_servos"]
    t = servos["timestamp_sample"] / 1e6
    sel = t >= ph.flight_s
    # PX4 surfaces: trailing edge up (horizontal) / right (vertical) positive.
    right_aileron = servos["control[1]"][sel] * LIMIT
    assert np.allclose(right_aileron, _sim_command(flight, ph, t[sel], "cmd_aileron"), atol=1e-6)
    assert np.allclose(servos["control[0]"], -servos["control[1]"])
    elevator = -servos["control[2]"][sel] * LIMIT
    assert np.allclose(elevator, _sim_command(flight, ph, t[sel], "cmd_elevator"), atol=1e-6)
    assert np.all(np.isnan(servos["control[4]"]))


def test_ulg_ends_in_a_half_written_message(ulg_log):
    data = ulg_log.path.read_bytes()
    position = 16
    while position + 3 <= len(data):
        size = struct.unpack_from("<H", data, position)[0]
        position += 3 + size
    assert position > len(data)  # the last message runs past the end of the file


# ---------------------------------------------------------------- both
@pytest.mark.parametrize("writer", [write_ardupilot_log, write_px4_log])
def test_same_seed_same_bytes_and_only_measured_data(writer, flight, tmp_path):
    a = writer(flight, tmp_path / "a", seed=7).path.read_bytes()
    b = writer(flight, tmp_path / "b", seed=7).path.read_bytes()
    c = writer(flight, tmp_path / "c", seed=8).path.read_bytes()
    assert a == b and a != c
    for word in (b"vane", b"truth", b"noise", b"sample_rate", b"aerosonde", b"alpha"):
        assert word not in a.lower()


def test_takeoff_joins_the_flight_and_phases_are_ordered(flight):
    profile = LogProfile()
    extended = extend_flight(flight, seed=0)
    ph, ch = extended.phases, extended.channels
    assert 4.8 < ph.gps_fix_s < ph.arm_s < ph.takeoff_s < ph.flight_s < ph.end_s
    k = int(np.searchsorted(extended.time, ph.flight_s))
    assert ph.flight_s - ph.takeoff_s == pytest.approx(profile.roll_s + profile.climb_s)
    window = slice(k - 50, k + 50)
    assert np.ptp(ch["gps_pd"][window]) < 10.0 and np.ptp(ch["att_yaw"][window]) < 0.2
    assert np.all(ch["cmd_throttle"][extended.time < ph.takeoff_s] == 0.0)
    takeoff = (extended.time >= ph.takeoff_s) & (extended.time < ph.flight_s)
    assert np.all(ch["cmd_throttle"][takeoff] == 1.0)


def test_motor_speed_is_logged_as_rpm(flight, tmp_path):
    measured = {k: flight[k] for k in flight.measured_names}
    measured["motor_speed"] = np.full(len(flight), 2.0 * np.pi * 60.0)  # 3600 rev/min
    log = FlightLog(flight.time, measured, units={**flight.units, "motor_speed": "rad/s"},
                    metadata=flight.metadata)
    rpm = _dataflash(write_ardupilot_log(log, tmp_path / "f.bin", seed=0).path)["RPM"]
    assert [x.RPM for x in rpm][-5:] == pytest.approx([3600.0] * 5)
    ulog = ULog(str(write_px4_log(log, tmp_path / "f.ulg", seed=0).path))
    assert ulog.get_dataset("rpm").data["indicated_frequency_rpm"][-5:] == pytest.approx(3600.0)


@pytest.mark.parametrize("writer", [write_ardupilot_log, write_px4_log])
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_motor_speed_as_esc_telemetry_reads_back_as_the_propellers_shaft_speed(
        writer, flight, tmp_path):
    """profile.shaft_speed "esc": the ESC message (ArduPilot ESC, PX4 esc_status) at 10 Hz,
    read as esc_rpm_0 at its native rate, and taken as motor_speed by the job."""
    measured = {k: flight[k] for k in flight.measured_names}
    speed = 400.0 + 30.0 * np.sin(flight.time)  # rad/s, 3800-4100 rev/min
    measured["motor_speed"] = speed
    log = FlightLog(flight.time, measured, units={**flight.units, "motor_speed": "rad/s"},
                    metadata=flight.metadata)
    path = tmp_path / ("f.bin" if writer is write_ardupilot_log else "f.ulg")
    written = writer(log, path, seed=0, profile=LogProfile(shaft_speed="esc"))
    read = read_log(written.path)
    assert "motor_speed" not in read and logged_rate(read, "esc_rpm_0") == pytest.approx(10.0)
    job, note = with_motor_speed(read)
    assert note == "propeller shaft speed from the ESC telemetry (esc_rpm_0)"
    assert "esc_rpm_0" not in job and logged_rate(job, "motor_speed") == pytest.approx(10.0)
    inside = (job.time > written.phases.flight_s + 1.0) & (job.time < job.time[-1] - 1.0)
    expected = np.interp(job.time[inside] - written.phases.flight_s, flight.time - flight.time[0],
                         speed)
    # Held or interpolated 10 Hz samples of a 1 rad/s sine: within 30 * 0.1 rad/s; PX4's
    # esc_rpm is a whole number of rev/min.
    assert np.max(np.abs(job["motor_speed"][inside] - expected)) < 3.2


def test_profile_sets_rates_and_truncation_and_is_checked(flight, tmp_path):
    with pytest.raises(ValueError, match="profile.imu_rate_hz: must be positive"):
        write_ardupilot_log(flight, tmp_path / "x.bin", seed=0, profile=LogProfile(imu_rate_hz=0))
    profile = LogProfile(imu_rate_hz=100.0, truncate=False)
    path = write_ardupilot_log(flight, tmp_path / "f.bin", seed=0, profile=profile).path
    assert _rate([x.TimeUS / 1e6 for x in _dataflash(path)["IMU"]]) == pytest.approx(100.0)
    reader = DFReader.DFReader_binary(str(path))
    assert max(int(o[-1]) + reader.formats[t].len for t, o in enumerate(reader.offsets)
               if o) == path.stat().st_size


def test_a_flight_without_a_channel_is_refused_by_name(flight):
    measured = {k: flight[k] for k in flight.measured_names if k != "pitot_qbar"}
    log = FlightLog(flight.time, measured, units=flight.units, metadata=flight.metadata)
    with pytest.raises(ValueError, match="missing measured channel 'pitot_qbar'"):
        extend_flight(log, seed=0)


# ---------------------------------------------------------------- the project's readers
def _read(path, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_log(path, **options)
    return log, [str(w.message) for w in caught]


def test_read_log_bin_modes_servos_and_commands(bin_log, flight):
    log, caught = _read(bin_log.path)
    ph, md = bin_log.phases, log.metadata
    assert md["firmware"] == FIRMWARE and md["vehicle_type"]["mav_type"] == 1
    assert [name for _, name in md["flight_modes"]] == ["MANUAL", "TAKEOFF", "FBWA"]
    assert md["imu_rate_hz"] == pytest.approx(50.0) and md["parameters"]["SERVO2_REVERSED"] == 1
    assert any("truncated" in w for w in caught) and any("50 Hz" in w for w in caught)
    assert md["dropped_streams"] == ["XKF2"]
    assert md["segments"][0][0] == pytest.approx(ph.arm_s)  # PWM 0 before arming: invalid
    assert "vane_alpha" not in log.measured_names
    sel = log.time >= ph.flight_s + 0.05
    for name in ("cmd_aileron", "cmd_elevator", "cmd_rudder"):
        error = log[name][sel] - _sim_command(flight, ph, log.time[sel], name)
        assert np.max(np.abs(error)) <= 0.5 * LIMIT / 400 + 1e-9


def test_read_log_ulg_modes_and_commands(ulg_log, flight):
    log, caught = _read(ulg_log.path)
    ph, md = ulg_log.phases, log.metadata
    assert md["vehicle_type"]["mav_type"] == 1 and md["firmware"].startswith("PX4 v1.14.3")
    assert [name for _, name in md["flight_modes"]] == ["MANUAL", "AUTO_TAKEOFF", "STAB"]
    assert any("truncated" in w for w in caught)
    assert {"differential_pressure", "wind"} <= set(md["dropped_streams"])
    sel = log.time >= ph.flight_s + 0.05
    for name in ("cmd_aileron", "cmd_elevator", "cmd_rudder", "cmd_throttle"):
        error = log[name][sel] - _sim_command(flight, ph, log.time[sel], name)
        assert np.max(np.abs(error)) < 1e-6


def test_read_log_ulg_keeps_airspeed_and_gps_for_the_flight(ulg_log):
    log, _ = _read(ulg_log.path)
    assert {"pitot_airspeed", "gps_pn", "gps_vn"} <= set(log.measured_names)
