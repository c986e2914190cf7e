"""Air-data and wind filter model for flights without vanes, scalar-generic.

:class:`VanelessAirDataModel` extends the model-free filter of Vaiopoulos 2017,
sec. 5.4.3 (:class:`~drake_uav.estimation.air_data_models.AirDataModel`: IMU and attitude
as inputs, GPS velocity and pitot as measurements) with two optional parts:

* ``gust``: the wind split into a slowly wandering mean (random walk) and a gust
  (first-order Gauss-Markov process, time constant ``L / Va``, standard deviation
  ``sigma``; the first-order approximation of the Dryden spectra, Beard & McLain 2012,
  sec. 4.4), so the unobservable wind components stay bounded instead of drifting.
* ``lift_relation``: the accelerometer's vertical and lateral rows as measurements of a
  specific-force relation with free coefficients estimated jointly,

      a_z = qbar (c_z0 + c_za alpha + c_ze elevator),
      a_y = qbar (c_y0 + c_yb beta + c_yr rudder)       [m/s^2, c in m^2/kg],

  the linear force-coefficient model (Beard & McLain 2012, eq. 4.12-4.14) divided by
  the mass, with the coefficients ``S C / m`` unknown states (a slow random walk).
  Pitot, GPS and attitude fix alpha and beta at low frequency through the wind
  triangle, which is what the coefficients are learnt from; the accelerometer then
  follows the fast part of the flow angles that gusts cause and that the wind
  triangle cannot see (a vertical gust changes the airspeed only to second order). No
  catalog aerodynamics enter: only the wing geometry and mass set a loose prior.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import exp

from drake_uav.estimation.air_data_models import _start_values, _wind_triangle_start
from drake_uav.estimation.attitude import ATTITUDE_TIME_CONSTANT, SmoothedAttitude
from drake_uav.estimation.ekf import EkfModel, EkfNoise
from drake_uav.estimation.gps import DEFAULT_GPS_LATENCY
from drake_uav.estimation.noise import sensor_std
from drake_uav.estimation.offline import FilterData, LogReader
from drake_uav.estimation.signals import ATTITUDE, GPS_VELOCITY, IMU
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import air_data_from_velocity, dynamic_pressure
from drake_uav.model.dryden import dryden_scales
from drake_uav.model.fixed_wing import body_gravity, body_velocity_rate
from drake_uav.model.rotations import euler_to_rotmat, rotate, rotate_back
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["VanelessAirDataModel", "MEAN_WIND_PSD", "LIFT_COEFFICIENT_WALK",
           "SPECIFIC_FORCE_MODEL_STD", "COEFFICIENT_NAMES"]

MEAN_WIND_PSD = 0.01
"""Random-walk density of the mean wind when the gust is a separate state [m^2/s^3]."""

LIFT_COEFFICIENT_WALK = 0.0
"""Random-walk density of the specific-force coefficient states [(state unit)^2 / s]:
constant coefficients (with a walk the offset of alpha drifted with ``c_z0``)."""

SPECIFIC_FORCE_MODEL_STD = 0.05
"""Error of the linear specific-force relation per sample [m/s^2] (unmodelled rate,
thrust and nonlinear terms), added to the accelerometer noise."""

COEFFICIENT_NAMES = ("c_z0", "c_za", "c_ze", "c_y0", "c_yb", "c_yr")
"""The specific-force coefficients [m^2/kg] (:meth:`VanelessAirDataModel.coefficients`)."""

_SPECIFIC_FORCE_COEFFICIENTS = ("c_z0", "log_c_za", "c_ze", "c_y0", "log_c_yb", "c_yr")
"""The coefficient states; the slopes as ``log(-c_za)`` and ``log(-c_yb)``: lift grows with
alpha and the side force opposes sideslip on any conventional airframe, and the slopes,
weakly observed in straight flight, must not change sign."""


class VanelessAirDataModel(SmoothedAttitude, EkfModel):
    """Air-data and wind filter model without vanes (see the module docstring).

    ===========  ============================================================  =========
    name         meaning                                                        unit
    ===========  ============================================================  =========
    state        u_r, v_r, w_r (air-relative body velocity), W_N, W_E, W_D      m/s
                 (mean wind); with ``gust``: G_N, G_E, G_D; with
                 ``lift_relation``: c_z0, c_za, c_ze, c_y0, c_yb, c_yr           m^2/kg
    input        ax, ay, az, p, q, r, roll, pitch, yaw; with                    m/s^2,
                 ``lift_relation``: elevator, rudder                             rad/s, rad
    noise        wind_n, wind_e, wind_d (mean wind walk); gust_n, gust_e,       m/s^1.5
                 gust_d; coefficient walks
    measurement  gps_vn, gps_ve, gps_vd, pitot; with ``lift_relation``:         m/s, Pa,
                 ay_meas, az_meas (accelerometer rows)                           m/s^2
    ===========  ============================================================  =========

    Args:
        params: the aircraft (density, gravity; with ``lift_relation`` the mass, wing
            area and span for the coefficient prior).
        gust: add the Gauss-Markov gust states.
        lift_relation: add the specific-force relation.
        turbulence, altitude: MIL-F-8785C level and altitude [m] of the gust prior
            (Dryden scales; sigma and length per axis).
        airspeed: nominal airspeed [m/s] for the gust time constants ``L / Va``.
        averaged_imu: the IMU inputs are held over each step (their mean over the step,
            for a filter that steps on a subset of the IMU samples) instead of
            interpolated between two samples.
    """

    held_inputs: tuple[int, ...] = ()
    command_inputs: tuple[int, ...] = ()
    """Indices of the commands among the inputs (elevator, rudder)."""

    def __init__(self, params: FixedWingParams, *, gust: bool = False,
                 lift_relation: bool = True, turbulence: str = "light",
                 altitude: float = 100.0, airspeed: float = 25.0,
                 averaged_imu: bool = False,
                 attitude_time_constant: float = ATTITUDE_TIME_CONSTANT):
        self.params, self.gust, self.lift_relation = params, gust, lift_relation
        self.rho, self.gravity = params.rho, params.gravity
        scales = dryden_scales(turbulence, altitude)
        self.gust_sigma = np.asarray(scales.sigmas, float)
        self.gust_tau = np.asarray(scales.lengths, float) / airspeed
        states = ["u_r", "v_r", "w_r", "W_N", "W_E", "W_D"]
        noises = ["wind_n", "wind_e", "wind_d"]
        if gust:
            states += ["G_N", "G_E"]
            noises += ["gust_n", "gust_e"]
        inputs = list(IMU + ATTITUDE)
        measurements = list(GPS_VELOCITY) + ["pitot"]
        groups = {"gps_velocity": (0, 1, 2), "pitot": (3,)}
        if lift_relation:
            states += list(_SPECIFIC_FORCE_COEFFICIENTS)
            noises += [f"walk_{c}" for c in _SPECIFIC_FORCE_COEFFICIENTS]
            inputs += ["elevator", "rudder"]
            measurements += ["ay_meas", "az_meas"]
            groups = {**groups, "accelerometer_y": (4,), "accelerometer_z": (5,)}
            self.command_inputs = (9, 10)
        self.held_inputs = (tuple(range(6)) if averaged_imu else ()) + self.command_inputs
        self.state_names, self.noise_names = tuple(states), tuple(noises)
        self.input_names, self.measurement_names = tuple(inputs), tuple(measurements)
        self.groups = groups
        self._rates, self._angles = slice(3, 6), slice(6, 9)
        self._init_smoothing(attitude_time_constant)

    def _wind(self, x):
        """Total wind NED [m/s]: mean plus gust horizontally, the vertical gust."""
        if not self.gust:
            return [x[3], x[4], x[5]]
        return [x[3] + x[6], x[4] + x[7], x[5]]

    def dynamics(self, x, u, w):
        R = euler_to_rotmat(u[6:9])
        # Vertical wind: zero-mean Gauss-Markov; horizontal: random-walk mean (+ gust).
        vertical = -x[5] / self.gust_tau[2] + w[2]
        wind_rate = [w[0], w[1], vertical]
        gust_rate = []
        if self.gust:
            gust_rate = [-x[6 + i] / self.gust_tau[i] + w[3 + i] for i in range(2)]
            wind_rate = [wind_rate[0] + gust_rate[0], wind_rate[1] + gust_rate[1], vertical]
        gravity, wind_change = body_gravity(R, self.gravity), rotate_back(R, wind_rate)
        accel = [u[i] + gravity[i] - wind_change[i] for i in range(3)]
        derivative = [*body_velocity_rate(x[0:3], u[3:6], accel), w[0], w[1], vertical,
                      *gust_rate]
        if self.lift_relation:
            first = 5 if self.gust else 3
            derivative += [w[first + i] for i in range(6)]
        return np.array(derivative)

    def measurement(self, x, u):
        R = euler_to_rotmat(u[6:9])
        air = rotate(R, x[0:3])
        wind = self._wind(x)
        airspeed, alpha, beta = air_data_from_velocity(x[0], x[1], x[2])
        qbar = dynamic_pressure(airspeed, self.rho)
        rows = [air[0] + wind[0], air[1] + wind[1], air[2] + wind[2], qbar]
        if self.lift_relation:
            c = self.coefficients(x[len(self.state_names) - 6:])
            rows += [qbar * (c[3] + c[4] * beta + c[5] * u[10]),
                     qbar * (c[0] + c[1] * alpha + c[2] * u[9])]
        return np.array(rows)

    @staticmethod
    def coefficients(states) -> list:
        """``c_z0, c_za, c_ze, c_y0, c_yb, c_yr`` [m^2/kg] of the six coefficient states
        (scalar-generic)."""
        return [states[0], -exp(states[1]), states[2], states[3], -exp(states[4]), states[5]]

    def coefficient_prior(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial values and standard deviations of the coefficient states (m^2/kg; the
        slopes' logarithms, std in ln units): the lift slope of a finite wing
        ``2 pi AR / (AR + 2)`` (Beard & McLain 2012, eq. 4.9 with the aspect ratio of the
        geometry) for ``-c_za`` (a factor e^0.5 loose), a side-force slope of a fifth of
        it for ``-c_yb`` (a factor e loose), zero for the others; all loose but ``c_y0``,
        held at zero: a symmetric airframe has no side force at zero sideslip and rudder,
        and without that the sideslip offset trades with the crosswind, which straight
        flight does not observe (a lateral accelerometer bias then biases beta by
        ``bias / (qbar c_yb)``)."""
        p = self.params
        aspect = p.b**2 / p.S
        scale = p.S / p.mass
        slope = 2.0 * math.pi * aspect / (aspect + 2.0) * scale
        value = np.array([0.0, math.log(slope), 0.0, 0.0, math.log(0.2 * slope), 0.0])
        std = np.array([0.5 * slope, 0.5, 0.1 * slope, 1e-6 * slope, 1.0, 0.05 * slope])
        return value, std

    def initial_state(self, u, y, available):
        """Wind triangle with the pitot airspeed (Vaiopoulos 2017, eq. 5.24-5.25): along
        the ground track (zero flow angles), or, with the specific-force relation, at the
        flow angles the first accelerometer sample gives through the coefficient prior
        (within +-15 deg); zero gust, the coefficient prior."""
        R = euler_to_rotmat(u[6:9])
        gps, airspeed, _ = _start_values(np.append(y[:4], [np.nan, np.nan]),
                                         np.append(available[:4], [False, False]),
                                         (0, 1, 2), 3, (4, 5), self.rho)
        prior = self.coefficient_prior()[0]
        angles = None
        if self.lift_relation and available[3] and available[4] and available[5] and y[3] > 0:
            limit = math.radians(15.0)
            c = self.coefficients(prior)
            alpha = (y[5] / y[3] - c[0] - c[2] * u[9]) / c[1]
            beta = (y[4] / y[3] - c[3] - c[5] * u[10]) / c[4]
            angles = np.clip([alpha, beta], -limit, limit)
        v_r, wind = _wind_triangle_start(R, gps, airspeed, angles)
        x = [*v_r, *wind]
        if angles is None:
            x[5] = 0.0  # zero-mean vertical wind
        if self.gust:
            x += [0.0, 0.0]
        if self.lift_relation:
            x += prior.tolist()
        return np.array(x, float)

    def default_noise(self, std: dict[str, float] | None = None,
                      sensors: SensorSuiteParams | None = None, period: float = 0.01,
                      wind_psd: float | None = None) -> EkfNoise:
        """Noise description: sensor stds by filter signal name ``std`` (default those of
        ``sensors``, default Vaiopoulos 2017, Table 7), the wind walk (``wind_psd``
        [m^2/s^3] per axis; default :data:`MEAN_WIND_PSD` with gust states, else the
        light-turbulence :data:`~drake_uav.estimation.noise.WIND_PSD`), the Gauss-Markov
        gust densities ``2 sigma^2 / tau``, the coefficient walk and a loose start."""
        from drake_uav.estimation.noise import WIND_PSD

        std = {**sensor_std(sensors), **(std or {})}
        horizontal = (MEAN_WIND_PSD if self.gust else WIND_PSD["wind_n"]) if (
            wind_psd is None) else wind_psd
        psd = {"wind_n": horizontal, "wind_e": horizontal,
               "wind_d": float(2.0 * self.gust_sigma[2] ** 2 / self.gust_tau[2])}
        initial = {"u_r": 2.0, "v_r": 2.0, "w_r": 2.0, "W_N": 3.0, "W_E": 3.0,
                   "W_D": float(self.gust_sigma[2])}
        if self.gust:
            for i, axis in enumerate("NE"):
                psd[f"gust_{axis.lower()}"] = float(2.0 * self.gust_sigma[i] ** 2
                                                    / self.gust_tau[i])
                initial[f"G_{axis}"] = float(self.gust_sigma[i])
        measurement = {n: std[n] for n in (*GPS_VELOCITY, "pitot")}
        if self.lift_relation:
            value, spread = self.coefficient_prior()
            for name, s in zip(_SPECIFIC_FORCE_COEFFICIENTS, spread, strict=True):
                psd[f"walk_{name}"] = LIFT_COEFFICIENT_WALK
                initial[name] = float(s)
            for axis in "yz":
                measurement[f"a{axis}_meas"] = math.hypot(std[f"a{axis}"],
                                                          SPECIFIC_FORCE_MODEL_STD)
        return EkfNoise(
            process_psd=psd,
            input_std={n: std[n] for n in IMU + ATTITUDE},
            measurement_std=measurement,
            initial_std=initial,
            measurement_input_std=self._attitude_noise(std, period))

    def log_data(self, log: FlightLog, gps_latency: float = DEFAULT_GPS_LATENCY) -> FilterData:
        """Filter arrays of a flight log: measured channels only (no truth); the GPS
        velocity is moved forward by ``gps_latency`` [s]. The commands are shifted one
        sample (the command in effect during the step ending at a sample); the IMU
        samples are not (with ``averaged_imu`` the caller averages them over its steps)."""
        reader = LogReader(log, gps_latency, self.gravity)
        names = [n.removesuffix("_meas") for n in self.measurement_names]
        y, fresh = reader.sensors(names)
        return FilterData(reader.time, reader.inputs(self.input_names, self.command_inputs), y,
                          fresh, None)
