"""An identification flight: plant, Dryden wind, sensors and designed excitation.

:func:`build_identification_flight` wires

    ExcitationSource (trim + excitation) --+--> Adder --> FixedWingPlant --> SensorSuite
    SafetyPilot (weak attitude hold) ------+                |   ^          (imu: gyro
                                                            |   |           to the pilot)
                                                            v   | wind_ned
                                                         DrydenWind

and logs the measurements, the commands, the plant's state and inputs; the
other truth channels (air data, Euler angles, coefficients, forces, body gust)
are computed from those after the flight with the plant's own compiled model.
:func:`fly` builds and simulates it and returns a
:class:`~drake_uav.io.flight_log.FlightLog`. ``extend`` adds your own systems
(an estimator, an on-line identifier) to the same diagram.

Timing: everything runs at the sensor suite's base rate (default 100 Hz). Row k
of the log holds the sensor samples taken at t_k, the command issued at t_k, and
the truth at t_k just before the events at t_k (so truth coefficients, forces
and controls belong together: the controls and wind in effect over the step
that ends at t_k).

The safety pilot (:class:`~drake_uav.systems.safety_pilot.SafetyPilot`) is a weak
attitude/altitude/heading/airspeed hold added on top of trim + excitation so that long
flights stay near the trim condition; its rate dampers use the IMU's gyro (the sample
of the previous period). It can be switched off (``stabilize=False``) for open-loop
excitation. A signal on a reference channel (a
:class:`~drake_uav.systems.excitation.Turn` of the heading) goes to its
``reference_offsets`` input through a second ExcitationSource, ``reference_schedule``:
the holds fly it.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    DiscreteTimeDelay,
    LogVectorOutput,
)

from drake_uav.io.flight_log import FlightLog
from drake_uav.model.rotations import quat_to_euler, quat_to_rotmat
from drake_uav.optimization.trim import TrimResult, trim
from drake_uav.systems.disturbances import AerodynamicIncrement
from drake_uav.systems.excitation import (
    REFERENCES,
    SURFACES,
    Doublet,
    ExcitationSource,
    ThreeTwoOneOne,
    orthogonal_multisines,
)
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.systems.safety_pilot import SafetyPilot, SafetyPilotGains
from drake_uav.systems.sensors import SensorSuite
from drake_uav.systems.wind import DrydenParams, DrydenWind
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.loading import load_fixed_wing
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = [
    "IdentificationFlight",
    "default_excitation",
    "build_identification_flight",
    "fly",
]

_DEFAULT_PILOT_GAINS = SafetyPilotGains()

# Truth channels: group -> (channel names, units).
_TRUTH = {
    "state": (("pn", "pe", "pd", "qw", "qx", "qy", "qz", "u", "v", "w", "p", "q", "r"),
              ("m",) * 3 + ("1",) * 4 + ("m/s",) * 3 + ("rad/s",) * 3),
    "euler": (("roll", "pitch", "yaw"), ("rad",) * 3),
    "air_data": (("airspeed", "alpha", "beta"), ("m/s", "rad", "rad")),
    "wind_ned": (("wind_n", "wind_e", "wind_d"), ("m/s",) * 3),
    "gust_body": (("gust_u", "gust_v", "gust_w"), ("m/s",) * 3),
    "aero_coefficients": (("CX", "CY", "CZ", "Cl", "Cm", "Cn"), ("1",) * 6),
    "forces_moments": (("Fx", "Fy", "Fz", "Mx", "My", "Mz"), ("N",) * 3 + ("N m",) * 3),
    "specific_force": (("ax", "ay", "az"), ("m/s^2",) * 3),
    "controls": (SURFACES, ("rad", "rad", "rad", "1")),
}


@dataclasses.dataclass(frozen=True)
class IdentificationFlight:
    """A built identification flight; :meth:`simulate` runs it and returns the log."""

    diagram: Diagram
    plant: FixedWingPlant
    wind: DrydenWind | None
    sensors: SensorSuite
    excitation: ExcitationSource
    pilot: SafetyPilot | None
    loggers: Mapping[str, object]
    """VectorLogSink per signal: "measurements", "commands", "surfaces" (the plant's
    controls), "state", "wind_ned" and, with a disturbance, "wrench"."""
    aircraft: FixedWingParams
    trim: TrimResult
    initial_state: np.ndarray
    seed: int
    duration: float
    sample_period: float
    simulator_config: SimulatorConfig
    metadata: Mapping[str, object]

    def simulate(self, seed: int | None = None) -> FlightLog:
        """Flies ``duration`` seconds from the trim state; the same seed gives the same log."""
        return self.simulate_with_context(seed)[0]

    def simulate_with_context(self, seed: int | None = None) -> tuple[FlightLog, Context]:
        """:meth:`simulate`, also returning the final root context (to read the loggers
        of systems added through ``extend``)."""
        seed = self.seed if seed is None else _check_seed(seed)
        simulator = Simulator(self.diagram)
        ApplySimulatorConfig(self.simulator_config, simulator)
        context = simulator.get_mutable_context()
        self.diagram.SetRandomContext(context, RandomGenerator(seed))
        self.plant.set_state(self.plant.GetMyMutableContextFromRoot(context), self.initial_state)
        simulator.Initialize()
        dt = self.sample_period
        n = int(round(self.duration / dt)) + 1
        # One extra period: the samples taken at t_k are logged at t_(k+1).
        simulator.AdvanceTo((n + 0.5) * dt)
        return self._flight_log(context, n, seed), context

    def _flight_log(self, context, n: int, seed: int) -> FlightLog:
        logs = {name: logger.FindLog(context) for name, logger in self.loggers.items()}
        time = logs["measurements"].sample_times()[:n]
        measured, units = {}, {}
        data = logs["measurements"].data()[:, 1:n + 1]
        for name, row in zip(self.sensors.channel_names, data, strict=True):
            measured[name], units[name] = row, self.sensors.channel_units[name]
        # The command issued at t_k (held over [t_k, t_(k+1))) is published at t_(k+1).
        commands = logs["commands"].data()[:, 1:n + 1]
        for i, surface in enumerate(SURFACES):
            name = f"cmd_{surface}"
            measured[name], units[name] = commands[i], _TRUTH["controls"][1][i]
        truth = {}
        for key, values in self._truth(logs, n).items():
            names, channel_units = _TRUTH[key]
            for name, unit, row in zip(names, channel_units, values, strict=True):
                truth[name], units[name] = row, unit
        return FlightLog(time, measured, truth, units, {**self.metadata, "seed": seed})

    def _truth(self, logs, n: int) -> dict[str, np.ndarray]:
        """Truth groups (rows of samples) at the log times, before the events there.

        The loggers keep the plant's inputs and state; everything else is the
        plant model evaluated on them afterwards, all samples at once (the same
        compiled equations the plant ran).
        """
        state = logs["state"].data()[:, :n]
        surfaces = logs["surfaces"].data()[:, :n]
        wind = logs["wind_ned"].data()[:, :n]
        model = self.plant.model.compiled
        evaluation = model.evaluate_batch(state.T, surfaces.T, wind.T)
        forces = evaluation
        if "wrench" in logs:  # the coefficients stay those of the model (no effect)
            wrench = logs["wrench"].data()[:, :n]
            forces = model.evaluate_batch(state.T, surfaces.T, wind.T, wrench.T)
        rotation = quat_to_rotmat(state[3:7] / np.linalg.norm(state[3:7], axis=0))
        steady = np.asarray(self.metadata["steady_wind_ned"])[:, None]
        gust = np.einsum("jin,jn->in", rotation, wind - steady)
        return {
            "state": state,
            "euler": quat_to_euler(state[3:7]),
            "air_data": evaluation.air_data.T,
            "wind_ned": wind,
            "gust_body": gust,
            "aero_coefficients": evaluation.coefficients.T,
            "forces_moments": forces.forces_moments.T,
            "specific_force": forces.specific_force.T,
            "controls": np.clip(surfaces.T, self.aircraft.limits.lower(),
                                self.aircraft.limits.upper()).T,
        }


def _check_seed(seed) -> int:
    if not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    return int(seed)


THROTTLE_PEAK = 0.1
"""Peak of the throttle's multisine in "multisine_throttle" [-] (a tenth of full throttle)."""


