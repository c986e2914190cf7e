"""Speed of the fixed-wing plant, alone and against JSBSim in the same run.

1. Model evaluation: scalar-generic ``FixedWingModel.evaluate`` and the compiled state
   derivative the plant calls, CPU time per call.
2. A 60 s open-loop Aerosonde flight from trim with an elevator doublet (+0.05 rad at
   5-6 s, -0.05 rad at 6-7 s), Drake's default error-controlled RK3, the state logged at
   three rates (each logging period bounds the step). Target: >= 200x real time.
3. The same flight against JSBSim (Berndt 2004; pip ``jsbsim``, the optional ``[bench]``
   extra), both at a fixed 120 Hz step (JSBSim's default rate) for 60 s with an elevator
   doublet from trimmed level flight. JSBSim flies 'c172x', the aircraft of its own test
   scripts: like the Aerosonde a single piston engine and propeller, a 13-entry rigid-body
   state (position, quaternion, velocity, rates; plus engine and actuator states), its
   doublet of +/-0.1 of full elevator command (about +/-2.5 deg) at 5-6 s and 6-7 s. JSBSim's
   default integrators evaluate forces and moments once per step (rectangular Euler for
   rates and attitude, Adams-Bashforth 2/3 for velocity and position), so the drake_uav
   figure to compare is explicit Euler (one evaluation per step); RK2 (the identification
   flight's scheme) and RK3 are printed too. Each line gives the real-time factor, the
   ratio to JSBSim's (target >= 1) and the integration error of the 120 Hz run against the
   same simulator at 960 Hz (drake_uav: RK3), so the accuracy bought per step is visible.
4. Where the time of one explicit-Euler step goes, measured by difference in the same
   simulator setup: the simulator with the controls source and a C++ plant of the same
   size; a Python LeafSystem with the same ports returning zeros; the same reading the
   state and its ports as the plant does; the plant itself (the rest is the compiled model).

Times are CPU time of this process (``time.process_time``), best of ``--repeats`` rounds
that run every case once, so other load on a shared machine inflates them less than wall
time; a ratio to JSBSim is the median over the rounds of the ratio of the two runs made in
the same round.

``--quick`` runs every case once (and the model evaluation 10 times fewer calls): the same
figures, noisier.

Run: python benchmarks/bench_fixed_wing.py [--repeats 10] [--quick]
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import tempfile
import time

import numpy as np
from figures import figure
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import ContinuousStateIndex, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LinearSystem, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.optimization.trim import trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde

DURATION = 60.0  # s
RATE = 120.0  # Hz, JSBSim's default step rate
TARGET = 200.0  # real-time factor of the plant alone
DOUBLET = ((5.0, 1.0), (6.0, -1.0), (7.0, 0.0))  # (start time [s], sign)
AEROSONDE_DOUBLET = 0.05  # rad
JSBSIM_AIRCRAFT = "c172x"
JSBSIM_DOUBLET = 0.1  # of full elevator command
SCHEMES = ("explicit_euler", "runge_kutta2", "runge_kutta3")
EVALUATIONS_PER_STEP = {"explicit_euler": 1, "runge_kutta2": 2, "runge_kutta3": 3}


def cpu_samples(cases: dict, repeats: int) -> dict[str, list[float]]:
    """CPU seconds of each case in each of ``repeats`` rounds that run every case once
    (interleaved). A case is a function that prepares a run and returns the function to
    time."""
    samples = {name: [] for name in cases}
    for _ in range(repeats):
        for name, prepare in cases.items():
            run = prepare()
            start = time.process_time()
            run()
            samples[name].append(time.process_time() - start)
    return samples


def best_cpu(cases: dict, repeats: int) -> dict[str, float]:
    """Least CPU seconds of each case over ``repeats`` interleaved rounds."""
    return {name: min(values) for name, values in cpu_samples(cases, repeats).items()}


def paired_ratio(numerator: list[float], denominator: list[float]) -> float:
    """Median of the ratios of runs made in the same round: a change of the machine's load
    between rounds cancels out."""
    return float(np.median(np.asarray(numerator) / np.asarray(denominator)))


@functools.cache
def level_flight():
    """The Aerosonde trimmed in level flight at 25 m/s."""
    return trim(aerosonde(), 25.0)


# ------------------------------------------------------------------------- drake_uav side
def doublet_controls(level_controls) -> PiecewisePolynomial:
    """Trim controls with the elevator doublet, held between the switch times."""
    times = [0.0] + [t for t, _ in DOUBLET] + [DURATION]
    controls = np.tile(np.asarray(level_controls, float)[:, None], (1, len(times)))
    for k, (_, sign) in enumerate(DOUBLET):
        controls[0, k + 1] += sign * AEROSONDE_DOUBLET
    return PiecewisePolynomial.ZeroOrderHold(times, controls)


def drake_flight(plant_factory, config: SimulatorConfig | None, log_period: float | None = None,
                 level=None):
    """A prepared doublet flight: (simulator ready to ``AdvanceTo``, state logger or None)."""
    params = aerosonde()
    level = level or level_flight()
    builder = DiagramBuilder()
    plant = builder.AddSystem(plant_factory(params))
    source = builder.AddSystem(TrajectorySource(doublet_controls(level.controls)))
    builder.Connect(source.get_output_port(), plant.get_input_port(0))
    logger = LogVectorOutput(plant.get_output_port(0), builder, log_period) if log_period else None
    simulator = Simulator(builder.Build())
    if config is not None:
        ApplySimulatorConfig(config, simulator)
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    context.SetContinuousState(level.state)
    simulator.Initialize()
    return simulator, logger


def fixed_step(scheme: str, rate: float = RATE) -> SimulatorConfig:
    return SimulatorConfig(integration_scheme=scheme, max_step_size=1.0 / rate,
                           use_error_control=False)


def drake_case(plant_factory, config=None, log_period=None):
    def prepare():
        simulator, _ = drake_flight(plant_factory, config, log_period)
        return lambda: simulator.AdvanceTo(DURATION)
    return prepare


class EmptyPlant(LeafSystem):
    """The plant's ports and state size, zero derivatives; with ``reads`` it reads the
    state and its ports the way FixedWingPlant does before calling the model."""

    def __init__(self, reads: bool):
        super().__init__()
        self.DeclareContinuousState(13)
        self._ports = (self.DeclareVectorInputPort("controls", 4),
                       self.DeclareVectorInputPort("wind_ned", 3),
                       self.DeclareVectorInputPort("external_wrench", 6))
        self.DeclareStateOutputPort("state", ContinuousStateIndex(0))
        self._zero = np.zeros(13)
        self._reads = reads

    def DoCalcTimeDerivatives(self, context, derivatives):
        if self._reads:
            controls, wind, wrench = self._ports
            context.get_continuous_state_vector().value().tolist()
            controls.Eval(context).tolist()
            _ = wind.Eval(context).tolist() if wind.HasValue(context) else None
            _ = wrench.Eval(context).tolist() if wrench.HasValue(context) else None
        derivatives.SetFromVector(self._zero)


def cpp_plant(params) -> LinearSystem:
    """A C++ system of the plant's state and controls size (zero dynamics)."""
    return LinearSystem(np.zeros((13, 13)), np.zeros((13, 4)), np.zeros((13, 13)),
                        np.zeros((13, 4)))


