"""Log readers: CSV schema and units, ArduPilot .bin and PX4 .ulg mappings, alignment, errors.

The .bin and .ulg files are written here by the minimal writers of tests/log_writers.py.
"""

import dataclasses
import math

import numpy as np
import pytest
from log_writers import (
    FULL_DEFLECTION,
    DataFlashWriter,
    ULogWriter,
    dataflash_from_log,
    ulog_from_log,
)

from drake_uav.identification.samples.flight_data import REQUIRED_CHANNELS
from drake_uav.io.ardupilot import read_ardupilot
from drake_uav.io.csv_log import read_csv
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.px4 import read_px4
from drake_uav.io.readers import read_log
from drake_uav.io.streams import (
    CHANNELS,
    ActuatorChannel,
    ActuatorMapping,
    FieldSource,
    Stream,
    align_streams,
)
from drake_uav.model.rotations import euler_to_quat

DEG = math.pi / 180.0


def _wrap(angle):
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


def _last_stamp(t, stamps):
    """Stamp [s] of the last sample at or before each time ``t`` [s] (previous-sample hold)."""
    index = np.searchsorted(stamps, t, side="right") - 1
    return np.asarray(stamps)[np.clip(index, 0, len(stamps) - 1)]


def _canonical_log(n: int = 401, seed: int = 0) -> FlightLog:
    """Smooth random signals on the 24 channels the simulator's sensors produce."""
    rng = np.random.default_rng(seed)
    t = 1.0 + 0.02 * np.arange(n)
    names = [c for c in CHANNELS if c not in ("est_wind_n", "est_wind_e", "motor_speed")]
    scale = {"m/s^2": 3.0, "rad/s": 0.5, "rad": 0.2, "m/s": 5.0, "Pa": 50.0, "m": 30.0,
             "1": 0.2}
    measured = {}
    for name in names:
        f = rng.uniform(0.05, 1.0, 3)
        phase = rng.uniform(0, 2 * np.pi, 3)
        measured[name] = scale[CHANNELS[name][0]] * np.sin(f[:, None] * t + phase[:, None]).sum(0)
    measured["cmd_throttle"] = 0.5 + measured["cmd_throttle"] / 2
    measured["pitot_airspeed"] += 25.0
    measured["pitot_qbar"] += 400.0
    measured["att_yaw"] = _wrap(3.0 + 0.5 * (t - 1.0))  # crosses +-pi
    return FlightLog(t, measured, units={n: CHANNELS[n][0] for n in names})


# ------------------------------------------------------------------------- CSV
def test_csv_unit_variants_are_converted_to_si(tmp_path):
    path = tmp_path / "variants.csv"
    path.write_text(
        "\ufeff# aircraft: \"aerosonde\"\n# pilot: J. Doe\n"
        "time [ms], att_roll [deg], imu_p [deg/s], pitot_airspeed [kt], cmd_throttle [%],"
        " imu_az [g], baro_alt [ft], vane_alpha [rad], pitot_qbar [hPa], gps_vn [km/h],"
        " air_temp [K]\n"
        "0, 10, 5, 40, 50, -1, 1000, 0.05, 3.5, 72, 288\n"
        "20, 11, 6, 41, 55, -1.5, 1010, 0.06, 3.6, 90, 289\n", encoding="utf-8")
    log = read_log(path)
    assert log.metadata == {"aircraft": "aerosonde", "pilot": "J. Doe"}
    np.testing.assert_array_equal(log.time, [0.0, 0.020])
    expected = {
        "att_roll": [10 * DEG, 11 * DEG], "imu_p": [5 * DEG, 6 * DEG],
        "pitot_airspeed": [40 * 1852 / 3600, 41 * 1852 / 3600], "cmd_throttle": [0.5, 0.55],
        "imu_az": [-9.80665, -1.5 * 9.80665], "baro_alt": [304.8, 1010 * 0.3048],
        "vane_alpha": [0.05, 0.06], "pitot_qbar": [350.0, 360.0], "gps_vn": [20.0, 25.0],
        "air_temp": [288.0, 289.0],
    }
    for name, values in expected.items():
        np.testing.assert_allclose(log[name], values, rtol=1e-15, err_msg=name)
        unit = CHANNELS[name][0] if name in CHANNELS else "K"
        assert log.unit(name) == unit


def test_csv_round_trip_of_a_saved_flight_log(tmp_path):
    log = _canonical_log(101)
    full = FlightLog(log.time, {n: log[n] for n in log.names},
                     truth={"airspeed": log["pitot_airspeed"] * 0.99},
                     units={**log.units, "airspeed": "m/s"}, metadata={"seed": 3, "a": [1, 2]})
    for suffix in (".csv", ".parquet"):
        back = read_log(full.save(tmp_path / f"log{suffix}"))
        assert back.equals(full), suffix
        assert back.metadata == full.metadata
        assert back.truth_names == ("airspeed",)


def _csv(tmp_path, text: str):
    path = tmp_path / "bad.csv"
    path.write_text(text, encoding="utf-8")
    return path


_HEAD = "time [s], imu_p [rad/s], vane_alpha [deg]\n"


