"""Filter models (drake_uav.estimation) and the EKF LeafSystems (systems/estimators.py)."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.diagrams.identification_flight import fly
from drake_uav.estimation import (
    AirDataModel,
    ModelBasedAirDataModel,
    ParameterModel,
    fresh_samples,
    gps_latency_correction,
    gust_rate_psd,
    is_new_sample,
    smoothed_attitude,
    smoothed_attitude_std,
)
from drake_uav.estimation.ekf import ExtendedKalmanFilter, run_filter, wrap_angle
from drake_uav.model.air_data import (
    air_data_from_velocity,
    air_data_rates,
    velocity_from_air_data,
)
from drake_uav.model.dryden import dryden_psd, dryden_scales
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.rotations import euler_rates, euler_to_quat, euler_to_rotmat
from drake_uav.optimization.trim import trim
from drake_uav.systems.estimators import (
    AirDataEkf,
    EkfSystemParams,
    ModelBasedAirDataEkf,
    ParameterEkf,
)
from drake_uav.vehicles.fixed_wing import aerosonde

PARAMS = aerosonde()


@pytest.fixture(scope="module")
def log():
    return fly(PARAMS, "light", steady_wind=(3.0, -2.0, 0.0), seed=4, duration=12.0)


def test_air_data_rates_are_the_derivative_of_the_triplet():
    rng = np.random.default_rng(0)
    for _ in range(5):
        v = np.array([25.0, 0.0, 0.0]) + rng.normal(0.0, 2.0, 3)
        v_dot = rng.normal(0.0, 3.0, 3)
        h = 1e-6
        numeric = (np.array(air_data_from_velocity(*(v + h * v_dot)))
                   - np.array(air_data_from_velocity(*(v - h * v_dot)))) / (2 * h)
        np.testing.assert_allclose(air_data_rates(v, v_dot), numeric, rtol=1e-6, atol=1e-9)


def test_model_based_prediction_is_the_body_axis_model_in_wind_axes():
    """Vaiopoulos 2017, eq. 5.31 (corrected) equals the plant's
    body-axis equations."""
    model = ModelBasedAirDataModel(PARAMS)
    plant = FixedWingModel(PARAMS)
    level = trim(PARAMS, 25.0)
    rpy, omega = np.array([0.2, 0.05, 1.0]), np.array([0.1, -0.05, 0.08])
    wind = np.array([4.0, -2.0, 0.5])
    air = np.array([24.0, 0.07, -0.03])
    R = euler_to_rotmat(rpy)
    v_ground = np.array(velocity_from_air_data(*air)) + R.T @ wind
    state = np.concatenate([[0, 0, -100], euler_to_quat(rpy), v_ground, omega])
    evaluation = plant.evaluate(state, level.controls, wind)
    # Constant NED wind: the air-relative velocity changes like the ground velocity minus
    # the rotation of the wind seen in body axes.
    v_r_dot = evaluation.state_derivative[7:10] + np.cross(omega, R.T @ wind)
    expected = air_data_rates(np.array(velocity_from_air_data(*air)), v_r_dot)
    u = np.concatenate([omega, rpy, level.controls])
    xdot = model.dynamics(np.concatenate([air, wind]), u, np.zeros(6))
    np.testing.assert_allclose(np.array(xdot[:3], float), expected, rtol=1e-10, atol=1e-12)
    y = np.array(model.measurement(np.concatenate([air, wind]), u), float)
    np.testing.assert_allclose(y[0:3], evaluation.specific_force, rtol=1e-12)
    np.testing.assert_allclose(y[3:6], R @ v_ground, rtol=1e-12)
    assert y[6] == pytest.approx(0.5 * PARAMS.rho * air[0] ** 2)


def test_model_free_dynamics_and_measurements():
    model = AirDataModel(PARAMS)
    rpy = np.array([0.3, -0.1, 2.0])
    R = euler_to_rotmat(rpy)
    x = np.array([24.0, 1.0, 2.0, 3.0, -4.0, 0.5])
    accel, omega = np.array([0.5, -0.2, -9.0]), np.array([0.1, 0.2, -0.3])
    w = np.array([0.3, -0.1, 0.2])
    xdot = np.array(model.dynamics(x, np.concatenate([accel, omega, rpy]), w), float)
    gravity = R.T @ np.array([0.0, 0.0, PARAMS.gravity])
    np.testing.assert_allclose(xdot[:3], accel + gravity - np.cross(omega, x[:3]) - R.T @ w,
                               rtol=1e-12)
    np.testing.assert_allclose(xdot[3:], w)
    y = np.array(model.measurement(x, np.concatenate([accel, omega, rpy])), float)
    np.testing.assert_allclose(y[:3], R @ x[:3] + x[3:], rtol=1e-12)
    airspeed, alpha, beta = air_data_from_velocity(*x[:3])
    np.testing.assert_allclose(y[3:], [0.5 * PARAMS.rho * airspeed**2, alpha, beta],
                               rtol=1e-12)


def test_wind_triangle_initialisation():
    """Vaiopoulos 2017, eq. 5.24-5.25 (corrected): start along the ground track,
    or from the vanes."""
    model = AirDataModel(PARAMS)
    rpy = np.array([0.0, 0.05, 0.7])
    R = euler_to_rotmat(rpy)
    u = np.concatenate([np.zeros(6), rpy])
    gps = np.array([20.0, 15.0, -1.0])
    q_bar = 0.5 * PARAMS.rho * 22.0**2
    y = np.array([*gps, q_bar, 0.05, 0.02])
    x = model.initial_state(u, y, np.array([1, 1, 1, 1, 0, 0], bool))
    np.testing.assert_allclose(R @ x[:3], 22.0 * gps / np.linalg.norm(gps), rtol=1e-12)
    np.testing.assert_allclose(x[3:], gps * (1.0 - 22.0 / np.linalg.norm(gps)), rtol=1e-12)
    x = model.initial_state(u, y, np.ones(6, bool))
    np.testing.assert_allclose(air_data_from_velocity(*x[:3]), [22.0, 0.05, 0.02], rtol=1e-12)
    np.testing.assert_allclose(R @ x[:3] + x[3:], gps, rtol=1e-12)
    assert np.all(np.isnan(model.initial_state(u, y, np.zeros(6, bool))))


def test_parameter_model_reproduces_the_aircraft_model():
    level = trim(PARAMS, 25.0)
    plant = FixedWingModel(PARAMS)
    air, omega, rpy = np.array([25.0, 0.08, 0.03]), np.array([0.1, 0.05, -0.07]), [0.2, 0.1, 0.0]
    state = np.concatenate([[0, 0, -100], euler_to_quat(rpy),
                            velocity_from_air_data(*air), omega])
    evaluation = plant.evaluate(state, level.controls)
    lon = ParameterModel(PARAMS, "longitudinal")
    lat = ParameterModel(PARAMS, "lateral")
    x_lon = np.concatenate([[air[0], air[1], omega[1], rpy[1]],
                            [PARAMS.derivative(n) for n in lon.parameter_names]])
    u_lon = np.concatenate([[air[2], omega[0], omega[2], rpy[0]], level.controls])
    y = np.array(lon.measurement(x_lon, u_lon), float)
    np.testing.assert_allclose(y[4:6], evaluation.specific_force[[0, 2]], rtol=1e-12)
    assert y[6] == pytest.approx(evaluation.state_derivative[11], rel=1e-12)
    x_lat = np.concatenate([[air[2], omega[0], omega[2], rpy[0], rpy[2]],
                            [PARAMS.derivative(n) for n in lat.parameter_names]])
    u_lat = np.concatenate([[air[0], air[1], omega[1], rpy[1]], level.controls])
    y = np.array(lat.measurement(x_lat, u_lat), float)
    assert y[5] == pytest.approx(evaluation.specific_force[1], rel=1e-12)
    np.testing.assert_allclose(y[6:8], evaluation.state_derivative[[10, 12]], rtol=1e-12)
    xdot = np.array(lat.dynamics(x_lat, u_lat, np.zeros(len(lat.noise_names))), float)
    np.testing.assert_allclose(xdot[1:3], evaluation.state_derivative[[10, 12]], rtol=1e-12)
    assert np.all(xdot[5:] == 0.0)
    assert lat.parameter_names == tuple(
        n for n in PARAMS.derivatives if n[:2] in ("CY", "Cl", "Cn") and not n.endswith("_0"))
    with pytest.raises(ValueError, match="not a lateral derivative"):
        ParameterModel(PARAMS, "lateral", ["CL_alpha"])
    with pytest.raises(ValueError, match="axis"):
        ParameterModel(PARAMS, "vertical")


def test_fresh_samples_and_gps_latency_correction():
    values = np.array([1.0, 1.0, 2.0, np.nan, np.nan, 2.0])
    assert fresh_samples(values).tolist() == [True, False, True, True, False, True]
    assert not is_new_sample(np.nan, np.nan) and is_new_sample(1.0, np.nan)
    time = np.arange(0.0, 2.0, 0.01)
    n = time.size
    rpy = np.tile([0.0, 0.0, 0.5], (n, 1))
    specific_force = np.tile([0.8, 0.0, -PARAMS.gravity], (n, 1))
    correction = gps_latency_correction(time, specific_force, rpy, 0.1, PARAMS.gravity)
    expected = euler_to_rotmat(rpy[0]) @ np.array([0.8, 0.0, 0.0]) * 0.1
    np.testing.assert_allclose(correction[20:], np.tile(expected, (n - 20, 1)), atol=1e-12)
    np.testing.assert_allclose(correction[5], expected * 0.5, atol=1e-12)


def test_ekf_system_params_validation():
    with pytest.raises(ValueError, match="period"):
        EkfSystemParams(PARAMS, period=0.0).validate()
    with pytest.raises(ValueError, match="gps_latency"):
        EkfSystemParams(PARAMS, gps_latency=-1.0).validate()
    with pytest.raises(ValueError, match="gate_probability"):
        EkfSystemParams(PARAMS, gate_probability=1.5).validate()


@pytest.mark.parametrize("system_type", [AirDataEkf, ModelBasedAirDataEkf, ParameterEkf])
def test_ports_and_no_direct_feedthrough(system_type):
    system = system_type(EkfSystemParams(PARAMS))
    sizes = {system.get_input_port(i).get_name(): system.get_input_port(i).size()
             for i in range(system.num_input_ports())}
    outputs = {system.get_output_port(i).get_name(): system.get_output_port(i).size()
               for i in range(system.num_output_ports())}
    if system_type is ParameterEkf:
        assert sizes == {"air_data": 3, "imu": 6, "attitude": 3, "controls": 4,
                         "angular_acceleration": 3}
        n = len(system.derivative_names)
        assert outputs == {"derivatives": n, "derivatives_std": n, "state": 9, "nis": 4}
    else:
        assert {k: sizes[k] for k in ("imu", "attitude", "gps", "pitot", "vanes")} == {
            "imu": 6, "attitude": 3, "gps": 6, "pitot": 2, "vanes": 2}
        assert ("controls" in sizes) == (system_type is ModelBasedAirDataEkf)
        assert outputs == {"air_data": 3, "wind_ned": 3, "covariance": 36, "state": 6,
                           "nis": 2, "counters": 2}
    for i in range(system.num_input_ports()):
        for j in range(system.num_output_ports()):
            assert not system.HasDirectFeedthrough(i, j)


def _replay(system, sources: dict[str, np.ndarray], time: np.ndarray, until: int):
    """Feeds logged rows to ``system`` (row k at t_k) and advances past update ``until``."""
    builder = DiagramBuilder()
    builder.AddSystem(system)
    for name, values in sources.items():
        trajectory = PiecewisePolynomial.ZeroOrderHold(
            np.append(time, time[-1] + 1.0), np.vstack([values, values[-1:]]).T)
        source = builder.AddSystem(TrajectorySource(trajectory))
        builder.Connect(source.get_output_port(), system.GetInputPort(name))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(time[until] + 0.5 * (time[1] - time[0]))
    return system.GetMyContextFromRoot(simulator.get_context())


def _sensor_sources(log, controls: bool) -> dict[str, np.ndarray]:
    out = {
        "imu": log.stack(["imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r"]),
        "attitude": log.stack(["att_roll", "att_pitch", "att_yaw"]),
        "gps": log.stack(["gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve", "gps_vd"]),
        "pitot": log.stack(["pitot_qbar", "pitot_airspeed"]),
        "vanes": log.stack(["vane_alpha", "vane_beta"]),
    }
    if controls:
        out["controls"] = log.stack(["cmd_elevator", "cmd_aileron", "cmd_rudder",
                                     "cmd_throttle"])
    return out


@pytest.mark.parametrize("system_type", [AirDataEkf, ModelBasedAirDataEkf])
def test_air_data_systems_equal_the_offline_run(log, system_type):
    """The LeafSystem and run_filter share the core: same estimate from the same samples."""
    system = system_type(EkfSystemParams(PARAMS))
    data = system.ekf.model.log_data(log)
    offline = run_filter(system.ekf, data.time, data.inputs, data.measurements, data.available)
    last = len(data.time) - 1
    context = _replay(system, _sensor_sources(log, system_type is ModelBasedAirDataEkf),
                      data.time, last)
    state = system.GetOutputPort("state").Eval(context)
    np.testing.assert_allclose(state, offline.state[last], rtol=1e-9, atol=1e-9)
    P = system.GetOutputPort("covariance").Eval(context).reshape(6, 6)
    np.testing.assert_allclose(np.sqrt(np.diag(P)), offline.std[last], rtol=1e-8)
    truth = data.truth[last, :3]
    air = system.GetOutputPort("air_data").Eval(context)
    if system_type is AirDataEkf:
        truth = np.array(air_data_from_velocity(*truth))
    assert abs(air[0] - truth[0]) < 0.5 and abs(air[1] - truth[1]) < math.radians(1.0)


def test_air_data_system_counts_a_nan_sample_and_keeps_going(log):
    system = AirDataEkf(EkfSystemParams(PARAMS))
    sources = _sensor_sources(log, controls=False)
    time = np.asarray(log.time)
    k = int(np.searchsorted(time, 5.0))
    sources["vanes"] = sources["vanes"].copy()
    sources["vanes"][k, 0] = np.nan
    context = _replay(system, sources, time, len(time) - 1)
    assert system.GetOutputPort("counters").Eval(context)[1] == 1.0
    assert np.all(np.isfinite(system.GetOutputPort("state").Eval(context)))


def test_air_data_system_without_vanes_or_gps_is_still_running(log):
    system = AirDataEkf(EkfSystemParams(PARAMS))
    sources = _sensor_sources(log, controls=False)
    del sources["vanes"], sources["gps"]
    context = _replay(system, sources, np.asarray(log.time), len(log.time) - 1)
    airspeed = system.GetOutputPort("air_data").Eval(context)[0]
    assert abs(airspeed - log["airspeed"][-1]) < 1.0
    assert system.GetOutputPort("nis").Eval(context)[1] == 1.0  # the pitot alone


def test_parameter_system_equals_the_offline_runs(log):
    system = ParameterEkf(EkfSystemParams(PARAMS))
    air = log.stack(["pitot_airspeed", "vane_alpha", "vane_beta"])
    sources = {**{k: v for k, v in _sensor_sources(log, True).items()
                  if k in ("imu", "attitude", "controls")}, "air_data": air}
    last = len(log.time) - 1
    context = _replay(system, sources, np.asarray(log.time), last)
    derivatives = system.GetOutputPort("derivatives").Eval(context)
    physical = system.GetOutputPort("state").Eval(context)
    offset = 0
    for i, ekf in enumerate(system.ekfs):
        model = ekf.model
        data = model.log_data(log)
        run = run_filter(ekf, data.time, data.inputs, data.measurements, data.available)
        n = len(model.parameter_names)
        np.testing.assert_allclose(derivatives[offset:offset + n],
                                   run.state[last, len(model.physical_names):], rtol=1e-8,
                                   atol=1e-10)
        part = physical[:4] if i == 0 else physical[4:]
        np.testing.assert_allclose(part, run.state[last, :len(model.physical_names)],
                                   rtol=1e-8, atol=1e-10)
        offset += n
    assert isinstance(system.ekfs[0], ExtendedKalmanFilter)


def test_attitude_smoothing_reduces_the_noise_the_gps_rows_see(log):
    """The smoothed attitude's error is the steady state of the complementary filter
    (formula of smoothed_attitude_std), far below the samples'."""
    model = AirDataModel(PARAMS)
    noise = model.default_noise()
    data = model.log_data(log)
    smoothed = data.inputs.copy()
    for k in range(1, len(smoothed)):
        smoothed[k] = model.smooth_inputs(smoothed[k - 1], data.inputs[k], 0.01)
    truth = log.stack(["roll", "pitch", "yaw"])
    keep = data.time > 1.0
    raw_error = np.std(data.inputs[keep, 6:9] - truth[keep], axis=0)
    error = np.std(wrap_angle(smoothed[keep, 6:9] - truth[keep]), axis=0)
    expected = smoothed_attitude_std(noise.input_std["p"], noise.input_std["roll"], 0.01, 0.05)
    assert noise.measurement_input_std == {"roll": expected, "pitch": expected, "yaw": expected}
    np.testing.assert_allclose(error, expected, rtol=0.25)
    assert np.all(error < 0.4 * raw_error)
    # One step is the Euler-angle kinematics plus the pull towards the sample, wrapped.
    previous, rates, sample = np.array([0.1, 0.2, 3.1]), np.array([0.1, -0.2, 0.3]), np.array(
        [0.12, 0.19, -3.13])
    predicted = previous + 0.01 * np.array(euler_rates(previous, rates), float)
    expected_step = wrap_angle(predicted + 0.2 * wrap_angle(sample - predicted))
    step = np.array(smoothed_attitude(np.concatenate([previous, rates, sample, [0.2, 0.01]])),
                    float)
    np.testing.assert_allclose(step, expected_step, atol=1e-12)
    assert AirDataModel(PARAMS, attitude_time_constant=0.0).smoothed_inputs == ()
    with pytest.raises(ValueError, match="attitude_time_constant"):
        AirDataModel(PARAMS, attitude_time_constant=-1.0)


