"""Process and measurement models of the two air-data and wind filters, scalar-generic.

* :class:`AirDataModel`: model-free filter of Vaiopoulos 2017, sec. 5.4.3: state
  ``[u_r, v_r, w_r, W_N, W_E, W_D]``, IMU and attitude as inputs, GPS velocity,
  pitot and vanes as measurements.
* :class:`ModelBasedAirDataModel`: Vaiopoulos 2017, sec. 5.4.5: state
  ``[Va, alpha, beta, W_N, W_E, W_D]`` driven by the aircraft's equations of motion
  (:class:`~drake_uav.model.fixed_wing.FixedWingModel`), accelerometer as a
  measurement; observes alpha and beta without vanes.

Wind is modelled as a random walk (Vaiopoulos 2017, eq. 5.20); with a changing wind
the air-relative velocity changes by ``-R^T dW`` as well, so the wind noise enters
both blocks (exact for the kinematics ``v_r = v - R^T W``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from drake_uav.estimation.attitude import ATTITUDE_TIME_CONSTANT, SmoothedAttitude
from drake_uav.estimation.ekf import EkfModel, EkfNoise
from drake_uav.estimation.gps import DEFAULT_GPS_LATENCY
from drake_uav.estimation.noise import WIND_PSD, sensor_std
from drake_uav.estimation.offline import FilterData, LogReader
from drake_uav.estimation.signals import (
    AIR_DATA,
    AIR_DATA_SENSORS,
    ATTITUDE,
    CONTROLS,
    GPS_VELOCITY,
    IMU,
    WIND,
)
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import (
    air_data_from_velocity,
    air_data_rates,
    airspeed_from_dynamic_pressure,
    dynamic_pressure,
    velocity_from_air_data,
)
from drake_uav.model.fixed_wing import FixedWingModel, body_gravity, body_velocity_rate
from drake_uav.model.rotations import euler_to_quat, euler_to_rotmat, rotate, rotate_back
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["MIN_START_AIRSPEED", "AirDataModel", "ModelBasedAirDataModel"]

MIN_START_AIRSPEED = 3.0
"""Airspeed [m/s] below which the filters do not start (the triplet is undefined at rest)."""

_WIND_NOISE = ("wind_n", "wind_e", "wind_d")


def _ground_velocity(R, v_r, wind):
    """GPS velocity ``R v_r + W`` [m/s] of the air-relative body velocity and the wind."""
    air = rotate(R, v_r)
    return [air[i] + wind[i] for i in range(3)]


def _wind_triangle_start(R: np.ndarray, gps: np.ndarray | None, airspeed: float | None,
                         vanes: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Air-relative body velocity and NED wind [m/s] at the first sample (Vaiopoulos 2017,
    eq. 5.24-5.25).

    With vanes the direction of the air-relative velocity comes from alpha and
    beta; without, it is taken along the ground track (corrected eq. 5.24).
    Without a usable airspeed (pitot, else GPS ground speed, at least
    :data:`MIN_START_AIRSPEED`) the result is NaN: the filter cannot start yet.
    """
    if airspeed is None and gps is not None:
        airspeed = float(np.linalg.norm(gps))
    if airspeed is None or not airspeed >= MIN_START_AIRSPEED:
        return np.full(3, np.nan), np.full(3, np.nan)
    if vanes is not None:
        v_r = np.array(velocity_from_air_data(airspeed, vanes[0], vanes[1]), float)
        wind = gps - R @ v_r if gps is not None else np.zeros(3)
        return v_r, wind
    if gps is not None and np.linalg.norm(gps) >= MIN_START_AIRSPEED:
        v_air_ned = airspeed * gps / np.linalg.norm(gps)
        return R.T @ v_air_ned, gps - v_air_ned
    return np.array([airspeed, 0.0, 0.0]), np.zeros(3)


def _start_values(y: np.ndarray, available: np.ndarray, gps_idx: Sequence[int], pitot: int,
                  vanes: Sequence[int], rho: float):
    """GPS velocity, pitot airspeed and vane angles of the first samples (None when absent)."""
    gps = y[list(gps_idx)] if all(available[list(gps_idx)]) else None
    airspeed = airspeed_from_dynamic_pressure(y[pitot], rho) if available[pitot] else None
    vane = y[list(vanes)] if all(available[list(vanes)]) else None
    return gps, airspeed, vane


def _log_data(model, log: FlightLog, gps_latency: float, gravity: float, truth) -> FilterData:
    """Filter arrays of a flight log; ``truth(air_data, wind)`` makes the true states from
    the log's air-data and wind channels."""
    reader = LogReader(log, gps_latency, gravity)
    y, fresh = reader.sensors(model.measurement_names)
    air, wind = reader.truth(AIR_DATA), reader.truth(WIND)
    states = None if air is None or wind is None else truth(air, wind)
    return FilterData(reader.time, reader.inputs(model.input_names, model.held_inputs), y,
                      fresh, states)


