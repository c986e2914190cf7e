"""Multirotor rigid-body plant: a LeafSystem over :mod:`drake_uav.model.multirotor`."""

from __future__ import annotations

import pydrake.math as pm
from pydrake.systems.framework import BasicVector_, LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_uav.model.multirotor import (
    QUATERNION,
    STATE_SIZE,
    motor_wrench,
    multirotor_derivatives,
    produced_thrusts,
    specific_force,
)
from drake_uav.model.rotations import quat_to_euler
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["MultirotorPlant_", "MultirotorPlant"]


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
