"""CSV flight logs: one header line of ``name [unit]`` columns, then one row per sample.

::

    # aircraft: "aerosonde"
    time [s], imu_ax [m/s^2], imu_ay [m/s^2], imu_az [m/s^2], imu_p [deg/s], ...
    0.00, 0.12, -0.03, -9.79, 0.5, ...

* Optional leading ``# key: value`` lines are metadata (value parsed as JSON when
  it is JSON, else kept as text); other ``#`` lines before the header are ignored.
* A ``time`` column is required (any position). Canonical channel names and
  their SI units are :data:`drake_uav.io.readers.CHANNELS`; ``truth/<name>``
  columns become truth channels (as written by :meth:`FlightLog.save`).
* Every other column is an extra channel (a tension, a voltage, a payload signal):
  its name made a valid channel name (``load cell`` -> ``load_cell``), its unit
  ``1`` when the header gives none (``payload`` instead of ``payload [1]``).
* Units may be any variant of :data:`UNIT_VARIANTS` (``deg``, ``deg/s``, ``g``,
  ``km/h``, ``kt``, ``ms``, ``us``, ``%``, ``hPa``, ...): values are converted to
  SI on reading. A canonical channel must carry a unit of its own quantity;
  other columns keep a unit of the FlightLog registry or are converted to SI.
* Every cell must be a number: empty cells, ``nan``/``inf``, a row with a
  different number of fields (a cut last line), or time that does not strictly
  increase raise :class:`FlightLogError` naming the file, column and line.
* IMU columns logged below 100 Hz give a warning (fast dynamics are aliased).

Several time columns (ground-station and ROS-bridge exports, where each message group
keeps its own time stamps)::

    time [s], imu_ax [m/s^2], ..., att_yaw [rad], time_cmd [ms], cmd_elevator [deg], ...
    0.00,     0.12,           ..., 0.5,           5,             1.2,                ...
    0.01,     0.11,           ..., 0.5,           338,           1.4,                ...
    0.02,     0.13,           ..., 0.5,           ,              ,                   ...

* The first column is a time column; each ``time`` or ``time_<group>`` column times
  the columns to its right up to the next time column. A group ends at its time
  column's first empty cell: its rows below are empty (padding), its rows above full.
* Each group is a stream at its own native rate (``metadata["streams"]``), aligned
  on the IMU's group as the autopilot readers do
  (:func:`~drake_uav.io.streams.align_streams`): commands held, slow sensors held,
  others interpolated; a group of IMU, attitude or command columns is required (its
  gaps cut the log), any other group optional (dropped with a warning when sparse).
  Truth columns need the single-time layout.
"""

from __future__ import annotations

import codecs
import json
import math
import re
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError
from drake_uav.io.streams import CHANNELS, MIN_IMU_RATE_HZ, Stream, align_streams

__all__ = ["UNIT_VARIANTS", "channel_name", "read_csv", "resolve_unit"]

_KNOT = 1852.0 / 3600.0
UNIT_VARIANTS: dict[str, tuple[str, float]] = {
    "s": ("s", 1.0), "ms": ("s", 1e-3), "us": ("s", 1e-6), "µs": ("s", 1e-6),
    "m/s^2": ("m/s^2", 1.0), "m/s2": ("m/s^2", 1.0), "m/s²": ("m/s^2", 1.0),
    "g": ("m/s^2", 9.80665),
    "rad": ("rad", 1.0), "deg": ("rad", math.pi / 180.0), "°": ("rad", math.pi / 180.0),
    "rad/s": ("rad/s", 1.0), "deg/s": ("rad/s", math.pi / 180.0),
    "°/s": ("rad/s", math.pi / 180.0), "rpm": ("rad/s", math.pi / 30.0),
    "m/s": ("m/s", 1.0), "km/h": ("m/s", 1.0 / 3.6), "kt": ("m/s", _KNOT),
    "kn": ("m/s", _KNOT), "kts": ("m/s", _KNOT), "knots": ("m/s", _KNOT),
    "mph": ("m/s", 0.44704), "ft/s": ("m/s", 0.3048),
    "m": ("m", 1.0), "ft": ("m", 0.3048),
    "Pa": ("Pa", 1.0), "hPa": ("Pa", 100.0), "mbar": ("Pa", 100.0), "kPa": ("Pa", 1000.0),
    "V": ("V", 1.0), "mV": ("V", 1e-3), "cV": ("V", 1e-2),
    "A": ("A", 1.0), "mA": ("A", 1e-3), "cA": ("A", 1e-2),
    "1": ("1", 1.0), "-": ("1", 1.0), "%": ("1", 0.01), "percent": ("1", 0.01),
}
"""Accepted unit symbol -> (SI symbol, factor): ``value_SI = factor * value``."""

