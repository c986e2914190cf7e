"""Low-cost sensor suite: IMU, GPS, pitot, wind vanes, attitude (INS) and barometer.

Every channel follows the generic model of seed S0 eq. (5.1):

    y_k = (1 + s_f) x(t_k - latency) + b_0 + b_rw(t_k) + eta_k

with x the true value, s_f a scale-factor error, b_0 a constant bias, b_rw a
bias random walk (bias instability, density sigma_rw [unit/sqrt(s)], so the
bias moves by sigma_rw sqrt(dt) per sample), and eta_k white noise
N(0, sigma^2). The true values are the seed's: specific force for the
accelerometer (5.4)-(5.6), body rates (5.7), NED position and velocity (5.8),
Euler angles (5.9), dynamic pressure (5.10), alpha/beta (5.11). The pitot
channel also reports airspeed sqrt(2 q_meas / rho).

:class:`SensorSuite` is one diagram: a Drake ``RandomSource`` (seeded through the
root context) and one :class:`SampledSensors` LeafSystem whose single periodic
update, at ``base_rate_hz``, samples every sensor that is due (each sensor's
rate divides the base rate) and holds the measurements in between.

Default noise levels (:meth:`SensorSuiteParams.seed_table7`) come from seed S0
Table 7 (values printed as +-2 sigma, so sigma = value / 2); the biases are
zero as in the seed's simplification (5.12). Where the seed is silent,
typical low-cost autopilot figures are used: GPS position sigma 1.0 m
horizontal / 2.0 m vertical with 0.1 s latency (u-blox class receiver), GPS
velocity taken from Table 7 at 20 Hz, barometric altitude sigma 0.5 m at
50 Hz (MS5611 class). The printed gyro noise, 0.7 rad/s (2 sigma), is
implausible for a MEMS gyro; the unit is a parameter and deg/s is the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer, RandomSource

from drake_uav.rotations import quat_to_euler, rotate, unit_quat_rotation

__all__ = [
    "ChannelErrors",
    "ImuParams",
    "GpsParams",
    "PitotParams",
    "VaneParams",
    "AttitudeParams",
    "BaroParams",
    "SensorSuiteParams",
    "SampledSensors",
    "SensorSuite",
]

# Layout of the truth vector assembled from the plant outputs.
_TRUTH = {
    "specific_force": slice(0, 3),
    "rates": slice(3, 6),
    "position": slice(6, 9),
    "velocity": slice(9, 12),
    "dynamic_pressure": slice(12, 13),
    "air_angles": slice(13, 15),
    "euler": slice(15, 18),
    "altitude": slice(18, 19),
}
_ZERO3 = [0.0, 0.0, 0.0]
_ZERO13 = [0.0] * 13


@dataclass(frozen=True)
class ChannelErrors:
    """Error model of a group of channels (scalars apply to every channel).

    Attributes:
        noise_std: white-noise standard deviation per sample [unit].
        bias: constant bias b_0 [unit].
        bias_instability: random-walk density of the bias [unit / sqrt(s)].
        scale_factor: scale-factor error s_f [-] (measured = (1 + s_f) true).
    """

    noise_std: float | tuple[float, ...] = 0.0
    bias: float | tuple[float, ...] = 0.0
    bias_instability: float | tuple[float, ...] = 0.0
    scale_factor: float | tuple[float, ...] = 0.0

    def arrays(self, n: int, where: str) -> dict[str, np.ndarray]:
        """Each field broadcast to ``n`` channels; ValueError naming ``where.field``."""
        out = {}
        for f in fields(self):
            try:
                value = np.broadcast_to(np.asarray(getattr(self, f.name), float), (n,)).copy()
            except ValueError:
                raise ValueError(
                    f"{where}.{f.name}: need a scalar or {n} values, got {getattr(self, f.name)}"
                ) from None
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{where}.{f.name}: must be finite, got {value.tolist()}")
            if f.name in ("noise_std", "bias_instability") and np.any(value < 0):
                raise ValueError(f"{where}.{f.name}: must be >= 0, got {value.tolist()}")
            if f.name == "scale_factor" and np.any(value <= -1):
                raise ValueError(f"{where}.{f.name}: must be > -1, got {value.tolist()}")
            out[f.name] = value
        return out


@dataclass(frozen=True)
class _Sampling:
    """Shared validation of a sensor's rate [Hz] and latency [s]."""

    def _check_sampling(self, name: str, base_rate_hz: float) -> tuple[int, int]:
        """(ticks per sample, latency in ticks) at the base rate."""
        rate, latency = self.rate_hz, self.latency
        if not (rate > 0 and math.isfinite(rate)):
            raise ValueError(f"{name}.rate_hz: must be positive, got {rate}")
        if rate > base_rate_hz * (1 + 1e-12):
            raise ValueError(
                f"{name}.rate_hz: {rate} Hz is above the simulation rate "
                f"base_rate_hz = {base_rate_hz} Hz"
            )
        ratio = base_rate_hz / rate
        if abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise ValueError(
                f"{name}.rate_hz: {rate} Hz does not divide base_rate_hz = {base_rate_hz} Hz"
            )
        if not (latency >= 0 and math.isfinite(latency)):
            raise ValueError(f"{name}.latency: must be >= 0, got {latency}")
        return int(round(ratio)), int(round(latency * base_rate_hz))


