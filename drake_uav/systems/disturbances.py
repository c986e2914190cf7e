"""Aerodynamic effects the plant's model lacks, applied as an external wrench.

:class:`AerodynamicIncrement` turns coefficient increments into a body wrench
for the plant's ``external_wrench`` port. It lets a test, a what-if study or a
regression campaign put a physical effect into a simulated flight (stall onset,
propwash drag, rate coupling, ...) without touching the plant's coefficient
model, so that identification has to find it in the data.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_uav.model.coefficients import AeroCondition, lift_drag_to_body
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["AerodynamicIncrement"]

IncrementFunction = Callable[[AeroCondition], tuple] | Callable[[AeroCondition, float], tuple]
"""``f(condition) -> (dCL, dCD, dCY, dCl, dCm, dCn)``, or ``f(condition, t)`` with the
simulation time t [s]; condition fields are floats."""


class AerodynamicIncrement(LeafSystem):
    """Coefficient increments as a body wrench.

    ============  =====  =================================================
    Input port    size   content [unit]
    ============  =====  =================================================
    ``air_data``  3      Va [m/s], alpha, beta [rad] (plant ``air_data``)
    ``state``     13     plant state (body rates are read from it)
    ``controls``  4      elevator, aileron, rudder [rad], throttle [0..1]
    ============  =====  =================================================

    ==========  =====  ==============================================
    Output      size   content [unit]
    ==========  =====  ==============================================
    ``wrench``  6      body force [N], body moment [N m]
    ==========  =====  ==============================================

    ``increment(condition)`` returns ``(dCL, dCD, dCY, dCl, dCm, dCn)``; the
    condition (:meth:`FixedWingModel.aero_condition`) carries the air data,
    body rates, surfaces (saturated as in the plant) and the thrust coefficient of
    the params' propulsion model. An increment with a second required parameter,
    ``increment(condition, t)``, also reads the simulation time t [s] (a derivative
    that drifts over the flight: icing, fuel burn, a loosening surface); the arity is
    read once, here. The wrench is ``qbar S`` times the increments in body axes:
    ``(dC_X, dC_Z)`` from ``(dCL, dCD)`` at alpha, the moments scaled by the span
    (roll, yaw) and the chord (pitch).
    """

    def __init__(self, params: FixedWingParams, increment: IncrementFunction):
        super().__init__()
        self._params = params
        self._model = FixedWingModel(params)
        self._increment = increment
        self._reads_time = _takes_time(increment)
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._state = self.DeclareVectorInputPort("state", 13)
        self._controls = self.DeclareVectorInputPort("controls", 4)
        self.DeclareVectorOutputPort("wrench", 6, self._calc_wrench)

    def _calc_wrench(self, context, output: BasicVector) -> None:
        prm = self._params
        cond = self._model.aero_condition(self._air.Eval(context).tolist(),
                                          self._state.Eval(context)[10:13].tolist(),
                                          self._controls.Eval(context).tolist())
        time = (context.get_time(),) if self._reads_time else ()
        dCL, dCD, dCY, dCl, dCm, dCn = self._increment(cond, *time)
        dCX, dCZ = lift_drag_to_body(dCL, dCD, cond.alpha)
        output.SetFromVector(self._model.dynamic_pressure_area(cond.airspeed) * np.array(
            [dCX, dCY, dCZ, prm.b * dCl, prm.c * dCm, prm.b * dCn]))


def _takes_time(increment: IncrementFunction) -> bool:
    """True when ``increment`` has a second positional parameter without a default (the
    time [s]); ``lambda c, k=k: ...`` closures read the condition only."""
    required = [p for p in inspect.signature(increment).parameters.values()
                if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
                and p.default is p.empty]
    return len(required) >= 2
