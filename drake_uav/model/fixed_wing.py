"""Six-degree-of-freedom fixed-wing equations of motion, scalar-generic.

:class:`FixedWingModel` holds the equations once (Vaiopoulos 2017, ch. 3; Ortiz &
Gutierrez 2009, sec. 2, with the corrections listed in ``docs/references.md``)
for float, AutoDiffXd and symbolic Expression; the plant, the trim solver, the
estimators and the identifiers all call it. :class:`CompiledFixedWingModel` is
the same model as generated code for floats, per sample or over a whole log.

State (13): ``[pN, pE, pD, qw, qx, qy, qz, u, v, w, p, q, r]``: NED position
[m], body->NED unit quaternion, ground-relative body velocity [m/s], body rates
[rad/s]. The aerodynamics see the air-relative velocity
``v_r = v - R^T W_ned`` (steady wind plus gust); the alpha-dot terms see its rate,
``d v_r / dt = F / m + g - omega x v_r - R^T dW_ned/dt``, with the wind's rate
``dW_ned/dt`` an input (zero: the wind taken constant over the instant).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.model.coefficients import AeroCondition, CoefficientModel, lift_drag_to_body
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.rotations import (
    quat_derivative,
    quat_to_euler,
    rotate_back,
    unit_quat_rotation,
)
from drake_uav.model.scalar import as_list, clamp, smax

if TYPE_CHECKING:  # parameters are duck-typed: the model layer sits below vehicles
    from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["STATE_NAMES", "CONTROL_NAMES", "FixedWingModel", "FixedWingEvaluation",
           "CompiledFixedWingModel", "body_gravity", "body_velocity_rate"]

STATE_NAMES = ("pN", "pE", "pD", "qw", "qx", "qy", "qz", "u", "v", "w", "p", "q", "r")
"""Names of the 13 state entries, in order."""
CONTROL_NAMES = ("elevator", "aileron", "rudder", "throttle")
"""Names of the 4 control inputs, in order."""

QUATERNION_STABILIZATION = 1.0
"""Gain [1/s] of the term that keeps the integrated quaternion at unit norm."""


def body_gravity(R, g) -> tuple:
    """Gravity per unit mass in body axes, ``g R^T e_down`` [m/s^2]: ``g`` [m/s^2] times the
    third row of the body -> NED rotation rows ``R`` (Vaiopoulos 2017, eq. 3.20)."""
    return (g * R[2][0], g * R[2][1], g * R[2][2])


def body_velocity_rate(v, omega, accel) -> list:
    """Rate [m/s^2] of a body-axis velocity ``v`` [m/s] on a frame turning at the body rates
    ``omega`` [rad/s]: ``accel - omega x v``, with ``accel`` the specific force plus
    gravity in body axes [m/s^2] (the translational equations of Vaiopoulos 2017, ch. 3)."""
    p, q, r = omega[0], omega[1], omega[2]
    return [r * v[1] - q * v[2] + accel[0], p * v[2] - r * v[0] + accel[1],
            q * v[0] - p * v[1] + accel[2]]


class FixedWingEvaluation(NamedTuple):
    """Everything the model computes at one (state, input) point."""

    state_derivative: np.ndarray
    """d(state)/dt (13)."""
    air_data: np.ndarray
    """[Va (m/s), alpha (rad), beta (rad)]."""
    coefficients: np.ndarray
    """Body-axis aerodynamic coefficients [C_X, C_Y, C_Z, C_l, C_m, C_n]."""
    forces_moments: np.ndarray
    """Total body force [N] (gravity included) and moment [N m] (6)."""
    specific_force: np.ndarray
    """Non-gravitational force per unit mass, body axes [m/s^2] (accelerometer truth)."""
    thrust: Any
    """Propeller thrust [N]."""


@dataclasses.dataclass(frozen=True)
class FixedWingModel:
    """Equations of motion of one aircraft; works for any Drake scalar type.

    ``aerodynamics``, ``propulsion`` and ``gravity`` switch the corresponding
    force groups off for verification runs (e.g. torque-free tumbling).
    """

    params: FixedWingParams
    aerodynamics: bool = True
    propulsion: bool = True
    gravity: bool = True

    def __post_init__(self):
        p = self.params
        gamma = p.Jx * p.Jz - p.Jxz**2
        object.__setattr__(self, "coefficient_model", CoefficientModel(p.derivatives))
        object.__setattr__(
            self,
            "_gamma",
            (
                p.Jxz * (p.Jx - p.Jy + p.Jz) / gamma,  # Gamma1
                (p.Jz * (p.Jz - p.Jy) + p.Jxz**2) / gamma,  # Gamma2
                p.Jz / gamma,  # Gamma3
                p.Jxz / gamma,  # Gamma4
                (p.Jz - p.Jx) / p.Jy,  # Gamma5
                p.Jxz / p.Jy,  # Gamma6
                (p.Jx * (p.Jx - p.Jy) + p.Jxz**2) / gamma,  # Gamma7 (corrected)
                p.Jx / gamma,  # Gamma8
            ),
        )
        limits = p.limits
        object.__setattr__(self, "_lower", tuple(limits.lower()))
        object.__setattr__(self, "_upper", tuple(limits.upper()))

    def saturate(self, controls) -> list:
        """Controls clipped to the actuator limits of the params."""
        lower, upper = self._lower, self._upper
        if all(isinstance(u, float) for u in controls):
            return [min(max(controls[i], lower[i]), upper[i]) for i in range(4)]
        return [clamp(controls[i], lower[i], upper[i]) for i in range(4)]

    def thrust(self, airspeed, throttle) -> tuple:
        """Propeller thrust [N] and reaction torque [N m] of the params' propulsion model."""
        return self.params.propulsion.thrust_torque(airspeed, throttle, self.params.rho)

    def dynamic_pressure_area(self, airspeed):
        """Dynamic pressure times wing area, qbar S = rho Va^2 S / 2 [N]."""
        return 0.5 * self.params.rho * airspeed * airspeed * self.params.S

    def thrust_coefficient(self, thrust, airspeed):
        """T / (qbar S) [-] (qbar S floored at 1e-9 N)."""
        return thrust / smax(self.dynamic_pressure_area(airspeed), 1e-9)

    def aero_condition(self, air_data, omega, controls) -> AeroCondition:
        """The aerodynamic condition at air data [Va (m/s), alpha, beta (rad)], body rates
        [rad/s] and controls (saturated; thrust coefficient from the propulsion model)."""
        airspeed = air_data[0]
        elevator, aileron, rudder, throttle = self.saturate(controls)
        thrust = self.thrust(airspeed, throttle)[0] if self.propulsion else 0.0 * airspeed
        return self._condition(air_data, omega, (elevator, aileron, rudder), thrust)

    def _condition(self, air_data, omega, surfaces, thrust) -> AeroCondition:
        """AeroCondition of saturated surfaces [rad] and a thrust [N]."""
        return AeroCondition(
            airspeed=air_data[0], alpha=air_data[1], beta=air_data[2], p=omega[0], q=omega[1],
            r=omega[2], elevator=surfaces[0], aileron=surfaces[1], rudder=surfaces[2],
            thrust_coefficient=self.thrust_coefficient(thrust, air_data[0]),
        )

    def angular_acceleration(self, omega, moment) -> list:
        """Body angular acceleration [rad/s^2] from J w_dot = M - w x J w (Gamma form)."""
        g1, g2, g3, g4, g5, g6, g7, g8 = self._gamma
        p, q, r = omega[0], omega[1], omega[2]
        l, m, n = moment[0], moment[1], moment[2]
        return [
            g1 * p * q - g2 * q * r + g3 * l + g4 * n,
            g5 * p * r - g6 * (p * p - r * r) + m / self.params.Jy,
            g7 * p * q - g1 * q * r + g4 * l + g8 * n,
        ]

    @staticmethod
    def _relative_velocity(x, R, wind_ned) -> tuple:
        """Air-relative body velocity v - R^T W [m/s]."""
        wind_body = rotate_back(R, wind_ned)
        return tuple(x[7 + i] - wind_body[i] for i in range(3))

    def air_data(self, x, wind_ned=(0.0, 0.0, 0.0)) -> np.ndarray:
        """[Va (m/s), alpha (rad), beta (rad)] of state ``x`` in the wind ``wind_ned``."""
        x, wind_ned = as_list(x), as_list(wind_ned)
        return np.array(air_data_from_velocity(
            *self._relative_velocity(x, unit_quat_rotation(x[3:7]), wind_ned)))

    def evaluate(self, x, controls, wind_ned=(0.0, 0.0, 0.0), wrench=None,
                 wind_rate_ned=(0.0, 0.0, 0.0)) -> FixedWingEvaluation:
        """Evaluates the model at state ``x`` (13) and controls (4).

        ``wind_ned`` is the total wind [m/s]; ``wrench`` an external body force
        [N] and moment [N m] (6) or ``None``; ``wind_rate_ned`` the wind's rate of
        change [m/s^2], which only the alpha-dot terms read (a gust changes alpha).
        """
        prm = self.params
        x, controls, wind_ned = as_list(x), as_list(controls), as_list(wind_ned)
        R = unit_quat_rotation(x[3:7])  # Argyropoulos 2020, eq. A.55, normalised
        u, v, w = x[7], x[8], x[9]
        omega = (x[10], x[11], x[12])
        v_rel = self._relative_velocity(x, R, wind_ned)
        air_data = air_data_from_velocity(*v_rel)
        elevator, aileron, rudder, throttle = self.saturate(controls)
        force, moment, thrust = self._propulsion_and_wrench(air_data[0], throttle, wrench, 0.0 * u)

        gravity_body = body_gravity(R, prm.gravity if self.gravity else 0.0)
        coefficients = [0.0 * u] * 6
        if self.aerodynamics:
            coefficients, force, moment = self._aerodynamics(
                air_data, omega, (elevator, aileron, rudder), thrust, (force, moment),
                gravity_body, v_rel, (R, wind_rate_ned))

        m = prm.mass
        specific_force = [force[0] / m, force[1] / m, force[2] / m]
        accel = [specific_force[i] + gravity_body[i] for i in range(3)]
        v_dot = body_velocity_rate((u, v, w), omega, accel)
        omega_dot = self.angular_acceleration(omega, moment)
        p_dot = [R[i][0] * u + R[i][1] * v + R[i][2] * w for i in range(3)]
        q_dot = quat_derivative(x[3:7], omega, QUATERNION_STABILIZATION)
        xdot = np.array([*p_dot, *q_dot, *v_dot, *omega_dot])
        total_force = [force[i] + m * gravity_body[i] for i in range(3)]
        return FixedWingEvaluation(
            state_derivative=xdot,
            air_data=np.array(air_data),
            coefficients=np.array(coefficients),
            forces_moments=np.array([*total_force, *moment]),
            specific_force=np.array(specific_force),
            thrust=thrust,
        )

    def _propulsion_and_wrench(self, airspeed, throttle, wrench, zero) -> tuple:
        """Body force [N] and moment [N m] of the propeller and the external wrench (or
        None), and the thrust [N]; ``zero`` is the zero of the scalar type."""
        force, moment, thrust = [zero, zero, zero], [zero, zero, zero], zero
        if self.propulsion:
            thrust, torque = self.thrust(airspeed, throttle)
            force[0] = force[0] + thrust
            moment[0] = moment[0] + torque
        if wrench is not None:
            wrench = as_list(wrench)
            force = [force[i] + wrench[i] for i in range(3)]
            moment = [moment[i] + wrench[3 + i] for i in range(3)]
        return force, moment, thrust

    def _aerodynamics(self, air_data, omega, surfaces, thrust, force_moment, gravity_body,
                      v_rel, wind_rate) -> tuple:
        """Body-axis coefficients [C_X, C_Y, C_Z, C_l, C_m, C_n] and the body force [N] and
        moment [N m] of ``force_moment`` with the aerodynamic ones added; ``wind_rate`` is
        (R, the wind's rate NED), read by the alpha-dot terms only."""
        prm, model = self.params, self.coefficient_model
        force, moment = force_moment
        q_bar_s = self.dynamic_pressure_area(air_data[0])
        cond = self._condition(air_data, omega, surfaces, thrust)
        CL, CD, CY, Cl, Cm, Cn = model.evaluate(cond, prm.b, prm.c)
        CX, CZ = lift_drag_to_body(CL, CD, air_data[1])
        coefficients = [CX, CY, CZ, Cl, Cm, Cn]
        if model.has_alphadot:
            coefficients = self._add_alphadot_terms(
                coefficients, cond, force, gravity_body, omega, v_rel,
                rotate_back(wind_rate[0], as_list(wind_rate[1])), q_bar_s)
        aero = self.aerodynamic_wrench(coefficients, q_bar_s)
        force = [force[i] + aero[i] for i in range(3)]
        moment = [moment[i] + aero[3 + i] for i in range(3)]
        return coefficients, force, moment

    def aerodynamic_wrench(self, coefficients, q_bar_s) -> list:
        """Body force [N] and moment [N m] of the body-axis coefficients
        ``[C_X, C_Y, C_Z, C_l, C_m, C_n]`` at dynamic pressure times wing area ``q_bar_s``
        [N] (moments scaled by the span, chord, span)."""
        b, c = self.params.b, self.params.c
        return [q_bar_s * coefficients[0], q_bar_s * coefficients[1], q_bar_s * coefficients[2],
                q_bar_s * b * coefficients[3], q_bar_s * c * coefficients[4],
                q_bar_s * b * coefficients[5]]

    def _add_alphadot_terms(self, coefficients, cond, force, gravity_body, omega, v_rel,
                            wind_rate_body, q_bar_s):
        """Adds alpha-dot terms, solving alpha_dot = f(v_dot(alpha_dot)) exactly.

        alpha_dot enters the X/Z forces linearly, so the implicit equation is
        linear; alpha_dot is the air-relative one, with the wind's rate
        ``wind_rate_body`` [m/s^2] (a gust moves alpha without moving the aircraft).
        """
        prm, model = self.params, self.coefficient_model
        u_r, v_r, w_r = v_rel
        p, q, r = omega
        m = prm.mass
        # Air-relative acceleration without the alpha-dot terms
        # (d/dt v_r = F/m + g - omega x v_r - R^T dW/dt).
        base = [(force[i] + q_bar_s * coefficients[i]) / m + gravity_body[i] - wind_rate_body[i]
                for i in (0, 2)]
        base_x = base[0] + r * v_r - q * w_r
        base_z = base[1] + q * u_r - p * v_r
        cl_a = model.alphadot_sensitivity("CL", cond.airspeed, prm.c)
        cd_a = model.alphadot_sensitivity("CD", cond.airspeed, prm.c)
        cx_a, cz_a = lift_drag_to_body(cl_a, cd_a, cond.alpha)
        denom = u_r * u_r + w_r * w_r
        gain = (u_r * q_bar_s * cz_a - w_r * q_bar_s * cx_a) / (m * denom)
        alpha_dot = (u_r * base_z - w_r * base_x) / denom / (1.0 - gain)
        cm_a = model.alphadot_sensitivity("Cm", cond.airspeed, prm.c)
        return [coefficients[0] + cx_a * alpha_dot, coefficients[1],
                coefficients[2] + cz_a * alpha_dot, coefficients[3],
                coefficients[4] + cm_a * alpha_dot, coefficients[5]]

    def field(self, name: str) -> Callable:
        """``f(x, controls, wind_ned, wrench, wind_rate_ned) -> ndarray``: one field of
        :meth:`evaluate` (the interface of :meth:`CompiledFixedWingModel.field`, any
        scalar type)."""
        if name not in FixedWingEvaluation._fields or name == "thrust":
            raise ValueError(f"name: no vector field {name!r} of FixedWingEvaluation")
        return lambda x, controls, wind_ned, wrench, wind_rate_ned: getattr(
            self.evaluate(x, controls, wind_ned, wrench, wind_rate_ned), name)

    def euler(self, x) -> np.ndarray:
        """Roll, pitch, yaw [rad] of a state."""
        return quat_to_euler(x[3:7])

    @functools.cached_property
    def compiled(self) -> CompiledFixedWingModel:
        """:meth:`evaluate` compiled for floats (traced on first use; models with equal
        parameters and switches share one compilation)."""
        key = repr(self)
        compiled = _COMPILED.pop(key, None) or CompiledFixedWingModel(self)
        _COMPILED[key] = compiled  # most recently used last
        while len(_COMPILED) > _COMPILED_KEPT:
            del _COMPILED[next(iter(_COMPILED))]
        return compiled


