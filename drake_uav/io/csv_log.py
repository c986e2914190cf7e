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
* Units may be any variant of :data:`UNIT_VARIANTS` (``deg``, ``deg/s``, ``g``,
  ``km/h``, ``kt``, ``ms``, ``us``, ``%``, ``hPa``, ...): values are converted to
  SI on reading. A canonical channel must carry a unit of its own quantity;
  other columns keep a unit of the FlightLog registry or are converted to SI.
* Every cell must be a number: empty cells, ``nan``/``inf``, a row with a
  different number of fields (a cut last line), or time that does not strictly
  increase raise :class:`FlightLogError` naming the file, column and line.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError
from drake_uav.io.readers import CHANNELS

__all__ = ["UNIT_VARIANTS", "read_csv", "resolve_unit"]

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
    "1": ("1", 1.0), "-": ("1", 1.0), "%": ("1", 0.01), "percent": ("1", 0.01),
}
"""Accepted unit symbol -> (SI symbol, factor): ``value_SI = factor * value``."""

_LOWER = {k.lower(): k for k in UNIT_VARIANTS}
_HEADER = re.compile(r"^(?P<name>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]$")
_TRUTH = "truth/"
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


def _header(line: str, source: str) -> list[tuple[str, str]]:
    columns = []
    for i, field in enumerate(line.split(",")):
        match = _HEADER.match(field.strip())
        if not match or not match["name"]:
            raise FlightLogError(f"{source}: column {i + 1} header {field.strip()!r} is not "
                                 "'name [unit]'")
        columns.append((match["name"], match["unit"].strip()))
    names = [n for n, _ in columns]
    for name in names:
        if names.count(name) > 1:
            raise FlightLogError(f"{source}: column '{name}' appears {names.count(name)} times")
    if "time" not in names:
        raise FlightLogError(f"{source}: no 'time [s]' column (columns: {', '.join(names)})")
    return columns


def _locate_bad_row(lines: list[str], first_line: int, names: list[str], source: str,
                    ends_with_newline: bool) -> FlightLogError:
    """The error of the first malformed data line (slow path, only after a failure)."""
    numbered = [(first_line + i, line) for i, line in enumerate(lines) if line.strip()]
    for k, (number, line) in enumerate(numbered):
        problem = _row_problem(line.split(","), names)
        if problem is None:
            continue
        last = k == len(numbered) - 1
        if last and (not ends_with_newline or line.count(",") < len(names) - 1):
            return FlightLogError(f"{source}: truncated last line {number}: {problem}")
        return FlightLogError(f"{source}: line {number}: {problem}")
    return FlightLogError(f"{source}: unreadable data")


def _row_problem(cells: list[str], names: list[str]) -> str | None:
    """What is wrong with one split data line, or None."""
    if len(cells) < len(names):
        return f"{len(cells)} of {len(names)} fields"
    if len(cells) > len(names):
        return f"{len(cells)} fields, the header has {len(names)}"
    for name, cell in zip(names, cells, strict=True):
        if not cell.strip():
            return f"column '{name}': empty cell"
        try:
            float(cell)
        except ValueError:
            return f"column '{name}': {cell.strip()!r} is not a number"
    return None


def read_csv(path: str | Path) -> FlightLog:
    """Reads a CSV flight log (see the module docstring) into a FlightLog in SI units.

    Raises:
        FlightLogError: naming the file and the column/line of a bad header,
            unknown or wrong unit, empty/NaN/non-numeric cell, truncated line,
            or time not strictly increasing.
    """
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise FlightLogError(f"{source}: not UTF-8 text ({err.reason} at byte {err.start})"
                             ) from None
    lines = text.splitlines()
    metadata: dict[str, object] = {}
    start = 0
    while start < len(lines) and (lines[start].startswith("#") or not lines[start].strip()):
        key, colon, value = lines[start][1:].partition(":")
        if lines[start].startswith("#") and colon and key.strip():
            try:
                metadata[key.strip()] = json.loads(value)
            except json.JSONDecodeError:
                metadata[key.strip()] = value.strip()
        start += 1
    if start == len(lines):
        raise FlightLogError(f"{source}: no header line")
    columns = _header(lines[start], source)
    names = [n for n, _ in columns]
    try:
        units = [resolve_unit(name, unit) for name, unit in columns]
    except FlightLogError as err:
        raise FlightLogError(f"{source}: {err}") from None
    body = lines[start + 1:]
    first_line = start + 2  # 1-based line number of body[0]
    if not any(line.strip() for line in body):
        raise FlightLogError(f"{source}: no data rows after the header")
    try:
        data = np.loadtxt(body, delimiter=",", comments=None, ndmin=2, dtype=float)
        if data.size and data.shape[1] != len(names):
            raise ValueError("column count")
    except ValueError:
        raise _locate_bad_row(body, first_line, names, source, text.endswith("\n")) from None
    line_of = None

    def line_number(row: int) -> int:
        nonlocal line_of
        if line_of is None:
            line_of = [first_line + i for i, line in enumerate(body) if line.strip()]
        return line_of[row]

    bad = ~np.isfinite(data)
    if bad.any():
        row = int(np.flatnonzero(bad.any(axis=1))[0])
        col = int(np.flatnonzero(bad[row])[0])
        value = "NaN" if np.isnan(data[row, col]) else f"{data[row, col]}"
        raise FlightLogError(
            f"{source}: column '{names[col]}': {value} at line {line_number(row)}, "
            f"{int(bad[:, col].sum())} non-finite cells in this column")
    data = data * np.array([factor for _, factor in units])
    time = data[:, names.index("time")]
    step = np.diff(time)
    wrong = np.flatnonzero(step <= 0)
    if wrong.size:
        row = int(wrong[0]) + 1
        what = "repeats" if step[row - 1] == 0 else "goes backwards"
        raise FlightLogError(f"{source}: time {what} at line {line_number(row)} "
                             f"(t = {time[row]:.9g} s after {time[row - 1]:.9g} s)")
    measured, truth, unit_of = {}, {}, {}
    for i, ((name, _), (unit, _)) in enumerate(zip(columns, units, strict=True)):
        if name == "time":
            continue
        target = measured
        if name.startswith(_TRUTH):
            name, target = name[len(_TRUTH):], truth
        target[name] = data[:, i]
        unit_of[name] = unit
    try:
        return FlightLog(time, measured, truth, unit_of, metadata)
    except FlightLogError as err:
        raise FlightLogError(f"{source}: {err}") from None