_LOWER = {k.lower(): k for k in UNIT_VARIANTS}
_HEADER = re.compile(r"^(?P<name>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]$")
_TRUTH = "truth/"
_NOT_IN_NAME = re.compile(r"[^A-Za-z0-9_.]")
_CANONICAL = {"time": ("s", "sample time"), **CHANNELS}


def resolve_unit(name: str, unit: str) -> tuple[str, float]:
    """(unit stored, factor to it) of a column ``name [unit]``; FlightLogError if wrong.

    Canonical channels need a variant of their SI unit; other columns get the SI
    unit of a known variant, or keep a unit of the FlightLog registry.
    """
    key = unit if unit in UNIT_VARIANTS else _LOWER.get(unit.lower())
    canonical = _CANONICAL.get(name.removeprefix(_TRUTH))
    if canonical is not None:
        expected = canonical[0]
        accepted = [k for k, (si, _) in UNIT_VARIANTS.items() if si == expected]
        if key is None or UNIT_VARIANTS[key][0] != expected:
            what = (f"unknown unit '{unit}'" if key is None and unit not in UNITS
                    else f"unit '{unit}' is not a unit of {UNITS[expected]}")
            raise FlightLogError(f"column '{name}': {what} (accepted: {', '.join(accepted)})")
        return UNIT_VARIANTS[key]
    if key is not None:
        return UNIT_VARIANTS[key]
    if unit in UNITS:
        return unit, 1.0
    raise FlightLogError(f"column '{name}': unknown unit '{unit}' (known: "
                         f"{', '.join(dict.fromkeys([*UNIT_VARIANTS, *UNITS]))})")


def _text(line: bytes, source: str, number: int) -> str:
    try:
        return bytes(line).decode("utf-8")
    except UnicodeDecodeError as err:
        raise FlightLogError(f"{source}: line {number} is not UTF-8 text ({err.reason})"
                             ) from None


def channel_name(text: str) -> str:
    """A column name as a channel name: each character a channel name cannot hold
    becomes ``_`` (``load cell`` -> ``load_cell``), a leading digit gets a ``_``."""
    name = _NOT_IN_NAME.sub("_", text)
    return f"_{name}" if name[:1].isdigit() else name


def _header(line: str, source: str) -> list[tuple[str, str]]:
    """(channel name, unit) per column; a column that is not canonical may come without
    a unit (``1``) and its name is made a valid channel name (:func:`channel_name`)."""
    columns = []
    for i, field in enumerate(line.split(",")):
        text = field.strip()
        match = _HEADER.match(text)
        name, unit = (match["name"], match["unit"].strip()) if match else (text, "1")
        truth = name.startswith(_TRUTH)
        bare = name.removeprefix(_TRUTH)
        if not bare or (not match and ("[" in text or "]" in text or bare in _CANONICAL)):
            raise FlightLogError(f"{source}: column {i + 1} header {text!r} is not "
                                 "'name [unit]'")
        if bare not in _CANONICAL:
            name = _TRUTH * truth + channel_name(bare)
        columns.append((name, unit))
    names = [n for n, _ in columns]
    for name in names:
        if names.count(name) > 1:
            raise FlightLogError(f"{source}: column '{name}' appears {names.count(name)} times")
    if "time" not in names:
        raise FlightLogError(f"{source}: no 'time [s]' column (columns: {', '.join(names)})")
    return columns


def _locate_bad_row(lines: list[str], first_line: int, names: list[str], source: str,
                    ends_with_newline: bool, reason: str,
                    allow_empty: bool = False) -> FlightLogError:
    """The error of the first malformed data line (slow path, only after a failure)."""
    numbered = [(first_line + i, line) for i, line in enumerate(lines) if line]
    if not numbered:
        return FlightLogError(f"{source}: no data rows after the header")
    for k, (number, line) in enumerate(numbered):
        problem = _row_problem(line.split(","), names, allow_empty)
        if problem is None:
            continue
        last = k == len(numbered) - 1
        if last and (not ends_with_newline or line.count(",") < len(names) - 1):
            return FlightLogError(f"{source}: truncated last line {number}: {problem}")
        return FlightLogError(f"{source}: line {number}: {problem}")
    return FlightLogError(f"{source}: unreadable data ({reason})")