@pytest.mark.parametrize("text, message", [
    (_HEAD + "0, 1, 2\n0.1, , 2\n", r"line 3: column 'imu_p': empty cell"),
    (_HEAD + "0, 1, 2\n0.1, 1, nan\n0.2, 1, 2\n", r"column 'vane_alpha': NaN at line 3"),
    (_HEAD + "0, 1, 2\n0.1, 1, 2\n0.2, 1, x7\n0.3, 1, 2\n",
     r"line 4: column 'vane_alpha': 'x7' is not a number"),
    (_HEAD + "0, 1, 2\n0.1, 1, 2\n0.05, 1, 2\n", r"time goes backwards at line 4 \(t = 0\.05 s"),
    (_HEAD + "0, 1, 2\n0.1, 1, 2\n0.1, 1, 2\n", r"time repeats at line 4"),
    (_HEAD + "0, 1, 2\n0.1, 1, 2\n0.2, 1", r"truncated last line 4: 2 of 3 fields"),
    (_HEAD + "0, 1, 2\n0.1, 1, 2\n0.2, 1,", r"truncated last line 4: column 'vane_alpha': empty"),
    (_HEAD + "0, 1, 2\n0.1, 1\n0.2, 1, 2\n", r"line 3: 2 of 3 fields"),
    (_HEAD + "0, 1, 2, 4\n", r"line 2: 4 fields, the header has 3"),
    ("time [s], imu_p\n0, 1\n", r"column 2 header 'imu_p' is not 'name \[unit\]'"),
    ("time [s], imu_p [furlong/s]\n0, 1\n", r"column 'imu_p': unknown unit 'furlong/s' "
                                            r"\(accepted: rad/s, deg/s"),
    ("time [s], imu_p [m/s]\n0, 1\n", r"column 'imu_p': unit 'm/s' is not a unit of angular"),
    ("time [deg], imu_p [rad/s]\n0, 1\n", r"column 'time': unit 'deg' is not a unit of time"),
    ("time [s], ozone [furlong]\n0, 1\n", r"column 'ozone': unknown unit 'furlong'"),
    ("t [s], imu_p [rad/s]\n0, 1\n", r"no 'time \[s\]' column \(columns: t, imu_p\)"),
    ("time [s], imu_p [rad/s], imu_p [deg/s]\n0, 1, 2\n", r"column 'imu_p' appears 2 times"),
    (_HEAD, r"no data rows"),
    ("# only: 1\n", r"no header line"),
])
def test_csv_bad_files_name_the_problem(tmp_path, text, message):
    path = _csv(tmp_path, text)
    with pytest.raises(FlightLogError, match=message) as err:
        read_log(path)
    assert str(path) in str(err.value)


def test_csv_missing_required_channel_names_file_and_channel(tmp_path):
    path = _csv(tmp_path, "time [s], imu_p [rad/s]\n0, 1\n0.1, 2\n")
    with pytest.raises(FlightLogError, match=r"bad\.csv: missing channel 'imu_ax' \(present: "
                                             r"imu_p\)"):
        read_log(path, required=REQUIRED_CHANNELS)
    assert len(read_csv(path)) == 2


# --------------------------------------------------------------------- read_log
def test_read_log_dispatch_and_file_errors(tmp_path):
    log = _canonical_log(11)
    csv = log.save(tmp_path / "log.csv")
    other = tmp_path / "log.txt"
    other.write_bytes(csv.read_bytes())
    assert read_log(other, format="csv").equals(log)
    with pytest.raises(FlightLogError, match=r"log\.txt: unknown log format '\.txt' "
                                             r"\(known: \.csv, \.bin, \.ulg, \.parquet"):
        read_log(other)
    with pytest.raises(FlightLogError, match=r"unknown log format 'txt'"):
        read_log(other, format="txt")
    with pytest.raises(FlightLogError, match=r"nothere\.bin: no such file"):
        read_log(tmp_path / "nothere.bin")
    with pytest.raises(FlightLogError, match=r": not a file"):
        read_log(tmp_path, format="csv")
    (tmp_path / "empty.ulg").write_bytes(b"")
    with pytest.raises(FlightLogError, match=r"empty\.ulg: empty file"):
        read_log(tmp_path / "empty.ulg")
    (tmp_path / "junk.parquet").write_bytes(b"not parquet at all")
    with pytest.raises(FlightLogError, match=r"junk\.parquet: not a readable Parquet file"):
        read_log(tmp_path / "junk.parquet")
    with pytest.raises(FlightLogError, match=r"junk\.bin: not an ArduPilot DataFlash log"):
        read_log(other.rename(tmp_path / "junk.bin"))
    (tmp_path / "junk.ulg").write_bytes(b"time [s], x [m]\n" * 4)
    with pytest.raises(FlightLogError, match=r"junk\.ulg: not a PX4 ULog file"):
        read_log(tmp_path / "junk.ulg")


# -------------------------------------------------------------- ArduPilot .bin
def _us(start_s: float, rate_hz: float, n: int) -> np.ndarray:
    return np.round(1e6 * start_s + np.arange(n) * 1e6 / rate_hz).astype(np.uint64)


