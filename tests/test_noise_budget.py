"""The sensor error budget of the measured coefficients (benchmarks/bench_noise_budget.py
prints the campaign's figures)."""

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.testing.discovery_cases import SUITES, measured_only
from drake_uav.testing.noise_budget import ALL, SENSOR_GROUPS, noise_budget
from drake_uav.vehicles.loading import load_fixed_wing

FORCES, MOMENTS = ("CL", "CD", "CY"), ("Cl", "Cm", "Cn")


@pytest.fixture(scope="module")
def budget():
    params = load_fixed_wing("aerosonde")
    flight = fly(params, "light", seed=3, duration=40.0, sensors=SUITES["default"](params.rho))
    return noise_budget(flight, params)


def test_each_sensor_moves_only_the_coefficients_it_enters(budget):
    """The accelerometers make the forces, the gyros' derivatives the moments."""
    assert set(budget) == {*SENSOR_GROUPS, ALL}
    for c in MOMENTS:
        assert budget["accelerometer"][c] == 0.0
        assert budget["gyro"][c] > 0.0
    for c in FORCES:
        assert budget["gyro"][c] == 0.0
        assert budget["accelerometer"][c] > 0.0
    assert all(budget["attitude"][c] == 0.0 for c in COEFFICIENTS)


def test_independent_sensor_errors_add_in_quadrature(budget):
    for c in COEFFICIENTS:
        parts = np.sqrt(sum(budget[g][c] ** 2 for g in SENSOR_GROUPS))
        assert budget[ALL][c] == pytest.approx(parts, rel=0.05)


def test_the_pitot_dominates_lift_through_the_dynamic_pressure(budget):
    """A relative airspeed error e moves C_L by -2 e C_L: with the default suite's pitot
    (10 Pa on about 380 Pa) that is the largest error of C_L, and of C_D through the thrust
    coefficient T / (qbar S) at the logged airspeed."""
    for c in ("CL", "CD"):
        others = max(budget[g][c] for g in SENSOR_GROUPS if g != "pitot")
        assert budget["pitot"][c] > others


def test_a_flight_without_truth_is_refused():
    params = load_fixed_wing("aerosonde")
    flight = fly(params, "light", seed=3, duration=30.0)
    measured = measured_only(flight)
    with pytest.raises(ValueError, match="truth channel"):
        noise_budget(measured, params)
