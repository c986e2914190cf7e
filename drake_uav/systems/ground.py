"""Flat ground at ``p_d = 0``: touchdown detection that ends the simulation."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    EventStatus,
    LeafSystem,
    UnrestrictedUpdateEvent,
    WitnessFunctionDirection,
)

from drake_uav.model.multirotor import STATE_SIZE

__all__ = ["Ground", "TOUCHDOWN_SIZE"]

TOUCHDOWN_SIZE = 8
"""``touchdown`` output: flag (0/1), time [s], position NED (3) [m], velocity NED (3) [m/s]."""


class Ground(LeafSystem):
    """Flat ground at ``p_d = 0`` (NED): a witness function on ``p_d`` localises the
    touchdown, records it and ends the simulation (``Simulator.AdvanceTo`` returns with
    ``ReachedTerminationCondition``).

    ==============  ====  ==============================================
    Input port      Size  Content [unit]
    ==============  ====  ==============================================
    ``state``       13    vehicle state: p NED [m], q, v NED [m/s], omega
    ==============  ====  ==============================================

    ==============  ====  ==============================================
    Output port     Size  Content [unit]
    ==============  ====  ==============================================
    ``touchdown``   8     1 after touchdown (else 0), its time [s],
                          position NED (3) [m], velocity NED (3) [m/s]
    ==============  ====  ==============================================

    The witness ``p_d`` crosses from negative to non-negative at touchdown; the
    simulator's integrator needs an accuracy (``context.SetAccuracy``) to localise it.
    A vehicle that starts on or below the ground is not detected (no crossing).
    """

    def __init__(self):
        super().__init__()
        self._state = self.DeclareVectorInputPort("state", STATE_SIZE)
        self._record = self.DeclareDiscreteState(np.zeros(TOUCHDOWN_SIZE))
        self.DeclareStateOutputPort("touchdown", self._record)
        self._witness = self.MakeWitnessFunction(
            "touchdown", WitnessFunctionDirection.kNegativeThenNonNegative,
            lambda context: float(self._state.Eval(context)[2]),
            UnrestrictedUpdateEvent(self._touch))

    def DoGetWitnessFunctions(self, context):
        return [self._witness]

    def _touch(self, context, event, state):
        x = self._state.Eval(context)
        record = np.concatenate([[1.0, context.get_time()], x[0:3], x[7:10]])
        state.get_mutable_discrete_state(self._record).SetFromVector(record)
        return EventStatus.ReachedTermination(self, "touchdown")
