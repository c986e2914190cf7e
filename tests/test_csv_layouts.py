"""CSV logs: the low-rate IMU warning, and the layout with a time column per group of
columns (ground-station and ROS-bridge exports), each group at its native rate."""

import warnings

import numpy as np
import pytest

from drake_uav.io import FlightLogError, read_log
from drake_uav.io.streams import logged_rate

IMU = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r")


def _single(path, rate_hz, n=50):
    t = np.arange(n) / rate_hz
    rows = "\n".join(",".join(f"{v:.6g}" for v in (ti, 0.1, 0.0, -9.8, 0.01, 0.0, 0.0))
                     for ti in t)
    path.write_text("time [s]," + ",".join(f"{c} [{'m/s^2' if 'a' in c[4:] else 'rad/s'}]"
                                          for c in IMU) + "\n" + rows + "\n")
    return path


def test_a_slow_imu_column_warns_and_a_100_hz_one_does_not(tmp_path):
    with pytest.warns(UserWarning, match=r"slow\.csv: IMU columns \(column 'time'\) logged at "
                                         r"20 Hz, below 100 Hz: fast dynamics are aliased"):
        read_log(_single(tmp_path / "slow.csv", 20.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_log(_single(tmp_path / "fast.csv", 100.0))


def _grouped(tmp_path, text_after=None):
    """2 s: IMU and attitude at 100 Hz (time [s]), commands at 3 Hz (time_cmd [ms], from
    5 ms), GPS velocity at 5 Hz (time_gps [s]), a tension at 1 Hz (time_load [s])."""
    t = np.arange(201) * 0.01
    groups = {
        "time [s]": (t, {**{f"{c} [{'m/s^2' if c[4] == 'a' else 'rad/s'}]": 0.0 * t
                            for c in IMU}, "att_roll [deg]": 10.0 * t,
                         "att_pitch [rad]": 0.0 * t, "att_yaw [rad]": 0.0 * t}),
        "time_cmd [ms]": (5.0 + np.arange(7) * 1000.0 / 3,
                          {"cmd_elevator [deg]": np.arange(7.0), "cmd_throttle [%]":
                           50.0 + np.arange(7.0)}),
        "time_gps [s]": (np.arange(11) * 0.2, {"gps_vn [m/s]": 20.0 + np.arange(11.0)}),
        "time_load [s]": (np.arange(3) * 1.0, {"tension [N]": np.array([1.0, 2.0, 3.0])}),
    }
    header, columns = [], []
    for time_name, (time, channels) in groups.items():
        header += [time_name, *channels]
        columns += [time, *channels.values()]
    rows = [",".join("" if i >= c.size else f"{c[i]:.9g}" for c in columns)
            for i in range(t.size)]
    if text_after is not None:
        rows = text_after(rows)
    path = tmp_path / "export.csv"
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def test_a_time_column_per_group_gives_each_group_its_native_rate(tmp_path):
    with pytest.warns(UserWarning) as caught:
        log = read_log(_grouped(tmp_path))
    messages = [str(w.message) for w in caught]
    assert not any("IMU columns" in m for m in messages)
    assert any("optional stream 'time_load' dropped: sparse: logged at 1 Hz" in m
               for m in messages)
    # The log starts at the first command (5 ms): the IMU's samples from 0.01 s on.
    assert log.metadata["time_base"] == "time" and log.time.size == 200
    assert logged_rate(log, "imu_ax") == pytest.approx(100.0)
    assert logged_rate(log, "cmd_elevator") == pytest.approx(3.0)
    assert logged_rate(log, "gps_vn") == pytest.approx(5.0)
    # Units converted per column; commands held from each of their own times (ms).
    np.testing.assert_allclose(log["att_roll"], np.radians(10.0 * log.time), atol=1e-12)
    held = np.floor((log.time - 0.005) * 3 + 1e-9)
    np.testing.assert_allclose(log["cmd_elevator"], np.radians(held), atol=1e-12)
    np.testing.assert_allclose(log["cmd_throttle"], 0.5 + 0.01 * held, atol=1e-12)
    # GPS (5 Hz, below 0.45 of the IMU's rate) held as logged.
    np.testing.assert_allclose(log["gps_vn"], 20.0 + np.floor(log.time / 0.2 + 1e-9))
    assert "tension" not in log


def test_grouped_layout_errors_name_the_column_and_line(tmp_path):
    def hole(rows):  # an empty GPS cell at data row 3 (file line 5)
        cells = rows[3].split(",")
        cells[14] = ""
        return [*rows[:3], ",".join(cells), *rows[4:]]

    with pytest.raises(FlightLogError, match=r"column 'gps_vn': empty cell at line 5, inside "
                                             r"its time group 'time_gps'"):
        read_log(_grouped(tmp_path, hole))

    def late(rows):  # a tension after the end of its 3 samples (data row 5, line 7)
        cells = rows[5].split(",")
        cells[-1] = "4"
        return [*rows[:5], ",".join(cells), *rows[6:]]

    with pytest.raises(FlightLogError, match=r"column 'tension': a value at line 7 after the "
                                             r"end of its time group 'time_load' \(its last "
                                             r"time at line 4\)"):
        read_log(_grouped(tmp_path, late))
    path = tmp_path / "bad.csv"
    path.write_text("imu_p [rad/s],time [s],time_gps [s],gps_vn [m/s]\n1,0,0,1\n1,1,1,1\n")
    with pytest.raises(FlightLogError, match="column 'imu_p' comes before the first time "
                                             "column 'time'"):
        read_log(path)
    path.write_text("time [s],imu_p [rad/s],time_gps [s],truth/gps_vn [m/s]\n0,1,0,1\n"
                    "1,1,1,1\n")
    with pytest.raises(FlightLogError, match="column 'truth/gps_vn': truth channels need the "
                                             "single-time layout"):
        read_log(path)
    path.write_text("time [s],imu_p [rad/s],time_gps [s],gps_vn [m/s]\n0,1,0,1\n1,1,0,1\n")
    with pytest.raises(FlightLogError, match="bad.csv: time_gps repeats at line 3"):
        read_log(path)


def test_voltage_and_current_units_convert_to_si(tmp_path):
    path = tmp_path / "battery.csv"
    path.write_text("time [s],bat_v [mV],bat_i [cA],esc [mA]\n0,12000,250,5\n0.1,11990,260,6\n")
    log = read_log(path)
    assert (log.unit("bat_v"), log.unit("bat_i"), log.unit("esc")) == ("V", "A", "A")
    np.testing.assert_allclose(log["bat_v"], [12.0, 11.99])
    np.testing.assert_allclose(log["bat_i"], [2.5, 2.6])
    np.testing.assert_allclose(log["esc"], [0.005, 0.006])