def _multirate_bin(path, *, gap_in_arsp=False, att_backwards=False, arsp_nan=False,
                   with_arsp=True, gps_fix=True, gap_in_rcou=False):
    """A 4 s log: IMU 50 Hz (two instances), ATT 25, GPS 5 (no fix first), ARSP/BARO/RCOU/RPM
    10, XKF2 25 (two cores), VANE 50. Signals are linear in time so the alignment is exact."""
    w = DataFlashWriter()
    w.define("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH")
    w.define("ATT", "QccccCCffB",
             "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    w.define("GPS", "QBBIHBcLLeffff",
             "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw")
    w.define("ARSP", "QBffcffBBffB",
             "TimeUS,I,Airspeed,DiffPress,Temp,RawPress,Offset,U,H,Hp,TR,Pri")
    w.define("BARO", "QBffcfIffB", "TimeUS,I,Alt,Press,Temp,CRt,SMS,Offset,GndTemp,Health")
    w.define("RCOU", "QHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6")
    w.define("XKF2", "QBfffff", "TimeUS,C,AX,AY,AZ,VWN,VWE")
    w.define("RPM", "Qff", "TimeUS,rpm1,rpm2")
    w.define("VANE", "Qff", "TimeUS,AoA,SSA")
    k = np.arange(201)
    imu = _us(1.0, 50, 201)
    for i in (0, 1):
        w.add("IMU", TimeUS=imu, I=i, AccX=0.1 * k + 100 * i, AccY=-0.2, AccZ=-9.75 - 0.01 * k,
              GyrX=0.01 * k, GyrY=-0.03, GyrZ=0.5 + i)
    att = _us(1.0, 25, 101)
    stamped = att.copy()
    if att_backwards:
        stamped[[40, 41]] = att[[41, 40]]
    k = np.arange(101)
    w.add("ATT", TimeUS=stamped, Roll=0.25 * k, Pitch=-0.5 * k, Yaw=(350 + 2.5 * k) % 360,
          at=att)
    k = np.arange(21)
    w.add("GPS", TimeUS=_us(1.0, 5, 21), I=0, Status=np.where((k < 2) | (not gps_fix), 1, 3),
          Lat=47 + 1e-5 * k, Lng=8.0 - 2e-5 * k, Alt=500.0 + 0.5 * k, Spd=20.0, GCrs=30.0, VZ=-1.5)
    k = np.arange(41)
    arsp = _us(1.0, 10, 41)
    airspeed = 20.0 + 0.5 * k
    if arsp_nan:
        airspeed[30] = np.nan
    keep = ~((k > 10) & (k < 32)) if gap_in_arsp else np.ones(41, bool)
    if with_arsp:
        w.add("ARSP", TimeUS=arsp[keep], I=0, Airspeed=airspeed[keep], DiffPress=240.0)
    w.add("BARO", TimeUS=arsp, I=0, Alt=100.0 + k)
    rcou = _us(1.005, 10, 40)
    k = np.arange(40)
    keep = ~((k > 10) & (k < 32)) if gap_in_rcou else np.ones(40, bool)
    w.add("RCOU", TimeUS=rcou[keep], C1=(1500 - 10 * k)[keep], C2=(1500 + 10 * k)[keep],
          C3=(1100 + 22 * k)[keep], C4=1500)
    k = np.arange(101)
    for core in (0, 1):
        w.add("XKF2", TimeUS=att, C=core, VWN=3.0 + 27 * core, VWE=-1.0)
    w.add("RPM", TimeUS=arsp, rpm1=6000.0)
    k = np.arange(201)
    w.add("VANE", TimeUS=imu, AoA=2.0 + 0.1 * k, SSA=-1.0)
    return w.save(path)


_VANES = {"vane_alpha": FieldSource("VANE", "AoA", "rad", scale=DEG),
          "vane_beta": FieldSource("VANE", "SSA", "rad", scale=DEG)}