@dataclass(frozen=True)
class ImuParams(_Sampling):
    """Accelerometer [m/s^2] (specific force, body) and gyro [rad/s] (body rates)."""

    accel: ChannelErrors = ChannelErrors(0.1 / 2)
    gyro: ChannelErrors = ChannelErrors(math.radians(0.7 / 2))
    rate_hz: float = 100.0
    latency: float = 0.0


@dataclass(frozen=True)
class GpsParams(_Sampling):
    """GPS position NED [m] and velocity NED [m/s], rate [Hz] and latency [s]."""

    position: ChannelErrors = ChannelErrors((1.0, 1.0, 2.0))
    velocity: ChannelErrors = ChannelErrors((0.1 / 2, 0.1 / 2, 0.2 / 2))
    rate_hz: float = 20.0
    latency: float = 0.1


@dataclass(frozen=True)
class PitotParams(_Sampling):
    """Pitot-static dynamic pressure [Pa]; airspeed = sqrt(2 q / air_density) [m/s]."""

    dynamic_pressure: ChannelErrors = ChannelErrors(20.0 / 2)
    air_density: float = 1.225
    rate_hz: float = 100.0
    latency: float = 0.0


@dataclass(frozen=True)
class VaneParams(_Sampling):
    """Wind vanes: angle of attack and sideslip [rad]."""

    angles: ChannelErrors = ChannelErrors(math.radians(1.2 / 2))
    rate_hz: float = 100.0
    latency: float = 0.0


@dataclass(frozen=True)
class AttitudeParams(_Sampling):
    """INS attitude: roll, pitch, yaw [rad] (yaw wrapped to [-pi, pi))."""

    angles: ChannelErrors = ChannelErrors(math.radians(1.5 / 2))
    rate_hz: float = 100.0
    latency: float = 0.0


@dataclass(frozen=True)
class BaroParams(_Sampling):
    """Barometric altitude above the NED origin [m]."""

    altitude: ChannelErrors = ChannelErrors(0.5)
    rate_hz: float = 50.0
    latency: float = 0.0


# (sensor, error group, truth key, channel names, unit) in output order.
_CHANNELS = (
    ("imu", "accel", "specific_force", ("imu_ax", "imu_ay", "imu_az"), "m/s^2"),
    ("imu", "gyro", "rates", ("imu_p", "imu_q", "imu_r"), "rad/s"),
    ("gps", "position", "position", ("gps_pn", "gps_pe", "gps_pd"), "m"),
    ("gps", "velocity", "velocity", ("gps_vn", "gps_ve", "gps_vd"), "m/s"),
    ("pitot", "dynamic_pressure", "dynamic_pressure", ("pitot_qbar",), "Pa"),
    ("vanes", "angles", "air_angles", ("vane_alpha", "vane_beta"), "rad"),
    ("attitude", "angles", "euler", ("att_roll", "att_pitch", "att_yaw"), "rad"),
    ("baro", "altitude", "altitude", ("baro_alt",), "m"),
)
_SENSORS = ("imu", "gps", "pitot", "vanes", "attitude", "baro")


