"""The safety pilot of an identification flight: weak hold loops around a trim condition.

Added on top of trim + excitation so that long identification flights stay near the
trim condition (open loop, the phugoid and the spiral mode carry a small aircraft far
from it within minutes). The loops are weak so that most of the surface motion is the
designed excitation.
"""

from __future__ import annotations

import dataclasses
import math

from pydrake.systems.framework import LeafSystem

from drake_uav.model.rotations import quat_to_euler

__all__ = ["SafetyPilotGains", "SafetyPilot"]


@dataclasses.dataclass(frozen=True)
class SafetyPilotGains:
    """Gains of the weak hold loops (Aerosonde-sized defaults). Positive elevator
    pitches the nose down."""

    pitch: float = 0.8
    """Elevator per pitch error [rad/rad]."""
    pitch_rate: float = 0.1
    """Elevator per pitch rate [rad/(rad/s)]."""
    altitude: float = 0.005
    """Pitch reference per altitude error [rad/m], limited to +-``max_pitch``."""
    roll: float = 0.5
    """Aileron per roll error [rad/rad]."""
    roll_rate: float = 0.05
    """Aileron per roll rate [rad/(rad/s)]."""
    heading: float = 0.5
    """Roll reference per heading error [rad/rad], limited to +-``max_roll``."""
    yaw_rate: float = 0.2
    """Rudder per yaw rate [rad/(rad/s)] (yaw damper)."""
    airspeed: float = 0.05
    """Throttle per airspeed error [1/(m/s)]."""
    max_pitch: float = 0.15
    """Limit of the pitch reference offset [rad]."""
    max_roll: float = 0.3
    """Limit of the roll reference [rad]."""

    def validate(self) -> SafetyPilotGains:
        """Raises ValueError naming the first negative or non-finite gain; returns self."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"{f.name}: gain must be finite and >= 0, got {value}")
        return self


class SafetyPilot(LeafSystem):
    """Weak attitude, altitude, heading and airspeed hold around a trim condition.

    Discrete (sample-and-hold at ``period`` [s]), so the output depends on its state
    only and closes no algebraic loop. References: pitch [rad], altitude [m], heading
    [rad], airspeed [m/s].

    | port (in)  | size | units                                              |
    |------------|------|----------------------------------------------------|
    | state      | 13   | plant ``state`` (attitude: its quaternion's Euler) |
    | air_data   | 3    | plant ``air_data``: Va [m/s], alpha, beta [rad]    |
    | imu        | 6    | sensor suite ``imu``: the rate dampers use its     |
    |            |      | gyro p, q, r [rad/s] (unconnected: the true rates) |
    | reference_ | 4    | offsets added to the references: pitch [rad],      |
    | offsets    |      | altitude [m], heading [rad], airspeed [m/s]        |
    |            |      | (unconnected: none; a turn moves the heading)      |

    | port (out) | size | units                                              |
    |------------|------|----------------------------------------------------|
    | correction | 4    | added elevator, aileron, rudder [rad], throttle    |

    The dampers feed back the gyro, as an autopilot does: with the true rates the
    commands would carry noise-free information on the state that no estimator
    working from the logged sensors has, and on-line estimators (the parameter
    EKF) would see a control input correlated with their own state error.
    """

    def __init__(self, gains: SafetyPilotGains, pitch_ref: float, altitude_ref: float,
                 heading_ref: float, airspeed_ref: float, period: float):
        super().__init__()
        self.gains = gains.validate()
        self._refs = (pitch_ref, altitude_ref, heading_ref, airspeed_ref)
        self._state = self.DeclareVectorInputPort("state", 13)
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._imu = self.DeclareVectorInputPort("imu", 6)
        self._offsets = self.DeclareVectorInputPort("reference_offsets", 4)
        xd = self.DeclareDiscreteState(4)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareStateOutputPort("correction", xd)

    def _update(self, context, discrete_state) -> None:
        g = self.gains
        refs = self._refs
        if self._offsets.HasValue(context):
            refs = [a + b for a, b in zip(refs, self._offsets.Eval(context).tolist(),
                                          strict=True)]
        pitch_ref, altitude_ref, heading_ref, airspeed_ref = refs
        x = self._state.Eval(context).tolist()
        roll, pitch, yaw = quat_to_euler(x[3:7]).tolist()
        p, q, r = (self._imu.Eval(context)[3:6].tolist() if self._imu.HasValue(context)
                   else x[10:13])
        climb_to = max(-g.max_pitch, min(g.max_pitch, g.altitude * (altitude_ref + x[2])))
        heading_error = (heading_ref - yaw + math.pi) % (2.0 * math.pi) - math.pi
        roll_ref = max(-g.max_roll, min(g.max_roll, g.heading * heading_error))
        airspeed = self._air.Eval(context)[0]
        discrete_state.set_value([
            g.pitch * (pitch - pitch_ref - climb_to) + g.pitch_rate * q,
            -g.roll * (roll - roll_ref) - g.roll_rate * p,
            g.yaw_rate * r,
            g.airspeed * (airspeed_ref - airspeed),
        ])
