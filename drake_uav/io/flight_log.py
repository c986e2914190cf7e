"""FlightLog: time-indexed named channels with units, measured and truth kept apart.

A log holds one strictly increasing time vector [s] and scalar channels sampled
on it. Each channel has a unit from a small registry (:data:`UNITS`) and is
either *measured* (what the aircraft logs: sensors, commands) or *truth*
(simulation ground truth: state, air data, wind, coefficients, forces).
Validation raises :class:`FlightLogError` (a ``ValueError``) naming the channel
and, where it applies, the sample index and time.

Files: CSV (header ``name [unit]``, truth columns prefixed ``truth/``, metadata
as leading ``# key: value`` lines, values written with 17 significant digits so
a round trip is exact) and Parquet (pyarrow; units and kinds in field metadata).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

__all__ = [
    "UNITS",
    "FlightLogError",
    "FlightLog",
    "register_unit",
]

# Known units: symbol -> physical quantity.
UNITS: dict[str, str] = {
    "s": "time",
    "m": "length",
    "m/s": "velocity",
    "m/s^2": "acceleration",
    "rad": "angle",
    "rad/s": "angular rate",
    "rad/s^2": "angular acceleration",
    "deg": "angle",
    "deg/s": "angular rate",
    "Pa": "pressure",
    "K": "temperature",
    "kg/m^3": "density",
    "N": "force",
    "N m": "moment",
    "Hz": "frequency",
    "V": "voltage",
    "A": "current",
    "1": "dimensionless",
}

_TRUTH_PREFIX = "truth/"
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.]*$")
_HEADER = re.compile(r"^\s*(?P<name>[^\[\]]+?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")


class FlightLogError(ValueError):
    """A flight log is malformed; the message names the channel and sample.

    The message is kept on one line (the line breaks of a parser's message it quotes
    become spaces): the command line prints it as its one ``error:`` line.
    """

    def __init__(self, message: str):
        super().__init__(" ".join(part.strip() for part in str(message).splitlines()
                                  if part.strip()))


def register_unit(symbol: str, quantity: str) -> None:
    """Adds a unit ``symbol`` (e.g. ``"mbar"``) for ``quantity`` to :data:`UNITS`."""
    if not symbol or symbol != symbol.strip() or "[" in symbol or "]" in symbol:
        raise ValueError(f"symbol: invalid unit symbol {symbol!r}")
    UNITS[symbol] = quantity


class FlightLog:
    """Time-indexed channels with units; measured and truth channels kept separate.

    Args:
        time: sample times [s], strictly increasing.
        measured: channel name -> samples (same length as ``time``).
        truth: channel name -> samples; names must differ from the measured ones.
        units: channel name -> unit symbol from :data:`UNITS`, for every channel.
        metadata: free-form string keys and JSON-serialisable values.
        validate: run :meth:`validate` on construction (default).
    """

    def __init__(
        self,
        time,
        measured: Mapping[str, Iterable[float]] | None = None,
        truth: Mapping[str, Iterable[float]] | None = None,
        units: Mapping[str, str] | None = None,
        metadata: Mapping[str, object] | None = None,
        validate: bool = True,
    ):
        self._time = _frozen(time, "time")
        self._measured = {str(k): _frozen(v, f"channel '{k}'") for k, v in (measured or {}).items()}
        self._truth = {str(k): _frozen(v, f"channel '{k}'") for k, v in (truth or {}).items()}
        self._units = dict(units or {})
        self.metadata: dict[str, object] = dict(metadata or {})
        if validate:
            self.validate()

    # ------------------------------------------------------------------ access
    @property
    def time(self) -> np.ndarray:
        """Sample times [s] (read-only)."""
        return self._time

    @property
    def measured_names(self) -> tuple[str, ...]:
        """Names of the measured channels, in insertion order."""
        return tuple(self._measured)

    @property
    def truth_names(self) -> tuple[str, ...]:
        """Names of the truth channels, in insertion order."""
        return tuple(self._truth)

    @property
    def names(self) -> tuple[str, ...]:
        """All channel names, measured first."""
        return self.measured_names + self.truth_names

    @property
    def units(self) -> dict[str, str]:
        """Channel name -> unit symbol (a copy)."""
        return dict(self._units)

    def __len__(self) -> int:
        return self._time.size

    def __contains__(self, name: str) -> bool:
        return name in self._measured or name in self._truth

    def __getitem__(self, name: str) -> np.ndarray:
        if name in self._measured:
            return self._measured[name]
        if name in self._truth:
            return self._truth[name]
        raise FlightLogError(self._missing_message(name))

    def _check(self, name: str) -> None:
        if name not in self:
            raise FlightLogError(self._missing_message(name))

    def unit(self, name: str) -> str:
        """Unit symbol of channel ``name``."""
        self._check(name)
        return self._units[name]

    def is_truth(self, name: str) -> bool:
        """True for a truth channel, False for a measured one."""
        self._check(name)
        return name in self._truth

    def stack(self, names: Iterable[str]) -> np.ndarray:
        """Channels ``names`` as columns of an (n_samples, len(names)) array."""
        return np.column_stack([self[n] for n in names])

    @property
    def duration(self) -> float:
        """Last minus first sample time [s]."""
        return float(self._time[-1] - self._time[0]) if len(self) else 0.0

    @property
    def sample_rate(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self._time))) if len(self) > 1 else math.nan

    def __repr__(self) -> str:
        return (
            f"FlightLog({len(self)} samples, {self.duration:.3f} s, "
            f"{len(self._measured)} measured + {len(self._truth)} truth channels)"
        )

    def equals(self, other: FlightLog) -> bool:
        """Bit-for-bit equality of times, channels, units and kinds."""
        return (
            isinstance(other, FlightLog)
            and np.array_equal(self._time, other._time)
            and self._units == other._units
            and self._measured.keys() == other._measured.keys()
            and self._truth.keys() == other._truth.keys()
            and all(np.array_equal(self[n], other[n]) for n in self.names)
        )

    # -------------------------------------------------------------- validation
    def validate(self, required: Iterable[str] = ()) -> FlightLog:
        """Checks the log; raises :class:`FlightLogError` naming channel and sample.

        Checks: time is 1-D, finite and strictly increasing; every channel is a
        1-D array of the time's length with finite values; channel names are
        valid and unique across measured/truth; every channel has a known unit;
        every name in ``required`` is present. Returns self.
        """
        t = self._time
        if t.ndim != 1 or t.size == 0:
            raise FlightLogError(f"time: need a non-empty 1-D array, got shape {t.shape}")
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise FlightLogError(f"time: non-finite value {t[bad[0]]} at sample {bad[0]}")
        step = np.diff(t)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            i = bad[0] + 1
            raise FlightLogError(
                f"time: not strictly increasing at sample {i} "
                f"(t[{i - 1}] = {t[i - 1]:.9g} s, t[{i}] = {t[i]:.9g} s)"
            )
        for name in self._measured.keys() & self._truth.keys():
            raise FlightLogError(f"channel '{name}': present both as measured and as truth")
        for name in self.names:
            self._validate_channel(name)
        for name in required:
            self._check(name)
        return self

    def require(self, *names: str) -> FlightLog:
        """Raises :class:`FlightLogError` for the first channel of ``names`` not present."""
        return self.validate(required=names)

    def _validate_channel(self, name: str) -> None:
        if not _NAME.match(name):
            raise FlightLogError(
                f"channel '{name}': invalid name (letters, digits, '_' and '.', "
                "not starting with a digit)"
            )
        values = self[name]
        if values.ndim != 1 or values.size != self._time.size:
            raise FlightLogError(
                f"channel '{name}': {values.size} samples (shape {values.shape}), "
                f"time has {self._time.size}"
            )
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = bad[0]
            what = "NaN" if np.isnan(values[i]) else f"non-finite value {values[i]}"
            raise FlightLogError(
                f"channel '{name}': {what} at sample {i} (t = {self._time[i]:.9g} s)"
                + (f", {bad.size} bad samples in total" if bad.size > 1 else "")
            )
        unit = self._units.get(name)
        if unit is None:
            raise FlightLogError(f"channel '{name}': no unit given")
        if unit not in UNITS:
            raise FlightLogError(
                f"channel '{name}': unknown unit '{unit}' (known: {', '.join(UNITS)}; "
                "add one with register_unit)"
            )

    def _missing_message(self, name: str) -> str:
        return (
            f"missing channel '{name}' (measured: {', '.join(self._measured) or 'none'}; "
            f"truth: {', '.join(self._truth) or 'none'})"
        )

    # -------------------------------------------------------- transformations
    def _replace(self, time, pick) -> FlightLog:
        return FlightLog(
            time,
            {n: pick(v) for n, v in self._measured.items()},
            {n: pick(v) for n, v in self._truth.items()},
            self._units,
            self.metadata,
        )

    def slice(self, t_start: float | None = None, t_end: float | None = None) -> FlightLog:
        """Samples with ``t_start <= t <= t_end`` [s] (either bound may be None)."""
        keep = np.ones(self._time.size, bool)
        if t_start is not None:
            keep &= self._time >= t_start
        if t_end is not None:
            keep &= self._time <= t_end
        if not keep.any():
            raise FlightLogError(
                f"slice: no samples in [{t_start}, {t_end}] s "
                f"(log spans {self._time[0]} .. {self._time[-1]} s)"
            )
        return self._replace(self._time[keep], lambda v: v[keep])

    def with_measured(self, values: Mapping[str, Iterable[float]],
                      units: Mapping[str, str] | None = None) -> FlightLog:
        """A log with the measured channels ``values`` added or replaced (``units`` for
        new channels); the other channels, truth and metadata are kept."""
        return FlightLog(self._time, {**self._measured, **values}, self._truth,
                         {**self._units, **(units or {})}, self.metadata)

    def select(self, names: Iterable[str]) -> FlightLog:
        """A log with only the channels ``names`` (kinds kept)."""
        names = list(names)
        for n in names:
            self._check(n)
        return FlightLog(
            self._time,
            {n: v for n, v in self._measured.items() if n in names},
            {n: v for n, v in self._truth.items() if n in names},
            {n: self._units[n] for n in names},
            self.metadata,
        )

    def resample(
        self, rate_hz: float | None = None, time=None, method: str = "linear"
    ) -> FlightLog:
        """Channels on a new time base.

        Give either ``rate_hz`` (uniform grid from the first sample on) or
        ``time`` (strictly increasing, inside the log's span). ``method`` is
        "linear" or "previous" (sample-and-hold, right for held sensor values).
        Angles are interpolated as plain numbers: unwrap yaw first if it wraps.
        """
        if (rate_hz is None) == (time is None):
            raise ValueError("resample: give exactly one of rate_hz and time")
        if method not in ("linear", "previous"):
            raise ValueError(f"method: unknown resampling method {method!r}")
        t = self._time
        if rate_hz is not None:
            if not rate_hz > 0:
                raise ValueError(f"rate_hz: must be positive, got {rate_hz}")
            n = int(math.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1
            new_t = t[0] + np.arange(n) / rate_hz
        else:
            new_t = np.asarray(time, float)
            if new_t.size and (new_t[0] < t[0] or new_t[-1] > t[-1]):
                raise ValueError(
                    f"time: new time base [{new_t[0]}, {new_t[-1]}] s leaves the log's span "
                    f"[{t[0]}, {t[-1]}] s"
                )
        if method == "linear":
            return self._replace(new_t, lambda v: np.interp(new_t, t, v))
        index = np.clip(np.searchsorted(t, new_t, side="right") - 1, 0, t.size - 1)
        return self._replace(new_t, lambda v: v[index])

    # ---------------------------------------------------------------- files
    def _columns(self) -> list[tuple[str, str, np.ndarray]]:
        """(column header name, unit, values) with the truth prefix applied."""
        cols = [("time", "s", self._time)]
        cols += [(n, self._units[n], v) for n, v in self._measured.items()]
        cols += [(_TRUTH_PREFIX + n, self._units[n], v) for n, v in self._truth.items()]
        return cols

    def save(self, path: str | Path) -> Path:
        """Writes ``.csv`` or ``.parquet`` (chosen by the suffix); returns the path."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            self._save_csv(path)
        elif suffix in (".parquet", ".pq"):
            self._save_parquet(path)
        else:
            raise ValueError(f"path: unsupported suffix {path.suffix!r} (use .csv or .parquet)")
        return path

    @classmethod
    def load(cls, path: str | Path) -> FlightLog:
        """Reads a file written by :meth:`save` (or any CSV with ``name [unit]`` headers)."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            return cls._load_csv(path)
        if suffix in (".parquet", ".pq"):
            return cls._load_parquet(path)
        raise ValueError(f"path: unsupported suffix {path.suffix!r} (use .csv or .parquet)")

    def _save_csv(self, path: Path) -> None:
        cols = self._columns()
        header = ",".join(f"{name} [{unit}]" for name, unit, _ in cols)
        lines = [f"# {k}: {json.dumps(v)}" for k, v in self.metadata.items()]
        data = np.column_stack([v.astype(float) for _, _, v in cols])
        with path.open("w", encoding="utf-8", newline="\n") as f:
            for line in lines:
                f.write(line + "\n")
            f.write(header + "\n")
            np.savetxt(f, data, fmt="%.17g", delimiter=",")

    @classmethod
    def _load_csv(cls, path: Path) -> FlightLog:
        metadata: dict[str, object] = {}
        skip = 0
        with path.open(encoding="utf-8") as f:
            for line in f:
                if not line.startswith("#"):
                    header = line.rstrip("\n")
                    break
                key, _, value = line[1:].partition(":")
                metadata[key.strip()] = json.loads(value)
                skip += 1
            else:
                raise FlightLogError(f"{path}: no header line")
        parsed = []
        for i, field in enumerate(header.split(",")):
            m = _HEADER.match(field)
            if not m:
                raise FlightLogError(f"{path}: column {i} header {field!r} is not 'name [unit]'")
            parsed.append((m["name"], m["unit"].strip()))
        if parsed[0][0] != "time":
            first = header.split(",")[0]
            raise FlightLogError(f"{path}: first column must be 'time [s]', got {first!r}")
        data = np.loadtxt(path, delimiter=",", skiprows=skip + 1, ndmin=2)
        return cls._from_columns(parsed, list(data.T), metadata)

    @classmethod
    def _from_columns(cls, headers, columns, metadata) -> FlightLog:
        (_, time_unit), time = headers[0], columns[0]
        if time_unit != "s":
            raise FlightLogError(f"time: unit must be 's', got '{time_unit}'")
        measured, truth, units = {}, {}, {}
        for (name, unit), values in zip(headers[1:], columns[1:], strict=True):
            target = measured
            if name.startswith(_TRUTH_PREFIX):
                name, target = name[len(_TRUTH_PREFIX):], truth
            if name in units:
                raise FlightLogError(f"channel '{name}': duplicate column")
            target[name] = values
            units[name] = unit
        return cls(time, measured, truth, units, metadata)

    def _save_parquet(self, path: Path) -> None:
        pa, pq = _pyarrow()
        fields, arrays = [], []
        for name, unit, values in self._columns():
            kind = "truth" if name.startswith(_TRUTH_PREFIX) else "measured"
            fields.append(pa.field(name, pa.float64(), metadata={"unit": unit, "kind": kind}))
            arrays.append(pa.array(values.astype(float)))
        schema = pa.schema(fields, metadata={"flight_log": json.dumps(self.metadata)})
        pq.write_table(pa.Table.from_arrays(arrays, schema=schema), path)

    @classmethod
    def _load_parquet(cls, path: Path) -> FlightLog:
        pa, pq = _pyarrow()
        # One file: read_table would import pyarrow's dataset API for it, which builds every
        # compute function at import (a tenth of a second).
        with pq.ParquetFile(path) as file:
            table = file.read()
        headers, columns = [], []
        for field, column in zip(table.schema, table.columns, strict=True):
            meta = field.metadata or {}
            if b"unit" not in meta:
                raise FlightLogError(f"channel '{field.name}': no unit in the Parquet metadata")
            headers.append((field.name, meta[b"unit"].decode()))
            columns.append(column.to_numpy())
        if not headers or headers[0][0] != "time":
            raise FlightLogError(f"{path}: first column must be 'time'")
        if not pa.types.is_float64(table.schema.field(0).type):
            raise FlightLogError(f"{path}: column 'time' is stored as "
                                 f"{table.schema.field(0).type}; sample times need float64 "
                                 "(double) to stay uniform")
        schema_meta = table.schema.metadata or {}
        metadata = json.loads(schema_meta.get(b"flight_log", b"{}"))
        return cls._from_columns(headers, columns, metadata)


def _frozen(values, what: str) -> np.ndarray:
    """A read-only float copy of ``values``; FlightLogError naming ``what`` if not numeric."""
    try:
        out = np.array(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise FlightLogError(f"{what}: values are not numeric ({exc})") from None
    out.setflags(write=False)
    return out


def _pyarrow():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("Parquet flight logs need pyarrow: pip install pyarrow") from exc
    return pa, pq