def test_dataflash_channels_units_and_alignment_exact(tmp_path):
    log = read_log(_multirate_bin(tmp_path / "flight.bin"), extra=_VANES)
    # The span every stream covers: first GPS fix (1.4 s) to the last RCOU message (4.905 s).
    t = log.time
    np.testing.assert_array_equal(t, (1_400_000 + 20_000 * np.arange(176)) / 1e6)
    j = np.round((t - 1.0) / 0.02)
    f32 = np.float32
    # IMU (time base, instance 0 of two): float32 values exactly.
    np.testing.assert_array_equal(log["imu_ax"], f32(0.1 * j).astype(float))
    np.testing.assert_array_equal(log["imu_az"], f32(-9.75 - 0.01 * j).astype(float))
    np.testing.assert_array_equal(log["imu_p"], f32(0.01 * j).astype(float))
    np.testing.assert_array_equal(log["imu_r"], np.full(t.size, 0.5))
    # ATT (25 Hz, centidegrees) interpolated at the IMU samples; yaw across 360 -> 0 deg.
    np.testing.assert_allclose(log["att_roll"], 6.25 * (t - 1.0) * DEG, atol=1e-12)
    np.testing.assert_allclose(log["att_pitch"], -12.5 * (t - 1.0) * DEG, atol=1e-12)
    np.testing.assert_allclose(log["att_yaw"], _wrap((350 + 62.5 * (t - 1.0)) * DEG), atol=1e-12)
    assert log["att_yaw"].min() >= -math.pi and log["att_yaw"].max() < math.pi
    # GPS: velocity from speed and course; positions about the first 3-D fix (t = 1.4 s).
    np.testing.assert_allclose(log["gps_vn"], 20 * math.cos(30 * DEG), rtol=1e-15)
    np.testing.assert_allclose(log["gps_ve"], 20 * math.sin(30 * DEG), rtol=1e-15)
    np.testing.assert_allclose(log["gps_vd"], -1.5)
    lat0 = math.radians(47 + 2e-5)
    e2 = 6.69437999014e-3
    r_north = 6378137.0 * (1 - e2) / (1 - e2 * math.sin(lat0) ** 2) ** 1.5
    r_east = 6378137.0 * math.cos(lat0) / math.sqrt(1 - e2 * math.sin(lat0) ** 2)
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(t, _us(1.0, 5, 21) / 1e6)
    np.testing.assert_allclose(log["gps_pn"], 5e-5 * (s - 1.4) * DEG * r_north, atol=1e-6)
    np.testing.assert_allclose(log["gps_pe"], -1e-4 * (s - 1.4) * DEG * r_east, atol=1e-6)
    np.testing.assert_allclose(log["gps_pd"], -2.5 * (s - 1.4), atol=1e-9)
    # ARSP, BARO, RPM (10 Hz); XKF2 core 0 only.
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(t, _us(1.0, 10, 41) / 1e6)
    np.testing.assert_allclose(log["pitot_airspeed"], 20 + 5 * (s - 1.0), atol=1e-12)
    np.testing.assert_array_equal(log["pitot_qbar"], np.full(t.size, 240.0))
    np.testing.assert_allclose(log["baro_alt"], 100 + 10 * (s - 1.0), atol=1e-12)
    np.testing.assert_allclose(log["motor_speed"], 6000 * 2 * math.pi / 60, rtol=1e-15)
    np.testing.assert_array_equal(log["est_wind_n"], np.full(t.size, 3.0))
    np.testing.assert_array_equal(log["est_wind_e"], np.full(t.size, -1.0))
    # RCOU (10 Hz, stamped 5 ms after the IMU) held from each message to the next.
    k = np.floor((t - 1.005) / 0.1 + 1e-9)
    np.testing.assert_allclose(log["cmd_elevator"], -(10 * k / 500) * 25 * DEG, atol=1e-15)
    np.testing.assert_allclose(log["cmd_aileron"], -(10 * k / 500) * 25 * DEG, atol=1e-15)
    np.testing.assert_allclose(log["cmd_throttle"], np.minimum(22 * k / 800, 1.0), atol=1e-15)
    np.testing.assert_array_equal(log["cmd_rudder"], np.zeros(t.size))
    # Extra (vane) channels from a named message.
    np.testing.assert_array_equal(log["vane_alpha"], f32(2.0 + 0.1 * j).astype(float) * DEG)
    np.testing.assert_array_equal(log["vane_beta"], np.full(t.size, -DEG))
    for name in log.names:
        assert log.unit(name) == CHANNELS[name][0], name
    streams = log.metadata["streams"]
    assert streams["ATT"]["rate_hz"] == pytest.approx(25.0)
    assert streams["RCOU"]["method"] == "previous-sample hold"
    assert streams["GPS"]["messages"] == 19
    assert log.metadata["trimmed_s"] == pytest.approx([0.4, 5.0 - 4.905])
    saved = read_log(log.save(tmp_path / "flight.parquet"))
    assert saved.equals(log) and saved.metadata == log.metadata


def test_dataflash_other_instance_and_actuator_mapping(tmp_path):
    path = _multirate_bin(tmp_path / "flight.bin")
    mapping = ActuatorMapping.ardupilot(elevator=10 * DEG)
    second = read_ardupilot(path, instance=1)  # IMU and EKF core 1; no GPS/ARSP/BARO 1
    np.testing.assert_array_equal(second["imu_r"], np.full(len(second), 1.5))
    np.testing.assert_array_equal(second["est_wind_n"], np.full(len(second), 30.0))
    assert "gps_vn" not in second and "pitot_airspeed" not in second and "baro_alt" not in second
    with pytest.raises(FlightLogError, match=r"no IMU messages with I = 2 \(the time base\)"):
        read_ardupilot(path, instance=2)
    log = read_ardupilot(path, actuators=mapping)
    k = np.floor((log.time - 1.005) / 0.1 + 1e-9)
    np.testing.assert_allclose(log["cmd_elevator"], -(10 * k / 500) * 10 * DEG, atol=1e-15)
    reversed_aileron = ActuatorMapping("RCOU", mapping.elevator,
                                       ActuatorChannel("C1", 1500, 2000, -25 * DEG),
                                       mapping.rudder, mapping.throttle)
    log = read_ardupilot(path, actuators=reversed_aileron)
    np.testing.assert_allclose(log["cmd_aileron"], (10 * k / 500) * 25 * DEG, atol=1e-15)
    with pytest.raises(ValueError, match=r"ActuatorMapping\.throttle\.full: must differ"):
        ActuatorMapping("RCOU", mapping.elevator, mapping.aileron, mapping.rudder,
                        ActuatorChannel("C3", 1500, 1500, 1.0)).validate()
    with pytest.raises(ValueError, match=r"FieldSource\.unit: unknown unit 'volts'"):
        read_ardupilot(path, extra={"vane_alpha": FieldSource("VANE", "AoA", "volts")})
    with pytest.raises(FlightLogError, match=r"no CUR2 messages for channel\(s\) vane_alpha"):
        read_ardupilot(path, extra={"vane_alpha": FieldSource("CUR2", "Volt", "rad")})
    with pytest.raises(FlightLogError, match=r"message VANE has no field Volt \(fields: TimeUS"):
        read_ardupilot(path, extra={"vane_alpha": FieldSource("VANE", "Volt", "rad")})


