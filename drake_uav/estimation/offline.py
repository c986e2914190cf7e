"""Flight logs -> filter arrays: what :func:`~drake_uav.estimation.ekf.run_filter` runs on.

Each filter model's ``log_data(log)`` reads its inputs and measurements with a
:class:`LogReader` and returns a :class:`FilterData`::

    data = model.log_data(log)
    run = run_filter(ekf, data.time, data.inputs, data.measurements, data.available,
                     truth=data.truth)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from drake_uav.estimation.gps import gps_latency_correction
from drake_uav.estimation.signals import ATTITUDE, GPS_VELOCITY, LOG_CHANNELS, fresh_samples
from drake_uav.io.flight_log import FlightLog

__all__ = ["FilterData", "LogReader"]


@dataclasses.dataclass(frozen=True)
class FilterData:
    """Arrays of one flight for :func:`~drake_uav.estimation.ekf.run_filter`."""

    time: np.ndarray
    """Sample times [s] (N)."""
    inputs: np.ndarray
    """(N, n_inputs) in the model's input order."""
    measurements: np.ndarray
    """(N, n_measurements) in the model's measurement order (NaN: no channel)."""
    available: np.ndarray
    """(N, n_measurements) bool, True where a new sample arrived."""
    truth: np.ndarray | None
    """(N, n_states) true states when the log has truth channels, else None."""


class LogReader:
    """Channels of a :class:`~drake_uav.io.flight_log.FlightLog` by filter signal name
    (:data:`~drake_uav.estimation.signals.LOG_CHANNELS`).

    ``gps_latency`` [s] moves the GPS velocity forward (:meth:`sensors`) with the
    strapdown velocity change; ``gravity`` [m/s^2] enters that integration.
    """

    def __init__(self, log: FlightLog, gps_latency: float, gravity: float):
        self.log, self.time = log, np.asarray(log.time, float)
        self.n = len(self.time)
        self._gps_latency, self._gravity = gps_latency, gravity
        self._gps_correction: np.ndarray | None = None

    def channel(self, name: str) -> np.ndarray:
        """A measured channel (NaN column when the log lacks it)."""
        return np.asarray(self.log[name], float) if name in self.log else np.full(self.n, np.nan)

    def inputs(self, names: Sequence[str], held: Sequence[int] = ()) -> np.ndarray:
        """Input columns by filter name; ``held`` columns (commands) are shifted one
        sample so each row holds the command in effect during the step ending there."""
        columns = [self.channel(LOG_CHANNELS[n]) for n in names]
        for i in held:
            columns[i] = np.concatenate([columns[i][:1], columns[i][:-1]])
        return np.column_stack(columns)

    def sensors(self, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Sensor samples and their freshness for filter measurement names; GPS
        velocity is moved forward by its latency."""
        columns, fresh = [], []
        for name in names:
            raw = self.channel(LOG_CHANNELS[name])
            fresh.append(fresh_samples(raw))
            if name in GPS_VELOCITY and self._gps_latency > 0:
                raw = raw + self.gps_correction()[:, GPS_VELOCITY.index(name)]
            columns.append(raw)
        return np.column_stack(columns), np.column_stack(fresh)

    def gps_correction(self) -> np.ndarray:
        """Ground-velocity change over the GPS latency (N, 3) [m/s]."""
        if self._gps_correction is None:
            self._gps_correction = gps_latency_correction(
                self.time, self.inputs(("ax", "ay", "az")), self.inputs(ATTITUDE),
                self._gps_latency, self._gravity)
        return self._gps_correction

    def truth(self, names: Sequence[str]) -> np.ndarray | None:
        """Truth columns, or None when the log lacks one."""
        if not all(n in self.log for n in names):
            return None
        return np.column_stack([self.log[n] for n in names])
