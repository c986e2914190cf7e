"""A noisy measurement of the rigid-body state, as a feedback controller reads it.

Position, velocity and body rates get additive white Gaussian errors; the attitude
gets a small body-frame rotation whose roll, pitch and yaw angles are white
Gaussian (``q_meas = q (x) q(droll, dpitch, dyaw)``), so the measured quaternion
stays a unit quaternion. A full-state estimator in the loop (GNSS/INS or motion
capture) is seen by the controller this way: its errors, without its dynamics.
The normalised samples arrive on an input port, so a Drake ``RandomSource``
(seeded through the root context) or given samples drive it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import RandomSource

from drake_uav.model.multirotor import STATE_SIZE
from drake_uav.model.rotations import euler_to_quat, quat_multiply

__all__ = ["StateNoise", "NoisyStateSensor", "add_noisy_state_sensor"]

NOISE_SIZE = 12
"""Normalised samples per measurement: position, attitude, velocity, rates (3 each)."""


@dataclasses.dataclass(frozen=True)
class StateNoise:
    """Standard deviations of the state measurement errors, per axis."""

    position: float = 0.02
    """[m]"""
    attitude: float = 0.01
    """Roll, pitch and yaw of the error rotation [rad]."""
    velocity: float = 0.05
    """[m/s]"""
    rates: float = 0.02
    """Body rates [rad/s]."""
    period: float = 0.025
    """A fresh error sample every ``period`` [s], held in between (the controller's
    period: one independent error per control step)."""

    def validate(self) -> StateNoise:
        """Raises ``ValueError`` naming the first field that is negative or not finite
        (or a non-positive ``period``)."""
        for field in ("position", "attitude", "velocity", "rates"):
            value = getattr(self, field)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"StateNoise.{field} must be finite and >= 0, got {value}")
        if not (math.isfinite(self.period) and self.period > 0.0):
            raise ValueError(f"StateNoise.period must be positive, got {self.period}")
        return self

    def scales(self) -> np.ndarray:
        """The 12 standard deviations in the order of the noise port."""
        return np.repeat([self.position, self.attitude, self.velocity, self.rates], 3)


class NoisyStateSensor(LeafSystem):
    """The state plus the errors of :class:`StateNoise` (direct feedthrough, no state).

    | port (in)        | size | content                                           |
    |------------------|------|---------------------------------------------------|
    | ``state``        | 13   | plant state: p NED [m], q (w, x, y, z), v NED     |
    |                  |      | [m/s], omega FRD [rad/s]                          |
    | ``noise``        | 12   | N(0, 1) samples (position, attitude, velocity,    |
    |                  |      | rates)                                            |

    | port (out)       | size | content                                           |
    |------------------|------|---------------------------------------------------|
    | ``measured_state`` | 13 | the state with the scaled errors, same units      |
    """

    def __init__(self, noise: StateNoise):
        super().__init__()
        self.noise = noise.validate()
        self._scales = noise.scales()
        self._state = self.DeclareVectorInputPort("state", STATE_SIZE)
        self._noise = self.DeclareVectorInputPort("noise", NOISE_SIZE)
        self.DeclareVectorOutputPort("measured_state", STATE_SIZE, self._measure)

    def measure(self, x, samples) -> np.ndarray:
        """The measured state (13) for the true state ``x`` and N(0, 1) ``samples`` (12)."""
        d = self._scales * np.asarray(samples, dtype=float)
        x = np.asarray(x, dtype=float)
        out = x.copy()
        out[0:3] += d[0:3]
        out[3:7] = quat_multiply(x[3:7], euler_to_quat(d[3:6]))
        out[7:10] += d[6:9]
        out[10:13] += d[9:12]
        return out

    def _measure(self, context, output) -> None:
        output.SetFromVector(self.measure(self._state.Eval(context), self._noise.Eval(context)))


def add_noisy_state_sensor(builder: DiagramBuilder, noise: StateNoise, state_port):
    """Adds a :class:`NoisyStateSensor` on ``state_port`` fed by a Gaussian
    ``RandomSource`` sampled every ``noise.period``; returns its ``measured_state``
    port. Seed it with ``diagram.SetRandomContext(context, RandomGenerator(seed))``."""
    sensor = builder.AddSystem(NoisyStateSensor(noise))
    source = builder.AddSystem(RandomSource(RandomDistribution.kGaussian, NOISE_SIZE,
                                            noise.period))
    builder.Connect(state_port, sensor.GetInputPort("state"))
    builder.Connect(source.get_output_port(), sensor.GetInputPort("noise"))
    return sensor.GetOutputPort("measured_state")
