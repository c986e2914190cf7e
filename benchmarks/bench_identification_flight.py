"""Benchmark: a 300 s identification flight (plant + Dryden + full sensor suite, 100 Hz IMU).

Prints the real-time factor (target >= 100x), the plant-only reference run with the
same integrator and step, and where the time goes: every callback of the diagram timed
on its own in a mid-flight context, times its calls per 10 ms tick. Real-time factors are
simulated time over CPU time of this process (best of ``--repeats``), so other load on a
shared machine inflates them less than wall time. ``--quick`` flies once, times each
callback over fewer calls and studies the integrators on a 10 s flight.

    python benchmarks/bench_identification_flight.py [--duration 300] [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from figures import figure
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from drake_uav.diagrams.identification_flight import build_identification_flight
from drake_uav.systems.fixed_wing import FixedWingPlant


def plant_only_rtf(flight, duration: float) -> float:
    """Real-time factor of the plant alone (trim controls, same integrator and step)."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(FixedWingPlant(flight.aircraft))
    source = builder.AddSystem(ConstantVectorSource(flight.trim.controls))
    builder.Connect(source.get_output_port(0), plant.GetInputPort("controls"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(flight.simulator_config, simulator)
    context = simulator.get_mutable_context()
    plant.set_state(plant.GetMyMutableContextFromRoot(context), flight.initial_state)
    simulator.Initialize()
    start = time.process_time()
    simulator.AdvanceTo(duration)
    return duration / (time.process_time() - start)


def _per_call(fn, invalidate, repeats: int = 2000) -> float:
    """Mean cost [us] of ``fn`` after ``invalidate`` (which is timed and subtracted)."""
    def loop(body):
        start = time.process_time()
        for _ in range(repeats):
            invalidate()
            body()
        return time.process_time() - start

    base = min(loop(lambda: None) for _ in range(3))
    return max(0.0, (min(loop(fn) for _ in range(3)) - base) / repeats * 1e6)


def model_evaluation(flight, repeats: int = 5000) -> None:
    """One model evaluation: the scalar-generic code against its compiled trace."""
    model = flight.plant.model
    x, u = flight.initial_state, flight.trim.controls
    wind, wrench = np.array([1.0, -2.0, 0.5]), np.zeros(6)
    costs = {}
    for label, evaluate in (("generic", model.evaluate), ("compiled", model.compiled.evaluate)):
        start = time.process_time()
        for _ in range(repeats):
            evaluate(x, u, wind, wrench)
        costs[label] = (time.process_time() - start) / repeats * 1e6
    print(f"  model evaluation      generic {costs['generic']:.1f} us, compiled "
          f"{costs['compiled']:.1f} us ({costs['generic'] / costs['compiled']:.1f}x)")


def breakdown(flight, tick_us: float, calls: int = 2000) -> None:
    """Cost of each callback per 10 ms tick, timed one by one in a mid-flight context."""
    simulator = Simulator(flight.diagram)
    ApplySimulatorConfig(flight.simulator_config, simulator)
    root = simulator.get_mutable_context()
    flight.plant.set_state(flight.plant.GetMyMutableContextFromRoot(root), flight.initial_state)
    simulator.AdvanceTo(5.0)
    plant = flight.plant
    pc = plant.GetMyMutableContextFromRoot(root)
    x = pc.get_continuous_state_vector().CopyToVector()

    def touch():  # marks the plant state changed: every plant cache entry is recomputed
        pc.SetContinuousState(x)

    rows = [("plant derivatives (RK2: 2 per step)", 2.0,
             _per_call(lambda: plant.EvalTimeDerivatives(pc), touch, calls))]
    # The sensors and the safety pilot read these at each sample, each computed by
    # its own compiled code (the Euler angles come from the state quaternion).
    for name in ("air_data", "specific_force"):
        port = plant.GetOutputPort(name)
        rows.append((f"plant output {name}", 1.0, _per_call(lambda p=port: p.Eval(pc), touch,
                                                                   calls)))
    updates = [("Dryden filter update", flight.wind.filter if flight.wind else None),
               ("sensor suite update", flight.sensors.sensors),
               ("safety pilot update", flight.pilot),
               ("excitation update", flight.excitation)]
    for label, system in updates:
        if system is None:
            continue
        context = system.GetMyContextFromRoot(root)
        values = system.AllocateDiscreteVariables()
        rows.append((label, 1.0, _per_call(lambda s=system, c=context, v=values: s._update(c, v),
                                           lambda: None, calls)))
    accounted = sum(calls * cost for _, calls, cost in rows)
    print(f"\nWhere the time goes (each callback timed alone; CPU {tick_us:.0f} us "
          "per 10 ms tick):")
    print(f"  {'callback':38s} {'calls/tick':>10s} {'us/call':>8s} {'us/tick':>8s} {'share':>6s}")
    for label, calls, cost in rows:
        print(f"  {label:38s} {calls:10.0f} {cost:8.1f} {calls * cost:8.1f} "
              f"{100 * calls * cost / tick_us:5.1f}%")
    rest = tick_us - accounted
    print(f"  {'simulator, events, loggers, bindings':38s} {'':10s} {'':8s} {rest:8.1f} "
          f"{100 * rest / tick_us:5.1f}%")


def integrators(duration: float = 30.0) -> None:
    """Speed and accuracy of fixed-step schemes against RK3 at a quarter of the step."""
    flight = build_identification_flight(turbulence="moderate", duration=duration)
    reference = dataclasses.replace(flight, simulator_config=SimulatorConfig(
        integration_scheme="runge_kutta3", max_step_size=flight.sample_period / 4,
        use_error_control=False)).simulate()
    print(f"\nIntegrators on a {duration:.0f} s flight (error against RK3 with h/4):")
    print(f"  {'scheme':16s} {'RTF':>7s} {'max |dp| [m]':>13s} {'max |d alpha| [deg]':>20s}")
    for scheme in ("explicit_euler", "runge_kutta2", "runge_kutta3"):
        config = SimulatorConfig(integration_scheme=scheme, max_step_size=flight.sample_period,
                                 use_error_control=False)
        candidate = dataclasses.replace(flight, simulator_config=config)
        start = time.process_time()
        log = candidate.simulate()
        rtf = duration / (time.process_time() - start)
        dp = np.abs(log.stack(["pn", "pe", "pd"]) - reference.stack(["pn", "pe", "pd"])).max()
        da = np.degrees(np.abs(log["alpha"] - reference["alpha"]).max())
        print(f"  {scheme:16s} {rtf:7.1f} {dp:13.2e} {da:20.2e}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=300.0, help="flight time [s]")
    parser.add_argument("--repeats", type=int, default=3, help="flights flown (best is shown)")
    parser.add_argument("--quick", action="store_true",
                        help="one flight; fewer calls per cost, a 10 s integrator flight")
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1

    start = time.perf_counter()
    flight = build_identification_flight(turbulence="moderate", duration=args.duration)
    build = time.perf_counter() - start
    cpu = []
    for _ in range(args.repeats):
        start = time.process_time()
        log = flight.simulate()
        cpu.append(time.process_time() - start)
    wall = min(cpu)
    rtf = args.duration / wall
    reference = max(plant_only_rtf(flight, min(args.duration, 60.0)) for _ in range(args.repeats))
    print(f"identification flight: {args.duration:.0f} s simulated in {wall:.2f} s CPU "
          f"(best of {args.repeats}: {', '.join(f'{w:.2f}' for w in cpu)} s; "
          f"build {build:.2f} s)")
    print(f"  real-time factor      {rtf:8.1f}x   (target >= 100x: "
          f"{'met' if rtf >= 100 else 'missed'})")
    print(f"  plant alone           {reference:8.1f}x   (same integrator, "
          f"{flight.simulator_config.integration_scheme}, h = {flight.sample_period} s)")
    print(f"  full / plant-only     {rtf / reference:8.2f}")
    print(f"  log: {log}; per tick {1e6 * wall / len(log):.0f} us")
    print(f"  sanity: roll max {np.degrees(np.abs(log['roll']).max()):.1f} deg, "
          f"airspeed {log['airspeed'].min():.1f}..{log['airspeed'].max():.1f} m/s")
    figure("identification_flight_rtf", rtf, "x")
    figure("plant_alone_rtf", reference, "x")
    figure("identification_flight_tick_us", 1e6 * wall / len(log), "us", "lower")
    model_evaluation(flight, 500 if args.quick else 5000)
    breakdown(flight, 1e6 * wall / len(log), 200 if args.quick else 2000)
    integrators(10.0 if args.quick else 30.0)


if __name__ == "__main__":
    main()
