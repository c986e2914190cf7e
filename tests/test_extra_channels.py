"""Extra logged channels (a tether tension, a battery voltage) from every log format to the
discovery loop's data-driven candidates (``logged:<channel>``).

The tether flights: a tension that varies slowly and randomly (sinusoids between 0.02 and
0.5 Hz, mean 3 N, standard deviation 1 N, about half the drag coefficient's variation in
light turbulence) pulls along -x body and is logged with a load cell's noise (0.05 N);
default sensors, light turbulence, 120 s. The clean flights (120 s; 60 s in the default
run) log a battery voltage that drains and wanders and acts on nothing. Tuned on seeds
100-109 (tension found, and only it, on 9 of 10; seed 105 adds a false
``accelerometer_lever_arm`` on C_Y); asserted on seeds 0-4.
"""

import math

import numpy as np
import pytest
from log_writers import DataFlashWriter, px4_imu_writer

from drake_uav.cli import main
from drake_uav.diagrams import fly
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.discovery.result import NO_EFFECT_MESSAGE
from drake_uav.identification.pipeline import identify, select_samples
from drake_uav.identification.samples.flight_data import (
    MIN_EXTRA_CHANGES,
    samples_from_log,
    usable_extras,
)
from drake_uav.identification.samples.regressor_noise import smoothing_gains, source_variances
from drake_uav.io import FlightLog, FlightLogError, extra_channels, read_log
from drake_uav.vehicles import aerosonde

PARAMS = aerosonde()
DURATION = 120.0
TENSION_MEAN, TENSION_STD, TENSION_NOISE = 3.0, 1.0, 0.05  # [N]


# ------------------------------------------------------------------------------ flights
def slow_process(seed: int, count: int = 12, band=(0.02, 0.5)):
    """A random signal of unit standard deviation: ``count`` sinusoids in ``band`` [Hz]."""
    rng = np.random.default_rng(seed)
    frequency, phase = rng.uniform(*band, count), rng.uniform(0.0, 2.0 * np.pi, count)
    amplitude = rng.uniform(0.5, 1.0, count)
    scale = math.sqrt(np.sum(amplitude**2) / 2.0)

    def signal(t):
        t = np.atleast_1d(np.asarray(t, float))
        return amplitude @ np.sin(2.0 * np.pi * frequency[:, None] * t + phase[:, None]) / scale

    return signal


def tether_flight(seed: int) -> FlightLog:
    """A flight pulled along -x body by a logged tension ``tension`` [N]: dC_X = -T/(qbar S),
    so dC_L = -T sin(alpha)/(qbar S) and dC_D = T cos(alpha)/(qbar S)."""
    wave = slow_process(1000 + seed)

    def tension(t):
        return np.maximum(TENSION_MEAN + TENSION_STD * wave(t), 0.0)

    def increment(c, t):
        force = float(tension(t)[0]) / (0.5 * PARAMS.rho * c.airspeed**2 * PARAMS.S)
        return (-force * np.sin(c.alpha), force * np.cos(c.alpha), 0.0, 0.0, 0.0, 0.0)

    log = fly(PARAMS, turbulence="light", seed=seed, duration=DURATION, disturbance=increment)
    noise = TENSION_NOISE * np.random.default_rng(5000 + seed).standard_normal(len(log))
    return log.with_measured({"tension": tension(log.time) + noise}, {"tension": "N"})


def voltage_flight(seed: int, duration: float = DURATION) -> FlightLog:
    """A clean flight of ``duration`` [s] logging a battery ``voltage`` [V] (draining,
    wandering by 0.2 V, 0.01 V of noise) that acts on nothing."""
    log = fly(PARAMS, turbulence="light", seed=seed, duration=duration)
    white = 0.01 * np.random.default_rng(6000 + seed).standard_normal(len(log))
    voltage = 12.0 - 0.005 * log.time + 0.2 * slow_process(2000 + seed)(log.time) + white
    return log.with_measured({"voltage": voltage}, {"voltage": "V"})


def findings(result):
    return [(f.name, f.coefficients) for f in result.found]


# ----------------------------------------------------------------------------------- io
def test_csv_columns_beyond_the_canonical_ones_are_extra_channels(tmp_path):
    path = tmp_path / "flight.csv"
    path.write_text("time [s], imu_p [deg/s], tension [N], bus voltage [V], payload, "
                    "probe speed [kt], ahrs_alpha [deg]\n"
                    "0, 1, 2.5, 12.1, 7, 10, 2\n0.1, 2, 2.75, 12.0, 8, 20, 3\n")
    log = read_log(path)
    assert extra_channels(log) == {"tension": "N", "bus_voltage": "V", "payload": "1",
                                   "probe_speed": "m/s"}
    np.testing.assert_array_equal(log["payload"], [7.0, 8.0])
    np.testing.assert_allclose(log["probe_speed"], np.array([10.0, 20.0]) * 1852 / 3600,
                               rtol=1e-15)
    for suffix in (".csv", ".parquet"):
        back = read_log(log.save(tmp_path / f"saved{suffix}"))
        assert back.equals(log) and extra_channels(back) == extra_channels(log), suffix
    assert extra_channels(log.slice(0.05).resample(rate_hz=20.0)) == extra_channels(log)
    with pytest.raises(FlightLogError, match=r"column 2 header 'imu_p' is not 'name \[unit\]'"):
        read_log(_written(tmp_path / "bad.csv", "time [s], imu_p\n0, 1\n"))