def default_excitation(kind: str, duration: float, start: float = 1.0) -> tuple:
    """Excitation of elevator, aileron and rudder (and throttle) for ``kind``.

    "multisine": mutually orthogonal low-peak-factor multisines, 0.1-1.5 Hz,
    period 20 s (or the flight, if shorter), peaks 2, 3, 3 deg, repeated to the end;
    "multisine_throttle": the same with the throttle as a fourth channel (peak
    :data:`THROTTLE_PEAK`), the four sharing out the band's harmonics: the thrust then
    moves on its own, not only as the airspeed hold moves it against the drag, so a force
    along the body x axis that is constant and one that scales with the thrust differ
    in the data;
    "doublet": 1 s doublets of 3 deg, one surface after another every 8 s;
    "3211": 3-2-1-1 of 3 deg with a 0.3 s unit, one surface after another;
    "none": no excitation (trim only).
    """
    surfaces = ("elevator", "aileron", "rudder")
    amplitude = math.radians(3.0)
    if kind in ("multisine", "multisine_throttle"):
        channels, peaks = surfaces, list(np.radians([2.0, 3.0, 3.0]))
        if kind == "multisine_throttle":
            channels, peaks = (*surfaces, "throttle"), [*peaks, THROTTLE_PEAK]
        if duration - start < len(channels):
            raise ValueError(
                f"duration: the default {kind} needs at least {start + len(channels):g} s of "
                f"flight ({len(channels)} harmonics up to 1.5 Hz after {start:g} s), got "
                f"{duration:g} s"
            )
        period = min(20.0, duration - start)
        return orthogonal_multisines(channels, period, peaks, band=(0.1, 1.5), start=start,
                                     cycles=(duration - start) / period)
    if kind == "doublet":
        return tuple(Doublet(s, amplitude, 0.5, start + 8.0 * i) for i, s in enumerate(surfaces))
    if kind == "3211":
        return tuple(ThreeTwoOneOne(s, amplitude, 0.3, start + 8.0 * i)
                     for i, s in enumerate(surfaces))
    if kind == "none":
        return ()
    raise ValueError(
        f"excitation: unknown kind {kind!r}; use 'multisine', 'multisine_throttle', "
        "'doublet', '3211', 'none' "
        "or a sequence of signals"
    )


