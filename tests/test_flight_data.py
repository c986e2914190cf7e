"""samples_from_log reads only what a real log holds: the noise from the data or the
user's declared specs, the commands' hold from the log itself, the GPS where the log has
it."""

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.samples.aero_samples import GPS_POSITION, GPS_VELOCITY
from drake_uav.identification.samples.flight_data import raw_noise_variance, samples_from_log
from drake_uav.identification.samples.segments import concatenate_samples
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
    # The 100 Hz log is averaged in pairs onto the 50 Hz grid: a declared standard deviation
    # is a single sample's, and the noise read from the data is the pairs' means'.
    on_grid = raw_noise_variance(flight, averaged=2)
    plain = samples_from_log(flight, PARAMS)
    specs = samples_from_log(flight, PARAMS, sensor_noise_std={"imu_az": 0.2})
    assert specs.noise_variance["az"] / plain.noise_variance["az"] == \
        pytest.approx(0.04 / 2 / on_grid["az"])
    assert specs.noise_variance["ax"] == plain.noise_variance["ax"]


def test_a_channel_logged_slower_than_the_log_keeps_its_noise():
    """A 10 Hz pitot interpolated onto a 100 Hz log: its noise is read at 10 Hz."""
    from drake_uav.identification.samples.flight_data import native_noise_variance

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


# ----------------------------------------------------------------------------- GPS


GPS = GPS_VELOCITY + GPS_POSITION


def _with(log: FlightLog, channels: dict) -> FlightLog:
    """The log with measured channels replaced or removed (a None value)."""
    kept = {n: channels.get(n, log[n]) for n in log.measured_names
            if channels.get(n, log[n]) is not None}
    return FlightLog(log.time, kept, units={n: log.unit(n) for n in kept})


def _truth_at(flight: FlightLog, samples) -> dict[str, np.ndarray]:
    """The true NED position and ground velocity at the samples' times."""
    position = {g: np.interp(samples.time, flight.time, flight[t])
                for g, t in zip(GPS_POSITION, ("pn", "pe", "pd"), strict=True)}
    velocity = {g: np.interp(samples.time, flight.time, np.gradient(flight[t], flight.time))
                for g, t in zip(GPS_VELOCITY, ("pn", "pe", "pd"), strict=True)}
    return position | velocity


def _rms(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)))


def test_the_gps_velocity_and_position_join_the_signals(flight):
    """Drawn between the receiver's fixes (20 Hz here, 1-2 m and 0.05-0.1 m/s of noise,
    0.1 s late: 2.5 m along the track at 25 m/s, 2.7 m with the noise), on both views."""
    samples = samples_from_log(flight, PARAMS)
    assert set(GPS) <= set(samples.signals) and set(GPS) <= set(samples.moment_view.signals)
    truth = _truth_at(flight, samples)
    for name in GPS_POSITION:
        assert _rms(samples.signals[name], truth[name]) < 3.5, name
    for name in GPS_VELOCITY:
        assert _rms(samples.signals[name], truth[name]) < 0.3, name


def test_a_5_hz_gps_is_drawn_between_its_fixes_not_held(flight):
    """A 5 Hz receiver held on the 100 Hz log: straight lines between its fixes, not the
    held staircase (another 2.5 m behind on average at 25 m/s)."""
    held = {n: flight[n][(np.arange(len(flight)) // 20) * 20] for n in GPS}
    samples = samples_from_log(_with(flight, held), PARAMS)
    truth = _truth_at(flight, samples)
    staircase = np.interp(samples.time, flight.time, held["gps_pn"])
    assert _rms(samples.signals["gps_pn"], truth["gps_pn"]) < 3.5
    assert _rms(staircase, truth["gps_pn"]) > 4.5


def test_a_log_without_gps_or_without_a_fix_over_the_airborne_span_leaves_it_out(flight):
    """No GPS channel, no fix during the first 10 s of flight, a 3 s dropout: no GPS in
    the signals, and nothing else changes. A receiver that gets its fix while the aircraft
    is still on the ground is kept."""
    with_gps = samples_from_log(flight, PARAMS)
    no_gps = samples_from_log(_with(flight, dict.fromkeys(GPS)), PARAMS)
    assert not set(GPS) & set(no_gps.signals)
    assert set(no_gps.signals) == set(with_gps.signals) - set(GPS)
    for name, values in with_gps.coefficients.items():
        np.testing.assert_array_equal(no_gps.coefficients[name], values)
    early = flight.time < 10.0
    no_fix = {n: np.where(early, 0.0, flight[n]) for n in GPS}
    assert not set(GPS) & set(samples_from_log(_with(flight, no_fix), PARAMS).signals)
    dropout = (flight.time >= 30.0) & (flight.time < 33.0)
    lost = {n: np.where(dropout, flight[n][np.argmax(dropout) - 1], flight[n]) for n in GPS}
    assert not set(GPS) & set(samples_from_log(_with(flight, lost), PARAMS).signals)
    on_ground = _with(flight, {**no_fix, "pitot_airspeed": np.where(
        flight.time < 12.0, 0.0, flight["pitot_airspeed"])})
    samples = samples_from_log(on_ground, PARAMS)
    assert samples.time[0] >= 12.0 and set(GPS) <= set(samples.signals)


def test_flight_segments_joined_keep_their_gps(flight):
    parts = [samples_from_log(flight.slice(a, b), PARAMS) for a, b in ((0.0, 25.0),
                                                                        (35.0, 60.0))]
    joined = concatenate_samples(parts)
    for name in GPS:
        np.testing.assert_array_equal(joined.signals[name],
                                      np.concatenate([p.signals[name] for p in parts]))
