"""samples_from_log reads only what a real log holds: the noise from the data or the
user's declared specs, the commands' hold from the log itself."""

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.flight_data import raw_noise_variance, samples_from_log
from drake_uav.io.flight_log import FlightLog
from drake_uav.vehicles import aerosonde

PARAMS = aerosonde()
CHANNELS = {"ax": "imu_ax", "ay": "imu_ay", "az": "imu_az", "p": "imu_p", "q": "imu_q",
            "r": "imu_r", "airspeed": "pitot_airspeed", "alpha": "vane_alpha",
            "beta": "vane_beta"}
TRUTH = {"ax": "ax", "ay": "ay", "az": "az", "p": "p", "q": "q", "r": "r",
         "airspeed": "airspeed", "alpha": "alpha", "beta": "beta"}


@pytest.fixture(scope="module")
def flight() -> FlightLog:
    """A minute of light turbulence with the default (Vaiopoulos 2017, Table 7) sensors."""
    return fly(PARAMS, turbulence="light", seed=4321, duration=60.0)


def _without_metadata(log: FlightLog) -> FlightLog:
    return FlightLog(log.time, {n: log[n] for n in log.measured_names}, units=log.units)


def test_the_simulator_metadata_is_never_read(flight):
    """The true noise and the command rate a simulated flight writes change nothing."""
    assert "sensor_noise_std" in flight.metadata and "sample_rate_hz" in flight.metadata
    bare = _without_metadata(flight)
    misleading = _without_metadata(flight)
    misleading.metadata.update(sample_rate_hz=400.0,
                               sensor_noise_std={c: 1.0 for c in CHANNELS.values()})
    reference = samples_from_log(bare, PARAMS)
    for log in (flight, misleading):
        samples = samples_from_log(log, PARAMS)
        assert samples.noise_variance == reference.noise_variance
        for name, values in reference.coefficients.items():
            np.testing.assert_array_equal(samples.coefficients[name], values)


def test_the_noise_read_from_the_data_is_the_sensors(flight):
    """The turbulence is above the accelerometer noise over the whole band; the
    estimated noise is still within 25 % of the sensors' (the spectrum's top fifth
    read ax 1.3x, az 1.9x too high at 100 Hz)."""
    estimate = raw_noise_variance(flight)
    for name, channel in CHANNELS.items():
        true = np.std(flight[channel] - flight[TRUTH[name]])
        assert 0.8 < np.sqrt(estimate[name]) / true < 1.25, (name, estimate[name], true)


def test_declared_specs_are_used_only_when_given(flight):
    from_data = raw_noise_variance(flight)
    declared = raw_noise_variance(flight, {"imu_az": 0.2, "pitot_qbar": 10.0, "gps_vn": 1.0},
                                  air_density=PARAMS.rho)
    assert declared["az"] == pytest.approx(0.04)
    airspeed = np.median(flight["pitot_airspeed"])
    assert declared["airspeed"] == pytest.approx((10.0 / (PARAMS.rho * airspeed)) ** 2)
    assert {k: v for k, v in declared.items() if k not in ("az", "airspeed")} == \
        {k: v for k, v in from_data.items() if k not in ("az", "airspeed")}
    plain = samples_from_log(flight, PARAMS)
    specs = samples_from_log(flight, PARAMS, sensor_noise_std={"imu_az": 0.2})
    assert specs.noise_variance["az"] / plain.noise_variance["az"] == \
        pytest.approx(0.04 / from_data["az"])
    assert specs.noise_variance["ax"] == plain.noise_variance["ax"]


def test_a_channel_logged_slower_than_the_log_keeps_its_noise():
    """A 10 Hz pitot interpolated onto a 100 Hz log: its noise is read at 10 Hz."""
    from drake_uav.identification.flight_data import native_noise_variance

    rng = np.random.default_rng(11)
    t = np.arange(0.0, 120.0, 0.01)
    logged = t[::10] + 0.004
    airspeed = 25.0 + np.sin(0.3 * logged) + rng.normal(0.0, 0.3, logged.size)
    channels = {"pitot_airspeed": np.interp(t, logged, airspeed)}
    for name in ("cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle"):
        channels[name] = np.zeros(t.size)
    units = {"pitot_airspeed": "m/s", "cmd_elevator": "rad", "cmd_aileron": "rad",
             "cmd_rudder": "rad", "cmd_throttle": "1"}
    streams = {"ARSP": {"rate_hz": 10.0, "channels": ["pitot_airspeed"]}}
    log = FlightLog(t, channels, units=units, metadata={"streams": streams})
    assert np.sqrt(native_noise_variance(log, "pitot_airspeed")) == pytest.approx(0.3, rel=0.15)
    plain = FlightLog(t, channels, units=units)  # without the reader's stream rates
    assert np.sqrt(native_noise_variance(plain, "pitot_airspeed")) < 0.05