def _turbulence_params(turbulence, steady_wind, sample_period: float) -> DrydenParams | None:
    if turbulence is None:
        return None
    if isinstance(turbulence, DrydenParams):
        if steady_wind is not None:
            turbulence = dataclasses.replace(turbulence, steady_wind_ned=tuple(steady_wind))
        return turbulence.validate()
    if not isinstance(turbulence, str):
        raise ValueError(f"turbulence: use a level name, DrydenParams or None, got {turbulence!r}")
    wind = (0.0, 0.0, 0.0) if steady_wind is None else tuple(float(w) for w in steady_wind)
    # Continuous (first-order hold) wind: no wind step meets a sensor sample.
    return DrydenParams(level=turbulence, steady_wind_ned=wind,
                        update_period=sample_period).validate()


def _connect_disturbance(builder, plant, params, disturbance, commands):
    """Feeds an effect the model lacks into the plant's ``external_wrench``; returns
    the wrench output port."""
    if callable(disturbance):
        effect = builder.AddNamedSystem("disturbance",
                                        AerodynamicIncrement(params, disturbance))
        builder.Connect(plant.GetOutputPort("air_data"), effect.GetInputPort("air_data"))
        builder.Connect(plant.GetOutputPort("state"), effect.GetInputPort("state"))
        builder.Connect(commands, effect.GetInputPort("controls"))
        wrench = effect.GetOutputPort("wrench")
    else:
        value = np.asarray(disturbance, dtype=float)
        if value.shape != (6,) or not np.all(np.isfinite(value)):
            raise ValueError(f"disturbance: need a function or 6 finite values, got {value}")
        wrench = builder.AddNamedSystem("disturbance", ConstantVectorSource(value)
                                        ).get_output_port(0)
    builder.Connect(wrench, plant.GetInputPort("external_wrench"))
    return wrench


@dataclasses.dataclass(frozen=True)
class _Setup:
    """The checked settings of a flight and its trim start."""

    params: FixedWingParams
    sensors: SensorSuiteParams
    dt: float
    """Sensor base period [s]: the step of everything in the flight."""
    wind: DrydenParams | None
    steady: np.ndarray
    """Steady wind NED [m/s]."""
    signals: tuple
    trim: TrimResult
    x0: np.ndarray
    airspeed: float
    altitude: float


