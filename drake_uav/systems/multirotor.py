"""Multirotor rigid-body plant with motor limits, motor faults and optional motor lag.

Model of seed S2 eq. 1.1 written in NED / FRD (thrust along ``-z_b``)::

    p_dot     = v
    v_dot     = R(q) f_b / m + [0, 0, g] + f_ext / m,   f_b = [0, 0, -F] - D R(q)^T v
    q_dot     = 0.5 q (x) [0, omega]
    omega_dot = J^-1 (tau + tau_ext - omega x J omega)

with ``[F, tau] = A diag(h) sat(f)`` (allocation from the frame geometry, health
``h`` in [0, 1] per motor, thrusts saturated to ``[0, f_max]``) and ``D`` the
optional linear rotor drag. With a motor time constant ``T_m > 0`` the produced
thrusts become states: ``f_dot = (sat(u) - f) / T_m``.

The equations live in plain functions that accept float, ``AutoDiffXd`` and
``symbolic.Expression`` entries; the plant, linearisation and the flatness
module all call them.
"""

from __future__ import annotations

import numpy as np
import pydrake.math as pm
from pydrake.systems.framework import BasicVector_, LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_uav.rotations import quat_derivative, quat_to_euler, quat_to_rotmat
from drake_uav.scalar import as_list, clamp
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "STATE_SIZE",
    "POSITION",
    "QUATERNION",
    "VELOCITY",
    "BODY_RATES",
    "produced_thrusts",
    "motor_wrench",
    "multirotor_dynamics",
    "multirotor_derivatives",
    "specific_force",
    "MultirotorPlant_",
    "MultirotorPlant",
]

STATE_SIZE = 13
"""Rigid-body state size: position (3), quaternion (4), velocity (3), body rates (3)."""
POSITION = slice(0, 3)
"""NED position [m]."""
QUATERNION = slice(3, 7)
"""Unit quaternion (w, x, y, z), body FRD -> NED."""
VELOCITY = slice(7, 10)
"""NED velocity [m/s]."""
BODY_RATES = slice(10, 13)
"""Body rates (p, q, r) in FRD [rad/s]."""


def _limit(values, low: float, high: float) -> np.ndarray:
    """Entry-wise clamp to ``[low, high]``; float arrays take numpy's vectorised path."""
    a = np.asarray(values)
    if a.dtype == float:
        return np.minimum(np.maximum(a, low), high)
    return np.array([clamp(v, low, high) for v in a])


def produced_thrusts(x, commands, params: MultirotorParams, health=None) -> np.ndarray:
    """Thrust each motor produces [N]: saturated command (or lag state) times health.

    ``x`` is the plant state (13, or 13 + n with motor lag, whose last n entries
    are the produced thrusts of healthy motors); ``commands`` the n thrust
    commands [N]; ``health`` n values in [0, 1] (None: all healthy).
    """
    if params.motor_time_constant > 0:
        thrust = np.asarray(x)[STATE_SIZE:STATE_SIZE + params.num_motors]
    else:
        thrust = _limit(commands, 0.0, params.f_max)
    if health is not None:
        thrust = thrust * _limit(health, 0.0, 1.0)
    return thrust


def motor_wrench(thrusts, params: MultirotorParams) -> np.ndarray:
    """``[F, tau_x, tau_y, tau_z]`` [N, N m] of produced motor thrusts (allocation A f)."""
    f = np.asarray(thrusts)
    A = params.allocation_matrix
    if f.dtype == float:
        return A @ f
    # numpy's object matmul raises floating-point flags on symbolic entries.
    return np.array([sum(a * fi for a, fi in zip(row, f, strict=True)) for row in A.tolist()])


def _rotation(q) -> tuple[list, object]:
    """``R(q)`` as nested lists and ``1/|q|^2``: ``R(q)/|q|^2`` is the rotation of ``q/|q|``."""
    return (quat_to_rotmat(q).tolist(),
            1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]))


def _body_force(R, scale, v, thrust, params: MultirotorParams) -> list:
    """Thrust plus rotor drag in body FRD [N] (``R``, ``scale`` from :func:`_rotation`)."""
    dx, dy, dz = params.rotor_drag
    vb = [(R[0][k] * v[0] + R[1][k] * v[1] + R[2][k] * v[2]) * scale for k in range(3)]
    return [-dx * vb[0], -dy * vb[1], -thrust - dz * vb[2]]


def _matvec(M, v) -> list:
    return [M[0][0] * v[0] + M[0][1] * v[1] + M[0][2] * v[2],
            M[1][0] * v[0] + M[1][1] * v[1] + M[1][2] * v[2],
            M[2][0] * v[0] + M[2][1] * v[1] + M[2][2] * v[2]]


