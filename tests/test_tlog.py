"""MAVLink telemetry logs (.tlog): written from the bundled sample flight with pymavlink's
encoder (drake_uav.io.tlog_writer) and read back (drake_uav.io.tlog), at the log's rate and
decimated as telemetry is; the native rates in the metadata; ESC telemetry; damaged bytes."""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import drake_uav
from drake_uav.identification.pipeline import check_fixed_wing
from drake_uav.io import FlightLog, FlightLogError, read_log
from drake_uav.io.esc import esc_channels
from drake_uav.io.streams import logged_rate
from drake_uav.io.tlog_writer import write_tlog

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
_STEP = {  # a step of each MAVLink field (or float32 rounding) -> channels
    9.80665e-3: ("imu_ax", "imu_ay", "imu_az"), 1e-3: ("imu_p", "imu_q", "imu_r"),
    2e-6: ("att_roll", "att_pitch", "att_yaw"), 1e-3 + 1e-12: ("cmd_throttle",),
    math.radians(25.0) / 500: ("cmd_elevator", "cmd_aileron", "cmd_rudder"),
    2e-4: ("pitot_airspeed", "pitot_qbar"), 0.01: ("gps_vn", "gps_ve", "gps_vd"),
}
RESOLUTION = {name: step / 2 + 1e-9 for step, names in _STEP.items() for name in names}


@pytest.fixture(scope="module")
def sample():
    log = read_log(SAMPLE)
    return log.select([n for n in log.names if not n.startswith("vane_")]).resample(
        time=log.time[:2001])  # the first 20 s


