"""Multirotor parameters (allocation from geometry) and the MultirotorPlant system."""

import dataclasses
import math

import numpy as np
import pytest
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.primitives import Linearize

from drake_uav.model.multirotor import BODY_RATES, QUATERNION, VELOCITY, multirotor_derivatives
from drake_uav.model.rotations import euler_to_quat, quat_to_euler, quat_to_rotmat
from drake_uav.systems.multirotor import MultirotorPlant
from drake_uav.vehicles.multirotor import (
    MultirotorParams,
    hexacopter,
    quadrotor_plus,
    quadrotor_x,
)

CATALOG = [quadrotor_plus, quadrotor_x, hexacopter]
SEED_TO_NED = np.diag([1.0, 1.0, -1.0, -1.0])  # rows F, tau_x, tau_y, tau_z


def _random_state(rng):
    q = rng.normal(size=4)
    return np.concatenate([rng.normal(size=3), q / np.linalg.norm(q), rng.normal(size=3),
                           rng.normal(size=3)])


def _plant_context(params_or_plant, commands, state=None, health=None, external=None):
    plant = (params_or_plant if isinstance(params_or_plant, MultirotorPlant)
             else MultirotorPlant(params_or_plant))
    context = plant.CreateDefaultContext()
    plant.GetInputPort("motor_thrusts").FixValue(context, np.asarray(commands, float))
    if state is not None:
        context.SetContinuousState(state)
    if health is not None:
        plant.GetInputPort("motor_health").FixValue(context, np.asarray(health, float))
    if external is not None:
        plant.GetInputPort("external_wrench").FixValue(context, np.asarray(external, float))
    return plant, context


def test_quad_allocation_matches_seed_eq_1_2():
    p = quadrotor_plus()
    l, km = p.arm_length, p.km
    seed = np.array([[1, 1, 1, 1], [0, l, 0, -l], [-l, 0, l, 0], [km, -km, km, -km]])
    np.testing.assert_allclose(p.allocation_matrix, SEED_TO_NED @ seed, atol=1e-15)


def test_hexa_allocation_matches_seed_eq_1_3():
    p = hexacopter()
    l, km = p.arm_length, p.km
    s6, s3 = math.sin(math.pi / 6), math.sin(math.pi / 3)
    seed = np.array([
        [1, 1, 1, 1, 1, 1],
        [l * s6, l, l * s6, -l * s6, -l, -l * s6],
        [-l * s3, 0, l * s3, l * s3, 0, -l * s3],
        [km, -km, km, -km, km, -km],
    ])
    np.testing.assert_allclose(p.allocation_matrix, SEED_TO_NED @ seed, atol=1e-15)


def test_quad_x_torque_signs_follow_frd_conventions():
    A = quadrotor_x().allocation_matrix
    # Motors 0 (front-left) and 3 (front-right) lift the nose: positive pitch torque.
    assert A[2, 0] > 0 and A[2, 3] > 0 and A[2, 1] < 0 and A[2, 2] < 0
    # Left motors (0, 1) raise the left side: positive roll (right wing down).
    assert A[1, 0] > 0 and A[1, 1] > 0 and A[1, 2] < 0 and A[1, 3] < 0
    # Clockwise rotors (seen from above) yaw the body counter-clockwise (negative in NED).
    assert A[3, 0] < 0 and A[3, 2] < 0
    np.testing.assert_allclose(A @ np.ones(4), [4, 0, 0, 0], atol=1e-15)


@pytest.mark.parametrize("make", CATALOG)
def test_hover_trim_equal_thrusts_sum_to_weight(make):
    p = make()
    f = p.thrusts_for_wrench([p.weight, 0, 0, 0])
    np.testing.assert_allclose(f, p.weight / p.num_motors, rtol=1e-12)
    assert f.sum() == pytest.approx(p.weight, rel=1e-12)
    plant, context = _plant_context(p, f)
    np.testing.assert_allclose(plant.EvalTimeDerivatives(context).CopyToVector(), 0, atol=1e-12)
    np.testing.assert_allclose(plant.GetOutputPort("specific_force").Eval(context),
                               [0, 0, -p.gravity], atol=1e-12)


@pytest.mark.parametrize("field, value", [
    ("mass", 0.0), ("arm_length", -0.1), ("f_max", math.nan), ("km", -0.01),
    ("motor_time_constant", -1.0), ("inertia", (0.01, 0.01, 0.05)),
    ("spin_directions", (1, -1, 2, -1)), ("spin_directions", (1, -1, 1)),
    ("rotor_drag", (-0.1, 0.0, 0.0)), ("gravity", 0.0),
])
def test_invalid_params_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(quadrotor_x(), **{field: value})


