"""The fixed-wing aircraft as a Drake plant (13 continuous states).

A thin LeafSystem over :class:`drake_uav.model.FixedWingModel`: the equations of
motion live in the model layer; this module only declares ports and calls them.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import ContinuousStateIndex, LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["FixedWingPlant", "FixedWingPlant_"]

_ZERO_WRENCH = (0.0,) * 6
_ZERO3 = [0.0, 0.0, 0.0]
_ZERO_CONTROLS = [0.0] * 4  # the air data do not depend on the controls


@TemplateSystem.define("FixedWingPlant_")
def FixedWingPlant_(T):
    class Impl(LeafSystem_[T]):
        """Fixed-wing aircraft plant (6-DOF rigid body, stability-derivative aerodynamics).

        ===================  =====  ==============================================
        Input port           size   content [unit]
        ===================  =====  ==============================================
        ``controls``         4      elevator, aileron, rudder [rad], throttle [0..1]
        ``wind_ned``         3      total wind, NED [m/s] (zero when unconnected)
        ``external_wrench``  6      body force [N], body moment [N m] (zero when
                                    unconnected)
        ``wind_rate_ned``    3      rate of the total wind, NED [m/s^2] (zero when
                                    unconnected); read by the alpha-dot terms only
        ===================  =====  ==============================================

        ======================  =====  ===========================================
        Output port             size   content [unit]
        ======================  =====  ===========================================
        ``state``               13     pNED [m], quaternion, uvw [m/s], pqr [rad/s]
        ``air_data``            3      Va [m/s], alpha [rad], beta [rad]
        ``euler``               3      roll, pitch, yaw [rad]
        ``specific_force``      3      accelerometer truth, body [m/s^2]
        ``aero_coefficients``   6      C_X, C_Y, C_Z, C_l, C_m, C_n [-]
        ``forces_moments``      6      total body force [N] and moment [N m]
        ======================  =====  ===========================================

        Controls saturate at the limits of the params. ``state`` and ``euler``
        have no direct feedthrough; ``air_data`` depends on ``wind_ned`` only and
        ``aero_coefficients`` on ``wind_ned``, ``wind_rate_ned`` and ``controls``, so a
        wrench computed from them may close the loop through ``external_wrench``.
        """

        def _construct(self, params: FixedWingParams, model: FixedWingModel | None = None,
                       converter=None):
            LeafSystem_[T].__init__(self, converter)
            self.params = params
            self.model = model if model is not None else FixedWingModel(params)
            # Floats run the compiled model (code per output that computes just that
            # output); AutoDiffXd and Expression the generic one.
            evaluator = self.model.compiled if T is float else self.model
            self._field = {name: evaluator.field(name) for name in (
                "state_derivative", "air_data", "specific_force", "coefficients",
                "forces_moments")}
            self.DeclareContinuousState(13)
            controls = self.DeclareVectorInputPort("controls", 4)
            wind = self.DeclareVectorInputPort("wind_ned", 3)
            wrench = self.DeclareVectorInputPort("external_wrench", 6)
            wind_rate = self.DeclareVectorInputPort("wind_rate_ned", 3)
            self._ports = (controls, wind, wrench, wind_rate)
            state_only = {self.all_state_ticket()}
            air_inputs = {self.all_state_ticket(), self.input_port_ticket(wind.get_index())}
            aero_inputs = air_inputs | {self.input_port_ticket(controls.get_index()),
                                        self.input_port_ticket(wind_rate.get_index())}
            self.DeclareStateOutputPort("state", ContinuousStateIndex(0))
            self.DeclareVectorOutputPort("air_data", 3, self._calc_air_data,
                                         prerequisites_of_calc=air_inputs)
            self.DeclareVectorOutputPort("euler", 3, self._calc_euler,
                                         prerequisites_of_calc=state_only)
            self.DeclareVectorOutputPort("specific_force", 3, self._calc_specific_force)
            self.DeclareVectorOutputPort("aero_coefficients", 6, self._calc_coefficients,
                                         prerequisites_of_calc=aero_inputs)
            self.DeclareVectorOutputPort("forces_moments", 6, self._calc_forces_moments)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other.params, other.model, converter=converter)

        def _state(self, context) -> list:
            vector = context.get_continuous_state_vector()
            # For floats value() is a view of the context's vector (no copy before the list).
            return (vector.value() if T is float else vector.CopyToVector()).tolist()

        def _wind(self, context) -> list:
            wind_port = self._ports[1]
            return wind_port.Eval(context).tolist() if wind_port.HasValue(context) else _ZERO3

        def _arguments(self, context, with_wrench: bool = True) -> tuple:
            """(state, controls, wind, wrench, wind rate) of the context as Python lists;
            zeros for an unconnected wind, wrench or wind rate, and for the wrench when
            ``with_wrench`` is False."""
            controls_port, wind_port, wrench_port, rate_port = self._ports
            vector = context.get_continuous_state_vector()  # as in _state, one call less
            return ((vector.value() if T is float else vector.CopyToVector()).tolist(),
                    controls_port.Eval(context).tolist(),
                    wind_port.Eval(context).tolist() if wind_port.HasValue(context) else _ZERO3,
                    wrench_port.Eval(context).tolist()
                    if with_wrench and wrench_port.HasValue(context) else _ZERO_WRENCH,
                    rate_port.Eval(context).tolist() if rate_port.HasValue(context) else _ZERO3)

        def DoCalcTimeDerivatives(self, context, derivatives):
            # Runs once per integrator stage: one read per port, and the compiled code of
            # the state derivative alone (see docs/performance.md).
            derivatives.SetFromVector(self._field["state_derivative"](*self._arguments(context)))

        def _calc_air_data(self, context, output):
            output.SetFromVector(self._field["air_data"](
                self._state(context), _ZERO_CONTROLS, self._wind(context), _ZERO_WRENCH,
                _ZERO3))

        def _calc_euler(self, context, output):
            output.SetFromVector(self.model.euler(self._state(context)))

        def _calc_specific_force(self, context, output):
            output.SetFromVector(self._field["specific_force"](*self._arguments(context)))

        def _calc_coefficients(self, context, output):
            # Computed without reading the wrench (no feedthrough from it), so a wrench
            # made from the coefficients closes no algebraic loop.
            output.SetFromVector(self._field["coefficients"](
                *self._arguments(context, with_wrench=False)))

        def _calc_forces_moments(self, context, output):
            output.SetFromVector(self._field["forces_moments"](*self._arguments(context)))

        def set_state(self, context, state) -> None:
            """Writes a 13-vector into the plant's continuous state."""
            context.get_mutable_continuous_state_vector().SetFromVector(np.asarray(state))

    return Impl


FixedWingPlant = FixedWingPlant_[None]
"""The default (float) instantiation of :func:`FixedWingPlant_`."""
