"""A simulated flight as an autopilot would have logged it: ground, take-off, flight.

A simulated identification flight (:func:`drake_uav.diagrams.fly`) starts in the air
at trim. An autopilot log starts at power-up on the ground. :func:`extend_flight`
puts in front of the flight's measured channels

1. a **ground segment**: the aircraft stands still, level, on the flight's initial
   heading; the IMU reads gravity plus noise, the pitot reads about 0 (small negative
   pressures included), the GPS has no fix until ``gps_fix_s``, the outputs are not
   driven (PWM 0) until ``arm_s``;
2. a **take-off run** at full throttle (ground roll, rotation, climb) that ends on the
   flight's first position, heading, pitch and ground speed.

The take-off is kinematic (positions, attitude and their derivatives; specific force
``f = R^T (a - g)``), not flown through the aircraft model: its air data, forces and
commands are not aerodynamically consistent, and identification must leave it out
(the flight-mode timeline marks it: TAKEOFF until the flight starts).

Only measured channels are used (no truth, no vanes); the noise of the synthesised
part has the flight's sensor noise levels when the log states them. The result is
one channel set on the flight's sample grid; the format writers
(:mod:`drake_uav.io.realistic_ardupilot`, :mod:`drake_uav.io.realistic_px4`) take
each message at its own rate from it. See docs/flight_logs.md, "Realistic
simulated logs".
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import airspeed_from_dynamic_pressure, dynamic_pressure
from drake_uav.model.fixed_wing import body_gravity
from drake_uav.model.rotations import euler_to_rotmat
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.loading import load_fixed_wing

__all__ = ["LogProfile", "LogPhases", "WrittenLog", "ExtendedFlight", "extend_flight",
           "cut_tail", "save_log", "SURFACE_DEMAND", "ORIGIN"]

ORIGIN = (47.3977, 8.5456, 488.0)
"""Latitude, longitude [deg] and ground altitude [m] of the flight's NED origin."""

SURFACE_DEMAND = {"aileron": 1.0, "elevator": -1.0, "rudder": -1.0}
"""Sign of the autopilot's demand (roll right, pitch up, yaw right positive) per unit of
the project's surface command (aileron right-wing-down, elevator and rudder
trailing edge down / left positive: docs/flight_logs.md)."""

_MEASURED = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r", "att_roll",
             "att_pitch", "att_yaw", "gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve",
             "gps_vd", "pitot_qbar", "pitot_airspeed", "baro_alt", "cmd_elevator",
             "cmd_aileron", "cmd_rudder", "cmd_throttle")
# Noise of the synthesised ground and take-off [SI] when the flight states none.
_DEFAULT_NOISE = {"imu_ax": 0.05, "imu_ay": 0.05, "imu_az": 0.05, "imu_p": 0.006,
                  "imu_q": 0.006, "imu_r": 0.006, "att_roll": 0.013, "att_pitch": 0.013,
                  "att_yaw": 0.013, "gps_pn": 1.0, "gps_pe": 1.0, "gps_pd": 2.0,
                  "gps_vn": 0.05, "gps_ve": 0.05, "gps_vd": 0.1, "pitot_qbar": 10.0,
                  "baro_alt": 0.5}


