"""Speed of the multirotor pieces, against the targets of the multirotor issue.

* minimum-snap QP, 10 segments in 3-D: one-shot (build + solve) and re-solve of
  a program built once; target <= 20 ms;
* time allocation (eq. 2.4-2.5) of the same 10 segments; target <= 2 s;
* MultirotorPlant real-time factor, hexacopter, Drake's default error-controlled
  RK3: hover, the flatness reference flown open loop (motor thrusts from a
  cubic spline, state logged at 100 Hz) and 40 Hz zero-order-hold commands (the
  NMPC rate of Argyropoulos 2020); target >= 200x. A fixed-step RK2 at 5 ms is printed
  for information. Each case runs three times and the best run is printed
  (the machine may be shared), next to the same case with an empty Python
  LeafSystem of the same size: the framework's own floor, measured in the same
  process.

Real-time factors are simulated time over CPU time of this process; each figure is also
printed as a FIGURE line (benchmarks/figures.py).

``--quick`` runs 10 min-snap solves and each plant case once.

Run: python benchmarks/bench_multirotor.py [--quick]
"""

import argparse
import time

import numpy as np
from figures import figure
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import ContinuousStateIndex, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.optimization.flatness import flat_reference, velocity_heading
from drake_uav.optimization.min_snap import MinimumSnap, minimum_snap, optimize_segment_times
from drake_uav.systems.multirotor import MultirotorPlant
from drake_uav.vehicles.multirotor import hexacopter

RNG = np.random.default_rng(7)
WAYPOINTS = np.cumsum(np.vstack([np.zeros(3), RNG.uniform(-4, 4, (10, 3))]), axis=0)
TIMES = np.linspace(0.0, 30.0, 11)
FLIGHT = 10.0


def median_ms(fn, repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return 1e3 * float(np.median(samples))


class EmptyPlant(LeafSystem):
    """13 states, n inputs, zero derivatives: the cost of any Python plant."""

    def __init__(self, num_motors: int):
        super().__init__()
        self.DeclareContinuousState(13)
        self._commands = self.DeclareVectorInputPort("motor_thrusts", num_motors)
        self.DeclareStateOutputPort("state", ContinuousStateIndex(0))
        self._zero = np.zeros(13)

    def DoCalcTimeDerivatives(self, context, derivatives):
        context.get_continuous_state_vector().CopyToVector()
        self._commands.Eval(context)
        derivatives.SetFromVector(self._zero)


def real_time_factor(system, commands: PiecewisePolynomial, state0, t0: float,
                     config: SimulatorConfig, log_period: float | None) -> tuple[float, int]:
    builder = DiagramBuilder()
    plant = builder.AddSystem(system)
    source = builder.AddSystem(TrajectorySource(commands))
    builder.Connect(source.get_output_port(), plant.GetInputPort("motor_thrusts"))
    if log_period:
        LogVectorOutput(plant.GetOutputPort("state"), builder, log_period)
    simulator = Simulator(builder.Build())
    ApplySimulatorConfig(config, simulator)
    context = simulator.get_mutable_context()
    context.SetTime(t0)
    plant.GetMyMutableContextFromRoot(context).SetContinuousState(state0)
    simulator.Initialize()
    start = time.process_time()
    simulator.AdvanceTo(t0 + FLIGHT)
    return FLIGHT / (time.process_time() - start), simulator.get_num_steps_taken()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="10 min-snap solves instead of 50, each plant case run once")
    quick = parser.parse_args().quick
    solves, runs = (10, 1) if quick else (50, 3)
    minimum_snap(WAYPOINTS, TIMES)  # warm-up (first program construction loads solvers)
    one_shot = median_ms(lambda: minimum_snap(WAYPOINTS, TIMES), solves)
    program = MinimumSnap(10)
    shifted = [WAYPOINTS + 0.01 * k for k in range(50)]
    resolve = median_ms(lambda: program.solve(shifted[RNG.integers(50)], TIMES), solves)
    print(f"min-snap 10 segments 3-D: one-shot {one_shot:.2f} ms, re-solve {resolve:.2f} ms "
          f"(target 20 ms: {20.0 / one_shot:.0f}x / {20.0 / resolve:.0f}x margin)")
    figure("min_snap_one_shot_ms", one_shot, "ms", "lower")
    figure("min_snap_resolve_ms", resolve, "ms", "lower")

    start = time.perf_counter()
    result = optimize_segment_times(WAYPOINTS, TIMES)
    seconds = time.perf_counter() - start
    print(f"time allocation 10 segments: {seconds:.2f} s, {result.iterations} iterations, "
          f"{result.evaluations} QP solves, cost {result.initial_cost:.2f} -> {result.cost:.2f} "
          f"(target 2 s: {2.0 / seconds:.1f}x margin)")
    figure("time_allocation_s", seconds, "s", "lower")

    params = hexacopter()
    trajectory = result.trajectory
    t = np.arange(0.0, 30.0 + 1e-9, 0.01)
    reference = flat_reference(trajectory, params, t, yaw=velocity_heading(trajectory))
    t0, k0 = 5.0, 500
    hover = PiecewisePolynomial(params.thrusts_for_wrench([params.weight, 0, 0, 0])[:, None])
    level = np.r_[0, 0, -5, 1, 0, 0, 0, np.zeros(6)]
    tz = t[::4]
    zoh = PiecewisePolynomial.ZeroOrderHold(tz, reference.motor_thrusts[::4].T)
    default = SimulatorConfig()
    rk2 = SimulatorConfig(integration_scheme="runge_kutta2", max_step_size=0.005,
                          use_error_control=False)
    cases = [
        ("hover, constant thrusts", hover, level, default, None),
        ("reference flight, cubic thrusts, 100 Hz log", reference.motor_thrust_trajectory(),
         reference.state[k0], default, 0.01),
        ("reference flight, 40 Hz zero-order hold", zoh, reference.state[k0], default, None),
        ("(info) fixed-step RK2 5 ms, cubic thrusts", reference.motor_thrust_trajectory(),
         reference.state[k0], rk2, None),
    ]
    keys = ("hover", "reference_log100hz", "reference_zoh40hz", "reference_rk2")
    for key, (name, commands, state0, config, log_period) in zip(keys, cases, strict=True):
        rtf, steps = max(real_time_factor(MultirotorPlant(params), commands, state0, t0,
                                          config, log_period) for _ in range(runs))
        floor, _ = max(real_time_factor(EmptyPlant(params.num_motors), commands, state0, t0,
                                        config, log_period) for _ in range(runs))
        print(f"plant {name}: {rtf:.0f}x real time, {steps} steps in {FLIGHT:.0f} s "
              f"(target 200x: ratio {rtf / 200.0:.2f}; empty Python system {floor:.0f}x)")
        figure(f"multirotor_rtf_{key}", rtf, "x")


if __name__ == "__main__":
    main()