def test_failed_motor_thrust_has_no_effect():
    p = hexacopter()
    rng = np.random.default_rng(1)
    health = np.ones(6)
    health[2] = 0.0
    for _ in range(5):
        x = _random_state(rng)
        f = rng.uniform(0, p.f_max, 6)
        g = f.copy()
        g[2] = rng.uniform(0, p.f_max)
        np.testing.assert_array_equal(multirotor_derivatives(x, f, p, health),
                                      multirotor_derivatives(x, g, p, health))
        assert not np.allclose(multirotor_derivatives(x, f, p), multirotor_derivatives(x, g, p))
    # The plant port does the same, and the wrench equals the zeroed-column allocation.
    plant, context = _plant_context(p, f, state=x, health=health)
    np.testing.assert_allclose(plant.GetOutputPort("wrench").Eval(context),
                               p.effective_allocation(health) @ f, atol=1e-12)


def test_partial_health_scales_thrust_and_saturation_clips():
    p = quadrotor_x()
    x = _random_state(np.random.default_rng(2))
    f = np.array([1.0, 2.0, 3.0, 4.0])
    half = np.array([1.0, 0.5, 1.0, 1.0])
    np.testing.assert_allclose(multirotor_derivatives(x, f, p, half),
                               multirotor_derivatives(x, f * half, p), atol=1e-12)
    wild = np.array([-3.0, 2.0, 3.0, 50.0])
    clipped = np.array([0.0, 2.0, 3.0, p.f_max])
    np.testing.assert_array_equal(multirotor_derivatives(x, wild, p),
                                  multirotor_derivatives(x, clipped, p))


def test_external_wrench_unconnected_is_zero_and_adds_force_and_torque():
    p = quadrotor_plus()
    x = _random_state(np.random.default_rng(3))
    f = np.full(4, 3.0)
    plant, context = _plant_context(p, f, state=x)
    base = plant.EvalTimeDerivatives(context).CopyToVector()
    _, ctx_zero = _plant_context(plant, f, state=x, external=np.zeros(6))
    np.testing.assert_array_equal(plant.EvalTimeDerivatives(ctx_zero).CopyToVector(), base)
    wrench = np.array([p.mass * 1.0, 0.0, -p.mass * 2.0, 0.01, 0.0, 0.0])
    _, ctx = _plant_context(plant, f, state=x, external=wrench)
    delta = plant.EvalTimeDerivatives(ctx).CopyToVector() - base
    np.testing.assert_allclose(delta[VELOCITY], [1.0, 0.0, -2.0], atol=1e-12)
    np.testing.assert_allclose(delta[BODY_RATES], p.inertia_inverse @ [0.01, 0, 0], atol=1e-12)
    # The accelerometer sees the external force, rotated into the body.
    R = quat_to_rotmat(x[QUATERNION])
    sf = plant.GetOutputPort("specific_force").Eval(ctx)
    sf0 = plant.GetOutputPort("specific_force").Eval(context)
    np.testing.assert_allclose(sf - sf0, R.T @ [1.0, 0.0, -2.0], atol=1e-12)


def test_rotor_drag_off_by_default_and_opposes_body_velocity():
    p = quadrotor_x()
    x = np.zeros(13)
    x[3] = 1.0
    x[VELOCITY] = [4.0, -2.0, 0.0]
    f = p.thrusts_for_wrench([p.weight, 0, 0, 0])
    assert multirotor_derivatives(x, f, p)[7:9] == pytest.approx([0.0, 0.0])
    dragged = dataclasses.replace(p, rotor_drag=(0.3, 0.2, 0.0))
    acc = multirotor_derivatives(x, f, dragged)[VELOCITY]
    np.testing.assert_allclose(acc[:2], [-0.3 * 4.0 / p.mass, 0.2 * 2.0 / p.mass], atol=1e-12)


def test_euler_output_and_rotor_thrusts():
    p = hexacopter()
    x = _random_state(np.random.default_rng(4))
    f = np.linspace(1.0, 6.0, 6)
    plant, context = _plant_context(p, f, state=x)
    np.testing.assert_allclose(plant.GetOutputPort("euler").Eval(context),
                               quat_to_euler(x[QUATERNION]), atol=1e-12)
    np.testing.assert_allclose(plant.GetOutputPort("rotor_thrusts").Eval(context), f)
    np.testing.assert_allclose(plant.GetOutputPort("state").Eval(context), x)


def test_linearisation_at_hover_gives_textbook_couplings():
    p = hexacopter()
    f = p.thrusts_for_wrench([p.weight, 0, 0, 0])
    plant, context = _plant_context(p, f)
    lin = Linearize(plant, context, equilibrium_check_tolerance=1e-9)
    A, B = lin.A(), lin.B()
    # A small pitch theta (q_y = theta/2) tilts the thrust backwards: dv_N/dt = -g theta.
    assert A[7, 5] == pytest.approx(-2 * p.gravity)
    # Roll phi (q_x = phi/2) tilts the thrust to the right (east): dv_E/dt = g phi.
    assert A[8, 4] == pytest.approx(2 * p.gravity)
    np.testing.assert_allclose(B[9], -np.ones(6) / p.mass)
    np.testing.assert_allclose(B[10:13], p.inertia_inverse @ p.allocation_matrix[1:], atol=1e-12)


