"""A log faster than the isolation's grid is averaged onto it: every sample's information
kept, the same filter on every channel, the commands aligned like the sensors."""

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.samples.decimation import bin_means, decimation_factor
from drake_uav.identification.samples.flight_data import (
    CONTROLS,
    _on_grid,
    held_commands,
    raw_noise_variance,
    samples_from_log,
)
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.isolation import differentiate
from drake_uav.vehicles import aerosonde

PARAMS = aerosonde()


@pytest.mark.parametrize("rate, jitter, factor", [
    (100.0, 0.0, 2), (150.0, 0.0, 3), (50.0, 0.0, 1), (75.0, 0.0, 1), (100.0, 0.05, 1)])
def test_only_a_uniform_log_an_integer_times_faster_is_averaged(rate, jitter, factor):
    time = np.arange(2000) / rate
    time = time + jitter / rate * np.random.default_rng(0).uniform(-1, 1, time.size)
    assert decimation_factor(time, 50.0) == factor


def test_the_means_keep_every_sample_and_their_times():
    """White noise falls by the factor in variance and stays white; a ramp stays on itself
    at the means' times; a wrapped yaw is averaged across the wrap; a channel the log says
    came at 10 Hz is read at the means' times, not averaged."""
    rng = np.random.default_rng(3)
    time = np.arange(40000) * 0.01
    yaw = (np.pi - 0.02 + 0.001 * np.arange(time.size) + np.pi) % (2 * np.pi) - np.pi
    slow = np.interp(time, time[::10], rng.normal(size=time[::10].size))
    log = FlightLog(time, {"noise": rng.normal(size=time.size), "ramp": 2.0 * time,
                           "att_yaw": yaw, "slow": slow},
                    units={"noise": "1", "ramp": "1", "att_yaw": "rad", "slow": "1"},
                    metadata={"streams": {"X": {"rate_hz": 10.0, "channels": ["slow"]}}})
    means = bin_means(log, 2, 50.0)
    np.testing.assert_allclose(np.diff(means.time), 0.02)
    assert means.time[0] == pytest.approx(0.005)
    assert np.var(means["noise"]) == pytest.approx(0.5, rel=0.05)
    assert abs(np.corrcoef(means["noise"][1:], means["noise"][:-1])[0, 1]) < 0.03
    np.testing.assert_allclose(means["ramp"], 2.0 * means.time)
    np.testing.assert_allclose(np.unwrap(means["att_yaw"]),
                               np.pi - 0.02 + 0.1 * means.time, atol=1e-12)
    np.testing.assert_allclose(means["slow"], np.interp(means.time, time, slow))


def test_a_microsecond_clock_jitter_gives_means_on_one_exact_interval():
    """A 100 Hz log stamped by a microsecond clock (+-2 us) is uniform enough to average;
    the means stand on one exact interval, as the derivatives need, within the jitter of
    their own times."""
    rng = np.random.default_rng(7)
    exact = np.arange(3000) * 0.01
    time = exact + rng.uniform(-2e-6, 2e-6, exact.size)
    log = FlightLog(time, {"ramp": 3.0 * time}, units={"ramp": "1"})
    assert decimation_factor(time, 50.0) == 2
    means = bin_means(log, 2, 50.0)
    steps = np.diff(means.time)
    assert np.ptp(steps) < 1e-12
    np.testing.assert_allclose(means.time, exact.reshape(-1, 2).mean(axis=1), atol=2e-6)
    differentiate(means.time, means["ramp"])  # raised "must be uniform" before


def test_the_commands_are_averaged_as_the_sensors_see_them():
    """Held commands: at the instants, the command in effect at each raw sample; over the
    intervals, the average over the grid step each raw sample starts."""
    stamps = np.arange(0.0, 1.0, 0.01)
    values = np.where(stamps < 0.5, 0.0, 1.0)[:, None]
    at, over = held_commands(stamps, values, stamps, span=0.02)
    assert at[50, 0] == 0.0 and at[51, 0] == 1.0  # a command acts after a sample stamped with it
    assert over[49, 0] == pytest.approx(0.5) and over[48, 0] == pytest.approx(0.0)
    assert over[50, 0] == pytest.approx(1.0)


@pytest.fixture(scope="module")
def flight() -> FlightLog:
    """A minute of light turbulence with the default sensors (logged at 100 Hz)."""
    return fly(PARAMS, turbulence="light", seed=2468, duration=60.0)


CHANNELS = {"imu_ax": "ax", "imu_az": "az", "imu_q": "q", "pitot_airspeed": "airspeed",
            "vane_alpha": "alpha", "vane_beta": "beta"}
"""Logged channels of a simulated flight -> their truth channels (the names the noise
estimate goes by)."""


def test_the_noise_of_the_means_is_read_from_the_data(flight):
    """The noise the job reads for the means (from the 100 Hz log's spectrum: at 50 Hz the
    turbulence hides the accelerometers' floor, 1.3x too high for ax) is that of the means
    of the sensors' errors (measured minus truth, averaged alike), within 20 %."""
    means = bin_means(flight, 2, 50.0)
    estimate = raw_noise_variance(flight, averaged=2)
    for channel, truth in CHANNELS.items():
        true = np.std(means[channel] - means[truth])
        assert 0.8 < np.sqrt(estimate[truth]) / true < 1.2, (channel, true)


def test_averaging_a_100_hz_log_cuts_the_coefficients_error_by_the_square_root_of_two(flight):
    """Against the same log interpolated onto the 50 Hz grid first (every other sample),
    the errors of the measured coefficients (:func:`noise_budget`: against the coefficients
    isolated from the true signals the same way) fall by about sqrt(2)."""
    from drake_uav.testing.noise_budget import ALL, noise_budget

    errors = noise_budget(flight, PARAMS)[ALL]
    before = noise_budget(flight.resample(rate_hz=50.0), PARAMS)[ALL]
    for name in ("CL", "CD", "CY", "Cm"):
        assert 1.25 < before[name] / errors[name] < 1.6, (name, before[name], errors[name])
    samples = samples_from_log(flight, PARAMS)
    assert np.median(np.diff(samples.time)) == pytest.approx(0.02)


@pytest.mark.parametrize("rate", [100.0, 75.0])
def test_a_yaw_across_the_wrap_reaches_the_grid_unwrapped(rate):
    """Averaged (100 Hz) or interpolated (75 Hz) onto the 50 Hz grid, a yaw turning through
    +-pi stays one continuous angle: neither a mean nor an interpolation spans the wrap."""
    time = np.arange(400) / rate
    yaw = (np.pi - 0.5 + 0.5 * time + np.pi) % (2 * np.pi) - np.pi
    channels = {"att_yaw": yaw, **{c: np.zeros(time.size) for c in CONTROLS}}
    log = FlightLog(time, channels, units={c: "rad" for c in channels})
    uniform = _on_grid(log, 50.0, decimation_factor(time, 50.0))[0]
    np.testing.assert_allclose(np.diff(uniform["att_yaw"]), 0.5 / 50.0, rtol=1e-6)
