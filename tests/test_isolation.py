"""Coefficient isolation (Vaiopoulos 2017, eq. 5.41) and Monte-Carlo uncertainty (sec. 5.6)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.diagrams.identification_flight import fly
from drake_uav.identification.discovery.coefficient_design import baseline_names
from drake_uav.identification.samples.flight_data import held_commands, samples_from_log
from drake_uav.identification.samples.isolation import (
    interval_averages,
    isolate_coefficients,
    monte_carlo_sigma,
    monte_carlo_sigmas,
)
from drake_uav.model.coefficients import COEFFICIENTS, body_to_lift_drag, regressor_matrix
from drake_uav.model.isolation import differentiate
from drake_uav.optimization.trim import trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde
from drake_uav.vehicles.sensors import (
    ChannelErrors,
    ImuParams,
    PitotParams,
    SensorSuiteParams,
    VaneParams,
)


@pytest.fixture(scope="module")
def smooth_flight():
    """Noise-free 20 s flight with smooth (cubic) elevator/aileron/rudder inputs."""
    params = aerosonde()
    level = trim(params, 25.0)
    t = np.linspace(0, 20, 81)
    u = np.tile(level.controls[:, None], (1, len(t)))
    u[0] += 0.04 * np.sin(1.3 * t)
    u[1] += 0.05 * np.sin(2.1 * t) * (t > 4)
    u[2] += 0.04 * np.sin(0.9 * t) * (t > 8)
    builder = DiagramBuilder()
    plant = builder.AddSystem(FixedWingPlant(params))
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.CubicShapePreserving(t, u)))
    builder.Connect(source.get_output_port(), plant.GetInputPort("controls"))
    logs = {name: LogVectorOutput(plant.GetOutputPort(name), builder, 0.01)
            for name in ("state", "air_data", "specific_force", "aero_coefficients")}
    controls_log = LogVectorOutput(source.get_output_port(), builder, 0.01)
    simulator = Simulator(builder.Build())
    simulator.get_mutable_integrator().set_target_accuracy(1e-8)
    plant.set_state(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                    level.state)
    simulator.AdvanceTo(20.0)
    ctx = simulator.get_context()
    data = {k: log.FindLog(ctx).data().T for k, log in logs.items()}
    data["controls"] = controls_log.FindLog(ctx).data().T
    data["time"] = logs["state"].FindLog(ctx).sample_times()
    return params, data


def test_isolation_recovers_the_simulator_coefficients(smooth_flight):
    params, d = smooth_flight
    samples = isolate_coefficients(params, d["time"], d["specific_force"], d["state"][:, 10:13],
                                   d["air_data"], d["controls"])
    truth = d["aero_coefficients"]
    CL, CD = body_to_lift_drag(truth[:, 0], truth[:, 2], d["air_data"][:, 1])
    # The 0.2 s Savitzky-Golay smoothing (and, for moments, differentiation against
    # a 0.09 s roll mode) bounds the agreement with the unfiltered truth.
    expected = {"CL": CL, "CD": CD, "CY": truth[:, 1], "Cl": truth[:, 3], "Cm": truth[:, 4],
                "Cn": truth[:, 5]}
    for name, value in expected.items():
        err = samples.coefficients[name] - value
        variation = np.std(value)
        assert np.sqrt(np.mean(err**2)) < 0.01 * variation, name


def test_differentiate_is_exact_for_cubics_and_rejects_bad_time():
    t = np.arange(0, 2, 0.01)
    y = 2 * t**3 - t + 1
    np.testing.assert_allclose(differentiate(t, y), 6 * t**2 - 1, atol=1e-8)
    with pytest.raises(ValueError, match="uniform"):
        differentiate(np.r_[t[:50], t[51:]], np.r_[y[:50], y[51:]])


def test_isolation_rejects_bad_input(smooth_flight):
    params, d = smooth_flight
    bad = d["air_data"].copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match="air_data is not finite at sample 7"):
        isolate_coefficients(params, d["time"], d["specific_force"], d["state"][:, 10:13], bad,
                             d["controls"])


def test_monte_carlo_sigma_matches_linear_propagation():
    a = np.array([2.0, -0.5, 1.5])
    sigma = np.array([0.1, 0.4, 0.05])
    estimate = monte_carlo_sigma(lambda x, y, z: a[0] * x + a[1] * y + a[2] * z,
                                 np.array([[0, 1], [-2, 2], [5, 6]]), sigma,
                                 correlation=np.array([[1, 0.8, 0], [0.8, 1, 0], [0, 0, 1]]))
    assert estimate == pytest.approx(np.sqrt(np.sum((a * sigma) ** 2)), rel=0.01)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_monte_carlo_sigmas_are_each_outputs_sigma_from_the_same_draws(seed):
    ranges, sigma = np.array([[0.0, 1.0], [-2.0, 2.0]]), np.array([0.1, 0.3])
    outputs = {"sum": lambda x, y: x + y, "product": lambda x, y: x * y,
               "square": lambda x, y: x**2}
    together = monte_carlo_sigmas(lambda x, y: {k: f(x, y) for k, f in outputs.items()},
                                  ranges, sigma, samples=20_000, seed=seed)
    assert together == {k: monte_carlo_sigma(f, ranges, sigma, samples=20_000, seed=seed)
                        for k, f in outputs.items()}


def test_interval_averages_are_exact_for_cubics_and_fourth_order_for_sinusoids():
    t = np.linspace(0.0, 1.0, 51)
    cubic = np.column_stack([1 + t - 2 * t**2 + 3 * t**3, t**2])
    exact = np.diff(np.column_stack([t + t**2 / 2 - 2 * t**3 / 3 + 3 * t**4 / 4, t**3 / 3]),
                    axis=0) / np.diff(t)[:, None]
    # Cubics exactly inside, quadratics up to the ends.
    np.testing.assert_allclose(interval_averages(cubic)[1:-1], exact[1:-1], rtol=1e-12)
    np.testing.assert_allclose(interval_averages(cubic[:, 1])[[0, -1]], exact[[0, -1], 1],
                               rtol=1e-12)
    # A 1.5 Hz sinusoid at 50 Hz: the trapezoid is (w h)^2 / 12 = 0.3 % short, the cubic
    # 11 (w h)^4 / 720 = 0.002 %.
    h, w = 0.02, 2 * np.pi * 1.5
    t = np.arange(0.0, 4.0, h)
    exact = np.diff(-np.cos(w * t)) / (w * h)
    trapezoid = 0.5 * (np.sin(w * t[1:]) + np.sin(w * t[:-1]))
    assert np.max(np.abs(trapezoid - exact)) == pytest.approx((w * h) ** 2 / 12, rel=0.01)
    error = np.max(np.abs(interval_averages(np.sin(w * t))[1:-1] - exact[1:-1]))
    assert error == pytest.approx(11 * (w * h) ** 4 / 720, rel=0.05)
    with pytest.raises(ValueError, match="interval_averages"):
        interval_averages(np.ones(2))


def test_held_commands_at_instants_and_over_intervals():
    stamps = np.arange(0.0, 1.0, 0.01)
    values = np.column_stack([np.arange(100.0), -np.arange(100.0)])
    time = stamps[2:90:2]
    instant, average = held_commands(stamps, values, time)
    # A sample sees the command issued before it; the interval [t, t + 0.02) holds two.
    np.testing.assert_array_equal(instant[:, 0], np.arange(1.0, 89.0, 2.0))
    np.testing.assert_allclose(average[:, 0], np.arange(2.5, 90.0, 2.0))
    np.testing.assert_allclose(average[:, 1], -average[:, 0])
    # A log thinned to every other command: the dropped (here linear) commands come back.
    thinned = held_commands(stamps[::2], values[::2], time, hold_period=0.01)
    np.testing.assert_allclose(thinned[0], instant)
    np.testing.assert_allclose(thinned[1], average)


NOISE_FREE = SensorSuiteParams(
    imu=ImuParams(accel=ChannelErrors(0.0), gyro=ChannelErrors(0.0)),
    vanes=VaneParams(angles=ChannelErrors(0.0)),
    pitot=PitotParams(dynamic_pressure=ChannelErrors(0.0), air_density=aerosonde().rho),
)


@pytest.mark.parametrize("turbulence", [None, "light"])
def test_flight_log_coefficients_match_the_true_model(turbulence):
    """Held commands are placed where the accelerometer and the rate increments see them:
    with exact sensors the measured coefficients are the aircraft's own model. A command
    half a hold period off leaves 1-2% of the variation (CD: most of it in turbulence,
    where the airspeed hold makes the throttle rough)."""
    params = aerosonde()
    log = fly(params, turbulence, sensors=NOISE_FREE, seed=3, duration=20.0)
    samples = samples_from_log(log, params)
    # The simulated wind steps at the sample instants, which the moments see half a
    # step apart from the air data: only the forces are held to the turbulent bound.
    bounds = ({k: 0.01 for k in COEFFICIENTS} if turbulence is None
              else {"CL": 0.003, "CD": 0.1, "CY": 0.003})
    for name, bound in bounds.items():
        names = baseline_names(params, name)
        theta = np.array([params.derivatives.get(n, 0.0) for n in names])
        X = regressor_matrix(names, samples.aligned(name).condition, params.b, params.c)
        z = samples.coefficients[name]
        error = (z - X @ theta)[20:-20]
        assert np.sqrt(np.mean(error**2)) < bound * np.std(z), name