def _row_problem(cells: list[str], names: list[str], allow_empty: bool = False
                 ) -> str | None:
    """What is wrong with one split data line, or None (an empty cell is fine where
    ``allow_empty``: the padding of a time group)."""
    if len(cells) < len(names):
        return f"{len(cells)} of {len(names)} fields"
    if len(cells) > len(names):
        return f"{len(cells)} fields, the header has {len(names)}"
    for name, cell in zip(names, cells, strict=True):
        if not cell.strip():
            if allow_empty:
                continue
            return f"column '{name}': empty cell"
        try:
            float(cell)
        except ValueError:
            return f"column '{name}': {cell.strip()!r} is not a number"
    return None


def _numbers(body: memoryview, n_columns: int, allow_empty: bool = False
             ) -> tuple[list[np.ndarray], list[np.ndarray]] | str:
    """(the columns of ``body`` as float arrays, each column's empty cells), or the
    parser's complaint when a cell is not a number, a row has another number of fields
    (pyarrow's parser) or, unless ``allow_empty``, a cell is empty."""
    pa, csv = _pyarrow_csv()
    names = [f"c{i}" for i in range(n_columns)]
    try:
        table = csv.read_csv(
            pa.py_buffer(body), read_options=csv.ReadOptions(column_names=names),
            convert_options=csv.ConvertOptions(
                column_types=dict.fromkeys(names, pa.float64()), null_values=[""],
                strings_can_be_null=False, quoted_strings_can_be_null=False))
    except pa.ArrowInvalid as err:
        return str(err)
    if not allow_empty and any(column.null_count for column in table.columns):
        return "empty cell"
    empty = [column.is_null().to_numpy(zero_copy_only=False) for column in table.columns]
    values = [column.to_numpy() if not column.null_count
              else column.fill_null(math.nan).to_numpy() for column in table.columns]
    return values, empty


def _pyarrow_csv():
    try:
        import pyarrow as pa
        import pyarrow.csv as csv
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("CSV flight logs need pyarrow: pip install pyarrow") from exc
    return pa, csv


def _preamble(raw: bytes, source: str) -> tuple[dict[str, object], str, int, int]:
    """(metadata, header line, byte offset after the header, lines read) of a CSV log.

    Skips a UTF-8 byte order mark; ``# key: value`` lines before the header are
    metadata (JSON value when it parses, else text), other ``#`` and blank lines
    are ignored.
    """
    pos = len(codecs.BOM_UTF8) if raw.startswith(codecs.BOM_UTF8) else 0
    metadata: dict[str, object] = {}
    header, line_count = None, 0
    while header is None and pos < len(raw):
        end = raw.find(b"\n", pos)
        end = len(raw) if end < 0 else end
        line = _text(raw[pos:end], source, line_count + 1).rstrip("\r")
        pos, line_count = end + 1, line_count + 1
        if line.startswith("#"):
            key, colon, value = line[1:].partition(":")
            if colon and key.strip():
                try:
                    metadata[key.strip()] = json.loads(value)
                except json.JSONDecodeError:
                    metadata[key.strip()] = value.strip()
        elif line.strip():
            header = line
    if header is None:
        raise FlightLogError(f"{source}: no header line")
    return metadata, header, pos, line_count


def _units(columns: list[tuple[str, str]], source: str) -> list[tuple[str, float]]:
    """(unit stored, factor to it) per column, errors prefixed with the file name."""
    try:
        return [resolve_unit(name, unit) for name, unit in columns]
    except FlightLogError as err:
        raise FlightLogError(f"{source}: {err}") from None


def _body_lines(body: memoryview) -> list[str]:
    """The data lines as text (slow path, only to name a line in an error)."""
    return bytes(body).decode("utf-8", errors="replace").splitlines()


def _line_number(body: memoryview, first_line: int, row: int) -> int:
    """1-based file line of data row ``row`` (blank lines hold no row)."""
    return [first_line + i for i, line in enumerate(_body_lines(body)) if line][row]


