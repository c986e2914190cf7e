"""The sensor suite as Drake systems: one sampled LeafSystem and its noise source.

:class:`SampledSensors` samples every fitted sensor that is due in one periodic
update at the suite's base rate (each sensor's rate divides it) and holds the
measurements in between: one update per tick instead of one per sensor keeps
a 100 Hz flight cheap. Noise arrives on an input port, so the same system runs
with a Drake ``RandomSource`` (:class:`SensorSuite`, seeded through the root
context) or with given samples. Measurements are in SI units (m/s^2, rad/s, m,
m/s, Pa, rad). The sensor models and their parameters are in
:mod:`drake_uav.vehicles.sensors`.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer, RandomSource

from drake_uav.model.air_data import airspeed_from_dynamic_pressure, dynamic_pressure
from drake_uav.model.rotations import quat_to_euler, rotate, unit_quat_rotation
from drake_uav.vehicles.sensors import CHANNEL_LAYOUT, TRUTH_LAYOUT, SensorSuiteParams

__all__ = ["SampledSensors", "SensorSuite"]

_DEFAULT_SUITE = SensorSuiteParams()
_ZERO3 = [0.0, 0.0, 0.0]
_ZERO13 = [0.0] * 13


class SampledSensors(LeafSystem):
    """All fitted sensors, sampled by one periodic update; noise from an input port.

    | port (in)       | size | units                                              |
    |-----------------|------|----------------------------------------------------|
    | noise           | 2 N  | N(0, 1) samples, fresh each base period            |
    | state           | 13   | plant ``state`` [m, -, m/s, rad/s] (the attitude   |
    |                 |      | sensor's Euler angles are those of its quaternion) |
    | air_data        | 3    | plant ``air_data`` Va [m/s], alpha, beta [rad]     |
    | specific_force  | 3    | plant ``specific_force``, body [m/s^2]             |

    | port (out)      | size | units                                              |
    |-----------------|------|----------------------------------------------------|
    | measurements    | M    | every fitted sensor's channels, names from         |
    |                 |      | ``channel_names`` (per sensor: ``port_slices``)    |

    Inputs that no fitted sensor needs may stay unconnected. N is the number of
    measured channels without the derived pitot airspeed. The output depends on
    the discrete state only; :class:`SensorSuite` splits it per sensor.
    """

    def __init__(self, params: SensorSuiteParams = _DEFAULT_SUITE):
        super().__init__()
        self.params = params.validate()
        self.base_period = 1.0 / params.base_rate_hz
        self.channel_names = tuple(n for n, _ in params.channels())
        self.channel_units = dict(params.channels())
        self._build_tables()
        n, m = self._n, len(self.channel_names)
        self._noise = self.DeclareVectorInputPort("noise", 2 * n)
        self._state = self.DeclareVectorInputPort("state", 13)
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._force = self.DeclareVectorInputPort("specific_force", 3)
        # Discrete state: the held outputs (m); [tick, bias walk (n), truth delay line
        # (depth n)].
        self._held_state = self.DeclareDiscreteState(m)
        self._walk = slice(1, 1 + n)
        self._line = slice(1 + n, 1 + n + self._depth * n)
        self._xd = self.DeclareDiscreteState(self._line.stop)
        self.DeclarePeriodicDiscreteUpdateEvent(self.base_period, 0.0, self._update)
        self.DeclareStateOutputPort("measurements", self._held_state)

    @property
    def port_slices(self) -> dict[str, slice]:
        """Entries of ``measurements`` per fitted sensor, in order and contiguous."""
        return dict(self._port_slices)

    def _build_tables(self) -> None:
        p = self.params
        truth_idx, out_idx, cols = [], [], {k: [] for k in
                                            ("noise_std", "bias", "bias_instability",
                                             "scale_factor")}
        decim, latency = [], []
        self._port_slices: dict[str, slice] = {}
        position = 0
        for sensor, group, truth_key, names, _ in CHANNEL_LAYOUT:
            params = getattr(p, sensor)
            if params is None:
                continue
            every, lag = params._check_sampling(sensor, p.base_rate_hz)
            errors = getattr(params, group).arrays(len(names), f"{sensor}.{group}")
            for k in cols:
                cols[k].append(errors[k])
            s = TRUTH_LAYOUT[truth_key]
            truth_idx += list(range(s.start, s.stop))
            out_idx += list(range(position, position + len(names)))
            decim += [every] * len(names)
            latency += [lag] * len(names)
            start = self._port_slices.get(sensor, slice(position, position)).start
            position += len(names)
            if sensor == "pitot":
                self._airspeed_index = position
                position += 1
            self._port_slices[sensor] = slice(start, position)
        self._n = len(truth_idx)
        self._truth_idx = np.array(truth_idx)
        self._all_truths = truth_idx == list(range(TRUTH_LAYOUT["altitude"].stop))
        self._out_idx = np.array(out_idx)
        self._sigma = np.concatenate(cols["noise_std"])
        self._bias = np.concatenate(cols["bias"])
        self._scale = 1.0 + np.concatenate(cols["scale_factor"])
        self._decim = np.array(decim)
        self._lag = np.array(latency)
        # Random-walk step per sample: density * sqrt(sample period).
        self._walk_step = np.concatenate(cols["bias_instability"]) * np.sqrt(
            self._decim * self.base_period
        )
        self._depth = int(self._lag.max()) + 1
        # Flat index into the delay line of each channel's delayed sample, per tick phase.
        phases = np.arange(self._depth)[:, None]
        self._delayed_index = ((phases - self._lag) % self._depth) * self._n + np.arange(self._n)
        # Which channels sample at a tick repeats with the lcm of the decimations once
        # every latency has passed: precompute that pattern.
        period = math.lcm(*self._decim.tolist())
        ticks = self._depth + np.arange(period)[:, None]
        self._due_pattern = (ticks - self._lag) % self._decim == 0
        self._walk_pattern = self._due_pattern * self._walk_step  # walk steps of due channels
        self._due_offset = self._depth % period
        yaw = [i for i, n in enumerate(self.channel_names) if n == "att_yaw"]
        self._yaw = yaw[0] if yaw else None
        needed = set(self._truth_idx.tolist())
        self._needs = {key: bool(needed & set(range(s.start, s.stop))) for key, s in
                       TRUTH_LAYOUT.items()}
        self._needs["state"] = any(self._needs[k] for k in ("position", "velocity", "rates",
                                                            "altitude", "euler"))
        self._needs["air"] = self._needs["dynamic_pressure"] or self._needs["air_angles"]
        self._density = p.pitot.air_density if p.pitot is not None else 0.0

    def _truth(self, context) -> np.ndarray:
        """True values of every quantity some fitted sensor measures (N).

        Assembled in the ``TRUTH_LAYOUT`` layout from the inputs the fitted sensors need
        (zeros for the others), then reduced to the fitted channels.
        """
        need = self._needs
        zero = _ZERO3
        x = self._state.Eval(context).tolist() if need["state"] else _ZERO13
        velocity = (rotate(unit_quat_rotation(x[3:7]), x[7:10]) if need["velocity"]
                    else zero)
        air = self._air.Eval(context).tolist() if need["air"] else zero
        force = self._force.Eval(context).tolist() if need["specific_force"] else zero
        euler = quat_to_euler(x[3:7]).tolist() if need["euler"] else zero
        truth = np.array((*force, *x[10:13], *x[0:3], *velocity,
                          dynamic_pressure(air[0], self._density), air[1], air[2], *euler, -x[2]))
        return truth if self._all_truths else truth[self._truth_idx]

    def _update(self, context, discrete_state) -> None:
        # Drake hands the update the current values: advance them in place.
        x = discrete_state.get_mutable_value(self._xd)
        tick = int(x[0])
        n = self._n
        line = x[self._line]  # the delay line, flat: one row of n per tick phase
        phase = tick % self._depth
        truth = self._truth(context)
        if tick == 0:
            line[:] = np.tile(truth, self._depth)
        else:
            line[phase * n:(phase + 1) * n] = truth
        delayed = line[self._delayed_index[phase]]
        if tick >= self._depth:
            k = (tick - self._due_offset) % len(self._due_pattern)
            due, walk_step = self._due_pattern[k], self._walk_pattern[k]
        else:
            due = (tick == 0) | ((tick >= self._lag) & ((tick - self._lag) % self._decim == 0))
            walk_step = self._walk_step * due
        noise = self._noise.Eval(context)
        walk = x[self._walk]  # a view: updated in place below
        measured = self._scale * delayed + self._bias + walk + self._sigma * noise[n:]
        out = discrete_state.get_mutable_value(self._held_state)
        out[self._out_idx] = np.where(due, measured, out[self._out_idx])
        if self._yaw is not None:
            out[self._yaw] = (out[self._yaw] + math.pi) % (2.0 * math.pi) - math.pi
        if self._density:
            out[self._airspeed_index] = airspeed_from_dynamic_pressure(
                out[self._airspeed_index - 1], self._density)
        walk += walk_step * noise[:n]
        x[0] = tick + 1


class SensorSuite(Diagram):
    """The fitted sensors with their own Gaussian noise source (a small diagram).

    Inputs are those of :class:`SampledSensors` without ``noise``. Outputs:
    ``measurements`` and, for each fitted sensor, its part of it (a Drake
    ``Demultiplexer``):

    | port (out)      | size | units                                              |
    |-----------------|------|----------------------------------------------------|
    | imu             | 6    | ax, ay, az [m/s^2], p, q, r [rad/s]                |
    | gps             | 6    | pN, pE, pD [m], vN, vE, vD [m/s]                   |
    | pitot           | 2    | dynamic pressure [Pa], airspeed [m/s]              |
    | vanes           | 2    | alpha, beta [rad]                                  |
    | attitude        | 3    | roll, pitch, yaw [rad]                             |
    | baro            | 1    | altitude [m]                                       |
    | measurements    | M    | all of the above, names from ``channel_names``     |

    Seed through the root context:
    ``diagram.SetRandomContext(context, RandomGenerator(seed))``.
    ``channel_names`` / ``channel_units`` describe the ``measurements`` output.
    """

    def __init__(self, params: SensorSuiteParams = _DEFAULT_SUITE):
        super().__init__()
        builder = DiagramBuilder()
        self.sensors = builder.AddNamedSystem("sampled_sensors", SampledSensors(params))
        noise = builder.AddNamedSystem(
            "sensor_noise",
            RandomSource(RandomDistribution.kGaussian, 2 * self.sensors._n,
                         self.sensors.base_period),
        )
        builder.Connect(noise.get_output_port(0), self.sensors.GetInputPort("noise"))
        for name in ("state", "air_data", "specific_force"):
            builder.ExportInput(self.sensors.GetInputPort(name), name)
        measurements = self.sensors.GetOutputPort("measurements")
        slices = self.sensors.port_slices
        split = builder.AddNamedSystem("per_sensor", Demultiplexer(
            [index.stop - index.start for index in slices.values()]))
        builder.Connect(measurements, split.get_input_port())
        for i, sensor in enumerate(slices):
            builder.ExportOutput(split.get_output_port(i), sensor)
        builder.ExportOutput(measurements, "measurements")
        builder.BuildInto(self)

    @property
    def params(self) -> SensorSuiteParams:
        """The validated parameters."""
        return self.sensors.params

    @property
    def channel_names(self) -> tuple[str, ...]:
        """Names of the ``measurements`` entries."""
        return self.sensors.channel_names

    @property
    def channel_units(self) -> dict[str, str]:
        """Unit of each measured channel."""
        return self.sensors.channel_units
