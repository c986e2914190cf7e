"""Reading flight logs: one entry point for every format.

:func:`read_log` reads a CSV, ArduPilot DataFlash ``.bin``, PX4 ``.ulg``, MAVLink
telemetry ``.tlog`` or Parquet file into a :class:`~drake_uav.io.flight_log.FlightLog`
whose measured channels carry the canonical names and SI units of
:data:`drake_uav.io.streams.CHANNELS`. See docs/flight_logs.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import CHANNELS, FORMATS, require_channels

__all__ = ["CORRUPT_MAGNITUDE", "check_magnitudes", "read_log"]


def read_log(path: str | Path, format: str | None = None, *, required: Iterable[str] = (),
             **options) -> FlightLog:
    """Reads a flight log into a FlightLog with canonical channels.

    Args:
        path: the file.
        format: "csv", "bin" (ArduPilot DataFlash), "ulg" (PX4), "tlog" (MAVLink
            telemetry) or "parquet";
            None picks it from the suffix (:data:`FORMATS`).
        required: channels that must be present (FlightLogError naming the first
            missing one, with the file).
        **options: passed to the format's reader (:func:`~drake_uav.io.csv_log.read_csv`,
            :func:`~drake_uav.io.ardupilot.read_ardupilot`, :func:`~drake_uav.io.px4.read_px4`,
            :func:`~drake_uav.io.tlog.read_tlog`).

    Raises:
        FlightLogError: unknown format, missing/empty/unreadable/truncated file,
            a corrupt value (:func:`check_magnitudes`) or any content problem; the
            message names the file.
    """
    path = Path(path)
    if format is None:
        format = FORMATS.get(path.suffix.lower())
        if format is None:
            raise FlightLogError(
                f"{path}: unknown log format {path.suffix or '(no suffix)'!r} (known: "
                f"{', '.join(FORMATS)}); pass format='csv', 'bin', 'ulg', 'tlog' or 'parquet'")
    elif format not in set(FORMATS.values()):
        raise FlightLogError(f"{path}: unknown log format {format!r} "
                             f"(known: {', '.join(sorted(set(FORMATS.values())))})")
    if not path.exists():
        raise FlightLogError(f"{path}: no such file")
    if not path.is_file():
        raise FlightLogError(f"{path}: not a file")
    if path.stat().st_size == 0:
        raise FlightLogError(f"{path}: empty file")
    # Format modules load on demand: pymavlink and pyulog are slow to import.
    if format == "csv":
        from drake_uav.io.csv_log import read_csv as reader
    elif format == "bin":
        from drake_uav.io.ardupilot import read_ardupilot as reader
    elif format == "ulg":
        from drake_uav.io.px4 import read_px4 as reader
    elif format == "tlog":
        from drake_uav.io.tlog import read_tlog as reader
    else:
        reader = _read_parquet
    try:
        log = reader(path, **options)
    except OSError as err:
        raise FlightLogError(f"{path}: cannot read the file ({err.strerror or err})") from None
    check_magnitudes(log, str(path))
    return require_channels(log, required, str(path))


CORRUPT_MAGNITUDE: dict[str, float] = {
    "m/s^2": 1e4,  # 1000 g
    "rad/s": 1e5,  # a million rpm (motor_speed too)
    "rad": 1e3,  # 160 turns (angles are logged wrapped)
    "m/s": 1e4,  # 30 times the speed of sound
    "m": 1e8,  # 15 Earth radii
    "Pa": 1e7,  # 100 atmospheres
    "1": 1e3,  # the throttle, 0..1
}
"""Magnitude [SI unit] beyond which a canonical channel's value is corrupt data, not a
reading: far beyond any sensor of a small aircraft, so that only a damaged number (a flipped
exponent bit, a field read with the wrong type) exceeds it. Physical plausibility (an
airspeed the aircraft cannot fly, a vane angle in degrees) is judged later, against the
aircraft and the redundant channels."""


def check_magnitudes(log: FlightLog, source: str) -> FlightLog:
    """Raises :class:`FlightLogError` naming ``source``, the channel, the value and its time
    when a canonical measured channel holds a value beyond :data:`CORRUPT_MAGNITUDE` for its
    unit (a corrupt number); returns ``log``."""
    for name in log.measured_names:
        bound = CORRUPT_MAGNITUDE.get(CHANNELS[name][0]) if name in CHANNELS else None
        if bound is None:
            continue
        values = log[name]
        bad = np.flatnonzero(np.abs(values) > bound)
        if bad.size:
            i = int(bad[0])
            unit = CHANNELS[name][0]
            raise FlightLogError(
                f"{source}: channel {name} holds {values[i]:.3g} {unit} at t = "
                f"{log.time[i]:.6g} s (sample {i}; {bad.size} such sample(s)), beyond any "
                f"sensor's range (|value| > {bound:g} {unit}): corrupt data")
    return log


def _read_parquet(path: Path) -> FlightLog:
    import pyarrow

    try:
        return FlightLog.load(path)
    except FlightLogError as err:
        message = str(err)  # named once: FlightLog.load names the file in some messages
        raise FlightLogError(message if message.startswith(f"{path}: ") else f"{path}: {message}"
                             ) from None
    except (ValueError, OSError, pyarrow.ArrowException) as err:
        raise FlightLogError(f"{path}: not a readable Parquet file ({err})") from None