def _check_finite(data: list[np.ndarray], names: list[str], source: str,
                  line_number: Callable[[int], int]) -> None:
    """FlightLogError at the first NaN/inf cell (lowest row, then lowest column)."""
    first_bad = [(int(np.argmin(np.isfinite(column))), col) for col, column in enumerate(data)
                 if not np.isfinite(column).all()]
    if first_bad:
        row, col = min(first_bad)
        value = "NaN" if np.isnan(data[col][row]) else f"{data[col][row]}"
        raise FlightLogError(
            f"{source}: column '{names[col]}': {value} at line {line_number(row)}, "
            f"{int(np.count_nonzero(~np.isfinite(data[col])))} non-finite cells in this column")


def _check_time(time: np.ndarray, source: str, line_number: Callable[[int], int],
                column: str = "time") -> None:
    """FlightLogError at the first sample whose time [s] (of ``column``) does not strictly
    increase."""
    step = np.diff(time)
    wrong = np.flatnonzero(step <= 0)
    if wrong.size:
        row = int(wrong[0]) + 1
        what = "repeats" if step[row - 1] == 0 else "goes backwards"
        raise FlightLogError(f"{source}: {column} {what} at line {line_number(row)} "
                             f"(t = {time[row]:.9g} s after {time[row - 1]:.9g} s)")


def _channels(columns: list[tuple[str, str]], units: list[tuple[str, float]],
              data: list[np.ndarray]
              ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, str]]:
    """(measured, truth, unit per channel) of the non-time columns; ``truth/`` columns
    go to truth under their name without the prefix."""
    measured, truth, unit_of = {}, {}, {}
    for (name, _), (unit, _), values in zip(columns, units, data, strict=True):
        if name == "time":
            continue
        target = measured
        if name.startswith(_TRUTH):
            name, target = name[len(_TRUTH):], truth
        target[name] = values
        unit_of[name] = unit
    return measured, truth, unit_of


def _time_groups(names: list[str], source: str) -> list[tuple[int, list[int]]]:
    """(time column, its data columns) per time group: one group of every column when the
    file has one time column; else each ``time`` / ``time_<group>`` column and the columns
    to its right up to the next time column."""
    times = [i for i, n in enumerate(names) if n == "time" or n.startswith("time_")]
    if len(times) < 2:
        t = names.index("time")
        return [(t, [i for i in range(len(names)) if i != t])]
    if times[0] != 0:
        raise FlightLogError(f"{source}: column '{names[0]}' comes before the first time "
                             f"column '{names[times[0]]}'; with several time columns, each "
                             "one times the columns to its right")
    groups = [(t, list(range(t + 1, end))) for t, end in zip(times, [*times[1:], len(names)],
                                                             strict=True)]
    for t, columns in groups:
        if not columns:
            raise FlightLogError(f"{source}: time column '{names[t]}' times no column")
        truth = [names[c] for c in columns if names[c].startswith(_TRUTH)]
        if truth:
            raise FlightLogError(f"{source}: column '{truth[0]}': truth channels need the "
                                 "single-time layout (one time column)")
    return groups


def _imu_rate_note(rate: float, source: str, what: str) -> None:
    """Warns when the IMU columns are logged below :data:`MIN_IMU_RATE_HZ`."""
    if round(rate, 3) < MIN_IMU_RATE_HZ:
        warnings.warn(f"{source}: IMU columns ({what}) logged at {rate:.3g} Hz, below "
                      f"{MIN_IMU_RATE_HZ:g} Hz: fast dynamics are aliased", stacklevel=4)


def _group_length(group: tuple[int, list[int]], empty: list[np.ndarray], names: list[str],
                  source: str, line_number: Callable[[int], int]) -> int:
    """Rows of a time group: up to its time column's first empty cell; FlightLogError at
    an empty cell inside the group or a value in its padding."""
    t, columns = group
    n = int(np.argmax(empty[t])) if empty[t].any() else empty[t].size
    if n < 2:
        raise FlightLogError(f"{source}: time column '{names[t]}' has {n} sample(s); a time "
                             "group needs 2")
    for c in (t, *columns):
        inside = np.flatnonzero(empty[c][:n])
        if inside.size:
            raise FlightLogError(f"{source}: column '{names[c]}': empty cell at line "
                                 f"{line_number(int(inside[0]))}, inside its time group "
                                 f"'{names[t]}' (rows up to line {line_number(n - 1)})")
        after = np.flatnonzero(~empty[c][n:])
        if after.size:
            raise FlightLogError(f"{source}: column '{names[c]}': a value at line "
                                 f"{line_number(n + int(after[0]))} after the end of its time "
                                 f"group '{names[t]}' (its last time at line "
                                 f"{line_number(n - 1)})")
    return n


