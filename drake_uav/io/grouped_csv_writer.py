"""A FlightLog as a CSV export with a time column per group, each group at its own rate.

Ground-station and ROS-bridge exports keep each message group on its own time stamps
(docs/flight_logs.md, "CSV"). :func:`write_grouped_csv` writes a flight that way, each
group sampled at its own rate (the log's latest sample at each time, as a logger records
what it has), so that a simulated flight can be turned into the low-rate export a user
would get, to see what the analysis says on it. :func:`~drake_uav.io.csv_log.read_csv`
reads it back with each group's native rate in ``metadata["streams"]``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import FlightLog

__all__ = ["write_grouped_csv"]


def _group_times(log: FlightLog, rate_hz: float, group: str) -> np.ndarray:
    """Times [s] of a group logged at ``rate_hz`` from the log's first sample on."""
    if not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValueError(f"groups: {group}: the rate must be positive and finite, got "
                         f"{rate_hz!r}")
    count = int(math.floor((log.time[-1] - log.time[0]) * rate_hz + 1e-9)) + 1
    return log.time[0] + np.arange(count) / rate_hz


def write_grouped_csv(log: FlightLog, path: str | Path,
                      groups: Mapping[str, tuple[float, Sequence[str]]]) -> Path:
    """Writes ``log`` as a CSV with one time column per group of channels.

    Parameters
    ----------
    log : FlightLog
        The flight (measured channels, SI units).
    path : str or Path
        The ``.csv`` file to write.
    groups : Mapping[str, (float, sequence of str)]
        Group name -> (rate [Hz], its channels). The first group's time column is ``time``,
        the others' ``time_<group>``; the reader aligns the log on the group of IMU
        columns, which must be among them.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    ValueError
        For a channel the log lacks, a channel in two groups, or a rate that is not
        positive.
    """
    seen: set[str] = set()
    header, columns = [], []
    for i, (group, (rate_hz, channels)) in enumerate(groups.items()):
        for channel in channels:
            if channel not in log.measured_names:
                raise ValueError(f"groups: {group}: the log has no measured channel "
                                 f"{channel!r}")
            if channel in seen:
                raise ValueError(f"groups: {group}: channel {channel!r} is in two groups")
            seen.add(channel)
        time = _group_times(log, rate_hz, group)
        latest = np.clip(np.searchsorted(log.time, time + 1e-9, side="right") - 1, 0,
                         log.time.size - 1)
        header += ["time [s]" if i == 0 else f"time_{group} [s]",
                   *(f"{c} [{log.unit(c)}]" for c in channels)]
        columns += [time, *(np.asarray(log[c], float)[latest] for c in channels)]
    rows = max(c.size for c in columns)
    lines = [",".join(f"{c[k]:.9g}" if k < c.size else "" for c in columns)
             for k in range(rows)]
    path = Path(path)
    path.write_text(",".join(header) + "\n" + "\n".join(lines) + "\n")
    return path