def _read(path, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_log(path, **options)
    return log, [str(w.message) for w in caught]


def test_a_written_tlog_reads_back_within_the_mavlink_resolution(sample, tmp_path):
    log, _ = _read(write_tlog(sample, tmp_path / "flight.tlog"))
    np.testing.assert_allclose(log.time, sample.time, atol=1e-9)
    for name, tolerance in RESOLUTION.items():
        assert np.max(np.abs(log[name] - sample[name])) <= tolerance, name
    # Positions about the first fix.
    for axis in ("gps_pn", "gps_pe", "gps_pd"):
        np.testing.assert_allclose(log[axis] - log[axis][0], sample[axis] - sample[axis][0],
                                   atol=0.02)
    meta = log.metadata
    assert meta["vehicle_type"] == {"mav_type": 1, "name": "fixed wing"}
    assert meta["firmware"] == "ArduPlane" and meta["flight_modes"] == [[0.0, "MANUAL"]]
    assert meta["actuators"]["source"] == "SERVOn parameters"
    assert meta["clock_offset_s"] == pytest.approx(-(1.7e9 + 0.02), abs=1e-5)
    assert meta["out_of_order"] == {} and meta["skipped_bytes"] == 0
    assert "imu_position" not in meta  # no INS_POS1_* parameters sent


def test_decimated_telemetry_keeps_each_stream_native_rate(sample, tmp_path):
    path = write_tlog(sample, tmp_path / "low.tlog",
                      rates={"imu": 10, "attitude": 10, "commands": 3, "air": 5,
                             "position": 2})
    log, messages = _read(path)
    assert any("IMU (RAW_IMU) telemetry at 10 Hz, below 100 Hz" in m for m in messages)
    assert log.metadata["time_base"] == "RAW_IMU" and log.time.size == 201
    expected = {"imu_ax": 10.0, "att_roll": 10.0, "cmd_elevator": 3.0, "pitot_airspeed": 5.0,
                "gps_pn": 2.0}
    for channel, rate in expected.items():
        assert logged_rate(log, channel) == pytest.approx(rate, rel=1e-6), channel
    # Commands held between their 3 Hz messages: the value sent at t = 1/3 s (the sample
    # at 0.33 s) until t = 2/3 s.
    at = (log.time > 0.34) & (log.time < 0.66)
    np.testing.assert_allclose(log["cmd_throttle"][at],
                               np.round(sample["cmd_throttle"][33] * 1000) / 1000, atol=1e-9)


def test_esc_telemetry_and_multicopter_heartbeat(sample, tmp_path):
    t = sample.time
    esc = {f"esc_rpm_{i}": 1000.0 + 10.0 * i + 50.0 * np.sin(t) for i in range(5)}
    esc.update({f"esc_voltage_{i}": 15.0 + 0.0 * t for i in range(5)})
    esc.update({"esc_temperature_0": 310.15 + 0.0 * t})
    units = {n: {"rpm": "rad/s", "voltage": "V", "temperature": "K"}[n.split("_")[1]]
             for n in esc}
    quad = FlightLog(t, {**{n: sample[n] for n in sample.names}, **esc},
                     units={**{n: sample.unit(n) for n in sample.names}, **units})
    path = write_tlog(quad, tmp_path / "quad.tlog", mav_type=2, rates={"esc": 4})
    log, _ = _read(path)
    assert list(esc_channels(log)) == [0, 1, 2, 3, 4]
    assert logged_rate(log, "esc_rpm_4") == pytest.approx(4.0)
    sent = np.searchsorted(t, log.time, side="right") - 1
    sent = (sent // 25) * 25  # the latest 4 Hz message
    np.testing.assert_allclose(log["esc_rpm_3"], np.rint(esc["esc_rpm_3"][sent] * 30 / math.pi)
                               * math.pi / 30, rtol=1e-12)
    np.testing.assert_allclose(log["esc_voltage_4"], 15.0)
    np.testing.assert_allclose(log["esc_temperature_0"], 310.15)
    np.testing.assert_allclose(log["esc_temperature_1"], 273.15)  # not sent: 0 deg C
    assert log.metadata["vehicle_type"] == {"mav_type": 2, "name": "quadrotor"}
    assert not any(n.startswith("cmd_") for n in log.names)
    with pytest.raises(FlightLogError, match="not a fixed-wing log .MAV_TYPE 2"):
        check_fixed_wing(log, str(path))


def test_damaged_repeated_and_foreign_bytes(sample, tmp_path):
    data = bytearray(write_tlog(sample.resample(time=sample.time[:301]),
                                tmp_path / "a.tlog").read_bytes())
    first = 8 + 12 + data[9]  # the first record (MAVLink 2, unsigned)
    damaged = data[:first] + data[:first] + b"\x00junk\xfd\x10" + data[first:]
    damaged[len(damaged) // 2] ^= 0xFF  # one bad checksum
    path = tmp_path / "damaged.tlog"
    path.write_bytes(bytes(damaged))
    log, _ = _read(path)
    assert log.metadata["out_of_order"] == {"HEARTBEAT": 1}
    assert 0 < log.metadata["skipped_bytes"] <= 64
    assert log.time.size >= 295
    path.write_bytes(bytes(range(256)) * 40)
    with pytest.raises(FlightLogError, match="not a MAVLink telemetry log"):
        read_log(path)


def test_named_extra_channels_and_their_units(sample, tmp_path):
    path = write_tlog(sample.resample(time=sample.time[:301]), tmp_path / "a.tlog")
    log, _ = _read(path, extra_channels=["VFR_HUD.alt", "ATTITUDE.rollspeed",
                                         "RAW_IMU.xgyro"])
    assert log.unit("VFR_HUD.alt") == "m" and log.unit("ATTITUDE.rollspeed") == "rad/s"
    assert log.unit("RAW_IMU.xgyro") == "1"  # mrad/s: not a unit the FlightLog knows
    np.testing.assert_allclose(log["RAW_IMU.xgyro"], np.rint(log["imu_p"] * 1000.0))
    with pytest.raises(FlightLogError, match="no field nope in VFR_HUD messages"):
        read_log(path, extra_channels=["VFR_HUD.nope"])


def test_only_the_aircraft_messages_are_read(sample, tmp_path):
    """A ground station's and a companion computer's heartbeats come first, and another
    vehicle (system 2) sends its own attitude: the aircraft is system 1, component 1."""
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    raw = write_tlog(sample.resample(time=sample.time[:301]), tmp_path / "a.tlog").read_bytes()
    foreign = bytearray()
    for system, component, autopilot, kind in ((255, 190, 8, 6), (1, 191, 0, 18),
                                               (2, 1, 3, 1)):
        link = dialect.MAVLink(None, srcSystem=system, srcComponent=component)
        stamp = int(1.7e9 * 1e6).to_bytes(8, "big")
        foreign += stamp + link.heartbeat_encode(kind, autopilot, 0, 0, 4).pack(link)
        foreign += stamp + link.attitude_encode(0, 3.0, 1.0, 1.0, 0, 0, 0).pack(link)
    path = tmp_path / "mixed.tlog"
    path.write_bytes(bytes(foreign) + raw)
    log, _ = _read(path)
    assert log.metadata["system_component"] == [1, 1]
    np.testing.assert_allclose(log["att_roll"], sample["att_roll"][:301], atol=1e-6)


def test_battery_of_sys_status_is_an_extra_channel_in_si_units(sample, tmp_path):
    """SYS_STATUS at 2 Hz: the voltage [mV] is read in V; the current, sent as -1 (not
    measured) throughout, is no channel."""
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    raw = write_tlog(sample.resample(time=sample.time[:301]), tmp_path / "a.tlog").read_bytes()
    link = dialect.MAVLink(None, srcSystem=1, srcComponent=1)
    status = bytearray()
    for k in range(7):
        stamp = int(round((1.7e9 + 0.02 + 0.5 * k) * 1e6)).to_bytes(8, "big")
        status += stamp + link.sys_status_encode(0, 0, 0, 0, 12000 - 10 * k, -1, 80, 0, 0, 0,
                                                 0, 0, 0).pack(link)
    path = tmp_path / "battery.tlog"
    path.write_bytes(raw + bytes(status))
    log, messages = _read(path)
    assert log.unit("SYS_STATUS.voltage_battery") == "V"
    assert logged_rate(log, "SYS_STATUS.voltage_battery") == pytest.approx(2.0)
    held = np.floor(log.time / 0.5 + 1e-9)
    np.testing.assert_allclose(log["SYS_STATUS.voltage_battery"], 12.0 - 0.01 * held)
    assert "SYS_STATUS.current_battery" not in log
    assert not any("SYS_STATUS" in m for m in messages)


def test_parameters_sent_give_the_imu_position(sample, tmp_path):
    path = write_tlog(sample.resample(time=sample.time[:101]), tmp_path / "a.tlog",
                      parameters={"INS_POS1_X": 0.25, "INS_POS1_Z": -0.05})
    log, _ = _read(path)
    assert log.metadata["imu_position"] == {"position": [0.25, 0.0, pytest.approx(-0.05)],
                                            "source": "INS_POS1_X/Y/Z"}
    assert log.metadata["parameters"]["SERVO2_FUNCTION"] == 19.0
