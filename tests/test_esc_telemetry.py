"""ESC telemetry (per-motor shaft speed, voltage, current, temperature) from real and written
logs: channel names, SI units, values and each ESC's native rate in the stream metadata.

Real log (tests/data/px4_quad_outdoor_esc_rollover.ulg, a PX4 v1.15 quadrotor flight
uploaded to PX4 Flight Review, from PX4/flight-review-rs, LICENSE-flight-review-rs.txt):
``esc_status`` at 4 Hz with four DShot ESCs.
"""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from log_writers import DataFlashWriter
from pyulog import ULog

from drake_uav.cli import main
from drake_uav.identification.pipeline import check_fixed_wing
from drake_uav.io import FlightLogError, extra_channels, read_log
from drake_uav.io.esc import esc_channel, esc_channels
from drake_uav.io.streams import logged_rate

QUAD = Path(__file__).parent / "data" / "px4_quad_outdoor_esc_rollover.ulg"
QUANTITIES = {"rpm": "rad/s", "voltage": "V", "current": "A", "temperature": "K"}


@pytest.fixture(scope="module")
def quad():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_log(QUAD)


def test_px4_esc_status_gives_every_esc_in_si_units_at_its_native_rate(quad):
    assert list(esc_channels(quad)) == [0, 1, 2, 3]
    for i in range(4):
        for quantity, unit in QUANTITIES.items():
            name = esc_channel(quantity, i)
            assert quad.unit(name) == unit
            assert extra_channels(quad)[name] == unit
            assert logged_rate(quad, name) == pytest.approx(4.0, abs=0.01)
        assert quad.metadata["streams"][f"esc_status.esc{i}"]["messages"] == 320
    # Held as logged (4 Hz against the 200 Hz IMU): the first log sample at or after each
    # ESC message carries that message's value, converted.
    raw = ULog(str(QUAD), ["esc_status"]).get_dataset("esc_status").data
    stamp = raw["timestamp"] / 1e6
    for k in (20, 150, 300):
        at = np.searchsorted(quad.time, stamp[k])
        assert quad["esc_rpm_2"][at] == pytest.approx(raw["esc[2].esc_rpm"][k] * math.pi / 30,
                                                      rel=1e-12)
        assert quad["esc_voltage_1"][at] == pytest.approx(raw["esc[1].esc_voltage"][k])
        assert quad["esc_current_3"][at] == pytest.approx(raw["esc[3].esc_current"][k])
        assert quad["esc_temperature_0"][at] == pytest.approx(
            raw["esc[0].esc_temperature"][k] + 273.15)
    # Airborne: the motors turn at 1000..2000 rad/s (10 to 19 thousand rev/min).
    spinning = quad["esc_rpm_0"][(quad.time > 60.0) & (quad.time < 100.0)]
    assert 900.0 < np.median(spinning) < 2000.0


def test_multicopter_log_is_read_but_refused_for_the_fixed_wing_job(quad):
    assert quad.metadata["vehicle_type"] == {"mav_type": 2, "name": "quadrotor"}
    assert not any(name.startswith("cmd_") for name in quad.names)
    with pytest.raises(FlightLogError, match="not a fixed-wing log .MAV_TYPE 2, quadrotor"):
        check_fixed_wing(quad, str(QUAD))


def test_identify_refuses_the_multicopter_log(tmp_path, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["identify", str(QUAD), "--out", str(tmp_path / "report")])
    assert code == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error")]
    assert errors == [f"error: {QUAD}: not a fixed-wing log (MAV_TYPE 2, quadrotor); identify "
                      "works on fixed-wing and VTOL flights"]
    assert not (tmp_path / "report").exists()


