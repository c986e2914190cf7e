"""Differential flatness (Argyropoulos 2020, sec. 2.2): flat outputs -> state and input."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink

from drake_uav.model.rotations import quat_conjugate, quat_multiply, quat_to_euler
from drake_uav.optimization.flatness import (
    attitude_from_flat_outputs,
    flat_reference,
    velocity_heading,
)
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.systems.multirotor import MultirotorPlant
from drake_uav.vehicles.multirotor import hexacopter, quadrotor_x

WAYPOINTS = np.array([[0, 0, 0], [2, 0, -1], [6, 3, -2], [7, 8, -2], [3, 10, -3],
                      [0, 6, -1]], dtype=float)
TIMES = np.linspace(0.0, 15.0, len(WAYPOINTS))
DT = 0.005


@pytest.fixture(scope="module")
def trajectory():
    return minimum_snap(WAYPOINTS, TIMES)


@pytest.fixture(scope="module")
def heading(trajectory):
    return velocity_heading(trajectory)


@pytest.fixture(scope="module")
def reference(trajectory, heading):
    return flat_reference(trajectory, hexacopter(), np.arange(0.0, 15.0 + DT / 2, DT),
                          yaw=heading)


@pytest.mark.parametrize("make", [quadrotor_x, hexacopter])
def test_hover_reference_is_level_with_equal_thrusts(make):
    p = make()
    still = minimum_snap([[1.0, 2.0, -5.0], [1.0, 2.0, -5.0]], [0.0, 1.0])
    ref = flat_reference(still, p, [0.0, 0.5, 1.0], yaw=0.4)
    np.testing.assert_allclose(ref.wrench, [[p.weight, 0, 0, 0]] * 3, atol=1e-12)
    np.testing.assert_allclose(ref.motor_thrusts, p.weight / p.num_motors, rtol=1e-12)
    np.testing.assert_allclose(ref.motor_thrusts.sum(axis=1), p.weight, rtol=1e-12)
    np.testing.assert_allclose(quat_to_euler(ref.state[1, 3:7]), [0.0, 0.0, 0.4], atol=1e-12)
    np.testing.assert_allclose(ref.state[:, 10:13], 0.0, atol=1e-12)


def test_reference_satisfies_the_plant_dynamics(reference):
    assert reference.dynamics_residual < 1e-9
    assert reference.within_limits()
    q = reference.state[:, 3:7]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0.99)  # no sign flips between samples


def test_body_rates_and_their_derivative_match_finite_differences(trajectory, heading):
    p = hexacopter()
    t = np.array([2.1, 5.3, 7.7, 11.2])
    h = 1e-5
    ref = flat_reference(trajectory, p, t, yaw=heading)
    plus = flat_reference(trajectory, p, t + h, yaw=heading)
    minus = flat_reference(trajectory, p, t - h, yaw=heading)
    for k in range(len(t)):
        q = ref.state[k, 3:7]
        q_dot = (plus.state[k, 3:7] - minus.state[k, 3:7]) / (2 * h)
        omega = 2.0 * quat_multiply(quat_conjugate(q), q_dot)[1:]
        np.testing.assert_allclose(omega, ref.state[k, 10:13], atol=1e-6)
    omega_dot = (plus.state[:, 10:13] - minus.state[:, 10:13]) / (2 * h)
    np.testing.assert_allclose(omega_dot, ref.body_acceleration, atol=1e-5)
    # The torque is J omega_dot + omega x J omega (seed eq. 2.11, corrected).
    J = p.inertia_matrix
    w = ref.state[:, 10:13]
    tau = ref.body_acceleration @ J.T + np.cross(w, w @ J.T)
    np.testing.assert_allclose(ref.wrench[:, 1:], tau, atol=1e-10)


def test_yaw_flat_output_is_the_euler_yaw(trajectory):
    yaw_traj = minimum_snap([[0.0], [2.5], [-1.0]], [0.0, 7.0, 15.0])
    t = np.linspace(0.0, 15.0, 31)
    ref = flat_reference(trajectory, quadrotor_x(), t, yaw=yaw_traj)
    euler = np.array([quat_to_euler(q) for q in ref.state[:, 3:7]])
    np.testing.assert_allclose(euler[:, 2], yaw_traj.position(t)[:, 0], atol=1e-12)
    assert np.abs(euler[:, :2]).max() > 0.05  # the vehicle does tilt


@pytest.mark.parametrize("start", [0.0, 2.0, 6.5])
def test_open_loop_reference_input_tracks_the_reference(reference, start):
    p = hexacopter()
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultirotorPlant(p))
    source = builder.AddSystem(TrajectorySource(reference.motor_thrust_trajectory()))
    builder.Connect(source.get_output_port(), plant.GetInputPort("motor_thrusts"))
    logger = builder.AddSystem(VectorLogSink(13, publish_period=0.05))
    builder.Connect(plant.GetOutputPort("state"), logger.get_input_port())
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    context.SetTime(start)
    k0 = int(round(start / DT))
    plant.GetMyMutableContextFromRoot(context).SetContinuousState(reference.state[k0])
    simulator.get_mutable_integrator().set_target_accuracy(1e-8)
    simulator.AdvanceTo(start + 1.0)
    log = logger.FindLog(context)
    k = np.rint(log.sample_times() / DT).astype(int)
    error = np.linalg.norm(log.data()[:3].T - reference.state[k, :3], axis=1)
    assert log.sample_times()[-1] == pytest.approx(start + 1.0)
    assert error.max() < 0.05
    if start > 0:  # mid-flight the vehicle really moves and turns over that second
        assert np.linalg.norm(reference.state[k[-1], :3] - reference.state[k0, :3]) > 1.0
        assert np.abs(reference.state[k0:k[-1], 10:13]).max() > 0.1


def test_velocity_heading_follows_the_path_and_stays_continuous():
    # Two laps around a square: the heading turns by 4 pi without wrapping.
    corners = np.array([[0, 0], [10, 0], [10, 10], [0, 10]] * 2 + [[0, 0]], dtype=float)
    w = np.column_stack([corners, np.full(len(corners), -5.0)])
    traj = minimum_snap(w, np.linspace(0.0, 40.0, len(w)))
    t = np.linspace(0.0, 40.0, 4001)
    heading = velocity_heading(traj)
    psi = heading.value(t)
    assert np.abs(np.diff(psi)).max() < 0.01
    assert psi[-1] - psi[0] > 3.5 * np.pi
    assert np.abs(heading.value(t, 1)).max() <= 1.0 + 1e-6  # max_yaw_rate
    assert heading.value(0.0, 1) == pytest.approx(0.0, abs=1e-9)
    assert heading.value(40.0, 1) == pytest.approx(0.0, abs=1e-9)
    assert heading.value(50.0, 2) == 0.0
    # Mid-leg a quick yaw filter points the body x axis along the velocity.
    fast = velocity_heading(traj, time_constant=0.3, max_yaw_rate=2.0)
    v = traj.velocity(t)
    mid = np.abs(t - 5.0 * np.round(t / 5.0)) > 2.0
    course = np.arctan2(v[:, 1], v[:, 0])
    error = np.abs(np.angle(np.exp(1j * (fast.value(t) - course))))[mid]
    assert error.mean() < 0.15 and error.max() < 0.4


def test_failed_motor_reference_uses_the_remaining_motors(trajectory):
    p = hexacopter()
    health = np.array([1.0, 1.0, 0.0, 1.0, 1.0, 1.0])
    still = minimum_snap([[0.0, 0.0, -5.0], [0.0, 0.0, -5.0]], [0.0, 1.0])
    hover = flat_reference(still, p, [0.5], yaw=0.0, health=health)
    # Losing motor 2 of the alternating hexa also idles the opposite motor 5 (same spin
    # balance); the other four share the weight.
    assert hover.within_limits()
    np.testing.assert_allclose(hover.motor_thrusts[0], np.array([1, 1, 0, 1, 1, 0]) * p.weight / 4,
                               atol=1e-9)
    ref = flat_reference(trajectory, p, np.linspace(0, 15, 61), yaw=0.0, health=health)
    assert np.all(ref.motor_thrusts[:, 2] == 0.0)
    assert np.all((ref.motor_thrusts >= 0) & (ref.motor_thrusts <= p.f_max))
    produced = ref.motor_thrusts @ p.effective_allocation(health).T
    assert ref.allocation_residual == pytest.approx(np.abs(produced - ref.wrench).max())
    np.testing.assert_allclose(produced[:, 0], ref.wrench[:, 0], rtol=1e-3)
    # A quadrotor cannot produce the wrench with one motor out.
    q = quadrotor_x()
    bad = flat_reference(trajectory, q, [3.0], yaw=0.0, health=[1.0, 0.0, 1.0, 1.0])
    assert not bad.within_limits()


def test_degenerate_references_are_rejected(trajectory):
    with pytest.raises(ValueError, match="free fall"):
        attitude_from_flat_outputs([[0.0, 0.0, 9.81]], [[0, 0, 0]], [[0, 0, 0]], [0.0], [0.0],
                                   [0.0], gravity=9.81)
    dragged = dataclasses.replace(hexacopter(), rotor_drag=(0.2, 0.2, 0.0))
    with pytest.raises(ValueError, match="rotor_drag"):
        flat_reference(trajectory, dragged, [1.0])