def multirotor_dynamics(x, wrench, params: MultirotorParams, external_wrench=None,
                        quaternion_stabilization: float = 1.0) -> np.ndarray:
    """Rigid-body state derivative (13) for a body wrench.

    ``x``: state (13) [m, -, m/s, rad/s]; ``wrench``: ``[F, tau_x, tau_y, tau_z]``
    with ``F`` the thrust along ``-z_b`` [N] and torques in FRD [N m];
    ``external_wrench``: ``[f_N, f_E, f_D]`` NED force [N] then body FRD torque
    [N m] (None: zero). ``quaternion_stabilization`` [1/s] pulls ``|q|`` to 1.
    """
    x = as_list(x)
    F, tx, ty, tz = as_list(wrench)
    q, v, w = x[3:7], x[7:10], x[10:13]
    R, scale = _rotation(q)
    k = scale / params.mass
    if params.rotor_drag == (0.0, 0.0, 0.0):  # thrust only: -F times the body z axis
        acc = [-F * k * R[0][2], -F * k * R[1][2], params.gravity - F * k * R[2][2]]
    else:
        acc = _matvec(R, _body_force(R, scale, v, F, params))
        acc = [acc[0] * k, acc[1] * k, acc[2] * k + params.gravity]
    if external_wrench is not None:
        e = as_list(external_wrench)
        inv_m = 1.0 / params.mass
        acc = [acc[0] + e[0] * inv_m, acc[1] + e[1] * inv_m, acc[2] + e[2] * inv_m]
        tx, ty, tz = tx + e[3], ty + e[4], tz + e[5]
    Jx, Jy, Jz = params.inertia
    principal = params.inertia_products == (0.0, 0.0, 0.0)
    Jw = [Jx * w[0], Jy * w[1], Jz * w[2]] if principal else \
        _matvec(params.inertia_matrix.tolist(), w)
    net = [tx - (w[1] * Jw[2] - w[2] * Jw[1]),
           ty - (w[2] * Jw[0] - w[0] * Jw[2]),
           tz - (w[0] * Jw[1] - w[1] * Jw[0])]
    w_dot = [net[0] / Jx, net[1] / Jy, net[2] / Jz] if principal else \
        _matvec(params.inertia_inverse.tolist(), net)
    q_dot = quat_derivative(q, w, quaternion_stabilization).tolist()
    return np.array(v + q_dot + acc + w_dot)


def multirotor_derivatives(x, commands, params: MultirotorParams, health=None,
                           external_wrench=None,
                           quaternion_stabilization: float = 1.0) -> np.ndarray:
    """Full plant state derivative: rigid body (13) plus motor lag states (n) if any.

    ``commands``: n motor thrust commands [N]; see :func:`produced_thrusts` and
    :func:`multirotor_dynamics` for the other arguments.
    """
    wrench = motor_wrench(produced_thrusts(x, commands, params, health), params)
    xdot = multirotor_dynamics(x, wrench, params, external_wrench, quaternion_stabilization)
    if params.motor_time_constant <= 0:
        return xdot
    lag = (_limit(commands, 0.0, params.f_max) - np.asarray(x)[STATE_SIZE:]) \
        / params.motor_time_constant
    return np.concatenate([xdot, lag])


def specific_force(x, wrench, params: MultirotorParams, external_wrench=None) -> np.ndarray:
    """Accelerometer reading in body FRD [m/s^2]: non-gravitational force / mass."""
    x = as_list(x)
    R, scale = _rotation(x[3:7])
    fb = _body_force(R, scale, x[7:10], as_list(wrench)[0], params)
    if external_wrench is not None:
        e = as_list(external_wrench)
        fb = [fb[k] + (R[0][k] * e[0] + R[1][k] * e[1] + R[2][k] * e[2]) * scale
              for k in range(3)]
    return np.array(fb) / params.mass