def pitch_altitude_drake(scheme: str, rate: float) -> np.ndarray:
    """Pitch angle [rad] and altitude [m] at 10 Hz over the flight."""
    simulator, logger = drake_flight(FixedWingPlant, fixed_step(scheme, rate), log_period=0.1)
    simulator.AdvanceTo(DURATION)
    x = logger.FindLog(simulator.get_context()).data()
    qw, qx, qy, qz = x[3], x[4], x[5], x[6]
    return np.vstack([np.arcsin(np.clip(2 * (qw * qy - qx * qz), -1, 1)), -x[2]])


# --------------------------------------------------------------------------- JSBSim side
def jsbsim_available() -> bool:
    try:
        import jsbsim  # noqa: F401
    except ImportError:
        return False
    return True


class JsbsimFlight:
    """JSBSim's FGFDMExec trimmed in level flight (3000 ft, 100 kt), ready to fly the
    doublet at ``rate``. Its output directives (files, sockets) are switched off and
    pointed at a temporary directory."""

    def __init__(self, rate: float = RATE):
        os.environ.setdefault("JSBSIM_DEBUG", "0")
        import jsbsim

        self._outputs = tempfile.TemporaryDirectory()
        fdm = jsbsim.FGFDMExec(None)
        fdm.set_debug_level(0)
        fdm.set_output_path(self._outputs.name)
        fdm.load_model(JSBSIM_AIRCRAFT)
        fdm.disable_output()
        fdm.set_dt(1.0 / rate)
        fdm["ic/h-sl-ft"] = 3000.0
        fdm["ic/vc-kts"] = 100.0
        fdm["ic/gamma-deg"] = 0.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm["simulation/do_simple_trim"] = 1
        self.fdm, self.rate = fdm, rate

    def segments(self) -> list[tuple[int, float]]:
        """(steps, elevator command) of each piece of the doublet flight."""
        times = [0.0] + [t for t, _ in DOUBLET] + [DURATION]
        signs = [0.0] + [s for _, s in DOUBLET]
        return [(round((b - a) * self.rate), sign * JSBSIM_DOUBLET)
                for a, b, sign in zip(times[:-1], times[1:], signs, strict=True)]

    def fly(self, every: int = 0) -> np.ndarray | None:
        """Flies the doublet (the command set once per piece); with ``every`` > 0 returns
        the pitch angle [rad] and altitude [m] every ``every`` steps."""
        fdm, run, samples = self.fdm, self.fdm.run, []
        for steps, command in self.segments():
            fdm["fcs/elevator-cmd-norm"] = command
            if every:
                for _ in range(steps):
                    run()
                    samples.append((fdm["attitude/theta-rad"], fdm["position/h-sl-meters"]))
            else:
                for _ in range(steps):
                    run()
        return np.array(samples[every - 1::every]).T if every else None

    def close(self) -> None:
        self._outputs.cleanup()


