import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from drake_uav.model.coefficients import lift_drag_to_body
from drake_uav.optimization.trim import trim
from drake_uav.systems.disturbances import AerodynamicIncrement
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde


def _closed_loop(increment):
    params = aerosonde()
    level = trim(params, 25.0)
    builder = DiagramBuilder()
    plant = builder.AddSystem(FixedWingPlant(params))
    controls = builder.AddSystem(ConstantVectorSource(level.controls))
    effect = builder.AddSystem(AerodynamicIncrement(params, increment))
    builder.Connect(controls.get_output_port(), plant.GetInputPort("controls"))
    builder.Connect(controls.get_output_port(), effect.GetInputPort("controls"))
    builder.Connect(plant.GetOutputPort("air_data"), effect.GetInputPort("air_data"))
    builder.Connect(plant.GetOutputPort("state"), effect.GetInputPort("state"))
    builder.Connect(effect.GetOutputPort("wrench"), plant.GetInputPort("external_wrench"))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.set_state(plant.GetMyMutableContextFromRoot(context), level.state)
    return params, level, plant, effect, diagram, context


def test_increment_becomes_the_expected_wrench_without_an_algebraic_loop():
    params, level, plant, effect, diagram, context = _closed_loop(
        lambda c: (-0.1, 0.02, 0.01, 0.001, -0.003, 0.002))
    wrench = effect.GetOutputPort("wrench").Eval(effect.GetMyContextFromRoot(context))
    q_bar_s = 0.5 * params.rho * 25.0**2 * params.S
    dCX, dCZ = lift_drag_to_body(-0.1, 0.02, level.alpha)
    np.testing.assert_allclose(
        wrench, q_bar_s * np.array([dCX, 0.01, dCZ, params.b * 0.001, params.c * -0.003,
                                    params.b * 0.002]), rtol=1e-12)


def test_lift_loss_makes_the_aircraft_sink():
    *_, plant, _, diagram, context = _closed_loop(lambda c: (-0.05, 0, 0, 0, 0, 0))
    Simulator(diagram, context).AdvanceTo(3.0)
    state = plant.GetOutputPort("state").Eval(plant.GetMyContextFromRoot(context))
    assert state[2] > -100.0 + 1.0  # lost more than a metre of height (pD grows)


def test_no_increment_keeps_the_trim():
    *_, plant, _, diagram, context = _closed_loop(lambda c: (0, 0, 0, 0, 0, 0))
    Simulator(diagram, context).AdvanceTo(3.0)
    air = plant.GetOutputPort("air_data").Eval(plant.GetMyContextFromRoot(context))
    assert air[0] == pytest.approx(25.0, abs=1e-6)


def test_an_increment_of_condition_and_time_reads_the_simulation_time():
    """``f(condition, t)`` gets the time [s]; ``lambda c, k=k:`` closures still get the
    condition alone."""
    times = []
    params, level, plant, effect, diagram, context = _closed_loop(
        lambda c, t: times.append(t) or (0, 0.001 * t, 0, 0, 0, 0))
    port = effect.GetOutputPort("wrench")
    context.SetTime(40.0)
    wrench = port.Eval(effect.GetMyContextFromRoot(context))
    dCX, dCZ = lift_drag_to_body(0.0, 0.04, level.alpha)
    np.testing.assert_allclose(wrench[[0, 2]], 0.5 * params.rho * 25.0**2 * params.S
                               * np.array([dCX, dCZ]), rtol=1e-12)
    assert times == [40.0]
    *_, effect, _, context = _closed_loop(lambda c, k=0.0: (0, k, 0, 0, 0, 0))
    context.SetTime(40.0)
    assert not effect.GetOutputPort("wrench").Eval(effect.GetMyContextFromRoot(context)).any()