def _setup(params: FixedWingParams, turbulence, steady_wind, excitation, sensors, duration,
           airspeed: float, altitude: float) -> _Setup:
    """Checks the settings, trims the aircraft and places it in the steady wind."""
    sensors = (SensorSuiteParams.seed_table7(air_density=params.rho) if sensors is None
               else sensors.validate())
    dt = 1.0 / sensors.base_rate_hz
    wind_params = _turbulence_params(turbulence, steady_wind, dt)
    steady = np.asarray(wind_params.steady_wind_ned if wind_params else
                        (steady_wind if steady_wind is not None else (0.0, 0.0, 0.0)), float)
    if steady.shape != (3,) or not np.all(np.isfinite(steady)):
        raise ValueError(f"steady_wind: need 3 finite values, got {steady_wind}")
    signals = (default_excitation(excitation, duration) if isinstance(excitation, str)
               else tuple(excitation))
    trimmed = trim(params, airspeed, altitude=altitude)
    x0 = trimmed.state.copy()
    # Trim is in still air: keep the air-relative velocity, add the wind to the ground speed.
    x0[7:10] += quat_to_rotmat(x0[3:7]).T @ steady
    return _Setup(params, sensors, dt, wind_params, steady, signals, trimmed, x0, airspeed,
                  altitude)


@dataclasses.dataclass(frozen=True)
class _Wiring:
    """The systems of a flight and the ports the loggers and ``extend`` see."""

    plant: FixedWingPlant
    excitation: ExcitationSource
    pilot: SafetyPilot | None
    commands: OutputPort
    """Logged commands: excitation plus the safety pilot's correction."""
    surfaces: OutputPort
    """The plant's controls (the commands, delayed by the actuator)."""
    wrench: OutputPort | None
    wind: DrydenWind | None
    wind_port: OutputPort
    sensors: SensorSuite

    def logged_ports(self) -> dict[str, OutputPort]:
        """The ports the flight log is made from (see ``IdentificationFlight.loggers``)."""
        logged = {"measurements": self.sensors.GetOutputPort("measurements"),
                  "commands": self.commands, "surfaces": self.surfaces,
                  "state": self.plant.GetOutputPort("state"), "wind_ned": self.wind_port}
        if self.wrench is not None:
            logged["wrench"] = self.wrench
        return logged

    def extension_ports(self) -> dict[str, OutputPort]:
        """The ports ``extend`` is given: plant and sensor outputs by name, commands,
        surfaces and wind."""
        ports = {}
        for system in (self.plant, self.sensors):
            ports.update({system.get_output_port(i).get_name(): system.get_output_port(i)
                          for i in range(system.num_output_ports())})
        ports.update(commands=self.commands, surfaces=self.surfaces, wind_ned=self.wind_port)
        return ports


def _add_safety_pilot(builder: DiagramBuilder, plant: FixedWingPlant, commands: OutputPort,
                      setup: _Setup, gains: SafetyPilotGains) -> tuple[SafetyPilot, OutputPort]:
    """Adds the safety pilot's correction to ``commands``; returns the pilot and the sum."""
    roll, pitch, yaw = quat_to_euler(setup.x0[3:7])
    pilot = builder.AddNamedSystem("safety_pilot", SafetyPilot(
        gains, pitch, setup.altitude, yaw, setup.airspeed, setup.dt))
    adder = builder.AddNamedSystem("command_sum", Adder(2, 4))
    builder.Connect(commands, adder.get_input_port(0))
    builder.Connect(pilot.GetOutputPort("correction"), adder.get_input_port(1))
    for name in ("state", "air_data"):
        builder.Connect(plant.GetOutputPort(name), pilot.GetInputPort(name))
    return pilot, adder.get_output_port(0)


def _add_actuator_delay(builder: DiagramBuilder, commands: OutputPort, delay: float,
                        dt: float) -> OutputPort:
    """The commands as the surfaces see them ``delay`` [s] later (whole periods ``dt``)."""
    if not delay > 0.0:
        return commands
    steps = int(round(delay / dt))
    if steps < 2:
        raise ValueError(f"actuator_delay: {delay} s is shorter than two sample "
                         f"periods ({2 * dt} s), the shortest delay the flight can model")
    # The delay samples the held command one period late: steps - 1 buffer slots.
    system = builder.AddNamedSystem("actuator_delay", DiscreteTimeDelay(dt, steps - 1, 4))
    builder.Connect(commands, system.get_input_port())
    return system.get_output_port()