@dataclasses.dataclass(frozen=True)
class LogProfile:
    """Timing and rates of a realistic log. Times [s] count from the first record."""

    boot_s: float = 4.8
    """Time since boot of the first record [s] (logs start a few seconds after power-up)."""
    gps_fix_s: float = 20.0
    """First 3-D GPS fix."""
    arm_s: float = 30.0
    """Arming: outputs go from PWM 0 to their trim values."""
    ground_s: float = 40.0
    """End of the ground segment: the take-off run starts."""
    roll_s: float = 8.0
    """Ground roll (full throttle, accelerating to ``rotate_fraction`` of the flight's
    ground speed)."""
    climb_s: float = 30.0
    """Climb from the runway to the flight's first altitude."""
    rotate_fraction: float = 0.75
    imu_rate_hz: float = 50.0
    """IMU and attitude logging rate (ArduPilot's default 50 Hz fast loop logging)."""
    command_rate_hz: float = 100.0
    """Servo outputs and demands. An autopilot logs its outputs once per control loop,
    the rate at which they change; the simulated flight's loop runs at its sensor base
    rate (100 Hz by default), so every command it flew is in the log. A lower rate
    drops commands the aircraft flew, which no reader can restore."""
    gps_rate_hz: float = 5.0
    airspeed_rate_hz: float = 10.0
    baro_rate_hz: float = 10.0
    position_rate_hz: float = 10.0
    """PX4 vehicle_local_position and actuator_outputs."""
    optional_rate_hz: float = 1.0
    """Sparse optional messages: ArduPilot XKF2 wind, PX4 differential_pressure and wind."""
    shaft_speed: str = "rpm"
    """Where a flight's ``motor_speed`` goes: ``"rpm"`` an RPM sensor (ArduPilot ``RPM``,
    PX4 ``rpm``), ``"esc"`` the ESC's telemetry (ArduPilot ``ESC`` instance 0, PX4
    ``esc_status``), which the readers give as ``esc_rpm_0``."""
    shaft_speed_rate_hz: float = 10.0
    """Rate of the RPM sensor or ESC telemetry messages [Hz]."""
    truncate: bool = True
    """End the file inside a half-written last message (a power loss while logging)."""

    def validate(self) -> LogProfile:
        """Checks the timing and rates; returns self."""
        if not (0.0 <= self.gps_fix_s and 0.0 <= self.arm_s <= self.ground_s):
            raise ValueError(f"profile: need 0 <= gps_fix_s and 0 <= arm_s <= ground_s, got "
                             f"{self.gps_fix_s}, {self.arm_s}, {self.ground_s}")
        for name in ("roll_s", "climb_s", "imu_rate_hz", "command_rate_hz", "gps_rate_hz",
                     "airspeed_rate_hz", "baro_rate_hz", "position_rate_hz",
                     "optional_rate_hz", "boot_s", "shaft_speed_rate_hz"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"profile.{name}: must be positive, got {getattr(self, name)}")
        if self.shaft_speed not in ("rpm", "esc"):
            raise ValueError(f"profile.shaft_speed: 'rpm' or 'esc', got {self.shaft_speed!r}")
        if not 0.0 < self.rotate_fraction <= 1.0:
            raise ValueError(f"profile.rotate_fraction: must be in (0, 1], got "
                             f"{self.rotate_fraction}")
        return self


@dataclasses.dataclass(frozen=True)
class LogPhases:
    """The phases of a realistic log in the log's time [s since boot]."""

    gps_fix_s: float
    arm_s: float
    takeoff_s: float
    """Start of the take-off run (synthesised, not aerodynamically consistent)."""
    flight_s: float
    """First sample of the simulated flight."""
    end_s: float
    """Last sample of the simulated flight (a truncated tail loses a fraction of a second
    before it)."""


@dataclasses.dataclass(frozen=True)
class WrittenLog:
    """A written log file and its phases."""

    path: Path
    phases: LogPhases


@dataclasses.dataclass(frozen=True)
class ExtendedFlight:
    """The flight's measured channels with the ground segment and take-off in front.

    ``time`` is uniform (the flight's sample period ``dt``) in seconds since boot;
    ``channels`` holds the measured channels of :data:`_MEASURED` (and ``motor_speed``
    when the flight has it). Surface commands are those of the project [rad].
    """

    time: np.ndarray
    dt: float
    channels: dict[str, np.ndarray]
    params: FixedWingParams
    profile: LogProfile
    phases: LogPhases
    heading: float
    """Runway heading [rad]."""

    def indices(self, rate_hz: float) -> np.ndarray:
        """Sample indices of a message logged at ``rate_hz`` (every k-th sample)."""
        step = max(1, int(round(1.0 / (rate_hz * self.dt))))
        return np.arange(0, self.time.size, step)

    def time_us(self, index: np.ndarray) -> np.ndarray:
        """Time since boot [us] of the samples ``index``."""
        return np.round(self.time[index] * 1e6).astype(np.uint64)

    def limit(self, surface: str) -> float:
        """The aircraft's limit deflection of ``surface`` [rad] (full servo throw)."""
        return float(getattr(self.params.limits, surface))

    def demand(self, surface: str) -> np.ndarray:
        """The autopilot's normalised demand of ``surface`` (-1..1, roll right, pitch up,
        yaw right positive) at every sample."""
        return np.clip(SURFACE_DEMAND[surface] * self.channels[f"cmd_{surface}"]
                       / self.limit(surface), -1.0, 1.0)

    def armed(self) -> np.ndarray:
        return self.time >= self.phases.arm_s

    def gps_fixed(self) -> np.ndarray:
        return self.time >= self.phases.gps_fix_s

    def wind_estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """A crude autopilot wind estimate (north, east) [m/s]: GPS ground velocity minus
        pitot airspeed along the heading, averaged over 10 s; 0 before the flight."""
        ch = self.channels
        yaw = ch["att_yaw"]
        speed = np.abs(ch["pitot_airspeed"]) * np.cos(ch["att_pitch"])
        kernel = np.ones(int(round(10.0 / self.dt)))
        kernel /= kernel.size
        north = np.convolve(ch["gps_vn"] - speed * np.cos(yaw), kernel, "same")
        east = np.convolve(ch["gps_ve"] - speed * np.sin(yaw), kernel, "same")
        flying = self.time >= self.phases.flight_s
        return np.where(flying, north, 0.0), np.where(flying, east, 0.0)


