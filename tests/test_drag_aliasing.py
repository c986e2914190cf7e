"""The drag-axis effects of the campaign against what the baseline already fits
(benchmarks/bench_drag_aliasing.py prints the campaign's figures)."""

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.testing.drag_aliasing import (
    CATALOG,
    DRAG_AXIS,
    WITH_THRUST,
    drag_axis_shares,
    unique_share,
)
from drake_uav.vehicles.loading import load_fixed_wing


def test_unique_share_is_the_part_the_columns_cannot_reproduce():
    t = np.linspace(0.0, 1.0, 400)
    ones, ramp = np.ones_like(t), t
    assert unique_share(2.0 * ramp + 3.0, [ones, ramp]) == pytest.approx(0.0, abs=1e-20)
    wave = np.sin(2 * np.pi * 5 * t)
    assert unique_share(wave, [ones]) == pytest.approx(1.0, abs=1e-3)
    assert unique_share(wave + ramp, [ones, ramp]) == pytest.approx(
        np.var(wave - np.polyval(np.polyfit(t, wave, 1), t)) / np.var(wave + ramp))


@pytest.fixture(scope="module")
def shares():
    params = load_fixed_wing("aerosonde")
    return drag_axis_shares(fly(params, "light", seed=3, duration=40.0), params)


def test_a_drag_that_scales_with_the_thrust_is_a_thrust_and_drag_change(shares):
    """With the thrust model of Beard & McLain (2012), k T / (qbar S) is a throttle^2 thrust
    term plus a C_D_0 change: what the job fits when it identifies the thrust."""
    assert shares["propwash_drag"][CATALOG] > 0.5
    assert shares["propwash_drag"][WITH_THRUST] < 1e-4


def test_a_drift_and_a_logged_tension_stay_visible(shares):
    assert set(shares) == set(DRAG_AXIS)
    for effect in ("drag_drift", "logged_tension"):
        assert min(shares[effect].values()) > 0.5