_COMPILED: dict[str, CompiledFixedWingModel] = {}
"""Compiled models by ``repr(FixedWingModel)``, least recently used first. The repr of the
frozen dataclasses spells every parameter and switch exactly (floats round-trip), and the
parameters hold mappings, so they have no hash of their own."""
_COMPILED_KEPT = 32


# Layout of the flat vector a compiled model returns: FixedWingEvaluation field -> size.
_EVALUATION_LAYOUT = (("state_derivative", 13), ("air_data", 3), ("coefficients", 6),
                      ("forces_moments", 6), ("specific_force", 3), ("thrust", 1))


class CompiledFixedWingModel:
    """:meth:`FixedWingModel.evaluate` as generated straight-line code (floats only).

    The model is traced once with symbolic inputs (state 13, controls 4, wind
    NED 3, external wrench 6, wind rate NED 3) and written by :class:`~drake_uav.compiled.
    CompiledFunction`: the same equations, about 5x faster per float sample than
    :meth:`FixedWingModel.evaluate` (docs/codegen.md), and vectorised over a whole log
    by :meth:`evaluate_batch`.
    """

    def __init__(self, model: FixedWingModel):
        self.model = model

        def flat(x, controls, wind_ned, wrench, wind_rate_ned):
            evaluation = model.evaluate(x, controls, wind_ned, wrench, wind_rate_ned)
            values = []
            for name, size in _EVALUATION_LAYOUT:
                field = getattr(evaluation, name)
                values.extend(field if size > 1 else [field])
            return values

        self._function = CompiledFunction(flat, (13, 4, 3, 6, 3), name=f"{model.params.name} model")
        bounds, start = {}, 0
        for field, size in _EVALUATION_LAYOUT:
            bounds[field] = (start, start + size)
            start += size
        self._bounds = bounds
        self._fields: dict[str, Callable] = {}

    def field(self, name: str) -> Callable:
        """``f(x, controls, wind_ned, wrench, wind_rate_ned) -> ndarray``: one field of
        :class:`FixedWingEvaluation` for one sample given as Python lists of floats (the
        wrench and wind rate too: zeros for none), from code that computes just that field
        (same trace). The generated code itself, without a wrapper: the plant calls it at
        every integrator stage."""
        if name not in self._fields:
            if name not in self._bounds or name == "thrust":
                raise ValueError(f"name: no vector field {name!r}; use one of "
                                 f"{[f for f in self._bounds if f != 'thrust']}")
            self._fields[name] = self._function.restricted(
                range(*self._bounds[name]), name=f"{self.model.params.name} {name}").program
        return self._fields[name]

    def evaluate(self, x, controls, wind_ned=(0.0, 0.0, 0.0), wrench=None,
                 wind_rate_ned=(0.0, 0.0, 0.0)) -> FixedWingEvaluation:
        """:meth:`FixedWingModel.evaluate` for one sample of floats."""
        flat = self._function.value(x, controls, wind_ned, _ZERO_WRENCH if wrench is None
                                    else wrench, wind_rate_ned)
        return self._split(flat)

    def evaluate_batch(self, x, controls, wind_ned, wrench=None, wind_rate_ned=None
                       ) -> FixedWingEvaluation:
        """The model at N samples: arguments (N, 13), (N, 4), (N, 3), (N, 6) or None,
        (N, 3) or None; every field of the result gets a leading axis N (``thrust`` is
        (N,))."""
        x = np.asarray(x, float)
        wrench = np.zeros((len(x), 6)) if wrench is None else wrench
        wind_rate_ned = np.zeros((len(x), 3)) if wind_rate_ned is None else wind_rate_ned
        return self._split(self._function.batch_value(x, controls, wind_ned, wrench,
                                                      wind_rate_ned))

    def _split(self, flat: np.ndarray) -> FixedWingEvaluation:
        return FixedWingEvaluation(*(flat[..., a:b] if b - a > 1 else flat[..., a]
                                     for a, b in self._bounds.values()))


_ZERO_WRENCH = (0.0,) * 6