def _flight_channels(log: FlightLog) -> dict[str, np.ndarray]:
    """The measured channels the logs are made of; a clear error for a missing one."""
    missing = [name for name in _MEASURED if name not in log.measured_names]
    if missing:
        raise ValueError(f"flight log: missing measured channel '{missing[0]}' (a simulated "
                         "flight from drake_uav.diagrams.fly has it)")
    names = _MEASURED + (("motor_speed",) if "motor_speed" in log.measured_names else ())
    return {name: np.asarray(log[name], float) for name in names}


def _sample_period(log: FlightLog) -> float:
    steps = np.diff(log.time)
    if steps.size < 2 or np.ptp(steps) > 1e-6 * steps.mean():
        raise ValueError("flight log: time: need a uniformly sampled flight of at least 3 "
                         "samples")
    return float(steps.mean())


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _takeoff_path(first: dict[str, float], profile: LogProfile, dt: float, n: int):
    """Positions NED [m] and pitch [rad] of the ``n`` samples before the flight.

    Ground roll at constant acceleration to the rotation speed, then a climb whose
    speed grows linearly to the flight's ground speed and whose height follows a
    smoothstep (level at both ends) up to the flight's first altitude.
    """
    t = (np.arange(n) - n) * dt  # the flight starts at t = 0
    speed, v_rot = first["speed"], profile.rotate_fraction * first["speed"]
    t_roll = np.clip(t + profile.roll_s + profile.climb_s, 0.0, profile.roll_s)
    t_climb = np.clip(t + profile.climb_s, 0.0, profile.climb_s)
    along = (0.5 * v_rot * t_roll ** 2 / profile.roll_s + v_rot * t_climb
             + 0.5 * (speed - v_rot) * t_climb ** 2 / profile.climb_s)
    along -= 0.5 * v_rot * profile.roll_s + 0.5 * (speed + v_rot) * profile.climb_s
    height = first["height"] * _smoothstep(t_climb / profile.climb_s)
    heading = first["yaw"]
    position = np.array([first["pn"] + along * math.cos(heading),
                         first["pe"] + along * math.sin(heading), -height])
    climb_angle = np.arctan2(np.gradient(height, dt), np.maximum(np.gradient(along, dt), 0.1))
    rotation = _smoothstep((t_roll - (profile.roll_s - 2.0)) / 2.0)
    return position, climb_angle + first["pitch"] * rotation


def _first_state(channels: dict[str, np.ndarray], dt: float) -> dict[str, float]:
    """Position, heading, pitch and ground speed over the flight's first second."""
    k = max(1, int(round(1.0 / dt)))
    yaw = channels["att_yaw"][:k]
    return {"pn": float(np.mean(channels["gps_pn"][:k])),
            "pe": float(np.mean(channels["gps_pe"][:k])),
            "height": max(float(-np.mean(channels["gps_pd"][:k])), 1.0),
            "yaw": float(np.arctan2(np.mean(np.sin(yaw)), np.mean(np.cos(yaw)))),
            "pitch": float(np.mean(channels["att_pitch"][:k])),
            "speed": float(np.hypot(np.mean(channels["gps_vn"][:k]),
                                    np.mean(channels["gps_ve"][:k])))}


def _synthesised(channels, params: FixedWingParams, profile: LogProfile, dt: float,
                 n: int, wind: np.ndarray) -> tuple[dict[str, np.ndarray], float]:
    """Noise-free measured channels of the ground segment and take-off; the heading."""
    first = _first_state(channels, dt)
    position, pitch = _takeoff_path(first, profile, dt, n)
    velocity = np.gradient(position, dt, axis=1)
    attitude = np.array([np.zeros(n), pitch, np.full(n, first["yaw"])])
    rotation = euler_to_rotmat(attitude)  # body -> NED, (3, 3, n)
    accel = np.einsum("jin,jn->in", rotation, np.gradient(velocity, dt, axis=1))
    force = accel - np.array(body_gravity(rotation, params.gravity))  # f = R^T a - g_B
    airspeed = np.linalg.norm(velocity - wind[:, None], axis=0)
    takeoff = np.arange(n) * dt >= profile.ground_s
    out = {f"imu_a{axis}": force[i] for i, axis in enumerate("xyz")}
    # Wings level on a constant heading: the body rates are (0, pitch rate, 0).
    out.update(imu_p=np.zeros(n), imu_q=np.gradient(pitch, dt), imu_r=np.zeros(n),
               att_roll=attitude[0], att_pitch=pitch, att_yaw=attitude[2],
               baro_alt=-position[2],
               pitot_qbar=dynamic_pressure(airspeed, params.rho),
               cmd_throttle=np.where(takeoff, 1.0, 0.0))
    out.update({f"gps_p{axis}": position[i] for i, axis in enumerate("ned")})
    out.update({f"gps_v{axis}": velocity[i] for i, axis in enumerate("ned")})
    for surface in SURFACE_DEMAND:
        out[f"cmd_{surface}"] = np.full(n, channels[f"cmd_{surface}"][0])
    if "motor_speed" in channels:
        out["motor_speed"] = np.where(takeoff, float(np.max(channels["motor_speed"])), 0.0)
    return out, first["yaw"]