class AirDataModel(SmoothedAttitude, EkfModel):
    """Model-free air-data and wind filter model (Vaiopoulos 2017, sec. 5.4.3).

    ===========  ============================================================  =========
    name         meaning                                                        unit
    ===========  ============================================================  =========
    state        u_r, v_r, w_r (air-relative body velocity), W_N, W_E, W_D      m/s
    input        ax, ay, az (accelerometer), p, q, r (gyro), roll, pitch, yaw   m/s^2,
                                                                                rad/s, rad
    noise        wind_n, wind_e, wind_d (wind random walk)                      m/s^1.5
    measurement  gps_vn, gps_ve, gps_vd, pitot (dynamic pressure),              m/s, Pa,
                 alpha_vane, beta_vane                                          rad
    ===========  ============================================================  =========

    Dynamics (Vaiopoulos 2017, eq. 5.21, corrected, plus the wind-change term):
    ``v_r_dot = a + g_B - omega x v_r - R^T w``, ``W_dot = w``. Measurements:
    eq. 5.26-5.28 (corrected). The attitude inputs are smoothed with the gyro
    (time constant ``attitude_time_constant`` [s], 0: raw samples).
    """

    state_names = ("u_r", "v_r", "w_r", "W_N", "W_E", "W_D")
    input_names = IMU + ATTITUDE
    noise_names = _WIND_NOISE
    measurement_names = GPS_VELOCITY + AIR_DATA_SENSORS
    groups = {"gps_velocity": (0, 1, 2), "pitot": (3,), "vanes": (4, 5)}
    angle_inputs = (6, 7, 8)

    _rates, _angles = slice(3, 6), slice(6, 9)

    def __init__(self, params: FixedWingParams,
                 attitude_time_constant: float = ATTITUDE_TIME_CONSTANT):
        self.rho = params.rho
        self.gravity = params.gravity
        self._init_smoothing(attitude_time_constant)

    def dynamics(self, x, u, w):
        R = euler_to_rotmat(u[6:9])
        gravity, wind_change = body_gravity(R, self.gravity), rotate_back(R, w)
        accel = [u[i] + gravity[i] - wind_change[i] for i in range(3)]
        return np.array([*body_velocity_rate(x[0:3], u[3:6], accel), w[0], w[1], w[2]])

    def measurement(self, x, u):
        R = euler_to_rotmat(u[6:9])
        gps = _ground_velocity(R, x[0:3], x[3:6])
        airspeed, alpha, beta = air_data_from_velocity(x[0], x[1], x[2])
        return np.array([*gps, dynamic_pressure(airspeed, self.rho), alpha, beta])

    def initial_state(self, u, y, available):
        R = euler_to_rotmat(u[6:9])
        gps, airspeed, vanes = _start_values(y, available, (0, 1, 2), 3, (4, 5), self.rho)
        v_r, wind = _wind_triangle_start(R, gps, airspeed, vanes)
        return np.concatenate([v_r, wind])

    def default_noise(self, sensors: SensorSuiteParams | None = None,
                      period: float = 0.01) -> EkfNoise:
        """Noise of ``sensors`` (default Vaiopoulos 2017, Table 7), :data:`WIND_PSD`, the
        smoothed attitude at the update ``period`` [s], and a loose start (2 m/s on the
        air-relative velocity, 3 m/s horizontal / 1 m/s vertical wind)."""
        std = sensor_std(sensors)
        return EkfNoise(
            process_psd=dict(WIND_PSD),
            input_std={n: std[n] for n in self.input_names},
            measurement_std={n: std[n] for n in self.measurement_names},
            initial_std={"u_r": 2.0, "v_r": 2.0, "w_r": 2.0, "W_N": 3.0, "W_E": 3.0,
                         "W_D": 1.0},
            measurement_input_std=self._attitude_noise(std, period))

    def log_data(self, log: FlightLog, gps_latency: float = DEFAULT_GPS_LATENCY) -> FilterData:
        """Filter arrays of a flight log (truth from its air-data and wind channels); the
        GPS velocity is moved forward by ``gps_latency`` [s]."""
        return _log_data(self, log, gps_latency, self.gravity, lambda air, wind: np.column_stack(
            [*velocity_from_air_data(air[:, 0], air[:, 1], air[:, 2]), wind]))