def _add_wind(builder: DiagramBuilder, plant: FixedWingPlant, params: DrydenParams | None,
              steady: np.ndarray) -> tuple[DrydenWind | None, OutputPort]:
    """Dryden turbulence (or the steady wind alone) into the plant's ``wind_ned`` and
    ``wind_rate_ned``."""
    wind = None
    if params is not None:
        wind = builder.AddNamedSystem("wind", DrydenWind(params))
        builder.Connect(plant.GetOutputPort("state"), wind.GetInputPort("plant_state"))
        builder.Connect(wind.GetOutputPort("wind_rate_ned"), plant.GetInputPort("wind_rate_ned"))
        port = wind.GetOutputPort("wind_ned")
    else:
        port = builder.AddNamedSystem("steady_wind",
                                      ConstantVectorSource(steady)).get_output_port(0)
    builder.Connect(port, plant.GetInputPort("wind_ned"))
    return wind, port


def _add_sensors(builder: DiagramBuilder, plant: FixedWingPlant, params: SensorSuiteParams,
                 pilot: SafetyPilot | None) -> SensorSuite:
    """The sensor suite on the plant's outputs; its gyro feeds the pilot's dampers."""
    suite = builder.AddNamedSystem("sensors", SensorSuite(params))
    for name in ("state", "air_data", "specific_force"):
        builder.Connect(plant.GetOutputPort(name), suite.GetInputPort(name))
    if pilot is not None and params.imu is not None:
        builder.Connect(suite.GetOutputPort("imu"), pilot.GetInputPort("imu"))
    return suite


def _wire(builder: DiagramBuilder, setup: _Setup, stabilize: bool, gains: SafetyPilotGains,
          disturbance, actuator_delay: float) -> _Wiring:
    """Adds plant, excitation, safety pilot, actuator delay, disturbance, wind and sensors
    (in this order: the order of the systems in the diagram)."""
    plant = builder.AddNamedSystem("plant", FixedWingPlant(setup.params))
    on_surfaces = [s for s in setup.signals if s.surface in SURFACES]
    on_references = [s for s in setup.signals if s.surface not in SURFACES]
    source = builder.AddNamedSystem("excitation",
                                    ExcitationSource(setup.trim.controls, on_surfaces, setup.dt))
    commands, pilot = source.GetOutputPort("controls"), None
    if on_references and not stabilize:
        raise ValueError("excitation: a signal on a reference ("
                         + ", ".join(sorted({s.surface for s in on_references}))
                         + ") is flown by the safety pilot's holds; keep stabilize=True")
    if stabilize:
        pilot, commands = _add_safety_pilot(builder, plant, commands, setup, gains)
    if on_references:
        references = builder.AddNamedSystem("reference_schedule", ExcitationSource(
            np.zeros(len(REFERENCES)), on_references, setup.dt, channels=REFERENCES,
            output="reference_offsets"))
        builder.Connect(references.GetOutputPort("reference_offsets"),
                        pilot.GetInputPort("reference_offsets"))
    surfaces = _add_actuator_delay(builder, commands, actuator_delay, setup.dt)
    builder.Connect(surfaces, plant.GetInputPort("controls"))
    wrench = None
    if disturbance is not None:
        wrench = _connect_disturbance(builder, plant, setup.params, disturbance, surfaces)
    wind, wind_port = _add_wind(builder, plant, setup.wind, setup.steady)
    suite = _add_sensors(builder, plant, setup.sensors, pilot)
    return _Wiring(plant, source, pilot, commands, surfaces, wrench, wind, wind_port, suite)


def _add_loggers(builder: DiagramBuilder, ports: Mapping[str, OutputPort],
                 dt: float) -> dict[str, object]:
    """One logger per port, sampled every ``dt`` [s] ("surfaces" is often "commands")."""
    loggers, by_port = {}, {}
    for name, port in ports.items():
        key = (port.get_system().get_name(), port.get_name())
        if key not in by_port:
            by_port[key] = LogVectorOutput(port, builder, dt)
        loggers[name] = by_port[key]
    return loggers


def _metadata(setup: _Setup, stabilize: bool, duration: float) -> dict[str, object]:
    """The flight's settings as the log's metadata."""
    wind = setup.wind
    return {
        "aircraft": setup.params.name,
        "airspeed": setup.airspeed,
        "altitude": setup.altitude,
        "turbulence": wind.level if wind else "none",
        "turbulence_model": wind.model if wind else "none",
        "steady_wind_ned": setup.steady.tolist(),
        "excitation": [f"{type(s).__name__}({s.surface})" for s in setup.signals],
        "sample_rate_hz": setup.sensors.base_rate_hz,
        "sensor_noise_std": setup.sensors.noise_std(setup.airspeed),
        "stabilized": stabilize,
        "duration": duration,
    }