def jsbsim_case():
    def prepare():
        flight = JsbsimFlight()
        return lambda: (flight.fly(), flight.close())
    return prepare


def pitch_altitude_jsbsim(rate: float) -> np.ndarray:
    flight = JsbsimFlight(rate)
    try:
        return flight.fly(every=round(rate / 10))
    finally:
        flight.close()


# ------------------------------------------------------------------------------ reports
def model_costs(repeats: int = 20000) -> None:
    params = aerosonde()
    level = trim(params, 25.0)
    model = FixedWingModel(params)
    x, u, wind = level.state.tolist(), level.controls.tolist(), [0.0, 0.0, 0.0]
    derivative = model.compiled.field("state_derivative")
    cases = {"generic": lambda: lambda: [model.evaluate(level.state, level.controls)
                                         for _ in range(repeats // 10)],
             "derivative": lambda: lambda: [derivative(x, u, wind, [0.0] * 6, wind)
                                            for _ in range(repeats)]}
    best = best_cpu(cases, 3)
    generic = best["generic"] / (repeats // 10) * 1e6
    compiled = best["derivative"] / repeats * 1e6
    print(f"FixedWingModel.evaluate: {generic:.1f} us per call (scalar-generic); compiled state "
          f"derivative {compiled:.2f} us per call")
    figure("fixed_wing_model_generic_us", generic, "us", "lower")
    figure("fixed_wing_state_derivative_us", compiled, "us", "lower")


def default_integrator(repeats: int) -> None:
    periods = {"no logger": None, "state logged at 20 Hz": 0.05, "state logged at 100 Hz": 0.01}
    cases = {label: drake_case(FixedWingPlant, None, period) for label, period in periods.items()}
    best = best_cpu(cases, repeats)
    print(f"\n60 s doublet flight, Drake's default error-controlled RK3, CPU best of {repeats}:")
    for label, period in periods.items():
        simulator, _ = drake_flight(FixedWingPlant, None, period)
        simulator.AdvanceTo(DURATION)
        rtf = DURATION / best[label]
        print(f"  {label:<24}: {rtf:7.1f}x real time ({simulator.get_num_steps_taken()} "
              f"steps), {rtf / TARGET:.2f} of the {TARGET:.0f}x target")
        suffix = "" if period is None else f"_log{1 / period:.0f}hz"
        figure(f"plant_rtf_default{suffix}", rtf, "x")


def against_jsbsim(repeats: int) -> None:
    cases = {scheme: drake_case(FixedWingPlant, fixed_step(scheme)) for scheme in SCHEMES}
    have_jsbsim = jsbsim_available()
    if have_jsbsim:
        cases["jsbsim"] = jsbsim_case()
    samples = cpu_samples(cases, repeats)
    best = {name: min(values) for name, values in samples.items()}
    print(f"\n60 s elevator doublet at a fixed {RATE:.0f} Hz step, CPU best of {repeats} "
          "(ratio: median of the runs' ratios in the same round):")
    reference = pitch_altitude_drake("runge_kutta3", 8 * RATE)
    jsbsim_rtf = DURATION / best["jsbsim"] if have_jsbsim else math.nan
    print(f"  {'simulator':36s} {'RTF':>7s} {'/ JSBSim':>9s} {'us/step':>8s} "
          f"{'max |d pitch| [deg]':>20s} {'max |d h| [m]':>14s}")
    ratios = {scheme: paired_ratio(samples["jsbsim"], samples[scheme]) if have_jsbsim
              else math.nan for scheme in SCHEMES}
    for scheme in SCHEMES:
        rtf = DURATION / best[scheme]
        error = np.abs(pitch_altitude_drake(scheme, RATE) - reference).max(axis=1)
        label = f"drake_uav {scheme} ({EVALUATIONS_PER_STEP[scheme]} eval.)"
        print(f"  {label:36s} {rtf:7.1f} {ratios[scheme]:9.2f} "
              f"{1e6 * best[scheme] / (DURATION * RATE):8.2f} {np.degrees(error[0]):20.2e} "
              f"{error[1]:14.2e}")
        figure(f"plant_rtf_{RATE:.0f}hz_{scheme}", rtf, "x")
        if have_jsbsim:
            figure(f"plant_over_jsbsim_{scheme}", ratios[scheme], "ratio")
    if not have_jsbsim:
        print("  JSBSim is not installed: pip install 'drake_uav[bench]' (or jsbsim)")
        return
    error = np.abs(pitch_altitude_jsbsim(RATE) - pitch_altitude_jsbsim(8 * RATE)).max(axis=1)
    label = f"JSBSim {JSBSIM_AIRCRAFT} (1 eval.)"
    print(f"  {label:36s} {jsbsim_rtf:7.1f} {1.0:9.2f} "
          f"{1e6 * best['jsbsim'] / (DURATION * RATE):8.2f} {np.degrees(error[0]):20.2e} "
          f"{error[1]:14.2e}")
    figure(f"jsbsim_rtf_{RATE:.0f}hz", jsbsim_rtf, "x")
    ratio = ratios["explicit_euler"]
    print(f"  drake_uav / JSBSim at one evaluation per step: {ratio:.2f} (target >= 1: "
          f"{'met' if ratio >= 1 else 'missed'})")


def step_breakdown(repeats: int) -> None:
    euler = fixed_step("explicit_euler")
    cases = {"cpp": drake_case(cpp_plant, euler),
             "empty": drake_case(lambda params: EmptyPlant(reads=False), euler),
             "reads": drake_case(lambda params: EmptyPlant(reads=True), euler),
             "plant": drake_case(FixedWingPlant, euler)}
    steps = DURATION * RATE
    cost = {name: 1e6 * seconds / steps for name, seconds in best_cpu(cases, repeats).items()}
    rows = [("simulator step, controls source (C++)", cost["cpp"], "step_simulator_us"),
            ("Python LeafSystem call, derivative write", cost["empty"] - cost["cpp"],
             "step_python_call_us"),
            ("state and port reads", cost["reads"] - cost["empty"], "step_port_reads_us"),
            ("compiled model (the rest)", cost["plant"] - cost["reads"], "step_model_us")]
    print(f"\nWhere one explicit-Euler step goes ({cost['plant']:.2f} us, CPU best of {repeats}; "
          "each row by difference):")
    for label, value, name in rows:
        print(f"  {label:42s} {value:6.2f} us {100 * value / cost['plant']:5.1f}%")
        figure(name, value, "us", "lower")
    figure("step_total_us", cost["plant"], "us", "lower")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10, help="runs per case (best is kept)")
    parser.add_argument("--quick", action="store_true", help="every case once")
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1
    model_costs(2000 if args.quick else 20000)
    default_integrator(args.repeats)
    against_jsbsim(args.repeats)
    step_breakdown(args.repeats)


if __name__ == "__main__":
    main()