def _written(path, text):
    path.write_text(text)
    return path


def _autopilot_log(tmp_path):
    """A 5 s .bin: IMU, ATT, RCOU at 100 Hz, two BAT instances at 10 Hz, ESC RPM at 20 Hz
    from 0.2 s on, with one NaN sample."""
    t = np.arange(500) * 0.01
    us = np.round(1e6 + t * 1e6).astype(np.uint64)
    w = DataFlashWriter()
    w.define("IMU", "QBffffffIIfBB", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH")
    w.define("ATT", "QccccCCffB",
             "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    w.define("RCOU", "QHHHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6,C7,C8")
    w.define("BAT", "QBffff", "TimeUS,Inst,Volt,Curr,CurrTot,Temp")
    w.define("ESC", "QBff", "TimeUS,Instance,RPM,Curr")
    w.add("IMU", TimeUS=us, I=0, AccZ=-9.8, GH=1, AH=1)
    w.add("ATT", TimeUS=us, Roll=0.0)
    w.add("RCOU", TimeUS=us, C1=1500, C2=1500, C3=1500, C4=1500)
    for instance in (0, 1):
        w.add("BAT", TimeUS=us[::10] + instance, Inst=instance, Volt=12.0 - t[::10] + instance,
              Curr=8.0 + instance, Temp=30.0)
    rpm = 6000.0 + 100.0 * t[20::5]
    rpm[36] = np.nan  # at t[200]
    w.add("ESC", TimeUS=us[20::5], Instance=0, RPM=rpm, Curr=5.0)
    return w.save(tmp_path / "flight.bin"), t, rpm


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_bin_battery_esc_and_named_fields_are_extra_channels(tmp_path):
    path, t, rpm = _autopilot_log(tmp_path)
    log = read_log(path, extra_channels=["BAT.Temp"])
    assert extra_channels(log) == {"BAT.Volt": "V", "BAT.Curr": "A", "BAT.Temp": "1",
                                   "esc_rpm_0": "rad/s", "esc_current_0": "A"}
    # Instance 0 only, held between its 10 Hz samples (a slow sensor, as logged).
    held = np.floor(np.round((log.time - 1.0) / 0.1, 9)) * 0.1
    np.testing.assert_allclose(log["BAT.Volt"], 12.0 - held, atol=1e-6)
    np.testing.assert_array_equal(log["BAT.Temp"], 30.0)
    # rev/min -> rad/s; the NaN sample is invalid: the one before it is held over it.
    at_nan = np.flatnonzero(np.isclose(log.time, 1.0 + t[200]))[0]
    assert log["esc_rpm_0"][at_nan] == pytest.approx(rpm[35] * math.pi / 30.0, rel=1e-6)
    # An extra channel never shortens the log: the ESC's first value is held before it.
    assert log.time[0] == 1.0 and log["esc_rpm_0"][0] == pytest.approx(rpm[0] * math.pi / 30.0)
    assert read_log(log.save(tmp_path / "saved.csv")).equals(log)
    with pytest.raises(FlightLogError, match="no field Nope in BAT messages"):
        read_log(path, extra_channels=["BAT.Nope"])
    with pytest.raises(ValueError, match="'BATVolt' is not MESSAGE.FIELD"):
        read_log(path, extra_channels=["BATVolt"])


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_field_of_the_imu_message_is_an_extra_channel_too(tmp_path):
    path, _, _ = _autopilot_log(tmp_path)
    log = read_log(path, extra_channels=["IMU.T"])
    np.testing.assert_array_equal(log["IMU.T"], 0.0)  # the temperature not written
    assert log.metadata["streams"]["IMU.extra"]["channels"] == ["IMU.T"]
    assert log.metadata["time_base"] == "IMU"


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_ulg_battery_and_named_fields_are_extra_channels(tmp_path):
    t = np.arange(500) * 0.01
    us = np.round(1e6 + t * 1e6).astype(np.uint64)
    n = len(t)
    w = px4_imu_writer()
    w.format("actuator_controls_0", "uint64_t timestamp;uint64_t timestamp_sample;"
             "float[8] control")
    w.format("battery_status", "uint64_t timestamp;float voltage_v;float current_a;"
             "float remaining")
    w.data("sensor_combined", w.subscribe("sensor_combined"), timestamp=us,
           gyro_rad=np.zeros((n, 3)), accelerometer_m_s2=np.tile([0.0, 0.0, -9.8], (n, 1)))
    w.data("vehicle_attitude", w.subscribe("vehicle_attitude"), timestamp=us,
           timestamp_sample=us, q=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)))
    w.data("actuator_controls_0", w.subscribe("actuator_controls_0"), timestamp=us,
           timestamp_sample=us, control=np.zeros((n, 8)))
    w.data("battery_status", w.subscribe("battery_status"), timestamp=us[::10],
           voltage_v=12.0 - t[::10], current_a=8.0, remaining=1.0 - 0.01 * t[::10])
    log = read_log(w.save(tmp_path / "flight.ulg"), extra_channels=["battery_status.remaining"])
    assert extra_channels(log) == {"battery_status.voltage_v": "V",
                                   "battery_status.current_a": "A",
                                   "battery_status.remaining": "1"}
    held = np.floor(np.round((log.time - 1.0) / 0.1, 9)) * 0.1
    np.testing.assert_allclose(log["battery_status.voltage_v"], 12.0 - held, atol=1e-6)


