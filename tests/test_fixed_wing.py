"""FixedWingPlant: physics, trim, linearisation and bad input."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.primitives import FirstOrderTaylorApproximation, Linearize

from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.rotations import quat_to_rotmat
from drake_uav.optimization.trim import TrimError, trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde, unatrap


def _plant_context(plant, state, controls, wind=(0, 0, 0), wrench=None, wind_rate=None):
    context = plant.CreateDefaultContext()
    plant.set_state(context, state)
    plant.GetInputPort("controls").FixValue(context, np.asarray(controls, float))
    plant.GetInputPort("wind_ned").FixValue(context, np.asarray(wind, float))
    if wrench is not None:
        plant.GetInputPort("external_wrench").FixValue(context, np.asarray(wrench, float))
    if wind_rate is not None:
        plant.GetInputPort("wind_rate_ned").FixValue(context, np.asarray(wind_rate, float))
    return context


@pytest.fixture(scope="module")
def trim25():
    return trim(aerosonde(), 25.0)


@pytest.mark.parametrize("airspeed", [15.0, 20.0, 25.0, 30.0])
@pytest.mark.parametrize("aircraft", [aerosonde, unatrap])
def test_trim_residual_is_tiny(aircraft, airspeed):
    params = aircraft()
    result = trim(params, airspeed)
    xdot = FixedWingModel(params).evaluate(result.state, result.controls).state_derivative
    assert np.linalg.norm(xdot[7:13]) < 1e-8
    assert np.linalg.norm(xdot[3:7]) < 1e-8  # wings level: attitude constant
    assert np.linalg.norm(xdot[0:3]) == pytest.approx(airspeed, rel=1e-10)
    assert xdot[2] == pytest.approx(0.0, abs=1e-8)  # level


def test_coordinated_turn_and_climb_trims():
    params = aerosonde()
    turn = trim(params, 25.0, turn_rate=0.15)
    climb = trim(params, 25.0, flight_path_angle=np.radians(5))
    model = FixedWingModel(params)
    for result in (turn, climb):
        ev = model.evaluate(result.state, result.controls)
        assert np.linalg.norm(ev.state_derivative[7:13]) < 1e-8
        assert ev.air_data[2] == pytest.approx(0.0, abs=1e-10)  # no sideslip
    # Climb rate is Va sin(gamma); turning right needs right bank, lift balances weight.
    assert -model.evaluate(climb.state, climb.controls).state_derivative[2] == pytest.approx(
        25.0 * np.sin(np.radians(5)), rel=1e-8)
    roll = np.arctan2(2 * (turn.state[3] * turn.state[4] + turn.state[5] * turn.state[6]),
                      1 - 2 * (turn.state[4] ** 2 + turn.state[5] ** 2))
    assert roll == pytest.approx(np.arctan(25.0 * 0.15 / params.gravity), rel=0.05)


def test_impossible_trim_raises_a_clear_error():
    with pytest.raises(TrimError, match="elevator"):
        trim(aerosonde(), 8.0)
    with pytest.raises(TrimError, match="throttle"):
        trim(unatrap(), 25.0, flight_path_angle=0.9)
    with pytest.raises(ValueError, match="airspeed"):
        trim(aerosonde(), -3.0)


def test_quaternion_norm_is_preserved_over_a_60_s_doublet_flight(trim25):
    plant = FixedWingPlant(aerosonde())
    controls = trim25.controls.copy()
    context = _plant_context(plant, trim25.state, controls)
    simulator = Simulator(plant, context)
    for t_end, d_elevator in ((2.0, 0.0), (3.0, 0.05), (4.0, -0.05), (60.0, 0.0)):
        controls[0] = trim25.controls[0] + d_elevator
        plant.GetInputPort("controls").FixValue(context, controls)
        simulator.AdvanceTo(t_end)
    x = context.get_continuous_state_vector().CopyToVector()
    assert abs(np.linalg.norm(x[3:7]) - 1.0) < 1e-6
    assert np.all(np.isfinite(x))


def test_torque_free_tumbling_conserves_energy_and_angular_momentum():
    params = aerosonde()
    model = FixedWingModel(params, aerodynamics=False, propulsion=False, gravity=False)
    plant = FixedWingPlant(params, model)
    omega0 = np.array([1.2, -0.7, 2.1])
    state = np.array([0, 0, 0, 1, 0, 0, 0, 3.0, -1.0, 0.5, *omega0])
    context = _plant_context(plant, state, [0, 0, 0, 0])
    simulator = Simulator(plant, context)
    integrator = ResetIntegratorFromFlags(simulator, "runge_kutta5", 0.01)
    integrator.set_target_accuracy(1e-10)
    J = params.inertia

    def invariants(x):
        omega = x[10:13]
        h_ned = quat_to_rotmat(x[3:7]) @ (J @ omega)
        return 0.5 * omega @ J @ omega, h_ned, 0.5 * params.mass * x[7:10] @ x[7:10]

    e0, h0, k0 = invariants(state)
    simulator.AdvanceTo(10.0)
    x = context.get_continuous_state_vector().CopyToVector()
    e1, h1, k1 = invariants(x)
    assert abs(e1 - e0) / e0 < 1e-6
    assert abs(np.linalg.norm(h1) - np.linalg.norm(h0)) / np.linalg.norm(h0) < 1e-6
    np.testing.assert_allclose(h1, h0, rtol=1e-6, atol=1e-6 * np.linalg.norm(h0))
    assert abs(k1 - k0) / k0 < 1e-6  # translational energy: no force


def test_linearize_matches_finite_differences_at_trim(trim25):
    params = aerosonde()
    plant = FixedWingPlant(params)
    context = _plant_context(plant, trim25.state, trim25.controls, wrench=np.zeros(6))
    # The position keeps moving at trim, so the linearisation is taken about a
    # non-equilibrium point: A and B are the Jacobians of f.
    linear = Linearize(plant, context, equilibrium_check_tolerance=np.inf)
    taylor = FirstOrderTaylorApproximation(plant, context)
    model = FixedWingModel(params)
    x0, u0 = trim25.state, trim25.controls
    eps = 1e-6
    A_fd = np.column_stack([
        (model.evaluate(x0 + eps * e, u0).state_derivative
         - model.evaluate(x0 - eps * e, u0).state_derivative) / (2 * eps) for e in np.eye(13)])
    B_fd = np.column_stack([
        (model.evaluate(x0, u0 + eps * e).state_derivative
         - model.evaluate(x0, u0 - eps * e).state_derivative) / (2 * eps) for e in np.eye(4)])
    np.testing.assert_allclose(linear.A(), A_fd, atol=1e-6)
    np.testing.assert_allclose(linear.B()[:, :4], B_fd, atol=1e-6)
    np.testing.assert_allclose(taylor.A(), A_fd, atol=1e-6)


def test_symbolic_conversion_gives_the_same_derivatives(trim25):
    plant = FixedWingPlant(aerosonde())
    symbolic = plant.ToSymbolic()
    context = _plant_context(symbolic, trim25.state, trim25.controls)
    derivatives = symbolic.EvalTimeDerivatives(context).CopyToVector()
    values = np.array([d.Evaluate() for d in derivatives])
    expected = FixedWingModel(aerosonde()).evaluate(trim25.state, trim25.controls)
    np.testing.assert_allclose(values, expected.state_derivative, atol=1e-12)


def test_external_wrench_gives_the_expected_acceleration(trim25):
    params = aerosonde()
    plant = FixedWingPlant(params)
    force = np.array([13.5, -27.0, 6.75])
    moment = np.array([0.8244, 0.0, 0.0])
    base = _plant_context(plant, trim25.state, trim25.controls, wrench=np.zeros(6))
    pushed = _plant_context(plant, trim25.state, trim25.controls,
                            wrench=np.concatenate([force, moment]))
    d0 = plant.EvalTimeDerivatives(base).CopyToVector()
    d1 = plant.EvalTimeDerivatives(pushed).CopyToVector()
    np.testing.assert_allclose(d1[7:10] - d0[7:10], force / params.mass, atol=1e-12)
    np.testing.assert_allclose(d1[10:13] - d0[10:13], np.linalg.solve(params.inertia, moment),
                               atol=1e-12)
    sf0 = plant.GetOutputPort("specific_force").Eval(base)
    sf1 = plant.GetOutputPort("specific_force").Eval(pushed)
    np.testing.assert_allclose(sf1 - sf0, force / params.mass, atol=1e-12)


def test_outputs_are_consistent_with_the_trim(trim25):
    params = aerosonde()
    plant = FixedWingPlant(params)
    wind = np.array([3.0, -2.0, 0.5])
    # Add the wind to the ground velocity: the air-relative flow is the trim one.
    state = trim25.state.copy()
    state[7:10] += quat_to_rotmat(state[3:7]).T @ wind
    context = _plant_context(plant, state, trim25.controls, wind=wind)
    air = plant.GetOutputPort("air_data").Eval(context)
    np.testing.assert_allclose(air, [25.0, trim25.alpha, 0.0], atol=1e-10)
    fm = plant.GetOutputPort("forces_moments").Eval(context)
    np.testing.assert_allclose(fm, np.zeros(6), atol=1e-8)  # steady: total force balances
    euler = plant.GetOutputPort("euler").Eval(context)
    assert euler[1] == pytest.approx(trim25.alpha, abs=1e-10)  # level: pitch = alpha
    sf = plant.GetOutputPort("specific_force").Eval(context)
    np.testing.assert_allclose(np.linalg.norm(sf), params.gravity, rtol=1e-9)


def test_controls_saturate_at_the_limits(trim25):
    params = aerosonde()
    plant = FixedWingPlant(params)
    over = trim25.controls + np.array([5.0, 0, 0, 0])
    at_limit = trim25.controls.copy()
    at_limit[0] = params.limits.elevator
    d_over = plant.EvalTimeDerivatives(_plant_context(plant, trim25.state, over)).CopyToVector()
    d_lim = plant.EvalTimeDerivatives(
        _plant_context(plant, trim25.state, at_limit)).CopyToVector()
    np.testing.assert_array_equal(d_over, d_lim)


@pytest.mark.parametrize(
    "change, field",
    [
        ({"mass": -1.0}, "mass"),
        ({"Jxz": 1.5}, "inertia"),
        ({"Jz": 5.0}, "inertia"),
        ({"derivatives": {"CL_alpha": 3.0, "CL_banana": 1.0}}, "CL_banana"),
        ({"S": 0.0}, "S"),
    ],
)
def test_invalid_params_name_the_field(change, field):
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(aerosonde(), **change)


def _random_points(rng, n):
    x = rng.normal(size=(n, 13)) * [50, 50, 20, 1, 1, 1, 1, 3, 2, 2, 0.5, 0.5, 0.5]
    x[:, 7] += 25.0
    u = rng.normal(size=(n, 4)) * 0.3
    u[:, 3] = rng.uniform(-0.2, 1.2, n)  # beyond the throttle limits too: saturation
    return x, u, rng.normal(size=(n, 3)) * 4.0, rng.normal(size=(n, 6))


@pytest.mark.parametrize("derivatives", [{}, {"CL_alphadot": 1.5, "Cm_alphadot": -6.0}],
                         ids=["aerosonde", "with_alpha_dot"])
def test_compiled_model_equals_the_generic_model(derivatives):
    params = aerosonde()
    if derivatives:
        params = dataclasses.replace(params, derivatives={**params.derivatives, **derivatives})
    model = FixedWingModel(params)
    x, u, wind, wrench = _random_points(np.random.default_rng(7), 40)
    batch = model.compiled.evaluate_batch(x, u, wind, wrench)
    for k in range(len(x)):
        generic = model.evaluate(x[k], u[k], wind[k], wrench[k])
        compiled = model.compiled.evaluate(x[k], u[k], wind[k], wrench[k])
        for field in generic._fields:
            reference = np.asarray(getattr(generic, field), float)
            tolerance = 1e-12 * (1.0 + np.abs(reference).max())
            np.testing.assert_allclose(getattr(compiled, field), reference, atol=tolerance)
            np.testing.assert_allclose(getattr(batch, field)[k], reference, atol=tolerance)
    # No wrench is the zero wrench.
    no_wrench = model.compiled.evaluate(x[0], u[0], wind[0])
    np.testing.assert_array_equal(no_wrench.state_derivative,
                                  model.compiled.evaluate(x[0], u[0], wind[0], np.zeros(6))
                                  .state_derivative)


def test_alpha_dot_terms_see_the_rate_of_the_air_relative_alpha_gusts_included():
    """The alpha-dot the C_m term is built on is d(alpha)/dt of the air data, with the
    aircraft's motion and the wind's rate both (a gust moves alpha, not the aircraft);
    the compiled model and the generic one agree on it."""
    derivatives = {"CL_alphadot": 1.5, "Cm_alphadot": -6.0}
    params = aerosonde()
    model = FixedWingModel(dataclasses.replace(
        params, derivatives={**params.derivatives, **derivatives}))
    without = FixedWingModel(params)
    rng = np.random.default_rng(11)
    x, u, wind, wrench = _random_points(rng, 5)
    wind_rate = rng.normal(size=(5, 3)) * 3.0
    h = 1e-6
    for k in range(len(x)):
        evaluation = model.evaluate(x[k], u[k], wind[k], wrench[k], wind_rate[k])
        va = evaluation.air_data[0]
        alpha_dot = ((evaluation.coefficients[4]
                      - without.evaluate(x[k], u[k], wind[k], wrench[k]).coefficients[4])
                     / (derivatives["Cm_alphadot"] * params.c / (2.0 * va)))
        step = evaluation.state_derivative * h
        ahead = model.air_data(x[k] + step, wind[k] + wind_rate[k] * h)[1]
        behind = model.air_data(x[k] - step, wind[k] - wind_rate[k] * h)[1]
        assert alpha_dot == pytest.approx((ahead - behind) / (2 * h), rel=1e-5, abs=1e-7)
        compiled = model.compiled.evaluate(x[k], u[k], wind[k], wrench[k], wind_rate[k])
        np.testing.assert_allclose(compiled.state_derivative, evaluation.state_derivative,
                                   rtol=1e-12, atol=1e-12)
    # Without alpha-dot terms the wind's rate changes nothing.
    plain = without.evaluate(x[0], u[0], wind[0], wrench[0], wind_rate[0])
    np.testing.assert_array_equal(plain.state_derivative,
                                  without.evaluate(x[0], u[0], wind[0], wrench[0])
                                  .state_derivative)


def test_float_plant_matches_the_model_away_from_trim():
    plant = FixedWingPlant(aerosonde())
    x, u, wind, wrench = _random_points(np.random.default_rng(8), 1)
    context = _plant_context(plant, x[0], u[0], wind[0], wrench[0])
    expected = plant.model.evaluate(x[0], u[0], wind[0], wrench[0])
    np.testing.assert_allclose(plant.EvalTimeDerivatives(context).CopyToVector(),
                               expected.state_derivative, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(plant.GetOutputPort("specific_force").Eval(context),
                               expected.specific_force, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("derivatives", [{}, {"CL_alphadot": 1.5, "Cm_alphadot": -6.0}],
                         ids=["aerosonde", "with_alpha_dot"])
def test_every_plant_output_matches_the_model_evaluation(derivatives):
    """Each output has its own compiled code; all of them agree with one model evaluation,
    and the generic (AutoDiffXd) plant with the float one."""
    params = aerosonde()
    if derivatives:
        params = dataclasses.replace(params, derivatives={**params.derivatives, **derivatives})
    plant = FixedWingPlant(params)
    autodiff = plant.ToAutoDiffXd()
    rng = np.random.default_rng(9)
    x, u, wind, wrench = _random_points(rng, 3)
    wind_rate = rng.normal(size=(3, 3))
    for k in range(len(x)):
        expected = plant.model.evaluate(x[k], u[k], wind[k], wrench[k], wind_rate[k])
        # The coefficients never read the wrench (no feedthrough from it).
        unforced = plant.model.evaluate(x[k], u[k], wind[k], wind_rate_ned=wind_rate[k])
        context = _plant_context(plant, x[k], u[k], wind[k], wrench[k], wind_rate[k])
        outputs = {"air_data": expected.air_data, "specific_force": expected.specific_force,
                   "aero_coefficients": unforced.coefficients,
                   "forces_moments": expected.forces_moments,
                   "euler": plant.model.euler(x[k]), "state": x[k]}
        for name, reference in outputs.items():
            np.testing.assert_allclose(plant.GetOutputPort(name).Eval(context), reference,
                                       rtol=1e-12, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(plant.EvalTimeDerivatives(context).CopyToVector(),
                                   expected.state_derivative, rtol=1e-12, atol=1e-12)
        ad_context = autodiff.CreateDefaultContext()
        ad_context.SetTimeStateAndParametersFrom(context)
        for port, value in (("controls", u[k]), ("wind_ned", wind[k]),
                            ("external_wrench", wrench[k]), ("wind_rate_ned", wind_rate[k])):
            autodiff.GetInputPort(port).FixValue(ad_context, value.astype(object))
        ad_air = autodiff.GetOutputPort("air_data").Eval(ad_context)
        np.testing.assert_allclose([a.value() for a in ad_air], expected.air_data, rtol=1e-12)


def test_a_compiled_field_computes_only_what_it_needs():
    compiled = FixedWingModel(aerosonde()).compiled
    full = compiled._function.operation_count
    air = compiled._function.restricted(range(13, 16)).operation_count
    assert air < full / 3  # air data need the rotation and the wind triangle only
    with pytest.raises(ValueError, match="^name:"):
        compiled.field("thrust")
    with pytest.raises(ValueError, match="^outputs:"):
        compiled._function.restricted([40])


def test_compilations_are_shared_only_between_equal_models():
    params = aerosonde()
    assert FixedWingModel(params).compiled is FixedWingModel(aerosonde()).compiled
    heavier = dataclasses.replace(params, mass=params.mass + 1.0)
    assert FixedWingModel(heavier).compiled is not FixedWingModel(params).compiled
    assert FixedWingModel(params, gravity=False).compiled is not FixedWingModel(params).compiled
    x, u = trim(params, 25.0).state, trim(params, 25.0).controls
    # The heavier aircraft's compiled code has its own mass in it.
    assert FixedWingModel(heavier).compiled.evaluate(x, u).state_derivative[9] == pytest.approx(
        FixedWingModel(heavier).evaluate(x, u).state_derivative[9], abs=1e-12)
