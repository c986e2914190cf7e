"""Process and measurement models of the three estimators, scalar-generic.

* :class:`AirDataModel` - model-free air-data/wind filter of Vaiopoulos 2017, sec. 5.4.3:
  state ``[u_r, v_r, w_r, W_N, W_E, W_D]``, IMU and attitude as inputs, GPS
  velocity, pitot and vanes as measurements.
* :class:`ModelBasedAirDataModel` - Vaiopoulos 2017, sec. 5.4.5: state
  ``[Va, alpha, beta, W_N, W_E, W_D]`` driven by the aircraft's aerodynamic model
  (:class:`~drake_uav.systems.fixed_wing.FixedWingModel`), accelerometer as a
  measurement; observes alpha and beta without vanes.
* :class:`ParameterModel` - Ortiz & Gutierrez 2009, sec. 5: the decoupled longitudinal
  ``[V, alpha, q, theta]`` or lateral ``[beta, p, r, phi, psi]`` motion augmented
  with the stability derivatives of that axis (eq. 42-50). The other axis'
  variables are measured inputs. Forces and moments come from the shared
  regressors (:func:`~drake_uav.systems.aerodynamics.regressor_matrix`) times the
  state's derivatives, and enter :class:`FixedWingModel` as an external wrench.

Wind is modelled as a random walk (Vaiopoulos 2017, eq. 5.20); with a changing wind the
air-relative velocity changes by ``-R^T dW`` as well, so the wind noise enters
both blocks (exact for the kinematics ``v_r = v - R^T W``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
from pydrake.math import atan2, cos, sin, sqrt

from drake_uav.estimation.ekf import EkfModel, EkfNoise
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import air_data_from_velocity, velocity_from_air_data
from drake_uav.model.coefficients import (
    COEFFICIENTS,
    AeroCondition,
    lift_drag_to_body,
    regressor_matrix,
    split_derivative_name,
)
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.dryden import dryden_scales
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.isolation import differentiate
from drake_uav.model.rotations import euler_rates, euler_to_quat, euler_to_rotmat
from drake_uav.model.scalar import as_list
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.sensors import GpsParams, SensorSuiteParams

__all__ = [
    "DEFAULT_GPS_LATENCY",
    "MIN_START_AIRSPEED",
    "ATTITUDE_TIME_CONSTANT",
    "smoothed_attitude",
    "smoothed_attitude_std",
    "WIND_PSD",
    "TURBULENT_DERIVATIVE_WALK",
    "gust_rate_psd",
    "sensor_std",
    "FilterData",
    "is_new_sample",
    "fresh_samples",
    "ned_acceleration",
    "gps_latency_correction",
    "air_data_rates",
    "AirDataModel",
    "ModelBasedAirDataModel",
    "ParameterModel",
    "LONGITUDINAL_COEFFICIENTS",
    "LATERAL_COEFFICIENTS",
]

LONGITUDINAL_COEFFICIENTS = ("CL", "CD", "Cm")
"""Coefficients estimated by the longitudinal parameter filter (Ortiz & Gutierrez 2009, eq. 48)."""
LATERAL_COEFFICIENTS = ("CY", "Cl", "Cn")
"""Coefficients estimated by the lateral parameter filter (Ortiz & Gutierrez 2009, eq. 43)."""

_IMU = ("ax", "ay", "az", "p", "q", "r")
_ATTITUDE = ("roll", "pitch", "yaw")
_CONTROLS = ("elevator", "aileron", "rudder", "throttle")
_WIND_NOISE = ("wind_n", "wind_e", "wind_d")
_GPS = ("gps_vn", "gps_ve", "gps_vd")
_AIR = ("pitot", "alpha_vane", "beta_vane")
_AIR_DATA_TRUTH = ("airspeed", "alpha", "beta")
_WIND_TRUTH = ("wind_n", "wind_e", "wind_d")
DEFAULT_GPS_LATENCY = GpsParams().latency
"""GPS latency [s] assumed for logs unless told otherwise (the sensor suite's default)."""

MIN_START_AIRSPEED = 3.0
"""Airspeed [m/s] below which the filters do not start (the triplet is undefined at rest)."""

WIND_PSD = {"wind_n": 0.3, "wind_e": 0.3, "wind_d": 0.45}
"""Wind random-walk density [m^2/s^3] for light low-altitude turbulence: about
``3 a sigma^2`` of the Dryden filters (a = Va / L) at 25 m/s and 100 m."""


ATTITUDE_TIME_CONSTANT = 0.05
"""Time constant [s] of the attitude smoothing of the air-data filters: the GPS sample
period of the default suite, so consecutive GPS samples see nearly independent
attitude errors (correlation e^-1)."""


def smoothed_attitude(z):
    """One step of the attitude smoothing (scalar-generic): ``z`` = previous smoothed
    roll, pitch, yaw [rad], body rates over the step [rad/s], attitude sample [rad],
    gain [-], step [s].

    The previous attitude is carried forward with the Euler-angle rates of the
    gyro (Vaiopoulos 2017, eq. 3.3) and pulled towards the sample by ``gain`` (a
    complementary filter, time constant ``step / gain``). Angles wrapped to
    (-pi, pi].
    """
    previous, rates = z[0:3], euler_rates(z[0:3], z[3:6])
    out = []
    for i in range(3):
        predicted = previous[i] + z[10] * rates[i]
        difference = z[6 + i] - predicted
        angle = predicted + z[9] * atan2(sin(difference), cos(difference))
        out.append(atan2(sin(angle), cos(angle)))
    return out


@functools.cache
def _attitude_smoother() -> CompiledFunction:
    return CompiledFunction(smoothed_attitude, (11,), {}, "smoothed_attitude")


def smoothed_attitude_std(gyro_std: float, attitude_std: float, dt: float,
                          time_constant: float) -> float:
    """Steady-state error std [rad] of :func:`smoothed_attitude` (gain ``dt / time_constant``)
    on white gyro noise ``gyro_std`` [rad/s] and attitude noise ``attitude_std`` [rad]:
    ``((1 - K)^2 (gyro_std dt)^2 + K^2 attitude_std^2) / (1 - (1 - K)^2)``."""
    gain = min(dt / time_constant, 1.0) if time_constant > 0 else 1.0
    if gain >= 1.0:
        return attitude_std
    keep = (1.0 - gain) ** 2
    return math.sqrt((keep * (gyro_std * dt) ** 2 + gain**2 * attitude_std**2) / (1.0 - keep))


class _SmoothedAttitude:
    """Attitude inputs smoothed with the gyro inputs (:func:`smoothed_attitude`).

    The GPS rows see the attitude through ``R(euler)``: the raw samples' noise
    (0.75 deg at 25 m/s: 0.33 m/s across the air velocity) would make a GPS
    spike of 20 receiver sigmas only 3 innovation sigmas. Smoothed, the error
    seen by ``h`` is :func:`smoothed_attitude_std`; its low-frequency part, which
    drives the prediction, is still that of the samples (``input_std``).
    """

    _rates: slice
    _angles: slice

    def _init_smoothing(self, time_constant: float) -> None:
        if not (math.isfinite(time_constant) and time_constant >= 0):
            raise ValueError(f"attitude_time_constant must be >= 0, got {time_constant}")
        self.attitude_time_constant = time_constant
        self.smoothed_inputs = tuple(range(self._angles.start, self._angles.stop)) if (
            time_constant > 0) else ()

    def smooth_inputs(self, previous, u, dt):
        """``u`` with its attitude smoothed from ``previous`` (see ``EkfModel``)."""
        gain = min(dt / self.attitude_time_constant, 1.0)
        rates, angles = self._rates, self._angles
        out = np.array(u, float)
        if out.ndim == 1:
            p, q = previous.tolist(), out.tolist()
            z = (p[angles] + [0.5 * (a + b) for a, b in zip(p[rates], q[rates], strict=True)]
                 + q[angles] + [gain, dt])
            out[angles] = _attitude_smoother().program(z)
        else:
            z = np.concatenate([previous[:, angles], 0.5 * (previous[:, rates] + out[:, rates]),
                                out[:, angles], np.broadcast_to([gain, dt], (len(out), 2))],
                               axis=1)
            out[:, angles] = _attitude_smoother().batch_value(z)
        return out

    def _attitude_noise(self, std: dict[str, float], period: float) -> dict[str, float]:
        """``measurement_input_std`` of the smoothed attitude (empty without smoothing)."""
        if not self.smoothed_inputs:
            return {}
        gyro = max(std["p"], std["q"], std["r"])
        return {n: smoothed_attitude_std(gyro, std[n], period, self.attitude_time_constant)
                for n in _ATTITUDE}


TURBULENT_DERIVATIVE_WALK = 1e-5
"""Random-walk density of the derivatives of the parameter filter in turbulence, as a
fraction of their initial variance per second [1/s]. The walk keeps the filter's
memory finite, so that the slow errors of the beta and alpha estimates that enter the
bilinear regressors (and that the linearisation does not carry into the covariance)
do not accumulate into overconfident derivatives: over 20 flights of 300 s in light
turbulence the largest normalised error of a final derivative is 2.3 longitudinally
and 2.4 laterally."""


def gust_rate_psd(level: str, airspeed: float, altitude: float) -> tuple[float, float, float]:
    """Density [m^2/s^3] of the Dryden gust rates (u, v, w) above the break frequencies.

    The spectra of ``s H(s)`` for the filters of Vaiopoulos 2017, eq. 2.11 level off at
    ``2 sigma_u^2 a_u`` (first order) and ``3 sigma^2 a`` (second order), with
    ``a = airspeed / L``; MIL-F-8785C scales at ``altitude`` [m].
    """
    scales = dryden_scales(level, altitude)
    a = airspeed / scales.lengths
    sigma = scales.sigmas
    return (float(2.0 * sigma[0] ** 2 * a[0]), float(3.0 * sigma[1] ** 2 * a[1]),
            float(3.0 * sigma[2] ** 2 * a[2]))


def sensor_std(sensors: SensorSuiteParams | None = None) -> dict[str, float]:
    """Per-sample noise standard deviation of every sensor channel by filter name.

    From the suite's white-noise levels (default: Vaiopoulos 2017, Table 7); channels of
    sensors that are not fitted keep the Table 7 value.
    """
    table7 = SensorSuiteParams.seed_table7()
    out = {}
    groups = (("imu", "accel", ("ax", "ay", "az")), ("imu", "gyro", ("p", "q", "r")),
              ("attitude", "angles", _ATTITUDE), ("gps", "velocity", _GPS),
              ("pitot", "dynamic_pressure", ("pitot",)),
              ("vanes", "angles", ("alpha_vane", "beta_vane")))
    for sensor, group, names in groups:
        params = getattr(sensors, sensor, None) if sensors is not None else None
        params = getattr(table7, sensor) if params is None else params
        std = getattr(params, group).arrays(len(names), f"{sensor}.{group}")["noise_std"]
        out.update(zip(names, std.tolist(), strict=True))
    return out


def air_data_rates(v_r, v_r_dot) -> tuple:
    """``(Va_dot, alpha_dot, beta_dot)`` from the air-relative body velocity and its rate.

    Time derivative of Vaiopoulos 2017, eq. 2.12-2.14 (``Va = |v_r|``,
    ``alpha = atan2(w, u)``, ``beta = atan2(v, sqrt(u^2 + w^2))``).
    """
    u, v, w = v_r[0], v_r[1], v_r[2]
    ud, vd, wd = v_r_dot[0], v_r_dot[1], v_r_dot[2]
    uw2 = u * u + w * w
    va2 = uw2 + v * v
    uw_dot = u * ud + w * wd
    va_dot = (uw_dot + v * vd) / sqrt(va2)
    alpha_dot = (u * wd - w * ud) / uw2
    beta_dot = (uw2 * vd - v * uw_dot) / (va2 * sqrt(uw2))
    return va_dot, alpha_dot, beta_dot


def _rotated_sum(R, body, ned):
    """``R @ body + ned`` for sequences of any scalar type."""
    return [R[i][0] * body[0] + R[i][1] * body[1] + R[i][2] * body[2] + ned[i] for i in range(3)]


def _body_from_ned(R, ned):
    """``R^T @ ned``."""
    return [R[0][i] * ned[0] + R[1][i] * ned[1] + R[2][i] * ned[2] for i in range(3)]


def _wind_triangle_start(R: np.ndarray, gps: np.ndarray | None, airspeed: float | None,
                         vanes: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Air-relative body velocity and NED wind at the first sample (Vaiopoulos 2017, eq. 5.24-5.25).

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
    gps = y[list(gps_idx)] if all(available[list(gps_idx)]) else None
    airspeed = math.sqrt(max(2.0 * y[pitot] / rho, 0.0)) if available[pitot] else None
    vane = y[list(vanes)] if all(available[list(vanes)]) else None
    return gps, airspeed, vane


class AirDataModel(_SmoothedAttitude, EkfModel):
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

    Dynamics (seed eq. 5.21, corrected, plus the wind-change term):
    ``v_r_dot = a + g_B - omega x v_r - R^T w``, ``W_dot = w``. Measurements:
    eq. 5.26-5.28 (corrected). The attitude inputs are smoothed with the gyro
    (time constant ``attitude_time_constant`` [s], 0: raw samples).
    """

    state_names = ("u_r", "v_r", "w_r", "W_N", "W_E", "W_D")
    input_names = _IMU + _ATTITUDE
    noise_names = _WIND_NOISE
    measurement_names = _GPS + _AIR
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
        g = self.gravity
        ur, vr, wr = x[0], x[1], x[2]
        p, q, r = u[3], u[4], u[5]
        dw = _body_from_ned(R, w)
        return np.array([
            u[0] + g * R[2][0] + r * vr - q * wr - dw[0],
            u[1] + g * R[2][1] + p * wr - r * ur - dw[1],
            u[2] + g * R[2][2] + q * ur - p * vr - dw[2],
            w[0], w[1], w[2],
        ])

    def measurement(self, x, u):
        R = euler_to_rotmat(u[6:9])
        gps = _rotated_sum(R, x[0:3], x[3:6])
        airspeed, alpha, beta = air_data_from_velocity(x[0], x[1], x[2])
        return np.array([*gps, 0.5 * self.rho * airspeed * airspeed, alpha, beta])

    def initial_state(self, u, y, available):
        R = euler_to_rotmat(u[6:9])
        gps, airspeed, vanes = _start_values(y, available, (0, 1, 2), 3, (4, 5), self.rho)
        v_r, wind = _wind_triangle_start(R, gps, airspeed, vanes)
        return np.concatenate([v_r, wind])

    def default_noise(self, sensors: SensorSuiteParams | None = None,
                      period: float = 0.01) -> EkfNoise:
        """Noise of ``sensors`` (default Table 7), :data:`WIND_PSD`, the smoothed attitude
        at the update ``period`` [s], and a loose start (2 m/s on the air-relative
        velocity, 3 m/s horizontal / 1 m/s vertical wind)."""
        std = sensor_std(sensors)
        return EkfNoise(
            process_psd=dict(WIND_PSD),
            input_std={n: std[n] for n in self.input_names},
            measurement_std={n: std[n] for n in self.measurement_names},
            initial_std={"u_r": 2.0, "v_r": 2.0, "w_r": 2.0, "W_N": 3.0, "W_E": 3.0,
                         "W_D": 1.0},
            measurement_input_std=self._attitude_noise(std, period))

    def log_data(self, log: FlightLog, gps_latency: float = DEFAULT_GPS_LATENCY) -> FilterData:
        """Filter arrays of a flight log (truth from its air-data and wind channels)."""
        reader = _LogReader(log, gps_latency, self.gravity)
        y, fresh = reader.sensors(self.measurement_names)
        air, wind = reader.truth(_AIR_DATA_TRUTH), reader.truth(_WIND_TRUTH)
        truth = None if air is None or wind is None else np.column_stack(
            [*velocity_from_air_data(air[:, 0], air[:, 1], air[:, 2]), wind])
        return FilterData(reader.time, reader.inputs(self.input_names), y, fresh, truth)


class ModelBasedAirDataModel(_SmoothedAttitude, EkfModel):
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
    one) at the estimated air-relative velocity: seed eq. 5.31 with the
    corrected thrust sign, written as the body-axis equations followed by
    :func:`air_data_rates`. The accelerometer row is the model's specific force
    (eq. 5.34), the others eq. 5.36-5.39. The attitude inputs are smoothed with
    the gyro (time constant ``attitude_time_constant`` [s], 0: raw samples).
    """

    state_names = ("Va", "alpha", "beta", "W_N", "W_E", "W_D")
    input_names = ("p", "q", "r") + _ATTITUDE + _CONTROLS
    noise_names = _WIND_NOISE + ("force_x", "force_y", "force_z")
    measurement_names = ("ax", "ay", "az") + _GPS + _AIR
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
        dw = _body_from_ned(R, w[0:3])
        # With zero wind the model's body acceleration is the air-relative one.
        accel = evaluation.state_derivative[7:10]
        v_r_dot = [accel[i] + w[3 + i] - dw[i] for i in range(3)]
        return np.array([*air_data_rates(v_r, v_r_dot), w[0], w[1], w[2]])

    def measurement(self, x, u):
        v_r, evaluation = self._evaluate(x, u)
        R = euler_to_rotmat(u[3:6])
        gps = _rotated_sum(R, v_r, x[3:6])
        rho = self.params.rho
        return np.array([*evaluation.specific_force, *gps, 0.5 * rho * x[0] * x[0], x[1], x[2]])

    def initial_state(self, u, y, available):
        R = euler_to_rotmat(u[3:6])
        gps, airspeed, vanes = _start_values(y, available, (3, 4, 5), 6, (7, 8),
                                             self.params.rho)
        v_r, wind = _wind_triangle_start(R, gps, airspeed, vanes)
        return np.array([*air_data_from_velocity(*v_r), *wind], float)

    def default_noise(self, sensors: SensorSuiteParams | None = None,
                      model_error: float = 0.003, period: float = 0.01) -> EkfNoise:
        """Noise of ``sensors`` (default Table 7), :data:`WIND_PSD`, a specific-force
        model error of density ``model_error`` [m^2/s^3] per axis, the smoothed
        attitude at the update ``period`` [s], and a loose start (2 m/s, 3 deg on
        the air data, 3 m/s horizontal / 1 m/s vertical wind)."""
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
        """Filter arrays of a flight log (truth from its air-data and wind channels)."""
        reader = _LogReader(log, gps_latency, self.params.gravity)
        y, fresh = reader.sensors(self.measurement_names)
        air, wind = reader.truth(_AIR_DATA_TRUTH), reader.truth(_WIND_TRUTH)
        truth = None if air is None or wind is None else np.column_stack([air, wind])
        return FilterData(reader.time, reader.inputs(self.input_names, self.held_inputs), y,
                          fresh, truth)


class ParameterModel(EkfModel):
    """Augmented-state model of Ortiz & Gutierrez 2009, sec. 5 for one axis.

    ``axis="longitudinal"``: physical state ``[V, alpha, q, theta]`` (eq. 47),
    measured inputs ``beta, p, r, phi`` and the controls, measurements
    ``[V, alpha, q, theta, a_x, a_z, q_dot]`` (eq. 49, with the corrected
    body-axis accelerometer rows; see docs/references.md).

    ``axis="lateral"``: physical state ``[beta, p, r, phi, psi]`` (eq. 42),
    measured inputs ``V, alpha, q, theta`` and the controls, measurements
    ``[beta, p, r, phi, psi, a_y, p_dot, r_dot]`` (eq. 45 plus the heading,
    which keeps psi observable; a_y per the corrected eq. 46).

    The parameter part of the state are the derivatives ``names`` (default:
    the aircraft's derivatives of the axis' coefficients, without constant
    terms of the lateral ones), constant up to a random walk (noise inputs named
    like the derivatives). Terms of the aircraft model that are not estimated
    keep their ``params`` values. Units: m/s, rad, rad/s; accelerations m/s^2,
    rad/s^2; derivatives non-dimensional.
    """

    _AXES = {
        "longitudinal": dict(
            states=("airspeed", "alpha", "q", "pitch"),
            inputs=("beta", "p", "r", "roll"),
            measurements=("airspeed", "alpha", "q", "pitch", "ax", "az", "q_dot"),
            groups={"air_data": (0, 1), "gyro": (2,), "attitude": (3,),
                    "accelerometer": (4, 5), "angular_acceleration": (6,)},
            angles=()),
        "lateral": dict(
            states=("beta", "p", "r", "roll", "yaw"),
            inputs=("airspeed", "alpha", "q", "pitch"),
            measurements=("beta", "p", "r", "roll", "yaw", "ay", "p_dot", "r_dot"),
            groups={"air_data": (0,), "gyro": (1, 2), "attitude": (3, 4),
                    "accelerometer": (5,), "angular_acceleration": (6, 7)},
            angles=(4,)),
    }

    def __init__(self, params: FixedWingParams, axis: str, names: Sequence[str] | None = None):
        if axis not in self._AXES:
            raise ValueError(f"axis must be one of {tuple(self._AXES)}, got {axis!r}")
        layout = self._AXES[axis]
        coefficients = LONGITUDINAL_COEFFICIENTS if axis == "longitudinal" else (
            LATERAL_COEFFICIENTS)
        if names is None:
            names = [n for n in params.derivatives
                     if split_derivative_name(n)[0] in coefficients
                     and not (axis == "lateral" and n.endswith("_0"))]
        for name in names:
            coefficient, signal = split_derivative_name(name)
            if coefficient not in coefficients:
                raise ValueError(f"names: '{name}' is not a {axis} derivative "
                                 f"({coefficients})")
            if signal == "alphadot":
                raise ValueError(f"names: '{name}': alpha-dot derivatives are not supported")
        self.params, self.axis = params, axis
        self.parameter_names = tuple(names)
        self.physical_names = layout["states"]
        self.state_names = self.physical_names + self.parameter_names
        self.input_names = layout["inputs"] + _CONTROLS
        self.noise_names = self.physical_names + self.parameter_names
        self.measurement_names = layout["measurements"]
        self.groups = layout["groups"]
        self.angle_measurements = layout["angles"]
        self.angle_inputs = (3,) if axis == "longitudinal" else ()
        self.angle_states = (4,) if axis == "lateral" else ()
        self.held_inputs = (4, 5, 6, 7)
        self.aircraft = FixedWingModel(params, aerodynamics=False)
        # Fixed (not estimated) terms per coefficient, from the aircraft model.
        fixed = {k: [] for k in COEFFICIENTS}
        for name, value in params.derivatives.items():
            if name not in self.parameter_names:
                fixed[split_derivative_name(name)[0]].append((name, value))
        self._fixed = fixed
        self._estimated = {k: [(i, n) for i, n in enumerate(self.parameter_names)
                               if split_derivative_name(n)[0] == k] for k in COEFFICIENTS}

    def _full_condition(self, x, u):
        """(airspeed, alpha, beta, p, q, r, roll, pitch, yaw) from state and inputs."""
        if self.axis == "longitudinal":
            airspeed, alpha, q, pitch = x[0], x[1], x[2], x[3]
            beta, p, r, roll = u[0], u[1], u[2], u[3]
            yaw = 0.0 * x[0]
        else:
            beta, p, r, roll, yaw = x[0], x[1], x[2], x[3], x[4]
            airspeed, alpha, q, pitch = u[0], u[1], u[2], u[3]
        return airspeed, alpha, beta, p, q, r, roll, pitch, yaw

    def coefficients(self, x, u) -> list:
        """``[CL, CD, CY, Cl, Cm, Cn]`` with the state's derivatives (scalar-generic)."""
        airspeed, alpha, beta, p, q, r, *_ = self._full_condition(x, u)
        elevator, aileron, rudder, _ = u[4], u[5], u[6], u[7]
        cond = AeroCondition(airspeed=airspeed, alpha=alpha, beta=beta, p=p, q=q, r=r,
                             elevator=elevator, aileron=aileron, rudder=rudder)
        theta = x[len(self.physical_names):]
        out = []
        prm = self.params
        for k in COEFFICIENTS:
            fixed_names = [n for n, _ in self._fixed[k]]
            est = self._estimated[k]
            names = fixed_names + [n for _, n in est]
            if not names:
                out.append(0.0 * airspeed)
                continue
            row = regressor_matrix(names, cond, prm.b, prm.c)
            total = 0.0 * airspeed
            for j, (_, value) in enumerate(self._fixed[k]):
                total = total + value * row[j]
            for j, (i, _) in enumerate(est):
                total = total + theta[i] * row[len(fixed_names) + j]
            out.append(total)
        return out

    def _evaluate(self, x, u):
        prm = self.params
        airspeed, alpha, beta, p, q, r, roll, pitch, yaw = self._full_condition(x, u)
        CL, CD, CY, Cl, Cm, Cn = self.coefficients(x, u)
        CX, CZ = lift_drag_to_body(CL, CD, alpha)
        q_bar_s = 0.5 * prm.rho * airspeed * airspeed * prm.S
        wrench = [q_bar_s * CX, q_bar_s * CY, q_bar_s * CZ, q_bar_s * prm.b * Cl,
                  q_bar_s * prm.c * Cm, q_bar_s * prm.b * Cn]
        v_r = velocity_from_air_data(airspeed, alpha, beta)
        zero = 0.0 * airspeed
        rpy = [roll, pitch, yaw]
        plant_state = np.array([zero, zero, zero, *euler_to_quat(rpy), *v_r, p, q, r])
        evaluation = self.aircraft.evaluate(plant_state, u[4:8], (0.0, 0.0, 0.0), wrench)
        return v_r, rpy, evaluation

    def dynamics(self, x, u, w):
        v_r, rpy, evaluation = self._evaluate(x, u)
        xdot = evaluation.state_derivative
        va_dot, alpha_dot, beta_dot = air_data_rates(v_r, xdot[7:10])
        omega = [xdot[10], xdot[11], xdot[12]]
        airspeed, alpha, beta, p, q, r, *_ = self._full_condition(x, u)
        rates = euler_rates(rpy, [p, q, r])
        if self.axis == "longitudinal":
            physical = [va_dot, alpha_dot, omega[1], rates[1]]
        else:
            physical = [beta_dot, omega[0], omega[2], rates[0], rates[2]]
        n = len(physical)
        return np.array([physical[i] + w[i] for i in range(n)]
                        + [w[n + i] for i in range(len(self.parameter_names))])

    def measurement(self, x, u):
        _, _, evaluation = self._evaluate(x, u)
        a = evaluation.specific_force
        omega_dot = evaluation.state_derivative[10:13]
        if self.axis == "longitudinal":
            return np.array([x[0], x[1], x[2], x[3], a[0], a[2], omega_dot[1]])
        return np.array([x[0], x[1], x[2], x[3], x[4], a[1], omega_dot[0], omega_dot[2]])

    def initial_state(self, u, y, available):
        theta = [self.params.derivative(n) for n in self.parameter_names]
        physical = [y[i] if available[i] else np.nan for i in range(len(self.physical_names))]
        if self.axis == "longitudinal" and not physical[0] >= MIN_START_AIRSPEED:
            physical[0] = np.nan
        return np.array(physical + theta, float)

    def default_noise(self, sensors: SensorSuiteParams | None = None, airspeed: float = 25.0,
                      turbulence: str | None = None, altitude: float = 100.0) -> EkfNoise:
        """Noise of ``sensors`` (default Table 7) and the tuning for steady wind or for
        Dryden ``turbulence`` ("light", "moderate", "severe"; MIL-F-8785C at ``altitude``
        [m] and ``airspeed`` [m/s]).

        Steady wind (Ortiz & Gutierrez 2009): the physical states get a small process noise
        (1e-6 rad^2/s on angles and air-flow angles, 1e-5 rad^2/s^3 on rates,
        1e-3 m^2/s^3 on V), the derivatives none (constant). Turbulence adds
        the gust rates (:func:`gust_rate_psd`) to V and, divided by
        ``airspeed``^2, the lateral and vertical ones to beta and alpha, and a
        slow random walk of the derivatives (:data:`TURBULENT_DERIVATIVE_WALK`).
        The pitot's airspeed noise is its dynamic-pressure noise at
        ``airspeed``. Initial uncertainty: half of each prior derivative (at
        least 0.05), 1 m/s, 3 deg and 3 deg/s on the physical states. Angular
        accelerations (when supplied) are trusted to 0.1 rad/s^2.
        """
        std = sensor_std(sensors)
        pitot_density = (sensors.pitot.air_density if sensors is not None and sensors.pitot
                         is not None else self.params.rho)
        std.update(airspeed=std["pitot"] / (pitot_density * airspeed),
                   alpha=std["alpha_vane"], beta=std["beta_vane"],
                   p_dot=0.1, q_dot=0.1, r_dot=0.1)
        gust_u, gust_v, gust_w = (gust_rate_psd(turbulence, airspeed, altitude)
                                  if turbulence is not None else (0.0, 0.0, 0.0))
        physical_psd = {"airspeed": 1e-3 + gust_u, "alpha": 1e-6 + gust_w / airspeed**2,
                        "beta": 1e-6 + gust_v / airspeed**2, "p": 1e-5, "q": 1e-5, "r": 1e-5,
                        "roll": 1e-6, "pitch": 1e-6, "yaw": 1e-6}
        physical_std = {"airspeed": 1.0, "alpha": math.radians(3.0), "beta": math.radians(3.0),
                        "p": math.radians(3.0), "q": math.radians(3.0), "r": math.radians(3.0),
                        "roll": math.radians(3.0), "pitch": math.radians(3.0),
                        "yaw": math.radians(3.0)}
        parameter_std = {n: max(0.5 * abs(self.params.derivative(n)), 0.05)
                         for n in self.parameter_names}
        walk = TURBULENT_DERIVATIVE_WALK if turbulence is not None else 0.0
        return EkfNoise(
            process_psd={**{n: physical_psd[n] for n in self.physical_names},
                         **{n: walk * parameter_std[n] ** 2 for n in self.parameter_names}},
            input_std={n: std[n] for n in self.input_names if n in std},
            measurement_std={n: std[n] for n in self.measurement_names},
            initial_std={**{n: physical_std[n] for n in self.physical_names},
                         **parameter_std})

    def log_data(self, log: FlightLog, air_data: np.ndarray | None = None,
                 truth_params: FixedWingParams | None = None,
                 angular_acceleration: bool = False,
                 derivative_window: float = 0.2) -> FilterData:
        """Filter arrays of a flight log.

        Air data (V, alpha, beta) come from the pitot and vanes, or from
        ``air_data`` (N, 3), e.g. an air-data filter's estimate. With
        ``angular_acceleration`` the gyro differentiated by a centred
        Savitzky-Golay filter of ``derivative_window`` seconds is offered as
        the p_dot, q_dot, r_dot measurements; off by default, because the
        smoothing filter's time-correlated errors bias the joint estimate. The
        true state uses the derivatives of ``truth_params`` (when given) and
        the log's truth channels.
        """
        reader = _LogReader(log, 0.0, self.params.gravity)
        signals, fresh = {}, {}
        for name in ("ax", "ay", "az", "p", "q", "r", "roll", "pitch", "yaw", *_AIR_DATA_TRUTH):
            signals[name] = reader.channel(_CHANNELS[name])
            fresh[name] = fresh_samples(signals[name])
        if air_data is not None:
            air_data = np.asarray(air_data, float)
            for i, name in enumerate(_AIR_DATA_TRUTH):
                signals[name], fresh[name] = air_data[:, i], np.isfinite(air_data[:, i])
        rates = differentiate(reader.time, np.column_stack([signals[n] for n in "pqr"]),
                              derivative_window)
        for i, name in enumerate(("p_dot", "q_dot", "r_dot")):
            signals[name], fresh[name] = rates[:, i], np.full(reader.n, angular_acceleration)
        inputs = reader.inputs(self.input_names, self.held_inputs)
        for i, name in enumerate(self.input_names[:4]):
            inputs[:, i] = signals[name]
        y = np.column_stack([signals[n] for n in self.measurement_names])
        available = np.column_stack([fresh[n] for n in self.measurement_names])
        physical = reader.truth(self.physical_names)
        truth = None
        if physical is not None and truth_params is not None:
            theta = [truth_params.derivative(n) for n in self.parameter_names]
            truth = np.column_stack([physical, np.tile(theta, (reader.n, 1))])
        return FilterData(reader.time, inputs, y, available, truth)


# --------------------------------------------------------------------------------------
# Flight logs -> filter arrays.
# --------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class FilterData:
    """Arrays of one flight for :func:`~drake_uav.estimation.ekf.run_filter`."""

    time: np.ndarray
    """Sample times [s] (N)."""
    inputs: np.ndarray
    """(N, n_inputs) in the model's input order."""
    measurements: np.ndarray
    """(N, n_measurements) in the model's measurement order (NaN: no channel)."""
    available: np.ndarray
    """(N, n_measurements) bool, True where a new sample arrived."""
    truth: np.ndarray | None
    """(N, n_states) true states when the log has truth channels, else None."""


def is_new_sample(value, previous) -> np.ndarray:
    """True where a held (sample-and-hold) sensor value differs from the previous one;
    a NaN that repeats is not new (so a NaN sample is counted once)."""
    value, previous = np.asarray(value, float), np.asarray(previous, float)
    return ~((value == previous) | (np.isnan(value) & np.isnan(previous)))


def fresh_samples(values: np.ndarray) -> np.ndarray:
    """True where a held sensor channel delivered a new sample (the first row is new)."""
    values = np.asarray(values, float)
    fresh = np.ones(len(values), bool)
    fresh[1:] = is_new_sample(values[1:], values[:-1])
    return fresh


@functools.cache
def _ned_acceleration_function(gravity: float) -> CompiledFunction:
    def ned_acceleration(z):
        R = euler_to_rotmat(z[3:6])
        return np.array(_rotated_sum(R, z[0:3], [0.0, 0.0, gravity]))

    return CompiledFunction(ned_acceleration, (6,), {}, "ned_acceleration")


def ned_acceleration(specific_force, euler, gravity: float) -> np.ndarray:
    """Ground acceleration NED [m/s^2] of one IMU sample: ``R(euler) a + g e_D``."""
    return _ned_acceleration_function(float(gravity)).program(
        as_list(specific_force) + as_list(euler))


def gps_latency_correction(time: np.ndarray, specific_force: np.ndarray, euler: np.ndarray,
                           latency: float, gravity: float) -> np.ndarray:
    """Ground-velocity change [m/s] (N, 3) over the last ``latency`` seconds.

    Strapdown integration (trapezoid) of ``R(euler) a + g e_D`` from the
    accelerometer and attitude samples; added to a GPS velocity measured
    ``latency`` seconds ago it gives the velocity now.
    """
    time = np.asarray(time, float)
    accel = _ned_acceleration_function(float(gravity)).batch_value(
        np.column_stack([specific_force, euler]))
    increments = np.zeros_like(accel)
    increments[1:] = 0.5 * (accel[1:] + accel[:-1]) * np.diff(time)[:, None]
    cumulative = np.cumsum(increments, axis=0)
    start = np.searchsorted(time, time - latency - 1e-9)
    return cumulative - cumulative[start]


_CHANNELS = {
    "ax": "imu_ax", "ay": "imu_ay", "az": "imu_az", "p": "imu_p", "q": "imu_q", "r": "imu_r",
    "roll": "att_roll", "pitch": "att_pitch", "yaw": "att_yaw", "gps_vn": "gps_vn",
    "gps_ve": "gps_ve", "gps_vd": "gps_vd", "pitot": "pitot_qbar", "alpha_vane": "vane_alpha",
    "beta_vane": "vane_beta", "airspeed": "pitot_airspeed", "alpha": "vane_alpha",
    "beta": "vane_beta", "elevator": "cmd_elevator", "aileron": "cmd_aileron",
    "rudder": "cmd_rudder", "throttle": "cmd_throttle",
}
"""Filter signal name -> measured channel of :func:`~drake_uav.diagrams.fly` logs."""


class _LogReader:
    """Channels of a :class:`~drake_uav.io.flight_log.FlightLog` by filter name."""

    def __init__(self, log: FlightLog, gps_latency: float, gravity: float):
        self.log, self.time = log, np.asarray(log.time, float)
        self.n = len(self.time)
        self._gps_latency, self._gravity = gps_latency, gravity
        self._gps_correction: np.ndarray | None = None

    def channel(self, name: str) -> np.ndarray:
        """A measured channel (NaN column when the log lacks it)."""
        return np.asarray(self.log[name], float) if name in self.log else np.full(self.n, np.nan)

    def inputs(self, names: Sequence[str], held: Sequence[int] = ()) -> np.ndarray:
        """Input columns by filter name; ``held`` columns (commands) are shifted one
        sample so each row holds the command in effect during the step ending there."""
        columns = [self.channel(_CHANNELS[n]) for n in names]
        for i in held:
            columns[i] = np.concatenate([columns[i][:1], columns[i][:-1]])
        return np.column_stack(columns)

    def sensors(self, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Sensor samples and their freshness for filter measurement names; GPS
        velocity is moved forward by its latency."""
        columns, fresh = [], []
        for name in names:
            raw = self.channel(_CHANNELS[name])
            fresh.append(fresh_samples(raw))
            if name in _GPS and self._gps_latency > 0:
                raw = raw + self.gps_correction()[:, _GPS.index(name)]
            columns.append(raw)
        return np.column_stack(columns), np.column_stack(fresh)

    def gps_correction(self) -> np.ndarray:
        if self._gps_correction is None:
            self._gps_correction = gps_latency_correction(
                self.time, self.inputs(("ax", "ay", "az")), self.inputs(_ATTITUDE),
                self._gps_latency, self._gravity)
        return self._gps_correction

    def truth(self, names: Sequence[str]) -> np.ndarray | None:
        """Truth columns, or None when the log lacks one."""
        if not all(n in self.log for n in names):
            return None
        return np.column_stack([self.log[n] for n in names])