class ModelBasedAirDataModel(SmoothedAttitude, EkfModel):
    """Model-based air-data and wind filter model (Vaiopoulos 2017, sec. 5.4.5).

    ===========  ============================================================  =========
    name         meaning                                                        unit
    ===========  ============================================================  =========
    state        Va, alpha, beta, W_N, W_E, W_D                                 m/s, rad
    input        p, q, r (gyro), roll, pitch, yaw, elevator, aileron, rudder,   rad/s,
                 throttle                                                       rad, -
    noise        wind_n, wind_e, wind_d (wind random walk), force_x, force_y,   m/s^1.5,
                 force_z (model error of the specific force)                    m/s^1.5
    measurement  ax, ay, az (accelerometer), gps_vn, gps_ve, gps_vd, pitot      m/s^2,
                 (dynamic pressure), alpha_vane, beta_vane                      m/s, Pa,
                                                                                rad
    ===========  ============================================================  =========

    The prediction evaluates the aircraft model of ``params`` (the identified
    one) at the estimated air-relative velocity: Vaiopoulos 2017, eq. 5.31 with the
    corrected thrust sign, written as the body-axis equations followed by
    :func:`~drake_uav.model.air_data.air_data_rates`. The accelerometer row is the
    model's specific force (eq. 5.34), the others eq. 5.36-5.39. The attitude inputs
    are smoothed with the gyro (time constant ``attitude_time_constant`` [s], 0: raw
    samples).
    """

    state_names = ("Va", "alpha", "beta", "W_N", "W_E", "W_D")
    input_names = ("p", "q", "r") + ATTITUDE + CONTROLS
    noise_names = _WIND_NOISE + ("force_x", "force_y", "force_z")
    measurement_names = ("ax", "ay", "az") + GPS_VELOCITY + AIR_DATA_SENSORS
    groups = {"accelerometer": (0, 1, 2), "gps_velocity": (3, 4, 5), "pitot": (6,),
              "vanes": (7, 8)}
    angle_inputs = (3, 4, 5)
    held_inputs = (6, 7, 8, 9)

    _rates, _angles = slice(0, 3), slice(3, 6)

    def __init__(self, params: FixedWingParams,
                 attitude_time_constant: float = ATTITUDE_TIME_CONSTANT):
        self.params = params
        self.aircraft = FixedWingModel(params)
        self._init_smoothing(attitude_time_constant)

    def _evaluate(self, x, u):
        v_r = velocity_from_air_data(x[0], x[1], x[2])
        zero = x[0] * 0.0
        plant_state = np.array([zero, zero, zero, *euler_to_quat(u[3:6]), *v_r, u[0], u[1],
                                u[2]])
        return v_r, self.aircraft.evaluate(plant_state, u[6:10])

    def dynamics(self, x, u, w):
        v_r, evaluation = self._evaluate(x, u)
        R = euler_to_rotmat(u[3:6])
        dw = rotate_back(R, w[0:3])
        # With zero wind the model's body acceleration is the air-relative one.
        accel = evaluation.state_derivative[7:10]
        v_r_dot = [accel[i] + w[3 + i] - dw[i] for i in range(3)]
        return np.array([*air_data_rates(v_r, v_r_dot), w[0], w[1], w[2]])

    def measurement(self, x, u):
        v_r, evaluation = self._evaluate(x, u)
        R = euler_to_rotmat(u[3:6])
        gps = _ground_velocity(R, v_r, x[3:6])
        return np.array([*evaluation.specific_force, *gps,
                         dynamic_pressure(x[0], self.params.rho), x[1], x[2]])

    def initial_state(self, u, y, available):
        R = euler_to_rotmat(u[3:6])
        gps, airspeed, vanes = _start_values(y, available, (3, 4, 5), 6, (7, 8),
                                             self.params.rho)
        v_r, wind = _wind_triangle_start(R, gps, airspeed, vanes)
        return np.array([*air_data_from_velocity(*v_r), *wind], float)

    def default_noise(self, sensors: SensorSuiteParams | None = None,
                      model_error: float = 0.003, period: float = 0.01) -> EkfNoise:
        """Noise of ``sensors`` (default Vaiopoulos 2017, Table 7), :data:`WIND_PSD`, a
        specific-force model error of density ``model_error`` [m^2/s^3] per axis, the
        smoothed attitude at the update ``period`` [s], and a loose start (2 m/s, 3 deg
        on the air data, 3 m/s horizontal / 1 m/s vertical wind)."""
        std = sensor_std(sensors)
        return EkfNoise(
            process_psd={**WIND_PSD, "force_x": model_error, "force_y": model_error,
                         "force_z": model_error},
            input_std={n: std[n] for n in self.input_names if n in std},
            measurement_std={n: std[n] for n in self.measurement_names},
            initial_std={"Va": 2.0, "alpha": math.radians(3.0), "beta": math.radians(3.0),
                         "W_N": 3.0, "W_E": 3.0, "W_D": 1.0},
            measurement_input_std=self._attitude_noise(std, period))

    def log_data(self, log: FlightLog, gps_latency: float = DEFAULT_GPS_LATENCY) -> FilterData:
        """Filter arrays of a flight log (truth from its air-data and wind channels); the
        GPS velocity is moved forward by ``gps_latency`` [s]."""
        return _log_data(self, log, gps_latency, self.params.gravity,
                         lambda air, wind: np.column_stack([air, wind]))