def test_gust_rate_density_is_the_high_frequency_level_of_the_dryden_spectra():
    scales = dryden_scales("light", 100.0)
    omega = np.array([1e3])
    # One-sided spectra in rad/s of the rates: a white density S reads S / pi.
    rates = dryden_psd(omega, scales, 25.0)[:, 0] * omega[0] ** 2
    np.testing.assert_allclose(np.array(gust_rate_psd("light", 25.0, 100.0)) / math.pi, rates,
                               rtol=1e-3)


def _spiked_runs(model, noise, data, start: float):
    """One filter per measurement channel with a single 20-sigma spike on it (after
    ``start`` [s]), next to the same spikes' samples dropped instead, and a nominal run."""
    t = data.time
    channels = [j for j in range(len(model.measurement_names)) if data.available[:, j].any()]
    batch = 1 + len(channels)
    U, Y, A = (np.repeat(a[None], batch, axis=0) for a in (data.inputs, data.measurements,
                                                           data.available))
    clean, dropped = Y.copy(), A.copy()
    spikes = []
    for b, j in enumerate(channels, start=1):
        k = int(np.flatnonzero(A[b, :, j] & (t > start + 0.4 * b))[0])
        name = model.measurement_names[j]
        Y[b, k, j] += 20.0 * noise.measurement_std[name]
        group = next(g for g, idx in model.groups.items() if j in idx)
        dropped[b, k, list(model.groups[group])] = False
        spikes.append((b, j, k, group))
    ekf = ExtendedKalmanFilter(model, noise)
    return ekf, run_filter(ekf, t, U, Y, A), run_filter(ekf, t, U, clean, dropped), spikes


