"""Sensor parameters of the low-cost suite: IMU, GPS, pitot, wind vanes, attitude (INS), barometer.

Every channel follows the generic model of Vaiopoulos 2017, eq. 5.1:

    y_k = (1 + s_f) x(t_k - latency) + b_0 + b_rw(t_k) + eta_k

with x the true value, s_f a scale-factor error, b_0 a constant bias, b_rw a
bias random walk (density sigma_rw [unit/sqrt(s)]: the bias moves by
sigma_rw sqrt(dt) per sample) and eta_k white noise N(0, sigma^2). The true
values are those of Vaiopoulos 2017: specific force for the accelerometer
(eq. 5.4-5.6), body rates (5.7), NED position and velocity (5.8), Euler angles
(5.9), dynamic pressure (5.10), alpha and beta (5.11); the pitot channel also
reports the airspeed sqrt(2 q_meas / rho).

Each sensor dataclass holds its error groups (:class:`ChannelErrors`, in the
unit of its channels), ``rate_hz`` [Hz] and ``latency`` [s];
:class:`SensorSuiteParams` says which sensors are fitted and the base rate.

Defaults: the white-noise levels of Vaiopoulos 2017, Table 7 (printed as
+-2 sigma, so sigma = value / 2) with zero biases, as in its eq. 5.12. The gyro
level is read in deg/s: Table 7 prints 0.7 rad/s, implausible for a MEMS gyro
(docs/references.md). GPS position and latency and the barometer, which the
thesis does not give, take typical low-cost figures (u-blox class receiver,
MS5611 class barometer); the table of defaults is in docs/flight_data.md.

The Drake systems that sample these sensors are in :mod:`drake_uav.systems.sensors`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

# Layout of the truth vector assembled from the plant outputs.
TRUTH_LAYOUT = {
    "specific_force": slice(0, 3),
    "rates": slice(3, 6),
    "position": slice(6, 9),
    "velocity": slice(9, 12),
    "dynamic_pressure": slice(12, 13),
    "air_angles": slice(13, 15),
    "euler": slice(15, 18),
    "altitude": slice(18, 19),
}


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
CHANNEL_LAYOUT = (
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
        """Vaiopoulos 2017, Table 7 noise levels (sigma = printed 2-sigma / 2) and rates.

        ``gyro_noise_unit``: "deg/s" (default, plausible) or "rad/s" (as printed).
        """
        units = {"deg/s": math.pi / 180.0, "rad/s": 1.0}
        if gyro_noise_unit not in units:
            raise ValueError(f"gyro_noise_unit: use one of {tuple(units)}, got {gyro_noise_unit!r}")
        imu = ImuParams(gyro=ChannelErrors(0.7 / 2 * units[gyro_noise_unit]))
        return cls(imu=imu, pitot=PitotParams(air_density=air_density),
                   base_rate_hz=base_rate_hz).validate()

    @classmethod
    def research_grade(cls, air_density: float = 1.225,
                       base_rate_hz: float = 100.0) -> SensorSuiteParams:
        """A research-grade IMU and air-data boom: accelerometer 0.02 m/s^2, gyro 0.1 deg/s,
        vanes 0.1 deg, dynamic pressure 2 Pa (1-sigma white noise); GPS, attitude and baro
        as in the default suite. Low-cost levels are 2.5x (accelerometer), 3.5x (gyro),
        6x (vanes) and 5x (dynamic pressure) these."""
        return cls(imu=ImuParams(accel=ChannelErrors(0.02), gyro=ChannelErrors(math.radians(0.1))),
                   vanes=VaneParams(angles=ChannelErrors(math.radians(0.1))),
                   pitot=PitotParams(dynamic_pressure=ChannelErrors(2.0), air_density=air_density),
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
        for sensor, group, _, names, _ in CHANNEL_LAYOUT:
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
        for sensor, group, _, names, _ in CHANNEL_LAYOUT:
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
        for sensor, _, _, names, unit in CHANNEL_LAYOUT:
            if getattr(self, sensor) is not None:
                out += [(n, unit) for n in names]
                if sensor == "pitot":
                    out.append(("pitot_airspeed", "m/s"))
        return tuple(out)