def _add_noise(values: dict[str, np.ndarray], noise: dict[str, float], rho: float,
               rng: np.random.Generator) -> None:
    """Sensor noise on the synthesised channels (in place); the pitot airspeed is the
    signed airspeed of the noisy pressure (negative pressure: negative airspeed)."""
    for name in _DEFAULT_NOISE:
        values[name] = values[name] + rng.normal(0.0, noise.get(name, _DEFAULT_NOISE[name]),
                                                 values[name].size)
    qbar = values["pitot_qbar"]
    speed = np.vectorize(airspeed_from_dynamic_pressure)(np.abs(qbar), rho)
    values["pitot_airspeed"] = np.sign(qbar) * speed


def extend_flight(log: FlightLog, aircraft: str | FixedWingParams | None = None,
                  profile: LogProfile | None = None, *, seed: int) -> ExtendedFlight:
    """The flight's measured channels with a ground segment and a take-off run in front.

    Args:
        log: a simulated fixed-wing flight (measured channels of
            :func:`drake_uav.diagrams.fly`, uniformly sampled).
        aircraft: the aircraft flown (its surface limits are the full servo throws,
            its air density and gravity shape the take-off); default the log's
            ``metadata["aircraft"]``.
        profile: timing and rates (default :class:`LogProfile`).
        seed: seed of the synthesised part's noise (the same seed gives the same data).
    """
    profile = (profile or LogProfile()).validate()
    if aircraft is None:
        aircraft = log.metadata.get("aircraft")
        if not isinstance(aircraft, str):
            raise ValueError("aircraft: the flight log names no aircraft (metadata "
                             "'aircraft'); pass the aircraft flown")
    params = load_fixed_wing(aircraft) if isinstance(aircraft, str) else aircraft
    channels, dt = _flight_channels(log), _sample_period(log)
    rng = np.random.default_rng(seed)
    n = int(round((profile.ground_s + profile.roll_s + profile.climb_s) / dt))
    wind = np.asarray(log.metadata.get("steady_wind_ned", (0.0, 0.0, 0.0)), float)
    before, heading = _synthesised(channels, params, profile, dt, n, wind)
    _add_noise(before, dict(log.metadata.get("sensor_noise_std", {})), params.rho, rng)
    merged = {name: np.concatenate([before[name], values]) for name, values in
              channels.items()}
    time = profile.boot_s + np.arange(n + log.time.size) * dt
    phases = LogPhases(profile.boot_s + profile.gps_fix_s,
                        profile.boot_s + profile.arm_s, profile.boot_s + profile.ground_s,
                        float(time[n]), float(time[-1]))
    return ExtendedFlight(time, dt, merged, params, profile, phases, heading)


def cut_tail(data: bytes, body_offset: int, sizes: np.ndarray, block: int | None) -> bytes:
    """``data`` ending inside its last message, as after a power loss while logging.

    With ``block`` (an SD-card block, 4096 bytes for ArduPilot) the file ends at the last
    block boundary that falls inside a message; that message holds its first half, then
    zeros up to the boundary; the messages after it are lost. Without ``block`` the
    last message keeps its first half.
    """
    ends = body_offset + np.cumsum(sizes)
    starts = ends - sizes
    if block is None:
        return data[:int(starts[-1] + sizes[-1] // 2)]
    boundary = (ends // block) * block
    crossing = np.flatnonzero((boundary > starts) & (boundary < ends))
    if crossing.size == 0:
        raise ValueError("log too short to end inside a message at a block boundary")
    k = crossing[-1]
    start, cut = int(starts[k]), int(boundary[k])
    written = min(cut - start, int(sizes[k]) // 2)
    return data[:start + written] + bytes(cut - start - written)


def save_log(writer, flight: ExtendedFlight, path: str | Path, block: int | None) -> WrittenLog:
    """Writes the messages of ``writer`` (a :mod:`drake_uav.io.writers` writer) to ``path``,
    cut inside the last message (:func:`cut_tail` with ``block``) when the profile says so."""
    data = writer.to_bytes()
    if flight.profile.truncate:
        data = cut_tail(data, writer.body_offset, writer.record_sizes, block)
    path = Path(path)
    path.write_bytes(data)
    return WrittenLog(path, flight.phases)