def test_dataflash_vanes_missing_only_an_error_when_required(tmp_path):
    path = _multirate_bin(tmp_path / "flight.bin")
    log = read_log(path)
    assert "vane_alpha" not in log and "pitot_airspeed" in log
    with pytest.raises(FlightLogError, match=r"flight\.bin: missing channel 'vane_alpha' "
                                             r"\(present: .*\); autopilot logs carry no vane"):
        read_log(path, required=REQUIRED_CHANNELS)
    no_fix = _multirate_bin(tmp_path / "no_fix.bin", gps_fix=False)
    with pytest.warns(UserWarning, match=r"no_fix\.bin: no GPS message with a 3-D fix"):
        log = read_log(no_fix)
    assert "gps_vn" not in log and log.time[0] == 1.02  # first IMU sample after RCOU's
    no_airspeed = _multirate_bin(tmp_path / "no_arsp.bin", with_arsp=False)
    with pytest.raises(FlightLogError, match=r"no_arsp\.bin: missing channel 'pitot_airspeed'"):
        read_log(no_airspeed, required=["pitot_airspeed"])


@pytest.mark.parametrize("flag, message", [
    ("att_backwards", r"stream 'ATT': time goes backwards at message 41 \(t = 2\.600000 s "
                      r"after 2\.640000 s\)"),
    ("arsp_nan", r"ARSP\.Airspeed is nan at message 30 of stream 'ARSP' \(t = 4\.000000 s\)"),
])
def test_dataflash_bad_streams_name_stream_and_time(tmp_path, flag, message):
    path = _multirate_bin(tmp_path / "bad.bin", **{flag: True})
    with pytest.raises(FlightLogError, match=message) as err:
        read_log(path)
    assert str(path) in str(err.value)


def test_dataflash_gap_in_a_stream_cuts_segments(tmp_path):
    path = _multirate_bin(tmp_path / "gap.bin", gap_in_rcou=True)
    log = read_log(path)
    np.testing.assert_allclose(log.metadata["segments"], [[1.4, 2.005], [4.205, 4.905]])
    assert log.time[0] == 1.4 and log.time[-1] == 4.9
    assert not np.any((log.time > 2.005) & (log.time < 4.205))
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(log.time, _us(1.0, 10, 41) / 1e6)
    np.testing.assert_allclose(log["pitot_airspeed"], 20 + 5 * (s - 1.0), atol=1e-12)
    k = np.floor((log.time - 1.005) / 0.1 + 1e-9)
    np.testing.assert_allclose(log["cmd_elevator"], -(10 * k / 500) * 25 * DEG, atol=1e-15)
    path = _multirate_bin(tmp_path / "arsp_gap.bin", gap_in_arsp=True)  # optional: dropped
    with pytest.warns(UserWarning, match=r"arsp_gap\.bin: optional stream 'ARSP' dropped: a "
                                         r"gap of 2\.200 s \(t = 2\.000 s to 4\.200 s\)"):
        log = read_log(path)
    assert "pitot_airspeed" not in log and log.metadata["dropped_streams"] == ["ARSP"]
    np.testing.assert_allclose(log.metadata["segments"], [[1.4, 4.905]])


def test_dataflash_gap_tolerance_is_configurable(tmp_path):
    path = _multirate_bin(tmp_path / "gap.bin", gap_in_arsp=True)
    log = read_log(path, max_gap=2.5)
    # held: logged slower than 0.45 of the time base (the last sample before the gap on)
    k = np.arange(41)
    s = _last_stamp(log.time, _us(1.0, 10, 41)[~((k > 10) & (k < 32))] / 1e6)
    np.testing.assert_allclose(log["pitot_airspeed"], 20 + 5 * (s - 1.0), atol=1e-12)


