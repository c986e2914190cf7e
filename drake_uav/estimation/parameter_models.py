"""Augmented-state model of the aerodynamic-derivative filter (Ortiz & Gutierrez 2009, sec. 5),
scalar-generic.

:class:`ParameterModel` holds the decoupled longitudinal ``[V, alpha, q, theta]`` or
lateral ``[beta, p, r, phi, psi]`` motion augmented with the stability derivatives of
that axis (Ortiz & Gutierrez 2009, eq. 42-50). The other axis' variables are measured
inputs. The coefficients are the shared coefficient model
(:class:`~drake_uav.model.coefficients.CoefficientModel`) with the state's derivatives;
their forces and moments enter :class:`~drake_uav.model.fixed_wing.FixedWingModel` as
an external wrench.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from drake_uav.estimation.air_data_models import MIN_START_AIRSPEED
from drake_uav.estimation.ekf import EkfModel, EkfNoise
from drake_uav.estimation.noise import TURBULENT_DERIVATIVE_WALK, gust_rate_psd, sensor_std
from drake_uav.estimation.offline import FilterData, LogReader
from drake_uav.estimation.signals import AIR_DATA, CONTROLS, LOG_CHANNELS, fresh_samples
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import air_data_rates, velocity_from_air_data
from drake_uav.model.coefficients import (
    LATERAL_COEFFICIENTS,
    LONGITUDINAL_COEFFICIENTS,
    AeroCondition,
    CoefficientModel,
    lift_drag_to_body,
    split_derivative_name,
)
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.isolation import differentiate
from drake_uav.model.rotations import euler_rates, euler_to_quat
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["ParameterModel", "LONGITUDINAL_COEFFICIENTS", "LATERAL_COEFFICIENTS"]

_AXES = {
    "longitudinal": dict(
        coefficients=LONGITUDINAL_COEFFICIENTS,
        states=("airspeed", "alpha", "q", "pitch"),
        inputs=("beta", "p", "r", "roll"),
        measurements=("airspeed", "alpha", "q", "pitch", "ax", "az", "q_dot"),
        groups={"air_data": (0, 1), "gyro": (2,), "attitude": (3,),
                "accelerometer": (4, 5), "angular_acceleration": (6,)},
        angles=()),
    "lateral": dict(
        coefficients=LATERAL_COEFFICIENTS,
        states=("beta", "p", "r", "roll", "yaw"),
        inputs=("airspeed", "alpha", "q", "pitch"),
        measurements=("beta", "p", "r", "roll", "yaw", "ay", "p_dot", "r_dot"),
        groups={"air_data": (0,), "gyro": (1, 2), "attitude": (3, 4),
                "accelerometer": (5,), "angular_acceleration": (6, 7)},
        angles=(4,)),
}


def _axis_derivatives(params: FixedWingParams, axis: str, names: Sequence[str] | None
                      ) -> tuple[str, ...]:
    """The derivatives a filter of ``axis`` estimates (default: the aircraft's derivatives
    of the axis' coefficients, without constant terms of the lateral ones)."""
    coefficients = _AXES[axis]["coefficients"]
    if names is None:
        names = [n for n in params.derivatives
                 if split_derivative_name(n)[0] in coefficients
                 and not (axis == "lateral" and n.endswith("_0"))]
    for name in names:
        coefficient, signal = split_derivative_name(name)
        if coefficient not in coefficients:
            raise ValueError(f"names: '{name}' is not a {axis} derivative ({coefficients})")
        if signal == "alphadot":
            raise ValueError(f"names: '{name}': alpha-dot derivatives are not supported")
    return tuple(names)


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

    def __init__(self, params: FixedWingParams, axis: str, names: Sequence[str] | None = None):
        if axis not in _AXES:
            raise ValueError(f"axis must be one of {tuple(_AXES)}, got {axis!r}")
        layout = _AXES[axis]
        self.params, self.axis = params, axis
        self.parameter_names = _axis_derivatives(params, axis, names)
        self.physical_names = layout["states"]
        self.state_names = self.physical_names + self.parameter_names
        self.input_names = layout["inputs"] + CONTROLS
        self.noise_names = self.physical_names + self.parameter_names
        self.measurement_names = layout["measurements"]
        self.groups = layout["groups"]
        self.angle_measurements = layout["angles"]
        self.angle_inputs = (3,) if axis == "longitudinal" else ()
        self.angle_states = (4,) if axis == "lateral" else ()
        self.held_inputs = (4, 5, 6, 7)
        self.aircraft = FixedWingModel(params, aerodynamics=False)
        # Terms of the aircraft model that are not estimated keep their values.
        self._fixed = {name: value for name, value in params.derivatives.items()
                       if name not in self.parameter_names}

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
        model = CoefficientModel({**self._fixed, **dict(zip(self.parameter_names, theta,
                                                            strict=True))})
        return list(model.evaluate(cond, self.params.b, self.params.c))

    def _evaluate(self, x, u):
        airspeed, alpha, beta, p, q, r, roll, pitch, yaw = self._full_condition(x, u)
        CL, CD, CY, Cl, Cm, Cn = self.coefficients(x, u)
        CX, CZ = lift_drag_to_body(CL, CD, alpha)
        wrench = self.aircraft.aerodynamic_wrench(
            [CX, CY, CZ, Cl, Cm, Cn], self.aircraft.dynamic_pressure_area(airspeed))
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
        """Noise of ``sensors`` (default Vaiopoulos 2017, Table 7) and the tuning for steady
        wind or for Dryden ``turbulence`` ("light", "moderate", "severe"; MIL-F-8785C at
        ``altitude`` [m] and ``airspeed`` [m/s]).

        Steady wind (Ortiz & Gutierrez 2009): the physical states get a small process noise
        (1e-6 rad^2/s on angles and air-flow angles, 1e-5 rad^2/s^3 on rates,
        1e-3 m^2/s^3 on V), the derivatives none (constant). Turbulence adds
        the gust rates (:func:`~drake_uav.estimation.noise.gust_rate_psd`) to V and,
        divided by ``airspeed``^2, the lateral and vertical ones to beta and alpha, and
        a slow random walk of the derivatives
        (:data:`~drake_uav.estimation.noise.TURBULENT_DERIVATIVE_WALK`). The pitot's
        airspeed noise is its dynamic-pressure noise at ``airspeed``. Initial
        uncertainty: half of each prior derivative (at least 0.05), 1 m/s, 3 deg and
        3 deg/s on the physical states. Angular accelerations (when supplied) are
        trusted to 0.1 rad/s^2.
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
        angle = math.radians(3.0)
        physical_std = {"airspeed": 1.0, "alpha": angle, "beta": angle, "p": angle, "q": angle,
                        "r": angle, "roll": angle, "pitch": angle, "yaw": angle}
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

        Air data (V [m/s], alpha, beta [rad]) come from the pitot and vanes, or from
        ``air_data`` (N, 3), e.g. an air-data filter's estimate. With
        ``angular_acceleration`` the gyro differentiated by a centred
        Savitzky-Golay filter of ``derivative_window`` seconds is offered as
        the p_dot, q_dot, r_dot measurements; off by default, because the
        smoothing filter's time-correlated errors bias the joint estimate. The
        true state uses the derivatives of ``truth_params`` (when given) and
        the log's truth channels.
        """
        reader = LogReader(log, 0.0, self.params.gravity)
        signals, fresh = {}, {}
        for name in ("ax", "ay", "az", "p", "q", "r", "roll", "pitch", "yaw", *AIR_DATA):
            signals[name] = reader.channel(LOG_CHANNELS[name])
            fresh[name] = fresh_samples(signals[name])
        if air_data is not None:
            air_data = np.asarray(air_data, float)
            for i, name in enumerate(AIR_DATA):
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
