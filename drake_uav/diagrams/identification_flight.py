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

The safety pilot is a weak attitude/altitude/heading/airspeed hold added on top
of trim + excitation so that long flights stay near the trim condition; its rate
dampers use the IMU's gyro (the sample of the previous period). It can be
switched off (``stabilize=False``) for open-loop excitation.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, LeafSystem, OutputPort
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
    SURFACES,
    Doublet,
    ExcitationSource,
    ThreeTwoOneOne,
    orthogonal_multisines,
)
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.systems.sensors import SensorSuite
from drake_uav.systems.wind import DrydenParams, DrydenWind
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.loading import load_fixed_wing
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = [
    "SafetyPilotGains",
    "SafetyPilot",
    "IdentificationFlight",
    "default_excitation",
    "build_identification_flight",
    "fly",
]

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
class SafetyPilotGains:
    """Gains of the weak hold loops (Aerosonde-sized defaults).

    Attributes:
        pitch: elevator per pitch error [rad/rad] (positive elevator: nose down).
        pitch_rate: elevator per pitch rate [rad/(rad/s)].
        altitude: pitch reference per altitude error [rad/m], limited to +-max_pitch.
        roll: aileron per roll error [rad/rad].
        roll_rate: aileron per roll rate [rad/(rad/s)].
        heading: roll reference per heading error [rad/rad], limited to +-max_roll.
        yaw_rate: rudder per yaw rate [rad/(rad/s)] (yaw damper).
        airspeed: throttle per airspeed error [1/(m/s)].
        max_pitch: limit of the pitch reference offset [rad].
        max_roll: limit of the roll reference [rad].
    """

    pitch: float = 0.8
    pitch_rate: float = 0.1
    altitude: float = 0.005
    roll: float = 0.5
    roll_rate: float = 0.05
    heading: float = 0.5
    yaw_rate: float = 0.2
    airspeed: float = 0.05
    max_pitch: float = 0.15
    max_roll: float = 0.3

    def validate(self) -> SafetyPilotGains:
        """Raises ValueError naming the first negative or non-finite gain; returns self."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"{f.name}: gain must be finite and >= 0, got {value}")
        return self


class SafetyPilot(LeafSystem):
    """Weak attitude, altitude, heading and airspeed hold around a trim condition.

    Discrete (sample-and-hold at ``period``), so the output depends on its state
    only and closes no algebraic loop.

    | port (in)  | size | units                                              |
    |------------|------|----------------------------------------------------|
    | state      | 13   | plant ``state`` (attitude: its quaternion's Euler) |
    | air_data   | 3    | plant ``air_data``: Va [m/s], alpha, beta [rad]    |
    | imu        | 6    | sensor suite ``imu``: the rate dampers use its     |
    |            |      | gyro p, q, r [rad/s] (unconnected: the true rates) |

    | port (out) | size | units                                              |
    |------------|------|----------------------------------------------------|
    | correction | 4    | added elevator, aileron, rudder [rad], throttle    |

    The dampers feed back the gyro, as an autopilot does: with the true rates the
    commands would carry noise-free information on the state that no estimator
    working from the logged sensors has, and on-line estimators (the parameter
    EKF) would see a control input correlated with their own state error.
    """

    def __init__(self, gains: SafetyPilotGains, pitch_ref: float, altitude_ref: float,
                 heading_ref: float, airspeed_ref: float, period: float):
        super().__init__()
        self.gains = gains.validate()
        self._refs = (pitch_ref, altitude_ref, heading_ref, airspeed_ref)
        self._state = self.DeclareVectorInputPort("state", 13)
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._imu = self.DeclareVectorInputPort("imu", 6)
        xd = self.DeclareDiscreteState(4)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareStateOutputPort("correction", xd)

    def _update(self, context, discrete_state) -> None:
        g = self.gains
        pitch_ref, altitude_ref, heading_ref, airspeed_ref = self._refs
        x = self._state.Eval(context).tolist()
        roll, pitch, yaw = quat_to_euler(x[3:7]).tolist()
        p, q, r = (self._imu.Eval(context)[3:6].tolist() if self._imu.HasValue(context)
                   else x[10:13])
        climb_to = max(-g.max_pitch, min(g.max_pitch, g.altitude * (altitude_ref + x[2])))
        heading_error = (heading_ref - yaw + math.pi) % (2.0 * math.pi) - math.pi
        roll_ref = max(-g.max_roll, min(g.max_roll, g.heading * heading_error))
        airspeed = self._air.Eval(context)[0]
        discrete_state.set_value([
            g.pitch * (pitch - pitch_ref - climb_to) + g.pitch_rate * q,
            -g.roll * (roll - roll_ref) - g.roll_rate * p,
            g.yaw_rate * r,
            g.airspeed * (airspeed_ref - airspeed),
        ])


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


def default_excitation(kind: str, duration: float, start: float = 1.0) -> tuple:
    """Excitation of elevator, aileron and rudder for ``kind``.

    "multisine": mutually orthogonal low-peak-factor multisines, 0.1-1.5 Hz,
    period 20 s (or the flight, if shorter), peaks 2, 3, 3 deg, repeated to the end;
    "doublet": 1 s doublets of 3 deg, one surface after another every 8 s;
    "3211": 3-2-1-1 of 3 deg with a 0.3 s unit, one surface after another;
    "none": no excitation (trim only).
    """
    surfaces = ("elevator", "aileron", "rudder")
    amplitude = math.radians(3.0)
    if kind == "multisine":
        if duration - start < 3.0:
            raise ValueError(
                f"duration: the default multisine needs at least {start + 3.0:g} s of flight "
                f"(3 harmonics up to 1.5 Hz after {start:g} s), got {duration:g} s"
            )
        period = min(20.0, duration - start)
        return orthogonal_multisines(surfaces, period, np.radians([2.0, 3.0, 3.0]),
                                     band=(0.1, 1.5), start=start,
                                     cycles=(duration - start) / period)
    if kind == "doublet":
        return tuple(Doublet(s, amplitude, 0.5, start + 8.0 * i) for i, s in enumerate(surfaces))
    if kind == "3211":
        return tuple(ThreeTwoOneOne(s, amplitude, 0.3, start + 8.0 * i)
                     for i, s in enumerate(surfaces))
    if kind == "none":
        return ()
    raise ValueError(
        f"excitation: unknown kind {kind!r}; use 'multisine', 'doublet', '3211', 'none' "
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
    pilot_gains: SafetyPilotGains = SafetyPilotGains(),
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
        excitation: a kind for :func:`default_excitation` or a sequence of signals.
        sensors: sensor suite; default seed Table 7 with the aircraft's air density.
        seed: default random seed of :meth:`IdentificationFlight.simulate`.
        duration: flight time [s].
        airspeed: trim airspeed [m/s]; altitude: initial altitude [m].
        stabilize: add the :class:`SafetyPilot` (weak hold loops).
        integrator: Drake integration scheme; fixed step = sensor base period.
        disturbance: an effect the aircraft model lacks, put into the physics: a
            function ``f(AeroCondition) -> (dCL, dCD, dCY, dCl, dCm, dCn)``
            (:class:`AerodynamicIncrement`) or a constant body wrench (6: N, N m).
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

    builder = DiagramBuilder()
    plant = builder.AddNamedSystem("plant", FixedWingPlant(params))
    source = builder.AddNamedSystem("excitation",
                                    ExcitationSource(trimmed.controls, signals, dt))
    commands = source.GetOutputPort("controls")
    pilot = None
    if stabilize:
        roll, pitch, yaw = quat_to_euler(x0[3:7])
        pilot = builder.AddNamedSystem(
            "safety_pilot", SafetyPilot(pilot_gains, pitch, altitude, yaw, airspeed, dt))
        adder = builder.AddNamedSystem("command_sum", Adder(2, 4))
        builder.Connect(commands, adder.get_input_port(0))
        builder.Connect(pilot.GetOutputPort("correction"), adder.get_input_port(1))
        for name in ("state", "air_data"):
            builder.Connect(plant.GetOutputPort(name), pilot.GetInputPort(name))
        commands = adder.get_output_port(0)
    plant_commands = commands
    if actuator_delay > 0.0:
        steps = int(round(actuator_delay / dt))
        if steps < 2:
            raise ValueError(f"actuator_delay: {actuator_delay} s is shorter than two sample "
                             f"periods ({2 * dt} s), the shortest delay the flight can model")
        # The delay samples the held command one period late: steps - 1 buffer slots.
        delay = builder.AddNamedSystem("actuator_delay",
                                       DiscreteTimeDelay(dt, steps - 1, 4))
        builder.Connect(commands, delay.get_input_port())
        plant_commands = delay.get_output_port()
    builder.Connect(plant_commands, plant.GetInputPort("controls"))
    wrench = None
    if disturbance is not None:
        wrench = _connect_disturbance(builder, plant, params, disturbance, plant_commands)

    wind = None
    if wind_params is not None:
        wind = builder.AddNamedSystem("wind", DrydenWind(wind_params))
        builder.Connect(plant.GetOutputPort("state"), wind.GetInputPort("plant_state"))
        wind_port = wind.GetOutputPort("wind_ned")
    else:
        wind_port = builder.AddNamedSystem("steady_wind",
                                           ConstantVectorSource(steady)).get_output_port(0)
    builder.Connect(wind_port, plant.GetInputPort("wind_ned"))

    suite = builder.AddNamedSystem("sensors", SensorSuite(sensors))
    for name in ("state", "air_data", "specific_force"):
        builder.Connect(plant.GetOutputPort(name), suite.GetInputPort(name))
    if pilot is not None and sensors.imu is not None:
        builder.Connect(suite.GetOutputPort("imu"), pilot.GetInputPort("imu"))

    # The plant's state and inputs are logged; the other truth channels are
    # computed from them after the flight (IdentificationFlight._truth).
    logged = {"measurements": suite.GetOutputPort("measurements"), "commands": commands,
              "surfaces": plant_commands, "state": plant.GetOutputPort("state"),
              "wind_ned": wind_port}
    if wrench is not None:
        logged["wrench"] = wrench
    loggers, by_port = {}, {}
    for name, port in logged.items():  # one logger per port ("surfaces" is often "commands")
        key = (port.get_system().get_name(), port.get_name())
        if key not in by_port:
            by_port[key] = LogVectorOutput(port, builder, dt)
        loggers[name] = by_port[key]
    if extend is not None:
        ports = {plant.get_output_port(i).get_name(): plant.get_output_port(i)
                 for i in range(plant.num_output_ports())}
        ports.update({suite.get_output_port(i).get_name(): suite.get_output_port(i)
                      for i in range(suite.num_output_ports())})
        ports.update(commands=commands, surfaces=plant_commands, wind_ned=wind_port)
        extend(builder, ports)
    diagram = builder.Build()

    metadata = {
        "aircraft": params.name,
        "airspeed": airspeed,
        "altitude": altitude,
        "turbulence": wind_params.level if wind_params else "none",
        "turbulence_model": wind_params.model if wind_params else "none",
        "steady_wind_ned": steady.tolist(),
        "excitation": [f"{type(s).__name__}({s.surface})" for s in signals],
        "sample_rate_hz": sensors.base_rate_hz,
        "sensor_noise_std": sensors.noise_std(airspeed),
        "stabilized": stabilize,
        "duration": duration,
    }
    config = SimulatorConfig(integration_scheme=integrator, max_step_size=dt,
                             use_error_control=False)
    return IdentificationFlight(
        diagram=diagram, plant=plant, wind=wind, sensors=suite, excitation=source, pilot=pilot,
        loggers=loggers, aircraft=params, trim=trimmed, initial_state=x0, seed=seed,
        duration=duration, sample_period=dt, simulator_config=config, metadata=metadata,
    )


def fly(
    aircraft: str | FixedWingParams = "aerosonde",
    turbulence: str | DrydenParams | None = "light",
    steady_wind: Sequence[float] | None = None,
    excitation: str | Sequence = "multisine",
    sensors: SensorSuiteParams | None = None,
    seed: int = 0,
    duration: float = 60.0,
    **options,
) -> FlightLog:
    """Builds and flies an identification flight; returns measured + truth channels.

    Same arguments as :func:`build_identification_flight` (``options`` are its
    keyword-only ones).
    """
    return build_identification_flight(aircraft, turbulence, steady_wind, excitation, sensors,
                                       seed, duration, **options).simulate()
