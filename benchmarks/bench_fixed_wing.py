"""Real-time factor of a 60 s open-loop Aerosonde flight with an elevator doublet.

Default integrator (Drake's error-controlled RK3); the state logged at three
rates, since each logging period bounds the integrator step. Target: >= 200x.

Run: python benchmarks/bench_fixed_wing.py
"""

import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.optimization.trim import trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde

DURATION = 60.0
TARGET = 200.0


def flight(log_period: float | None) -> tuple[float, int]:
    params = aerosonde()
    level = trim(params, 25.0)
    times = [0.0, 5.0, 6.0, 7.0, DURATION]
    controls = np.tile(level.controls[:, None], (1, len(times)))
    controls[0, 1] += 0.05
    controls[0, 2] -= 0.05
    builder = DiagramBuilder()
    plant = builder.AddSystem(FixedWingPlant(params))
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, controls)))
    builder.Connect(source.get_output_port(), plant.GetInputPort("controls"))
    if log_period:
        LogVectorOutput(plant.GetOutputPort("state"), builder, log_period)
    simulator = Simulator(builder.Build())
    plant.set_state(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                    level.state)
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(DURATION)
    return DURATION / (time.perf_counter() - start), simulator.get_num_steps_taken()


def model_cost_us(repeats: int = 20000) -> float:
    params = aerosonde()
    level = trim(params, 25.0)
    model = FixedWingModel(params)
    wind = np.zeros(3)
    start = time.perf_counter()
    for _ in range(repeats):
        model.evaluate(level.state, level.controls, wind)
    return (time.perf_counter() - start) / repeats * 1e6


if __name__ == "__main__":
    print(f"FixedWingModel.evaluate: {model_cost_us():.1f} us per call")
    for period in (None, 0.05, 0.01):
        rtf, steps = flight(period)
        label = "no logger" if period is None else f"state logged at {1 / period:.0f} Hz"
        print(f"60 s doublet flight, {label:<24}: {rtf:7.1f}x real time "
              f"({steps} steps), {rtf / TARGET:.2f} of the {TARGET:.0f}x target")