@dataclass(frozen=True)
class SensorSuiteParams:
    """Which sensors are fitted (None: absent), their errors, and the base rate.

    ``base_rate_hz`` is the rate of the suite's single periodic update (the
    simulation rate seen by the sensors): every sensor rate must divide it, and
    latencies are rounded to whole base periods.
    """

    imu: ImuParams | None = ImuParams()
    gps: GpsParams | None = GpsParams()
    pitot: PitotParams | None = PitotParams()
    vanes: VaneParams | None = VaneParams()
    attitude: AttitudeParams | None = AttitudeParams()
    baro: BaroParams | None = BaroParams()
    base_rate_hz: float = 100.0

    @classmethod
    def seed_table7(cls, gyro_noise_unit: str = "deg/s", air_density: float = 1.225,
                    base_rate_hz: float = 100.0) -> SensorSuiteParams:
        """Seed S0 Table 7 noise levels (sigma = printed 2-sigma / 2) and rates.

        ``gyro_noise_unit``: "deg/s" (default, plausible) or "rad/s" (as printed).
        """
        units = {"deg/s": math.pi / 180.0, "rad/s": 1.0}
        if gyro_noise_unit not in units:
            raise ValueError(f"gyro_noise_unit: use one of {tuple(units)}, got {gyro_noise_unit!r}")
        imu = ImuParams(gyro=ChannelErrors(0.7 / 2 * units[gyro_noise_unit]))
        return cls(imu=imu, pitot=PitotParams(air_density=air_density),
                   base_rate_hz=base_rate_hz).validate()

    def sensors(self) -> dict[str, _Sampling]:
        """The fitted sensors by name, in output order."""
        return {n: getattr(self, n) for n in _SENSORS if getattr(self, n) is not None}

    def validate(self) -> SensorSuiteParams:
        """Raises ValueError naming the first invalid field (``sensor.field``); returns self."""
        if not (self.base_rate_hz > 0 and math.isfinite(self.base_rate_hz)):
            raise ValueError(f"base_rate_hz: must be positive, got {self.base_rate_hz}")
        if not self.sensors():
            raise ValueError("imu: at least one sensor must be fitted")
        for name, sensor in self.sensors().items():
            sensor._check_sampling(name, self.base_rate_hz)
        for sensor, group, _, names, _ in _CHANNELS:
            params = getattr(self, sensor)
            if params is not None:
                getattr(params, group).arrays(len(names), f"{sensor}.{group}")
        if self.pitot is not None and not self.pitot.air_density > 0:
            raise ValueError(f"pitot.air_density: must be positive, got {self.pitot.air_density}")
        return self

    def noise_std(self, airspeed: float) -> dict[str, float]:
        """White-noise standard deviation of every measured channel [its unit].

        The pitot airspeed's is the dynamic-pressure noise carried through
        ``Va = sqrt(2 q / rho)`` at ``airspeed`` [m/s].
        """
        out = {}
        for sensor, group, _, names, _ in _CHANNELS:
            params = getattr(self, sensor)
            if params is None:
                continue
            std = getattr(params, group).arrays(len(names), f"{sensor}.{group}")["noise_std"]
            out.update(zip(names, np.broadcast_to(std, (len(names),)).tolist(), strict=True))
            if sensor == "pitot":
                out["pitot_airspeed"] = out["pitot_qbar"] / (params.air_density * airspeed)
        return out

    def channels(self) -> tuple[tuple[str, str], ...]:
        """(name, unit) of every measured channel in the ``measurements`` output."""
        out = []
        for sensor, _, _, names, unit in _CHANNELS:
            if getattr(self, sensor) is not None:
                out += [(n, unit) for n in names]
                if sensor == "pitot":
                    out.append(("pitot_airspeed", "m/s"))
        return tuple(out)


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

    def __init__(self, params: SensorSuiteParams = SensorSuiteParams()):
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
        for sensor, group, truth_key, names, _ in _CHANNELS:
            params = getattr(p, sensor)
            if params is None:
                continue
            every, lag = params._check_sampling(sensor, p.base_rate_hz)
            errors = getattr(params, group).arrays(len(names), f"{sensor}.{group}")
            for k in cols:
                cols[k].append(errors[k])
            s = _TRUTH[truth_key]
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
        self._all_truths = truth_idx == list(range(_TRUTH["altitude"].stop))
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
                       _TRUTH.items()}
        self._needs["state"] = any(self._needs[k] for k in ("position", "velocity", "rates",
                                                            "altitude", "euler"))
        self._needs["air"] = self._needs["dynamic_pressure"] or self._needs["air_angles"]
        self._density = p.pitot.air_density if p.pitot is not None else 0.0

    def _truth(self, context) -> np.ndarray:
        """True values of every quantity some fitted sensor measures (N).

        Assembled in the ``_TRUTH`` layout from the inputs the fitted sensors need
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
                          0.5 * self._density * air[0] * air[0], air[1], air[2], *euler, -x[2]))
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
            q = out[self._airspeed_index - 1]
            out[self._airspeed_index] = math.sqrt(2.0 * max(q, 0.0) / self._density)
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

    def __init__(self, params: SensorSuiteParams = SensorSuiteParams()):
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