def test_scalar_conversion_autodiff_and_symbolic():
    p = quadrotor_x()
    x = _random_state(np.random.default_rng(5))
    f = np.array([1.0, 2.0, 3.0, 4.0])
    plant, context = _plant_context(p, f, state=x)
    expected = plant.EvalTimeDerivatives(context).CopyToVector()
    ad = plant.ToAutoDiffXd()
    ad_context = ad.CreateDefaultContext()
    ad_context.SetContinuousState(x)
    ad.GetInputPort("motor_thrusts").FixValue(ad_context, f)
    ad_xdot = ad.EvalTimeDerivatives(ad_context).CopyToVector()
    np.testing.assert_allclose([v.value() for v in ad_xdot], expected, atol=1e-12)
    sym = plant.ToSymbolic()
    sym_context = sym.CreateDefaultContext()
    sym_context.SetContinuousState(x)
    u = [Variable(f"u{i}") for i in range(4)]
    sym.GetInputPort("motor_thrusts").FixValue(sym_context, np.array(u, dtype=object))
    vdot_d = sym.EvalTimeDerivatives(sym_context).CopyToVector()[9]
    env = dict(zip(u, f, strict=True))
    assert vdot_d.Evaluate(env) == pytest.approx(expected[9])


def test_torque_free_tumble_conserves_energy_momentum_and_unit_norm():
    p = dataclasses.replace(quadrotor_x(), inertia=(0.011, 0.015, 0.021),
                            inertia_products=(0.001, -0.0005, 0.0))
    x = np.zeros(13)
    x[QUATERNION] = euler_to_quat([0.3, -0.2, 1.0])
    x[BODY_RATES] = [3.0, -2.0, 5.0]
    plant, context = _plant_context(p, np.zeros(4), state=x)
    simulator = Simulator(plant, context)
    simulator.get_mutable_integrator().set_target_accuracy(1e-9)
    simulator.AdvanceTo(2.0)
    y = context.get_continuous_state_vector().CopyToVector()
    J, w0, w1 = p.inertia_matrix, x[BODY_RATES], y[BODY_RATES]
    assert w1 @ J @ w1 == pytest.approx(w0 @ J @ w0, rel=1e-6)
    R0, R1 = quat_to_rotmat(x[QUATERNION]), quat_to_rotmat(y[QUATERNION])
    np.testing.assert_allclose(R1 @ J @ w1, R0 @ J @ w0, rtol=1e-5, atol=1e-7)
    assert np.linalg.norm(y[QUATERNION]) == pytest.approx(1.0, abs=1e-7)
    # Free fall: no thrust, so v_D = g t and p_D = g t^2 / 2.
    assert y[9] == pytest.approx(p.gravity * 2.0, rel=1e-8)
    assert y[2] == pytest.approx(0.5 * p.gravity * 4.0, rel=1e-8)


def test_motor_lag_first_order_response():
    p = dataclasses.replace(hexacopter(), motor_time_constant=0.05)
    plant = MultirotorPlant(p)
    context = plant.CreateDefaultContext()
    hover = p.thrusts_for_wrench([p.weight, 0, 0, 0])
    np.testing.assert_allclose(context.get_continuous_state_vector().CopyToVector()[13:], hover)
    step = hover + 1.0
    plant.GetInputPort("motor_thrusts").FixValue(context, step)
    # With lag the wrench follows the state, not the command.
    np.testing.assert_allclose(plant.GetOutputPort("wrench").Eval(context)[0], p.weight)
    simulator = Simulator(plant, context)
    simulator.get_mutable_integrator().set_target_accuracy(1e-9)
    simulator.AdvanceTo(0.05)
    thrust = plant.GetOutputPort("rotor_thrusts").Eval(context)
    np.testing.assert_allclose(thrust, hover + 1.0 - math.exp(-1.0), rtol=1e-6)
    x = context.get_continuous_state_vector().CopyToVector()
    assert len(x) == 19
    np.testing.assert_array_equal(plant.GetOutputPort("state").Eval(context), x[:13])


def test_allocation_of_any_geometry_is_the_sum_of_rotor_moments():
    rng = np.random.default_rng(6)
    angles = np.sort(rng.uniform(-math.pi, math.pi, 8))
    spins = (1, -1) * 4
    p = MultirotorParams(name="octo", mass=3.0, inertia=(0.05, 0.05, 0.09), arm_length=0.4,
                         arm_angles=tuple(angles), spin_directions=spins, km=0.02, f_max=8.0)
    f = rng.uniform(0, p.f_max, 8)
    r = p.arm_length * np.column_stack([np.cos(angles), np.sin(angles), np.zeros(8)])
    forces = np.outer(f, [0.0, 0.0, -1.0])  # thrust along -z_b (up)
    torque = np.cross(r, forces).sum(axis=0)
    torque[2] -= p.km * np.dot(spins, f)  # clockwise rotors drag the body anticlockwise
    np.testing.assert_allclose(p.allocation_matrix @ f, np.r_[f.sum(), torque], atol=1e-12)