@TemplateSystem.define("MultirotorPlant_")
def MultirotorPlant_(T):
    class Impl(LeafSystem_[T]):
        """Multirotor with saturated, possibly failed and lagged motors.

        ========================  ======  =========================================
        Input port                Size    Content [unit]
        ========================  ======  =========================================
        ``motor_thrusts``         n       thrust commands, saturated to [0, f_max] [N]
        ``motor_health``          n       1 healthy, 0 failed, between: partial [-];
                                          all ones when unconnected
        ``external_wrench``       6       force NED [N], then torque FRD [N m];
                                          zero when unconnected
        ========================  ======  =========================================

        ========================  ======  =========================================
        Output port               Size    Content [unit]
        ========================  ======  =========================================
        ``state``                 13      p_NED [m], q (w,x,y,z), v_NED [m/s],
                                          omega FRD [rad/s]
        ``euler``                 3       roll, pitch, yaw [rad]
        ``specific_force``        3       accelerometer reading, FRD [m/s^2]
        ``wrench``                4       total thrust along -z_b [N], torques [N m]
        ``rotor_thrusts``         n       thrust each motor produces [N]
        ========================  ======  =========================================

        The continuous state is the 13 rigid-body states, followed by the n
        produced thrusts when ``params.motor_time_constant > 0`` (the ``state``
        output always holds the first 13). The default
        state is at rest at the origin, level, with the motors at hover thrust.
        """

        def _construct(self, params: MultirotorParams, quaternion_stabilization: float = 1.0,
                       converter=None):
            LeafSystem_[T].__init__(self, converter)
            params.validate()
            self.params = params
            self.quaternion_stabilization = float(quaternion_stabilization)
            n = params.num_motors
            self._has_lag = params.motor_time_constant > 0
            x0 = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            if self._has_lag:
                x0 += list(params.thrusts_for_wrench([params.weight, 0.0, 0.0, 0.0]))
            state_index = self.DeclareContinuousState(BasicVector_[T](x0))
            self._commands = self.DeclareVectorInputPort("motor_thrusts", n)
            self._health = self.DeclareVectorInputPort("motor_health", n)
            self._external = self.DeclareVectorInputPort("external_wrench", 6)
            state_only = {self.all_state_ticket()}
            motor_deps = (
                {self.all_state_ticket(), self._health.ticket()} if self._has_lag else
                {self._commands.ticket(), self._health.ticket()}
            )
            if self._has_lag:
                self.DeclareVectorOutputPort("state", STATE_SIZE, self._calc_state,
                                             prerequisites_of_calc=state_only)
            else:  # the whole continuous state, served without a Python call
                self.DeclareStateOutputPort("state", state_index)
            self.DeclareVectorOutputPort("euler", 3, self._calc_euler,
                                         prerequisites_of_calc=state_only)
            self.DeclareVectorOutputPort(
                "specific_force", 3, self._calc_specific_force,
                prerequisites_of_calc=motor_deps | {self.all_state_ticket(),
                                                    self._external.ticket()})
            self.DeclareVectorOutputPort("wrench", 4, self._calc_wrench,
                                         prerequisites_of_calc=motor_deps)
            self.DeclareVectorOutputPort("rotor_thrusts", n, self._calc_rotor_thrusts,
                                         prerequisites_of_calc=motor_deps)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other.params, other.quaternion_stabilization,
                            converter=converter)

        def _inputs(self, context, need_commands: bool):
            x = context.get_continuous_state_vector().CopyToVector()
            commands = self._commands.Eval(context) if need_commands else None
            health = self._health.Eval(context) if self._health.HasValue(context) else None
            external = (self._external.Eval(context) if self._external.HasValue(context)
                        else None)
            return x, commands, health, external

        def _produced(self, context):
            x, commands, health, _ = self._inputs(context, not self._has_lag)
            return produced_thrusts(x, commands, self.params, health)

        def DoCalcTimeDerivatives(self, context, derivatives):
            health, external = self._health, self._external
            derivatives.SetFromVector(multirotor_derivatives(
                context.get_continuous_state_vector().CopyToVector(),
                self._commands.Eval(context), self.params,
                health.Eval(context) if health.HasValue(context) else None,
                external.Eval(context) if external.HasValue(context) else None,
                self.quaternion_stabilization))

        def _calc_state(self, context, output):
            x = context.get_continuous_state_vector().CopyToVector()
            output.SetFromVector(x[:STATE_SIZE])

        def _calc_euler(self, context, output):
            q = context.get_continuous_state_vector().CopyToVector()[QUATERNION]
            output.SetFromVector(quat_to_euler(q / pm.sqrt(q @ q)))

        def _calc_specific_force(self, context, output):
            x, commands, health, external = self._inputs(context, not self._has_lag)
            wrench = motor_wrench(produced_thrusts(x, commands, self.params, health),
                                  self.params)
            output.SetFromVector(specific_force(x, wrench, self.params, external))

        def _calc_wrench(self, context, output):
            output.SetFromVector(motor_wrench(self._produced(context), self.params))

        def _calc_rotor_thrusts(self, context, output):
            output.SetFromVector(self._produced(context))

    return Impl


MultirotorPlant = MultirotorPlant_[None]
"""Double-valued :class:`MultirotorPlant_` (``MultirotorPlant(params)``)."""