@pytest.mark.parametrize("kind", ["model_free", "model_based", "longitudinal", "lateral"])
def test_a_twenty_sigma_spike_on_any_channel_is_rejected(log, kind):
    """Every channel of every filter, in light turbulence: a single spike of 20 sensor
    sigmas is rejected with its group, counted, and the filter carries on exactly as if
    that sample had been missing."""
    if kind == "model_free":
        model, noise = AirDataModel(PARAMS), None
    elif kind == "model_based":
        model, noise = ModelBasedAirDataModel(PARAMS), None
    else:
        model = ParameterModel(PARAMS, kind)
        noise = model.default_noise(turbulence="light")
    noise = noise or model.default_noise()
    data = model.log_data(log)
    ekf, spiked, dropped, spikes = _spiked_runs(model, noise, data, start=5.0)
    gate = math.sqrt(ekf._gate)
    for b, j, k, group in spikes:
        name = model.measurement_names[j]
        size = abs(spiked.innovation[b, k, j]) / math.sqrt(spiked.innovation_var[b, k, j])
        print(f"\n{kind} 20-sigma spike on {name}: {size:.1f} innovation sigmas (gate "
              f"{gate:.2f})")
        assert not spiked.used[b, k, j], name
        g = ekf.group_names.index(group)
        assert spiked.rejected[b, g] == spiked.rejected[0, g] + 1, name
        np.testing.assert_allclose(spiked.state[b], dropped.state[b], rtol=1e-9, atol=1e-12)