def test_dataflash_truncated_file(tmp_path):
    path = _multirate_bin(tmp_path / "flight.bin")
    whole = path.read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(whole[:-7])
    with pytest.raises(FlightLogError, match=r"cut\.bin: truncated file: the last \w+ message "
                                             r"\(byte \d+\) needs \d+ bytes, \d+ remain"):
        read_log(cut, extra=_VANES, allow_truncated=False)
    with pytest.warns(UserWarning, match=r"truncated file.*; dropped"):
        log = read_log(cut, extra=_VANES)
    assert log.equals(read_log(path, extra=_VANES))
    cut.write_bytes(whole[:len(whole) // 2])
    with pytest.raises(FlightLogError, match=r"cut\.bin: truncated file"):
        read_log(cut, allow_truncated=False)
    with pytest.warns(UserWarning, match=r"cut\.bin: truncated file"):
        assert read_log(cut).time[-1] < 3.0


def test_dataflash_corrupt_data(tmp_path, capfd):
    path = _multirate_bin(tmp_path / "flight.bin")
    whole = path.read_bytes()
    middle = whole.index(bytes([0xA3, 0x95]), len(whole) // 2)
    bad = tmp_path / "bad.bin"
    bad.write_bytes(whole[:middle] + b"\x11" * 50 + whole[middle:])
    with pytest.warns(UserWarning, match=r"bad\.bin: 50 bytes of corrupt data skipped"):
        log = read_log(bad)
    assert log.equals(read_log(path))
    bad.write_bytes(whole[:middle] + bytes([0xA3, 0x95, 0xF0]) + bytes(20) + whole[middle:])
    with pytest.raises(FlightLogError, match=rf"bad\.bin: the {len(whole) - middle + 23} bytes "
                                             rf"from byte {middle} on .* could not be parsed"):
        read_log(bad)
    capfd.readouterr()  # pymavlink reports the skipped bytes on stderr


def test_dataflash_without_imu(tmp_path):
    w = DataFlashWriter()
    w.define("BARO", "QBf", "TimeUS,I,Alt")
    w.add("BARO", TimeUS=_us(1.0, 10, 5), I=0, Alt=1.0)
    with pytest.raises(FlightLogError, match=r"noimu\.bin: no IMU messages"):
        read_log(w.save(tmp_path / "noimu.bin"))


# ------------------------------------------------------------------- alignment
def _stream(name, rate, t0, t1, **kwargs):
    time = np.arange(round((t1 - t0) * rate) + 1) / rate + t0
    return Stream(name, time, {f"{name}_x": 2.0 * time}, {f"{name}_x": "1"}, **kwargs)


def test_align_streams_segments_holes_and_optional_streams():
    base = _stream("imu", 100, 0.0, 10.0)
    att = _stream("att", 50, 0.0, 10.0)
    att = dataclasses.replace(att, time=np.delete(att.time, np.s_[100:160]),
                              channels={"att_x": np.delete(att.channels["att_x"],
                                                           np.s_[100:160])})
    out = _stream("out", 20, 0.0, 10.0, hold=True)
    valid = np.ones(out.time.size, bool)
    valid[:10] = False  # PWM 0 before arming: the log starts at the first valid output
    valid[150] = False  # one invalid sample: a hole
    out = dataclasses.replace(out, valid=valid)
    arsp = _stream("arsp", 1, 0.0, 10.0, optional=True)
    baro = _stream("baro", 10, 0.0, 10.0, optional=True)
    with pytest.warns(UserWarning, match=r"log\.bin: optional stream 'arsp' dropped: sparse: "
                                         r"logged at 1 Hz"):
        log = align_streams(base, [att, out, arsp, baro], source="log.bin")
    np.testing.assert_allclose(log.metadata["segments"],
                               [[0.5, 1.98], [3.2, 7.45], [7.55, 10.0]])
    assert log.metadata["dropped_streams"] == ["arsp"] and "arsp_x" not in log
    np.testing.assert_allclose(log["att_x"], 2 * log.time, atol=1e-12)
    # held: logged slower than 0.45 of the time base
    np.testing.assert_allclose(log["baro_x"], 2 * _last_stamp(log.time, baro.time), atol=1e-12)
    assert log.metadata["streams"]["out"]["invalid"] == 11
    k = np.arange(101)
    gappy = _stream("baro", 10, 0.0, 10.0, optional=True, valid=(k < 50) | (k > 59))
    with pytest.warns(UserWarning, match=r"optional stream 'baro' dropped: a gap of 1\.100 s "
                                         r"\(t = 4\.900 s to 6\.000 s\), longer than max_gap"):
        log = align_streams(base, [att, gappy], source="log.bin")
    assert log.metadata["dropped_streams"] == ["baro"]
    late = _stream("gps", 5, 4.0, 10.0, optional=True)  # late fix: the start stays
    with pytest.warns(UserWarning, match=r"'gps' dropped: valid only from t = 4\.000 s"):
        assert align_streams(base, [late], source="log.bin").time[0] == 0.0
    never = dataclasses.replace(out, valid=np.zeros(out.time.size, bool))
    with pytest.raises(FlightLogError, match=r"log\.bin: no segment of at least 2 samples where "
                                             r"every required stream has data: stream 'out' "
                                             r"has no valid samples \(201 invalid of 201\)"):
        align_streams(base, [att, never], source="log.bin")


# ------------------------------------------------------------------- PX4 .ulg
def _multirate_ulg(path, *, outputs=False, older_names=False):
    """A 3 s log: sensor_combined 100 Hz (two instances), vehicle_attitude 50 Hz (sample time
    2 ms before publication), local position / airspeed / air data 10 Hz, controls or outputs
    50 Hz, wind 5 Hz."""
    w = ULogWriter(start_us=900_000)
    w.format("sensor_combined", "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
             "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2")
    w.format("vehicle_attitude", "uint64_t timestamp;uint64_t timestamp_sample;float[4] q")
    w.format("vehicle_local_position",
             "uint64_t timestamp;float x;float y;float z;float vx;float vy;float vz")
    w.format("airspeed", "uint64_t timestamp;float indicated_airspeed_m_s;"
             "float true_airspeed_m_s;float confidence")
    pressure = "differential_pressure_filtered_pa" if older_names else "differential_pressure_pa"
    w.format("differential_pressure", f"uint64_t timestamp;float {pressure}")
    w.format("vehicle_air_data", "uint64_t timestamp;float baro_alt_meter")
    w.format("actuator_controls_0", "uint64_t timestamp;float[8] control")
    w.format("actuator_outputs", "uint64_t timestamp;uint32_t noutputs;float[16] output")
    wind = "wind_estimate" if older_names else "wind"
    w.format(wind, "uint64_t timestamp;float windspeed_north;float windspeed_east")
    k = np.arange(301)
    fast = _us(1.0, 100, 301)
    for multi_id in (0, 1):
        gyro = np.column_stack([0.01 * k, -0.02 * k, np.full(301, 0.3 + multi_id)])
        accel = np.column_stack([0.1 * k, np.zeros(301), np.full(301, -9.8)])
        w.data("sensor_combined", w.subscribe("sensor_combined", multi_id), timestamp=fast,
               gyro_rad=gyro, accelerometer_m_s2=accel)
    k = np.arange(151)
    sample = _us(1.0, 50, 151)
    euler = np.column_stack([0.1 + 0.01 * k, -0.05 + 0.002 * k, _wrap(3.0 + 0.01 * k)])
    w.data("vehicle_attitude", w.subscribe("vehicle_attitude"), timestamp=sample + 2000,
           timestamp_sample=sample, q=np.array([euler_to_quat(e) for e in euler]))
    k = np.arange(31)
    slow = _us(1.0, 10, 31)
    w.data("vehicle_local_position", w.subscribe("vehicle_local_position"), timestamp=slow,
           x=2.0 * k, y=-k, z=-50.0 + 0.25 * k, vx=20.0, vy=-10.0, vz=2.5)
    w.data("airspeed", w.subscribe("airspeed"), timestamp=slow, true_airspeed_m_s=20 + 0.5 * k,
           indicated_airspeed_m_s=18 + 0.5 * k, confidence=1.0)
    w.data("differential_pressure", w.subscribe("differential_pressure"), timestamp=slow,
           **{pressure: 240.0 + k})
    w.data("vehicle_air_data", w.subscribe("vehicle_air_data"), timestamp=slow,
           baro_alt_meter=50.0 + 0.25 * k)
    k = np.arange(151)
    if outputs:
        out = np.zeros((151, 16))
        out[:, :4] = np.column_stack([1500 + 2 * k, 1600 - 2 * k, np.full(151, 1500),
                                      np.full(151, 1500)])
        w.data("actuator_outputs", w.subscribe("actuator_outputs"), timestamp=sample,
               noutputs=8, output=out)
    else:
        control = np.zeros((151, 8))
        control[:, :4] = np.column_stack([0.004 * k, np.full(151, 0.1), -0.002 * k,
                                          np.full(151, 0.6)])
        w.data("actuator_controls_0", w.subscribe("actuator_controls_0"), timestamp=sample,
               control=control)
    w.data(wind, w.subscribe(wind), timestamp=_us(1.0, 5, 16), windspeed_north=4.0,
           windspeed_east=-2.0)
    return w.save(path)


def test_ulog_channels_units_and_alignment(tmp_path):
    log = read_log(_multirate_ulg(tmp_path / "flight.ulg"))
    t = log.time
    np.testing.assert_array_equal(t, (1_000_000 + 10_000 * np.arange(301)) / 1e6)
    j = np.arange(301)
    np.testing.assert_array_equal(log["imu_p"], np.float32(0.01 * j).astype(float))
    np.testing.assert_array_equal(log["imu_r"], np.full(301, np.float32(0.3), float))
    np.testing.assert_array_equal(log["imu_ax"], np.float32(0.1 * j).astype(float))
    np.testing.assert_array_equal(log["imu_az"], np.full(301, np.float32(-9.8), float))
    # Attitude from the quaternion (float32), on its sample time, yaw across +-pi.
    np.testing.assert_allclose(log["att_roll"], 0.1 + 0.5 * (t - 1.0), atol=2e-7)
    np.testing.assert_allclose(log["att_pitch"], -0.05 + 0.1 * (t - 1.0), atol=2e-7)
    np.testing.assert_allclose(_wrap(log["att_yaw"] - (3.0 + 0.5 * (t - 1.0))), 0, atol=2e-7)
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(t, _us(1.0, 10, 31) / 1e6)
    np.testing.assert_allclose(log["gps_pn"], 20 * (s - 1.0), atol=1e-5)
    np.testing.assert_allclose(log["gps_pe"], -10 * (s - 1.0), atol=1e-5)
    np.testing.assert_allclose(log["gps_pd"], -50 + 2.5 * (s - 1.0), atol=1e-5)
    np.testing.assert_array_equal(log["gps_vn"], np.full(301, 20.0))
    np.testing.assert_array_equal(log["gps_vd"], np.full(301, 2.5))
    np.testing.assert_allclose(log["pitot_airspeed"], 20 + 5 * (s - 1.0), atol=1e-12)
    np.testing.assert_allclose(log["pitot_qbar"], 240 + 10 * (s - 1.0), atol=1e-10)
    np.testing.assert_allclose(log["baro_alt"], 50 + 2.5 * (s - 1.0), atol=1e-12)
    np.testing.assert_array_equal(log["est_wind_n"], np.full(301, 4.0))
    # actuator_controls_0 (50 Hz) held: pitch-up demand 0.1 -> elevator -2.5 deg.
    k = np.floor((t - 1.0) / 0.02 + 1e-9)
    np.testing.assert_allclose(log["cmd_elevator"], -float(np.float32(0.1)) * 25 * DEG,
                               rtol=1e-15)
    np.testing.assert_allclose(log["cmd_aileron"], np.float32(0.004 * k) * 25 * DEG, rtol=1e-6)
    np.testing.assert_allclose(log["cmd_rudder"], np.float32(0.002 * k) * 25 * DEG, rtol=1e-6)
    np.testing.assert_allclose(log["cmd_throttle"], 0.6, rtol=1e-7)
    for name in log.names:
        assert log.unit(name) == CHANNELS[name][0], name
    assert log.metadata["actuators"]["message"] == "actuator_controls_0"


def test_ulog_outputs_older_topics_and_options(tmp_path):
    path = _multirate_ulg(tmp_path / "flight.ulg", outputs=True, older_names=True)
    log = read_px4(path, airspeed="indicated")
    t = log.time
    k = np.floor((t - 1.0) / 0.02 + 1e-9)
    np.testing.assert_allclose(log["cmd_aileron"], (2 * k / 500) * 25 * DEG, atol=1e-15)
    np.testing.assert_allclose(log["cmd_elevator"], -((100 - 2 * k) / 500) * 25 * DEG,
                               atol=1e-15)
    np.testing.assert_allclose(log["cmd_throttle"], 0.5)
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(t, _us(1.0, 10, 31) / 1e6)
    np.testing.assert_allclose(log["pitot_airspeed"], 18 + 5 * (s - 1.0), atol=1e-12)
    np.testing.assert_allclose(log["pitot_qbar"], 240 + 10 * (s - 1.0), atol=1e-10)
    np.testing.assert_array_equal(log["est_wind_e"], np.full(t.size, -2.0))
    with pytest.raises(ValueError, match="airspeed: 'true' or 'indicated'"):
        read_px4(path, airspeed="calibrated")
    log = read_px4(path, instance=1)
    np.testing.assert_array_equal(log["imu_r"], np.full(t.size, np.float32(1.3), float))
    # instance picks the IMU only; vehicle_attitude stays multi-id 0.
    np.testing.assert_array_equal(log["att_roll"], read_px4(path)["att_roll"])
    extra = {"gps_speed": FieldSource("vehicle_local_position", "vx", "m/s", scale=2.0)}
    np.testing.assert_array_equal(read_px4(path, extra=extra)["gps_speed"], np.full(301, 40.0))


def test_ulog_truncated_file(tmp_path):
    path = _multirate_ulg(tmp_path / "flight.ulg")
    whole = path.read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(whole[:-9])
    with pytest.raises(FlightLogError, match=r"cut\.ulg: truncated file: a message at byte \d+ "
                                             r"needs \d+ bytes, \d+ remain"):
        read_log(cut, allow_truncated=False)
    with pytest.warns(UserWarning, match=r"truncated file.*; dropped"):
        log = read_log(cut)  # by default the cut message is dropped
    assert len(log) > 290
    for size in (20, 2000, len(whole) // 2 + 1):
        cut.write_bytes(whole[:size])
        with pytest.raises(FlightLogError, match=r"cut\.ulg: truncated file"):
            read_log(cut, allow_truncated=False)
    cut.write_bytes(whole[:20])  # cut before any data: an error even by default
    with pytest.raises(FlightLogError, match=r"cut\.ulg: .*(truncated file|not a PX4 ULog)"):
        read_log(cut)


# ------------------------------------------------------------------ round trip
@pytest.mark.parametrize("suffix", [".bin", ".ulg"])
def test_round_trip_of_canonical_channels(tmp_path, suffix):
    """Canonical log -> native file -> reader: every channel back within its quantisation."""
    log = _canonical_log()
    if suffix == ".bin":
        path = dataflash_from_log(log, tmp_path / "log.bin")
        back = read_log(path, extra=_VANES)
    else:
        path = ulog_from_log(log, tmp_path / "log.ulg")
        back = read_log(path, extra={"vane_alpha": FieldSource("vane_angles", "alpha", "rad"),
                                     "vane_beta": FieldSource("vane_angles", "beta", "rad")})
    np.testing.assert_array_equal(back.time, np.round(log.time * 1e6) / 1e6)
    assert set(back.names) == set(log.names)
    pwm_step = FULL_DEFLECTION / 500  # one microsecond of servo PWM
    tolerance = {"m": 0.012, "rad": 1e-4, "1": 1 / 1600}
    for name in log.names:
        assert back.unit(name) == log.unit(name)
        error = back[name] - log[name]
        if name == "att_yaw":
            error = _wrap(error)
        if name.startswith("cmd_") and name != "cmd_throttle":
            limit = pwm_step / 2 + 1e-12 if suffix == ".bin" else 1e-7
        else:
            limit = max(tolerance.get(log.unit(name), 0.0), 1e-6 * np.abs(log[name]).max())
        assert np.abs(error).max() <= limit, (name, np.abs(error).max(), limit)


def test_commands_logged_faster_than_the_imu_are_the_time_base():
    """A 100 Hz servo stream next to a 50 Hz IMU: no command is lost to the hold."""
    from drake_uav.io.streams import Stream, align_streams

    imu_t = np.arange(0.0, 2.0, 0.02)
    cmd_t = np.arange(0.0, 2.0, 0.01) + 0.003
    imu = Stream("IMU", imu_t, {"imu_ax": np.sin(imu_t)}, {"imu_ax": "m/s^2"})
    commands = Stream("RCOU", cmd_t, {"cmd_elevator": 0.01 * np.arange(cmd_t.size)},
                      {"cmd_elevator": "rad"}, hold=True)
    log = align_streams(imu, [commands], source="test")
    assert log.metadata["time_base"] == "RCOU"
    np.testing.assert_array_equal(log.time, cmd_t[cmd_t <= imu_t[-1]])
    np.testing.assert_array_equal(log["cmd_elevator"], 0.01 * np.arange(log.time.size))
    np.testing.assert_allclose(log["imu_ax"], np.interp(log.time, imu_t, np.sin(imu_t)))
    slow = Stream("RCOU", cmd_t[::4], {"cmd_elevator": np.zeros(cmd_t[::4].size)},
                  {"cmd_elevator": "rad"}, hold=True)
    assert align_streams(imu, [slow], source="test").metadata["time_base"] == "IMU"
