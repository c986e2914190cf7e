"""ArduPilot .bin logs as they come off real aircraft.

Real files (tests/data/, LGPL-3.0, LICENSE-FlightData.txt; from the PyFlightCoach
FlightData test data): ArduPlane 4.2.3 logs recorded without IMU messages.
Synthetic files, written with the DataFlash writer, reproduce what other real
logs do: a half-written last record in block padding, TimeMS timing, a
separate IMU2 message, PWM 0 before arming, SERVOn parameters with a reversed
servo and +-400 us throws, logging gaps, a 1 Hz airspeed message.
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from drake_uav.io import FlightLogError, read_log
from drake_uav.io.ardupilot import read_ardupilot, read_ardupilot_metadata

try:
    from drake_uav.io.writers import DataFlashWriter
except ImportError:  # the writer's older home
    from log_writers import DataFlashWriter

DATA = Path(__file__).parent / "data"
REAL = {"ardupilot_center_0003.bin": 1038, "ardupilot_pilot_0004.BIN": 2376}
DEG = math.pi / 180.0
G = 9.80665


# --------------------------------------------------------------------- real logs
def _plausible(log) -> None:
    """No surface beyond its limit, attitude in range, specific force about g at rest."""
    for name in ("cmd_elevator", "cmd_aileron", "cmd_rudder"):
        if name in log:
            limit = abs(log.metadata["actuators"][name[4:]]["full_value"])
            assert np.abs(log[name]).max() <= limit + 1e-12, name
    assert np.abs(log["att_roll"]).max() <= math.pi
    assert np.abs(log["att_pitch"]).max() <= math.pi / 2
    still = np.linalg.norm(log.stack(["imu_p", "imu_q", "imu_r"]), axis=1) < 0.05
    if np.any(still):
        force = np.linalg.norm(log.stack(["imu_ax", "imu_ay", "imu_az"])[still], axis=1)
        assert abs(np.median(force) - G) < 0.5


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_logs_read_or_stop_with_one_line_reason(name):
    path = DATA / name
    try:
        log = read_log(path)
    except FlightLogError as err:
        message = str(err)
        assert "\n" not in message and message.startswith(str(path))
        # These logs were recorded without the IMU (LOG_BITMASK 1029).
        assert re.search(r"no IMU messages \(the time base\): recorded without IMU logging "
                         r"\(LOG_BITMASK = 1029 lacks the IMU bit 128", message), message
    else:
        _plausible(log)


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_logs_metadata_and_servo_mapping(name):
    meta = read_ardupilot_metadata(DATA / name)
    assert meta["firmware"] == "ArduPlane V4.2.3 (55685c43)"
    assert meta["vehicle_type"] == {"mav_type": 1, "name": "fixed wing"}
    assert [m[1] for m in meta["flight_modes"]] == ["MANUAL"]
    assert "vtol_state" not in meta
    assert len(meta["parameters"]) == 1081 and meta["parameters"]["SERVO2_FUNCTION"] == 19
    # The IMU position parameters as ArduPlane 4.2 writes them (this airframe: at the origin).
    assert meta["imu_position"] == {"position": [0.0, 0.0, 0.0], "source": "INS_POS1_X/Y/Z"}
    act = meta["actuators"]
    assert act["source"] == "SERVOn parameters" and act["message"] == "RCOU"
    fields = {c: act[c]["field"] for c in ("aileron", "elevator", "throttle", "rudder")}
    assert fields == {"aileron": "C1", "elevator": "C2", "throttle": "C3", "rudder": "C4"}
    # +-400 us throws about a 1500 us trim; the throttle from SERVO3_MIN..MAX.
    assert (act["elevator"]["neutral"], act["elevator"]["full"],
            act["elevator"]["full_low"]) == (1500, 1900, 1100)
    assert act["elevator"]["full_value"] == pytest.approx(-25 * DEG)
    assert act["elevator"]["valid_range"] == [1050, 1950]
    assert (act["throttle"]["neutral"], act["throttle"]["full"]) == (1100, 1900)


def test_real_logs_decoded_messages_are_plausible():
    """The streams the real logs do have: attitude in range, GPS fix, one record per
    message up to the block padding."""
    from drake_uav.io.dataflash import DataFlash

    for name, n_att in REAL.items():
        log = DataFlash(DATA / name)
        time, att = log.read("ATT", ["Roll", "Pitch", "Yaw"])
        assert time.size == n_att - 1 or time.size == n_att
        assert np.abs(att["Roll"]).max() <= 180 and np.abs(att["Pitch"]).max() <= 90
        assert 0 <= att["Yaw"].min() and att["Yaw"].max() < 360
        assert np.all(np.diff(time) > 0)
        _, gps = log.read("GPS", ["Status", "Lat", "Lng"], "I", 0)
        fix = gps["Status"] >= 3
        assert np.any(fix) and np.all(np.abs(gps["Lat"][fix]) <= 90)


# ------------------------------------------------------------------ synthetic logs
def _us(start_s, rate_hz, end_s):
    return np.round(1e6 * np.arange(start_s, end_s - 1e-9, 1.0 / rate_hz)).astype(np.uint64)


_SERVOS = {  # n: (function, min, max, trim, reversed)
    1: (4, 1100, 1900, 1500, 0), 2: (19, 1100, 1900, 1500, 1), 3: (70, 1000, 2000, 1000, 0),
    4: (21, 1000, 1900, 1400, 0), 5: (0, 1100, 1900, 1500, 0),
}


def _defines(w, *, time_ms=False, imu_field=True):
    clock = "TimeMS" if time_ms else "TimeUS"
    if imu_field:
        w.define("IMU", "QBffffff", f"{clock},I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    else:
        for name in ("IMU", "IMU2"):
            w.define(name, "Qffffff", f"{clock},GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    w.define("ATT", "QccccCC", f"{clock},DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw")
    w.define("RCOU", "QHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6")
    w.define("PARM", "QNf", "TimeUS,Name,Value")
    w.define("MSG", "QZ", "TimeUS,Message")
    w.define("MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn")


def _flight(path, *, duration=6.0, imu_hz=200.0, firmware="ArduPlane V4.3.7 (abcdef12)",
            params=None, servos=_SERVOS, arm_s=0.0, imu_gap=None, arsp_hz=10.0,
            imu_field=True, modes=((0.5, 5), (3.0, 10)), aoa=False, aetr=False, fix_s=0.0,
            ground_s=0.0):
    """A level, still aircraft: IMU (two instances, ``I`` field or IMU/IMU2), ATT 25 Hz,
    RCOU 50 Hz (PWM 0 before ``arm_s``), GPS 5 Hz (3-D fix from ``fix_s``), ARSP
    (-0.3 m/s before ``ground_s``), BARO 10 Hz, parameters, firmware string and modes.
    Servo PWMs ramp between the MIN and MAX of ``servos``."""
    w = DataFlashWriter()
    _defines(w, imu_field=imu_field)
    w.define("GPS", "QBBLLeffff", "TimeUS,I,Status,Lat,Lng,Alt,Spd,GCrs,VZ,U")
    w.define("ARSP", "QBff", "TimeUS,I,Airspeed,DiffPress")
    w.define("BARO", "QBf", "TimeUS,I,Alt")
    w.define("AOA", "Qff", "TimeUS,AOA,SSA")
    w.define("AETR", "Qfffff", "TimeUS,Ail,Elev,Thr,Rudd,Flap")
    imu = _us(0.0, imu_hz, duration)
    if imu_gap is not None:
        t = imu / 1e6
        imu = imu[(t < imu_gap[0]) | (t >= imu_gap[1])]
    for i in (0, 1):
        columns = dict(TimeUS=imu, GyrX=0.0, GyrY=0.001 * i, GyrZ=0.0, AccX=0.0, AccY=0.0,
                       AccZ=-G - 0.5 * i)
        if imu_field:
            w.add("IMU", I=i, **columns)
        else:
            w.add("IMU2" if i else "IMU", **columns)
    att = _us(0.0, 25, duration)
    w.add("ATT", TimeUS=att, Roll=1.0, Pitch=2.0, Yaw=90.0)
    rcou = _us(0.0, 50, duration)
    ramp = np.linspace(-1.0, 1.0, rcou.size)
    pwm = {}
    for n, (_, low, high, trim, _) in (servos or _SERVOS).items():
        pwm[f"C{n}"] = np.round(np.where(ramp >= 0, trim + ramp * (high - trim),
                                         trim + ramp * (trim - low)))
        pwm[f"C{n}"][rcou / 1e6 < arm_s] = 0
    w.add("RCOU", TimeUS=rcou, **pwm)
    gps = _us(0.0, 5, duration)
    w.add("GPS", TimeUS=gps, I=0, Status=np.where(gps < fix_s * 1e6, 1, 3), Lat=47.0, Lng=8.0,
          Alt=500.0, Spd=0.0, GCrs=0.0, VZ=0.0)
    slow = _us(0.0, arsp_hz, duration)
    w.add("ARSP", TimeUS=slow, I=0, Airspeed=np.where(slow < ground_s * 1e6, -0.3, 1.0),
          DiffPress=0.6)
    w.add("BARO", TimeUS=_us(0.0, 10, duration), I=0, Alt=0.1)
    if aoa:
        w.add("AOA", TimeUS=att, AOA=4.0, SSA=-1.0)
    if aetr:
        w.add("AETR", TimeUS=rcou, Ail=4500 * ramp, Elev=-2250.0, Thr=40.0, Rudd=0.0, Flap=0.0)
    _parameters(w, params, servos)
    w.add("MSG", TimeUS=np.uint64(10), Message=firmware)
    w.add("MODE", TimeUS=np.array([int(t * 1e6) for t, _ in modes], np.uint64), Mode=0,
          ModeNum=np.array([m for _, m in modes]), Rsn=1)
    return w.save(path)


def _parameters(w, params, servos):
    values = {}
    for n, (function, low, high, trim, rev) in (servos or {}).items():
        values.update({f"SERVO{n}_FUNCTION": function, f"SERVO{n}_MIN": low,
                       f"SERVO{n}_MAX": high, f"SERVO{n}_TRIM": trim,
                       f"SERVO{n}_REVERSED": rev})
    values.update(params or {})
    if values:
        w.add("PARM", TimeUS=np.full(len(values), 5, np.uint64), Name=list(values),
              Value=np.array(list(values.values()), float))


def test_truncated_tail_in_block_padding_is_dropped_with_a_warning(tmp_path):
    whole = _flight(tmp_path / "whole.bin").read_bytes()
    cut = whole[:-9]  # power lost halfway through the last record, then the block padded
    padded = tmp_path / "padded.bin"
    padded.write_bytes(cut + bytes(-len(cut) % 4096))
    with pytest.warns(UserWarning, match=r"padded\.bin: truncated file: the last \w+ message"):
        log = read_ardupilot(padded)
    assert log.equals(read_ardupilot(tmp_path / "whole.bin"))  # the cut IMU was instance 1
    with pytest.raises(FlightLogError, match=r"padded\.bin: truncated file.*allow_truncated"):
        read_ardupilot(padded, allow_truncated=False)
    middle = whole.index(bytes([0xA3, 0x95]), len(whole) // 2)
    corrupt = tmp_path / "corrupt.bin"
    corrupt.write_bytes(whole[:middle] + bytes([0xA3, 0x95, 0xF0]) + bytes(20) + whole[middle:])
    with pytest.raises(FlightLogError, match=r"corrupt\.bin: the \d+ bytes from byte \d+ on .* "
                                             r"could not be parsed: corrupt data in the log"):
        read_ardupilot(corrupt)


def test_time_ms_log_is_unsupported_firmware(tmp_path):
    w = DataFlashWriter()
    _defines(w, time_ms=True)
    w.add("IMU", TimeMS=np.arange(1, 100, dtype=np.uint64), I=0, AccZ=-G)
    w.add("ATT", TimeMS=np.arange(1, 100, dtype=np.uint64), Roll=0.0)
    path = w.save(tmp_path / "old.bin")
    with pytest.raises(FlightLogError, match=r"old\.bin: unsupported firmware \(TimeMS log\)"):
        read_log(path)


@pytest.mark.parametrize("imu_field", [True, False])
def test_second_imu_on_every_generation(tmp_path, imu_field):
    path = _flight(tmp_path / "two.bin", imu_field=imu_field)
    first, second = read_ardupilot(path), read_ardupilot(path, instance=1)
    np.testing.assert_allclose(first["imu_az"], -G, rtol=1e-6)
    np.testing.assert_allclose(second["imu_az"], -G - 0.5, rtol=1e-6)
    assert second.metadata["time_base"] == ("IMU" if imu_field else "IMU2")
    want = (r"no IMU messages with I = 2 \(the time base\); the log has I = 0, 1" if imu_field
            else r"no IMU3 messages \(the time base\); the log has IMU and IMU2 messages")
    with pytest.raises(FlightLogError, match=want):
        read_ardupilot(path, instance=2)


def test_second_gps_baro_and_airspeed_as_separate_messages(tmp_path):
    """ArduPilot 4.0 and earlier: GPS2, BAR2, ASP2 messages without an instance field."""
    w = DataFlashWriter()
    _defines(w, imu_field=False)
    for k, name in enumerate(("GPS", "GPS2")):
        w.define(name, "QBLLeffff", "TimeUS,Status,Lat,Lng,Alt,Spd,GCrs,VZ,U")
        w.add(name, TimeUS=_us(0.0, 5, 4.0), Status=3, Lat=47.0, Lng=8.0, Alt=500.0,
              Spd=10.0 + k, GCrs=0.0, VZ=0.0)
    for k, (baro, arsp) in enumerate((("BARO", "ARSP"), ("BAR2", "ASP2"))):
        w.define(baro, "Qf", "TimeUS,Alt")
        w.define(arsp, "Qff", "TimeUS,Airspeed,DiffPress")
        w.add(baro, TimeUS=_us(0.0, 10, 4.0), Alt=100.0 + k)
        w.add(arsp, TimeUS=_us(0.0, 10, 4.0), Airspeed=20.0 + k, DiffPress=240.0)
    for name in ("IMU", "IMU2"):
        w.add(name, TimeUS=_us(0.0, 200, 4.0), AccZ=-G)
    w.add("ATT", TimeUS=_us(0.0, 25, 4.0), Roll=0.0)
    w.add("RCOU", TimeUS=_us(0.0, 50, 4.0), C1=1500, C2=1500, C3=1100, C4=1500)
    path = w.save(tmp_path / "legacy.bin")
    with pytest.warns(UserWarning, match=r"no SERVOn parameters"):
        first, second = read_ardupilot(path), read_ardupilot(path, instance=1)
    for log, k in ((first, 0), (second, 1)):
        np.testing.assert_allclose(log["gps_vn"], 10.0 + k, rtol=1e-6)
        np.testing.assert_allclose(log["baro_alt"], 100.0 + k, rtol=1e-6)
        np.testing.assert_allclose(log["pitot_airspeed"], 20.0 + k, rtol=1e-6)
    assert set(second.metadata["streams"]) >= {"IMU2", "GPS2", "BAR2", "ASP2"}


def test_pwm_zero_before_arming_is_invalid_never_a_deflection(tmp_path):
    path = _flight(tmp_path / "arming.bin", arm_s=2.0)
    log = read_ardupilot(path)
    assert log.time[0] >= 2.0 and log.metadata["segments"][0][0] >= 2.0
    assert log.metadata["streams"]["RCOU"]["invalid"] == 100
    for name in ("cmd_elevator", "cmd_aileron", "cmd_rudder"):
        assert np.abs(log[name]).max() <= 25 * DEG + 1e-12


def test_servo_parameters_reversed_servo_and_400_us_throws(tmp_path):
    deflection = {"elevator": 20 * DEG, "aileron": 15 * DEG, "rudder": 30 * DEG}
    path = _flight(tmp_path / "servos.bin")
    log = read_ardupilot(path, deflections=deflection)
    rcou = (np.arange(300) / 50.0)  # RCOU times; commands held at the IMU samples
    ramp = np.linspace(-1.0, 1.0, 300)[np.searchsorted(rcou, log.time + 1e-9) - 1]
    pwm = {n: np.round(np.where(ramp >= 0, trim + ramp * (high - trim),
                                trim + ramp * (trim - low)))
           for n, (_, low, high, trim, _) in _SERVOS.items()}
    # C1 aileron 1100..1500..1900: +-400 us is full deflection (not 80 % of +-500).
    np.testing.assert_allclose(log["cmd_aileron"],
                               np.where(pwm[1] >= 1500, (pwm[1] - 1500) / 400,
                                        (pwm[1] - 1500) / 400) * 15 * DEG, atol=1e-12)
    # C2 elevator reversed: PWM above trim is a pitch-down demand = positive elevator.
    np.testing.assert_allclose(log["cmd_elevator"], (pwm[2] - 1500) / 400 * 20 * DEG,
                               atol=1e-12)
    # C4 rudder with an off-centre trim: 500 us below, 400 us above.
    np.testing.assert_allclose(log["cmd_rudder"],
                               -np.where(pwm[4] >= 1400, (pwm[4] - 1400) / 500,
                                         (pwm[4] - 1400) / 400) * 30 * DEG, atol=1e-12)
    np.testing.assert_allclose(log["cmd_throttle"], np.clip((pwm[3] - 1000) / 1000, 0, 1),
                               atol=1e-12)
    assert abs(log["cmd_elevator"]).max() == pytest.approx(20 * DEG)
    act = log.metadata["actuators"]
    assert act["source"] == "SERVOn parameters" and act["elevator"]["full_value"] > 0
    no_params = _flight(tmp_path / "no_params.bin", servos=None)
    with pytest.warns(UserWarning, match=r"no_params\.bin: no SERVOn parameters in the log; "
                                         r"RCOU read with the default mapping"):
        log = read_ardupilot(no_params)
    assert log.metadata["actuators"]["source"] == "default (no SERVOn parameters)"


def test_servo_pwm_out_of_range_cuts_and_elevons_are_named(tmp_path):
    servos = dict(_SERVOS)
    servos[5] = (77, 1100, 1900, 1500, 0)
    with pytest.warns(UserWarning, match=r"SERVO5_FUNCTION = 77 \(elevon left\): elevon and "
                                         r"V-tail mixes are not unmixed"):
        read_ardupilot(_flight(tmp_path / "elevon.bin", servos=servos))
    bad = {**_SERVOS, 2: (19, 1100, 1900, 1950, 0)}
    with pytest.raises(FlightLogError, match=r"SERVO2_TRIM = 1950 of the elevator is not between"):
        read_ardupilot(_flight(tmp_path / "trim.bin", servos=bad))
    narrow = {"SERVO1_MIN": 1200, "SERVO1_MAX": 1800}  # PWMs logged out to 1100..1900
    log = read_ardupilot(_flight(tmp_path / "narrow.bin", params=narrow), actuators="servo")
    assert log.metadata["streams"]["RCOU"]["invalid"] > 0
    assert len(log.metadata["segments"]) == 1 and np.abs(log["cmd_aileron"]).max() <= 25 * DEG


def test_gaps_cut_segments_and_sparse_airspeed_is_dropped(tmp_path):
    path = _flight(tmp_path / "gap.bin", imu_gap=(2.5, 3.74))
    log = read_ardupilot(path)
    segments = np.array(log.metadata["segments"])
    assert len(segments) == 2 and segments[0, 1] < 2.5 and segments[1, 0] >= 3.74
    assert not np.any((log.time > 2.5) & (log.time < 3.74))
    with pytest.warns(UserWarning, match=r"sparse\.bin: optional stream 'ARSP' dropped: sparse: "
                                         r"logged at 1 Hz"):
        log = read_ardupilot(_flight(tmp_path / "sparse.bin", arsp_hz=1.0))
    assert log.metadata["dropped_streams"] == ["ARSP"] and "pitot_airspeed" not in log
    assert "baro_alt" in log and "gps_vn" in log


def test_negative_airspeed_late_gps_fix_and_slow_imu(tmp_path):
    log = read_ardupilot(_flight(tmp_path / "ground.bin", fix_s=1.0, ground_s=2.0))
    # GPS without a fix for 1 s and airspeed -0.3 m/s for 2 s: both optional, the log
    # keeps its start and leaves them out (with a warning) rather than cutting it.
    assert log.time[0] == 0.0
    assert set(log.metadata["dropped_streams"]) == {"GPS", "ARSP"}
    later = read_ardupilot(tmp_path / "ground.bin", segment=(2.5, 5.0))
    assert later.time[0] == 2.5 and later.time[-1] == 5.0
    assert later.metadata["dropped_streams"] == [] and "gps_vn" in later
    with pytest.raises(FlightLogError, match=r"no segment .* stream 'IMU' .*span t = 7 s to 8 s"):
        read_ardupilot(tmp_path / "ground.bin", segment=(7.0, 8.0))
    with pytest.warns(UserWarning, match=r"slow\.bin: IMU logged at 50 Hz \(< 100 Hz\)"):
        log = read_ardupilot(_flight(tmp_path / "slow.bin", imu_hz=50.0))
    assert log.metadata["imu_rate_hz"] == pytest.approx(50.0)


def test_flight_modes_vehicle_type_and_ahrs_angles(tmp_path):
    log = read_ardupilot(_flight(tmp_path / "plane.bin", aoa=True))
    meta = log.metadata
    assert meta["firmware"] == "ArduPlane V4.3.7 (abcdef12)"
    assert meta["vehicle_type"] == {"mav_type": 1, "name": "fixed wing"}
    assert meta["flight_modes"] == [[0.5, "FBWA"], [3.0, "AUTO"]]
    assert meta["parameters"]["SERVO2_REVERSED"] == 1
    np.testing.assert_allclose(log["ahrs_alpha"], 4 * DEG, rtol=1e-6)
    np.testing.assert_allclose(log["ahrs_beta"], -DEG, rtol=1e-6)
    assert "vane_alpha" not in log and log.unit("ahrs_alpha") == "rad"
    quad = read_ardupilot(_flight(tmp_path / "quadplane.bin", params={"Q_ENABLE": 1},
                                  modes=((0.5, 18), (3.0, 5))))
    assert quad.metadata["vehicle_type"]["mav_type"] == 22
    assert quad.metadata["vtol_state"] == [[0.5, "mc"], [3.0, "fw"]]
    motors = {n: (32 + n, 1000, 2000, 1000, 0) for n in range(1, 7)}
    hexa = read_ardupilot(_flight(tmp_path / "hexa.bin", firmware="ArduCopter V4.4.0 (x)",
                                  params={"FRAME_CLASS": 2}, servos=motors,
                                  modes=((0.5, 5),)))
    assert hexa.metadata["vehicle_type"] == {"mav_type": 13, "name": "hexarotor"}
    assert hexa.metadata["flight_modes"] == [[0.5, "LOITER"]]
    assert not any(n.startswith("cmd_") for n in hexa.names)
    unknown = read_ardupilot(_flight(tmp_path / "unknown.bin", firmware=""))
    assert "vehicle_type" not in unknown.metadata  # not guessed when nothing tells


def test_aetr_demands_on_request(tmp_path):
    path = _flight(tmp_path / "aetr.bin", aetr=True)
    log = read_ardupilot(path, actuators="aetr")
    np.testing.assert_allclose(log["cmd_elevator"], 0.5 * 25 * DEG, rtol=1e-6)
    np.testing.assert_allclose(log["cmd_throttle"], 0.4, rtol=1e-6)
    assert log.metadata["actuators"]["source"] == "AETR demands"
    with pytest.raises(FlightLogError, match=r"actuators='aetr' but the log has no AETR"):
        read_ardupilot(_flight(tmp_path / "no_aetr.bin"), actuators="aetr")