def _grouped_log(groups, names, units, data, empty, source: str, metadata: dict,
                 line_number: Callable[[int], int], max_gap: float) -> FlightLog:
    """The FlightLog of a CSV with several time columns, its groups aligned as streams on
    the IMU's time base (:func:`~drake_uav.io.streams.align_streams`)."""
    streams = []
    for group in groups:
        t, columns = group
        n = _group_length(group, empty, names, source, line_number)
        _check_finite([data[c][:n] for c in (t, *columns)], [names[c] for c in (t, *columns)],
                      source, line_number)
        scaled = {c: data[c][:n] * units[c][1] for c in (t, *columns)}
        _check_time(scaled[t], source, line_number, names[t])
        channels = {names[c]: scaled[c] for c in columns}
        canonical = [c for c in channels if c in CHANNELS]
        required = any(c.startswith(("imu_", "att_", "cmd_")) for c in canonical)
        streams.append(Stream(
            names[t], scaled[t], channels, {names[c]: units[c][0] for c in columns},
            fields={c: f"column {c}" for c in channels},
            angles=tuple(c for c in ("att_roll", "att_yaw") if c in channels),
            hold=all(c.startswith("cmd_") for c in channels), optional=not required,
            trims=bool(canonical)))
    base = next((s for s in streams if "imu_ax" in s.channels), streams[0])
    rate = 1.0 / float(np.median(np.diff(base.time)))
    if any(c.startswith("imu_") for c in base.channels):
        _imu_rate_note(rate, source, f"time column '{base.name}'")
    return align_streams(base, [s for s in streams if s is not base], source=source,
                         max_gap=max_gap, metadata=metadata)


def read_csv(path: str | Path, *, max_gap: float = 1.0) -> FlightLog:
    """Reads a CSV flight log (see the module docstring) into a FlightLog in SI units.

    The cells are parsed by pyarrow's multi-threaded CSV reader; only when that
    fails is the file scanned line by line to name the first bad cell.

    Args:
        path: the file.
        max_gap: with several time columns, the longest interval between two samples of
            an IMU, attitude or command group before the log is cut into segments [s].

    Raises:
        FlightLogError: naming the file and the column/line of a bad header,
            unknown or wrong unit, empty/NaN/non-numeric cell, truncated line,
            time not strictly increasing, or a time group's padding that is not empty.
    """
    path = Path(path)
    source = str(path)
    raw = path.read_bytes()
    metadata, header, pos, line_count = _preamble(raw, source)
    columns = _header(header, source)
    names = [n for n, _ in columns]
    units = _units(columns, source)
    groups = _time_groups(names, source)
    body = memoryview(raw)[min(pos, len(raw)):]
    first_line = line_count + 1  # 1-based line number of the body's first line
    parsed = _numbers(body, len(names), allow_empty=len(groups) > 1)
    if isinstance(parsed, str):
        raise _locate_bad_row(_body_lines(body), first_line, names, source,
                              raw.endswith(b"\n"), parsed, allow_empty=len(groups) > 1)
    data, empty = parsed
    if data[0].size == 0:
        raise FlightLogError(f"{source}: no data rows after the header")

    def line_number(row: int) -> int:
        return _line_number(body, first_line, row)

    if len(groups) > 1:
        return _grouped_log(groups, names, units, data, empty, source, metadata,
                            line_number, max_gap)
    _check_finite(data, names, source, line_number)
    data = [column if factor == 1.0 else column * factor
            for column, (_, factor) in zip(data, units, strict=True)]
    time = data[names.index("time")]
    _check_time(time, source, line_number)
    measured, truth, unit_of = _channels(columns, units, data)
    if time.size > 1 and any(n.startswith("imu_") for n in measured):
        _imu_rate_note(1.0 / float(np.median(np.diff(time))), source, "column 'time'")
    try:
        return FlightLog(time, measured, truth, unit_of, metadata)
    except FlightLogError as err:
        raise FlightLogError(f"{source}: {err}") from None
