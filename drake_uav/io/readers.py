"""Reading flight logs: one entry point for every format.

:func:`read_log` reads a CSV, ArduPilot DataFlash ``.bin``, PX4 ``.ulg`` or
Parquet file into a :class:`~drake_uav.io.flight_log.FlightLog` whose measured
channels carry the canonical names and SI units of
:data:`drake_uav.io.streams.CHANNELS`. See docs/flight_logs.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.streams import FORMATS, require_channels

__all__ = ["read_log"]


def read_log(path: str | Path, format: str | None = None, *, required: Iterable[str] = (),
             **options) -> FlightLog:
    """Reads a flight log into a FlightLog with canonical channels.

    Args:
        path: the file.
        format: "csv", "bin" (ArduPilot DataFlash), "ulg" (PX4) or "parquet";
            None picks it from the suffix (:data:`FORMATS`).
        required: channels that must be present (FlightLogError naming the first
            missing one, with the file).
        **options: passed to the format's reader (:func:`~drake_uav.io.csv_log.read_csv`,
            :func:`~drake_uav.io.ardupilot.read_ardupilot`, :func:`~drake_uav.io.px4.read_px4`).

    Raises:
        FlightLogError: unknown format, missing/empty/unreadable/truncated file,
            or any content problem; the message names the file.
    """
    path = Path(path)
    if format is None:
        format = FORMATS.get(path.suffix.lower())
        if format is None:
            raise FlightLogError(
                f"{path}: unknown log format {path.suffix or '(no suffix)'!r} (known: "
                f"{', '.join(FORMATS)}); pass format='csv', 'bin', 'ulg' or 'parquet'")
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
    else:
        reader = _read_parquet
    try:
        log = reader(path, **options)
    except OSError as err:
        raise FlightLogError(f"{path}: cannot read the file ({err.strerror or err})") from None
    return require_channels(log, required, str(path))


def _read_parquet(path: Path) -> FlightLog:
    try:
        return FlightLog.load(path)
    except FlightLogError as err:
        raise FlightLogError(f"{path}: {err}") from None
    except (ValueError, OSError) as err:  # pyarrow's ArrowInvalid is a ValueError
        raise FlightLogError(f"{path}: not a readable Parquet file ({err})") from None