def build_identification_flight(
    aircraft: str | FixedWingParams = "aerosonde",
    turbulence: str | DrydenParams | None = "light",
    steady_wind: Sequence[float] | None = None,
    excitation: str | Sequence = "multisine",
    sensors: SensorSuiteParams | None = None,
    seed: int = 0,
    duration: float = 60.0,
    *,
    airspeed: float = 25.0,
    altitude: float = 100.0,
    stabilize: bool = True,
    pilot_gains: SafetyPilotGains = _DEFAULT_PILOT_GAINS,
    integrator: str = "runge_kutta2",
    disturbance=None,
    actuator_delay: float = 0.0,
    extend: Callable[[DiagramBuilder, Mapping[str, OutputPort]], None] | None = None,
) -> IdentificationFlight:
    """Builds the identification-flight diagram with its loggers.

    Args:
        aircraft: catalog name or parameters.
        turbulence: "light" / "moderate" / "severe" (MIL-F-8785C, updated at the
            sensor base rate), a :class:`DrydenParams`, or None (steady wind only).
        steady_wind: steady wind NED [m/s] (overrides the DrydenParams' value).
        excitation: a kind for :func:`default_excitation` or a sequence of signals
            (on surfaces, or on the safety pilot's references: a
            :class:`~drake_uav.systems.excitation.Turn`).
        sensors: sensor suite; default Vaiopoulos 2017, Table 7 with the aircraft's air
            density.
        seed: default random seed of :meth:`IdentificationFlight.simulate`.
        duration: flight time [s].
        airspeed: trim airspeed [m/s]; altitude: initial altitude [m].
        stabilize: add the :class:`~drake_uav.systems.safety_pilot.SafetyPilot` (weak
            hold loops) with ``pilot_gains``.
        integrator: Drake integration scheme; fixed step = sensor base period.
        disturbance: an effect the aircraft model lacks, put into the physics: a
            function ``f(AeroCondition) -> (dCL, dCD, dCY, dCl, dCm, dCn)``, or
            ``f(AeroCondition, t)`` reading the time t [s] too (a drifting derivative;
            :class:`AerodynamicIncrement`), or a constant body wrench (6: N, N m).
        actuator_delay: pure delay [s] between the logged commands and the
            surfaces (rounded to whole sample periods, at least two).
        extend: ``extend(builder, ports)`` adds systems to the flight before it is
            built (an estimator, an on-line identifier, their loggers). ``ports``
            maps names to output ports: every plant output by its name, every
            sensor output (``measurements``, ``imu``, ``gps``, ``pitot``, ``vanes``,
            ``attitude``, ``baro``, as fitted), ``commands`` (logged commands),
            ``surfaces`` (the plant's controls) and ``wind_ned``.
    """
    params = load_fixed_wing(aircraft) if isinstance(aircraft, str) else aircraft
    if not (duration > 0 and math.isfinite(duration)):
        raise ValueError(f"duration: must be positive, got {duration}")
    seed = _check_seed(seed)
    setup = _setup(params, turbulence, steady_wind, excitation, sensors, duration, airspeed,
                   altitude)
    builder = DiagramBuilder()
    wiring = _wire(builder, setup, stabilize, pilot_gains, disturbance, actuator_delay)
    # The plant's state and inputs are logged; the other truth channels are
    # computed from them after the flight (IdentificationFlight._truth).
    loggers = _add_loggers(builder, wiring.logged_ports(), setup.dt)
    if extend is not None:
        extend(builder, wiring.extension_ports())
    config = SimulatorConfig(integration_scheme=integrator, max_step_size=setup.dt,
                             use_error_control=False)
    return IdentificationFlight(
        diagram=builder.Build(), plant=wiring.plant, wind=wiring.wind, sensors=wiring.sensors,
        excitation=wiring.excitation, pilot=wiring.pilot, loggers=loggers, aircraft=params,
        trim=setup.trim, initial_state=setup.x0, seed=seed, duration=duration,
        sample_period=setup.dt, simulator_config=config,
        metadata=_metadata(setup, stabilize, duration),
    )


def fly(*args, **options) -> FlightLog:
    """Builds and flies an identification flight; returns measured + truth channels.

    Takes the arguments of :func:`build_identification_flight` (same names, order and
    defaults).
    """
    return build_identification_flight(*args, **options).simulate()


fly.__signature__ = inspect.signature(build_identification_flight).replace(
    return_annotation="FlightLog")