def test_extra_channels_option_is_for_autopilot_logs(tmp_path, capsys):
    path = _written(tmp_path / "flight.csv", "time [s], tension [N]\n0, 1\n0.1, 2\n")
    assert main(["identify", str(path), "--extra-channels", "BAT.Volt",
                 "--out", str(tmp_path / "report")]) == 2
    assert "--extra-channels: names fields of .bin, .ulg and .tlog logs" in capsys.readouterr().err


# --------------------------------------------------------------------- identification
def test_constant_and_sparse_extra_channels_are_left_out_with_a_note():
    t = np.arange(300) * 0.01
    log = FlightLog(t, {"tension": np.sin(t), "armed": np.ones_like(t),
                        "mode": np.arange(300) * MIN_EXTRA_CHANGES // 300,
                        "ahrs_alpha": 0.1 * t, "est_alpha": 0.1 * t, "boom_alpha": 0.1 * t,
                        "imu_p": 0 * t},
                  units={"tension": "N", "armed": "1", "mode": "1", "ahrs_alpha": "rad",
                         "est_alpha": "rad", "boom_alpha": "rad", "imu_p": "rad/s"})
    # Estimates of alpha are never extra, nor the flow channel in use (``exclude``).
    usable, notes = usable_extras(log, exclude=("boom_alpha",))
    assert usable == {"tension": "N"}
    assert notes == ("extra channel armed [1] left out: it is constant (1)",
                     f"extra channel mode [1] left out: too sparse: its value changes "
                     f"{MIN_EXTRA_CHANGES - 1} times (< {MIN_EXTRA_CHANGES})")


def test_a_logged_tether_tension_is_found_as_the_logged_channel():
    log = tether_flight(0)
    samples = samples_from_log(log, PARAMS)
    assert samples.signal_units == {"logged:tension": "N"}
    # Its noise, read from the data (or declared), enters the errors-in-variables fit of
    # every coefficient (averaged in pairs onto the 50 Hz grid and smoothed like the
    # regressors).
    smoothed = TENSION_NOISE**2 / 2 * smoothing_gains(0.02)[0]
    assert samples.noise_variance["logged:tension"] == pytest.approx(smoothed, rel=0.3)
    assert source_variances(samples, "CD")["logged:tension"] > 0
    declared = samples_from_log(log, PARAMS, sensor_noise_std={"tension": 0.1})
    assert declared.noise_variance["logged:tension"] == pytest.approx(4.0 * smoothed)
    result = discover(samples, PARAMS)
    assert findings(result) == [("logged:tension", ("CD",))], result.message
    found = result.found[0]
    assert "tension [N]" in found.explanation and "tension / (qbar S)" in found.explanation
    value, sigma = found.parameters["CD:tension"]
    assert abs(value - math.cos(np.mean(samples.condition.alpha))) < 4.0 * sigma


def test_an_unrelated_logged_voltage_finds_nothing():
    log = voltage_flight(0, duration=60.0)
    t = log.time
    log = log.with_measured({"armed": np.ones_like(t), "mode": np.floor(t / 30.0)},
                            {"armed": "1", "mode": "1"})
    samples, selection = select_samples(log, PARAMS)
    assert set(samples.signal_units) == {"logged:voltage"}
    assert [n.split(" left out")[0] for n in selection.notes if "extra channel" in n] == [
        "extra channel armed [1]", "extra channel mode [1]"]
    result = discover(samples, PARAMS)
    assert result.message == NO_EFFECT_MESSAGE and not result.found


# ------------------------------------------------------------------------ main job, slow
@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
def test_the_main_job_finds_the_logged_tension_from_a_csv(seed, tmp_path):
    log = read_log(tether_flight(seed).save(tmp_path / "tether.csv"))
    run = identify(log, PARAMS)
    assert findings(run.discovery) == [("logged:tension", ("CD",))], run.discovery.message
    value, sigma = run.discovery.found[0].parameters["CD:tension"]
    assert abs(value - math.cos(np.mean(run.samples.condition.alpha))) < 4.0 * sigma


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
def test_the_main_job_finds_nothing_in_a_clean_flight_with_a_logged_voltage(seed):
    run = identify(voltage_flight(seed), PARAMS)
    assert run.discovery.message == NO_EFFECT_MESSAGE, run.discovery.message