def _esc_bin(tmp_path, old_format=False):
    """A 4 s .bin: IMU, ATT, RCOU at 100 Hz; two ESCs, ESC 0 at 10 Hz and ESC 1 at 5 Hz
    (ESC messages with Instance, or ESC1/ESC2 of older firmware)."""
    t = np.arange(400) * 0.01
    us = np.round(1e6 + t * 1e6).astype(np.uint64)
    w = DataFlashWriter()
    w.define("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH")
    w.define("ATT", "QccccCCffB",
             "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    w.define("RCOU", "QHHHH", "TimeUS,C1,C2,C3,C4")
    w.add("IMU", TimeUS=us, I=0, AccZ=-9.8, GH=1, AH=1)
    w.add("ATT", TimeUS=us, Roll=0.0)
    w.add("RCOU", TimeUS=us, C1=1500, C2=1500, C3=1500, C4=1500)
    rows = {}
    for i, step in ((0, 10), (1, 20)):
        k = slice(i, None, step)
        rows[i] = dict(TimeUS=us[k] + 7, RPM=5000.0 + 1000.0 * i + 100.0 * t[k],
                       Volt=16.0 - i, Curr=3.0 + i, Temp=40.0 + i)
    if old_format:
        for i in rows:
            w.define(f"ESC{i + 1}", "Qffff", "TimeUS,RPM,Volt,Curr,Temp")
            w.add(f"ESC{i + 1}", **rows[i])
    else:
        w.define("ESC", "QBffff", "TimeUS,Instance,RPM,Volt,Curr,Temp")
        for i in rows:
            w.add("ESC", Instance=i, **rows[i])
    return w.save(tmp_path / "esc.bin"), rows


@pytest.mark.parametrize("old_format", [False, True])
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_ardupilot_esc_messages_give_one_stream_per_esc(tmp_path, old_format):
    path, rows = _esc_bin(tmp_path, old_format)
    log = read_log(path)
    assert list(esc_channels(log)) == [0, 1]
    for i, rate in ((0, 10.0), (1, 5.0)):
        assert logged_rate(log, f"esc_rpm_{i}") == pytest.approx(rate, rel=1e-6)
        stream = f"ESC{i + 1}" if old_format else f"ESC[{i}]"
        assert log.metadata["streams"][stream]["channels"] == [
            esc_channel(q, i) for q in QUANTITIES]
        np.testing.assert_array_equal(log[f"esc_voltage_{i}"], 16.0 - i)
        np.testing.assert_array_equal(log[f"esc_current_{i}"], 3.0 + i)
        np.testing.assert_allclose(log[f"esc_temperature_{i}"], 313.15 + i)
    # Held between messages: at the 20th message of ESC 0 (t = 1.90 s + 7 us) and after.
    row = rows[0]
    at = np.searchsorted(log.time, row["TimeUS"][19] / 1e6)
    assert log["esc_rpm_0"][at] == pytest.approx(row["RPM"][19] * math.pi / 30.0, rel=1e-6)
    assert log["esc_rpm_0"][at - 1] == pytest.approx(row["RPM"][18] * math.pi / 30.0,
                                                     rel=1e-6)


def test_esc_channel_names_are_checked():
    assert esc_channel("rpm", 3) == "esc_rpm_3"
    assert esc_channels(["esc_rpm_1", "esc_power_1", "esc_rpm_x", "imu_p", "esc_current_1"]
                        ) == {1: {"rpm": "esc_rpm_1", "current": "esc_current_1"}}
    with pytest.raises(ValueError, match="quantity: one of rpm, voltage, current, temperature"):
        esc_channel("power", 0)
    with pytest.raises(ValueError, match="index: must be >= 0"):
        esc_channel("rpm", -1)


def _rpm_bin(tmp_path, per_instance):
    """A 3 s .bin with IMU, ATT, RCOU at 100 Hz and two RPM sensors at 20 Hz, the second
    unhealthy (-1 rev/min) for its first 0.3 s."""
    t = np.arange(300) * 0.01
    us = np.round(1e6 + t * 1e6).astype(np.uint64)
    w = DataFlashWriter()
    w.define("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH")
    w.define("ATT", "QccccCCffB",
             "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    w.define("RCOU", "QHHHH", "TimeUS,C1,C2,C3,C4")
    w.add("IMU", TimeUS=us, I=0, AccZ=-9.8, GH=1, AH=1)
    w.add("ATT", TimeUS=us, Roll=0.0)
    w.add("RCOU", TimeUS=us, C1=1500, C2=1500, C3=1500, C4=1500)
    k = slice(None, None, 5)
    first = 6000.0 + 10.0 * np.arange(60)
    second = np.where(t[k] < 0.3, -1.0, 3000.0)
    if per_instance:
        w.define("RPM", "QBf", "TimeUS,I,RPM")
        w.add("RPM", TimeUS=us[k], I=0, RPM=first)
        w.add("RPM", TimeUS=us[k] + 3, I=1, RPM=second)
    else:
        w.define("RPM", "Qff", "TimeUS,rpm1,rpm2")
        w.add("RPM", TimeUS=us[k], rpm1=first, rpm2=second)
    return w.save(tmp_path / "rpm.bin"), first


@pytest.mark.parametrize("per_instance", [False, True])
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_ardupilot_rpm_sensors_are_motor_speed_and_motor_speed_2(tmp_path, per_instance):
    path, first = _rpm_bin(tmp_path, per_instance)
    log = read_log(path)
    assert log.unit("motor_speed") == log.unit("motor_speed_2") == "rad/s"
    assert logged_rate(log, "motor_speed") == pytest.approx(20.0)
    np.testing.assert_allclose(log["motor_speed"][::5], first * math.pi / 30.0, rtol=1e-6)
    # The unhealthy samples (-1) are invalid: the first healthy value is held before them.
    np.testing.assert_allclose(log["motor_speed_2"], 3000.0 * math.pi / 30.0, rtol=1e-6)
