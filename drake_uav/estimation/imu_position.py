"""The accelerometers read at the centre of gravity, from the IMU position the log gives.

An accelerometer at ``r`` from the centre of gravity reads ``w_dot x r + w x (w x r)``
more than the specific force there (:func:`~drake_uav.model.isolation.lever_arm_specific_force`).
The isolation (Vaiopoulos 2017, eq. 5.41) and the data-compatibility check take the
specific force at the centre of gravity; left in, the offset's pitch acceleration leads
the angle of attack and is read as an air-data time skew (14-18 ms for an IMU 20 cm ahead,
5 cm left and 10 cm below it, docs/compatibility.md). Flight-test practice corrects the
accelerometers for their measured position first (Klein & Morelli 2006, sec. 10.2).

Autopilots record that position: ArduPilot's ``INS_POS<n>_X/Y/Z`` and PX4's
``EKF2_IMU_POS_X/Y/Z`` (metres, body axes FRD, from the body origin the autopilot takes
for the centre of gravity). The readers put it in ``FlightLog.metadata["imu_position"]``
(:data:`METADATA_KEY`: ``{"position": [x, y, z], "source": "<parameters>"}``);
:func:`accelerometers_at_cg` moves the accelerometer channels there, with ``w`` from the
gyros and ``w_dot`` their Savitzky-Golay derivative (the isolation's, 0.2 s). Across a gap
in the log that derivative is wrong within 0.1 s of it, where the job's airborne spans
are cut anyway (they lose 1 s at each end inside the log).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from drake_uav.estimation.signals import IMU, LOG_CHANNELS
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.isolation import differentiate, lever_arm_specific_force

__all__ = ["ImuPosition", "METADATA_KEY", "ACCELEROMETERS", "logged_imu_position",
           "accelerometers_at_cg"]

METADATA_KEY = "imu_position"
"""The readers' metadata key of the IMU position."""

ACCELEROMETERS = tuple(LOG_CHANNELS[n] for n in IMU[:3])
"""The accelerometer channels [m/s^2] (body x, y, z)."""
_GYROS = tuple(LOG_CHANNELS[n] for n in IMU[3:])


class ImuPosition(NamedTuple):
    """The accelerometers' position from the centre of gravity, body axes FRD [m]."""

    position: tuple[float, float, float]
    source: str
    """Where it comes from: the log's parameters, or the user."""

    @classmethod
    def given(cls, position: Sequence[float]) -> ImuPosition:
        """The position a user gives; raises :class:`FlightLogError` unless it is three
        finite numbers."""
        r = np.asarray(position, dtype=float).ravel()
        if r.shape != (3,) or not np.all(np.isfinite(r)):
            raise FlightLogError(f"imu_position: need three finite numbers x, y, z [m], got "
                                 f"{list(r)}")
        return cls(tuple(float(v) for v in r), "given")

    def note(self) -> str:
        """The report's line."""
        x, y, z = self.position
        return (f"accelerometers moved to the centre of gravity from the IMU position "
                f"({x:.3g}, {y:.3g}, {z:.3g}) m ({self.source})")


def logged_imu_position(log: FlightLog) -> ImuPosition | None:
    """The IMU position the log's reader found in the autopilot's parameters, else None."""
    entry = log.metadata.get(METADATA_KEY)
    if not entry:
        return None
    return ImuPosition(tuple(float(v) for v in entry["position"]), str(entry["source"]))


def accelerometers_at_cg(log: FlightLog, position: Sequence[float]) -> FlightLog:
    """``log`` with its accelerometer channels read at the centre of gravity instead of at
    ``position`` [m] (body axes FRD). Raises :class:`FlightLogError` for a position that is
    not three finite numbers or a log without the gyros and accelerometers."""
    r = np.asarray(ImuPosition.given(position).position)
    log.require(*ACCELEROMETERS, *_GYROS)
    rates = log.stack(_GYROS)
    extra = r @ lever_arm_specific_force(differentiate(log.time, rates), rates)
    return log.with_measured({c: log[c] - extra[:, i] for i, c in enumerate(ACCELEROMETERS)})
