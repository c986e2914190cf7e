"""FlightLog: validation messages, slicing/resampling, CSV and Parquet round trips."""

import numpy as np
import pytest

from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError, register_unit


def _log(n: int = 101) -> FlightLog:
    t = np.linspace(0.0, 1.0, n)
    return FlightLog(
        t,
        measured={"imu_p": np.sin(3 * t), "baro_alt": 100.0 + 2.0 * t},
        truth={"p": np.sin(3 * t) * 0.99, "alt": 100.0 + 2.0 * t},
        units={"imu_p": "rad/s", "baro_alt": "m", "p": "rad/s", "alt": "m"},
        metadata={"aircraft": "aerosonde", "seed": 3, "wind": [1.0, 2.0, 0.0]},
    )


def test_access_and_kinds():
    log = _log()
    assert log.measured_names == ("imu_p", "baro_alt")
    assert log.truth_names == ("p", "alt")
    assert log.is_truth("alt") and not log.is_truth("imu_p")
    assert log.unit("imu_p") == "rad/s"
    assert len(log) == 101 and log.duration == pytest.approx(1.0)
    assert log.sample_rate == pytest.approx(100.0)
    assert log.stack(["imu_p", "p"]).shape == (101, 2)
    with pytest.raises(ValueError):
        log["imu_p"][0] = 1.0  # read-only
    with pytest.raises(FlightLogError, match="missing channel 'gyro_q'"):
        log["gyro_q"]


def test_nan_names_channel_and_sample():
    t = np.arange(50) * 0.02
    x = np.ones(50)
    x[17] = np.nan
    with pytest.raises(FlightLogError, match=r"channel 'vane_alpha': NaN at sample 17 \(t = 0\.34"):
        FlightLog(t, measured={"vane_alpha": x}, units={"vane_alpha": "rad"})
    x[17] = np.inf
    with pytest.raises(FlightLogError, match="'vane_alpha': non-finite value inf at sample 17"):
        FlightLog(t, measured={"vane_alpha": x}, units={"vane_alpha": "rad"})


@pytest.mark.parametrize("bad, index", [(5, 5), (1, 1), (49, 49)])
def test_non_monotonic_time_names_sample(bad, index):
    t = np.arange(50) * 0.02
    t[bad] = t[bad - 1]
    with pytest.raises(FlightLogError, match=rf"time: not strictly increasing at sample {index}"):
        FlightLog(t, measured={"x": np.zeros(50)}, units={"x": "m"})


def test_missing_channel_and_unit_errors():
    log = _log()
    with pytest.raises(FlightLogError, match="missing channel 'gps_vn'"):
        log.require("imu_p", "gps_vn")
    with pytest.raises(FlightLogError, match="missing channel 'elevator'"):
        log.validate(required=["elevator"])
    t = np.arange(3.0)
    with pytest.raises(FlightLogError, match="channel 'range': unknown unit 'furlong'"):
        FlightLog(t, measured={"range": t}, units={"range": "furlong"})
    with pytest.raises(FlightLogError, match="channel 'range': no unit given"):
        FlightLog(t, measured={"range": t})
    register_unit("furlong", "length")
    try:
        assert FlightLog(t, measured={"range": t}, units={"range": "furlong"}).unit("range")
    finally:
        UNITS.pop("furlong")


def test_shape_name_and_duplicate_errors():
    t = np.arange(4.0)
    with pytest.raises(FlightLogError, match="channel 'x': 3 samples .* time has 4"):
        FlightLog(t, measured={"x": [1.0, 2.0, 3.0]}, units={"x": "m"})
    with pytest.raises(FlightLogError, match="channel 'x': present both as measured and as truth"):
        FlightLog(t, measured={"x": t}, truth={"x": t}, units={"x": "m"})
    with pytest.raises(FlightLogError, match="channel 'gps vn': invalid name"):
        FlightLog(t, measured={"gps vn": t}, units={"gps vn": "m/s"})
    with pytest.raises(FlightLogError, match="channel 'x': values are not numeric"):
        FlightLog(t, measured={"x": ["a", "b", "c", "d"]}, units={"x": "m"})
    with pytest.raises(FlightLogError, match="time: non-finite value nan at sample 2"):
        FlightLog([0.0, 1.0, np.nan], measured={"x": [1.0, 2.0, 3.0]}, units={"x": "m"})


def test_slice_and_resample():
    log = _log()
    part = log.slice(0.25, 0.5)
    assert part.time[0] == pytest.approx(0.25) and part.time[-1] == pytest.approx(0.5)
    assert part.measured_names == log.measured_names and part.truth_names == log.truth_names
    with pytest.raises(FlightLogError, match="slice: no samples"):
        log.slice(2.0, 3.0)
    # Linear interpolation reproduces a linear channel exactly.
    fine = log.resample(rate_hz=330.0)
    assert fine.sample_rate == pytest.approx(330.0)
    np.testing.assert_allclose(fine["alt"], 100.0 + 2.0 * fine.time, rtol=1e-13)
    # Sample-and-hold returns the last sample at or before each new time.
    held = log.resample(time=[0.0, 0.015, 0.5], method="previous")
    np.testing.assert_array_equal(held["baro_alt"], log["baro_alt"][[0, 1, 50]])
    with pytest.raises(ValueError, match="time: new time base"):
        log.resample(time=[0.5, 1.5])
    with pytest.raises(ValueError, match="method"):
        log.resample(rate_hz=10.0, method="cubic")
    assert log.select(["p"]).names == ("p",)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_round_trip_is_exact(tmp_path, suffix):
    log = _log()
    path = log.save(tmp_path / f"flight{suffix}")
    back = FlightLog.load(path)
    assert back.equals(log)
    assert back.metadata == log.metadata
    assert back.truth_names == ("p", "alt")


def test_csv_from_other_tools_and_bad_files(tmp_path):
    path = tmp_path / "external.csv"
    path.write_text("time [s],gyro_p [rad/s],truth/p [rad/s]\n0,0.1,0.1\n0.1,0.2,0.2\n")
    log = FlightLog.load(path)
    assert log.measured_names == ("gyro_p",) and log.truth_names == ("p",)
    path.write_text("time [s],gyro_p\n0,0.1\n")
    with pytest.raises(FlightLogError, match="column 1 header 'gyro_p' is not 'name \\[unit\\]'"):
        FlightLog.load(path)
    path.write_text("time [s],gyro_p [rad/s]\n0,0.1\n0.2,nan\n")
    with pytest.raises(FlightLogError, match="channel 'gyro_p': NaN at sample 1"):
        FlightLog.load(path)
    path.write_text("time [ms],gyro_p [rad/s]\n0,0.1\n")
    with pytest.raises(FlightLogError, match="time: unit must be 's'"):
        FlightLog.load(path)
    with pytest.raises(ValueError, match="path: unsupported suffix"):
        _log().save(tmp_path / "flight.txt")


def test_with_measured_adds_and_replaces_channels_and_keeps_the_rest():
    log = FlightLog([0.0, 1.0], {"imu_ax": [1.0, 2.0]}, {"alpha": [0.1, 0.2]},
                    units={"imu_ax": "m/s^2", "alpha": "rad"}, metadata={"source": "x"})
    out = log.with_measured({"imu_ax": [3.0, 4.0], "est_alpha": [0.3, 0.4]},
                            {"est_alpha": "rad"})
    np.testing.assert_array_equal(out["imu_ax"], [3.0, 4.0])
    assert out.unit("est_alpha") == "rad" and out.is_truth("alpha")
    assert out.metadata == {"source": "x"} and log["imu_ax"][0] == 1.0
