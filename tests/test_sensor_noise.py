"""Noise floors read from the data: white noise under random-walk and command-driven signals."""

import numpy as np
import pytest
from scipy.signal import lfilter

from drake_uav.estimation.sensor_noise import (
    conditioned_spectrum,
    cross_spectral_density,
    noise_floor_variance,
)

RATE = 100.0
N = 12_000
SIGMA = 0.05


def _noise(seed: int) -> np.ndarray:
    return SIGMA * np.random.default_rng(seed).standard_normal(N)


def _random_walk(seed: int, step: float, integrations: int = 1) -> np.ndarray:
    """A discrete random walk (integrated ``integrations`` times), mean removed."""
    x = step * np.random.default_rng(seed).standard_normal(N)
    for _ in range(integrations):
        x = np.cumsum(x)
        x -= np.linspace(x[0], x[-1], N)  # no drift to the edges
    return x


def test_white_noise_alone():
    assert np.sqrt(noise_floor_variance(_noise(1), RATE)) == pytest.approx(SIGMA, rel=0.05)


def test_noise_under_a_random_walk_that_stays_above_it():
    """A turbulence-driven signal above the noise over the whole top fifth of the band,
    where a flight signal was supposed to have faded."""
    signal = _random_walk(2, 0.15)
    frequency, density, _ = cross_spectral_density(signal[:, None], RATE)
    top = (frequency >= 0.8 * frequency[-1]) & (frequency < frequency[-1])
    assert np.all(density[top, 0, 0].real > 1.5 * 2 * SIGMA**2 / RATE)
    estimate = np.sqrt(noise_floor_variance(signal + _noise(3), RATE))
    assert estimate == pytest.approx(SIGMA, rel=0.1)


def test_noise_under_a_random_walk_and_its_integral():
    signal = _random_walk(12, 0.05) + _random_walk(13, 0.1, integrations=2)
    estimate = np.sqrt(noise_floor_variance(signal + _noise(14), RATE))
    assert estimate == pytest.approx(SIGMA, rel=0.1)


@pytest.mark.parametrize("weight", [0.08, 0.3, 0.5])
def test_noise_averaged_over_two_samples(weight):
    """A channel re-timed by ``weight`` of a sample (linear interpolation) or averaged over
    two samples (0.5: no noise left at the Nyquist frequency): its noise variance per
    sample is ``(1 - w)^2 + w^2`` times the white noise's, under a random walk."""
    noise = _noise(20)
    smoothed = (1.0 - weight) * noise[1:] + weight * noise[:-1]
    signal = _random_walk(21, 0.02)[1:]
    expected = SIGMA * np.sqrt((1.0 - weight) ** 2 + weight**2)
    estimate = np.sqrt(noise_floor_variance(signal + smoothed, RATE))
    assert estimate == pytest.approx(expected, rel=0.1)


def test_a_command_driven_signal_is_set_aside():
    """A command that moves every step, seen through a first-order lag, has neither
    shape of the fit; the logged command removes it."""
    command = lfilter([0.5], [1.0, -0.5], np.random.default_rng(4).standard_normal(N))
    x = 0.3 * command + _random_walk(5, 0.02) + _noise(6)
    plain = np.sqrt(noise_floor_variance(x, RATE))
    assert abs(plain / SIGMA - 1.0) > 0.2
    estimate = np.sqrt(noise_floor_variance(x, RATE, command[:, None]))
    assert estimate == pytest.approx(SIGMA, rel=0.1)


def test_a_channel_fed_back_into_the_commands_keeps_its_noise():
    """A damper commands -k times the measured signal: the commands hold the channel's
    noise, and conditioning on them alone would remove it."""
    measured = _random_walk(7, 0.02) + _noise(8)
    command = -2.0 * measured + 0.01 * np.random.default_rng(9).standard_normal(N)
    frequency, conditioned = conditioned_spectrum(measured, command[:, None], RATE)
    assert np.median(conditioned[len(frequency) // 2:]) < 0.1 * 2 * SIGMA**2 / RATE
    estimate = np.sqrt(noise_floor_variance(measured, RATE, command[:, None]))
    assert estimate == pytest.approx(SIGMA, rel=0.1)


def test_constant_commands_and_silent_channels():
    x = _random_walk(10, 0.02)
    assert noise_floor_variance(np.zeros(N), RATE, np.zeros((N, 2))) == 0.0
    assert conditioned_spectrum(x, np.ones((N, 3)), RATE) is None
    assert np.sqrt(noise_floor_variance(x + _noise(11), RATE, np.ones((N, 3)))) == \
        pytest.approx(SIGMA, rel=0.1)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="at least 8 samples"):
        noise_floor_variance(np.ones(5), RATE)
    with pytest.raises(ValueError, match="1-D"):
        noise_floor_variance(np.ones((50, 2)), RATE)
    with pytest.raises(ValueError, match="rate_hz"):
        noise_floor_variance(np.ones(50), 0.0)
