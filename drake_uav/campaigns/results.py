"""Campaign results on disk: one Parquet row per run, streamed in parts, resumable.

Columns (in this order, then the parameter and metric columns sorted by name):

==================  ========  ===================================================
column              type      content
==================  ========  ===================================================
``point``           int64     grid point index
``seed``            int64     run seed
``status``          string    ``"ok"`` or ``"error"``
``error``           string    ``"ExceptionType: message"`` of a failed run, else null
``wall_time_s``     float64   wall time of the run [s] (varies between runs of
                              the same campaign: see :data:`NONDETERMINISTIC`)
``version``         string    ``drake_uav`` version that ran it
``param.<name>``    any       a parameter (a column of mixed kinds is JSON text)
``metric.<name>``   any       a metric; null in error rows
==================  ========  ===================================================

While a campaign runs, finished rows go to part files in ``<out>.parts/`` (each
written to a temporary name and renamed, so an interruption never leaves half a
part). When every run is done the parts are merged into ``<out>`` (rows sorted
by (point, seed), written atomically) and removed. A resumed campaign reads the
rows already in ``<out>`` and its parts and runs only the missing keys.

The file's schema metadata holds the campaign definition (``drake_uav.campaign``)
so that a resume with another definition is refused and comparisons know the grid.
An existing ``<out>`` that is not campaign results (another Parquet file, any other file)
is never overwritten: :func:`check_results_target` refuses it before any run.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from drake_uav.reporting.output import OutputRefusedError, check_writable

__all__ = [
    "FIXED_COLUMNS",
    "NONDETERMINISTIC",
    "PARAM",
    "METRIC",
    "ResultsStore",
    "check_results_target",
    "read_results",
    "results_equal",
    "campaign_definition",
    "metric_columns",
    "param_columns",
]

FIXED_COLUMNS = ("point", "seed", "status", "error", "wall_time_s", "version")
NONDETERMINISTIC = ("wall_time_s",)
"""Columns that differ between two runs of the same campaign; compare without them."""
PARAM, METRIC = "param.", "metric."
_META_KEY = b"drake_uav.campaign"
_JSON_KEY = b"json"
_FIXED_TYPES = {"point": pa.int64(), "seed": pa.int64(), "status": pa.string(),
                "error": pa.string(), "wall_time_s": pa.float64(), "version": pa.string()}


def _plain(value: Any) -> Any:
    """numpy scalars -> Python scalars; other values unchanged."""
    if isinstance(value, np.generic):
        return value.item()
    return value


def _column_type(values: Sequence[Any]) -> tuple[pa.DataType, bool]:
    """Arrow type of a column of Python values (None = null); True if JSON-encoded."""
    kinds = {type(v) for v in values if v is not None}
    if not kinds:
        return pa.float64(), False
    if kinds == {bool}:
        return pa.bool_(), False
    if kinds == {int}:
        return pa.int64(), False
    if kinds <= {int, float}:
        return pa.float64(), False
    if kinds == {str}:
        return pa.string(), False
    return pa.string(), True


def _to_table(rows: Sequence[Mapping[str, Any]], definition: Mapping[str, Any]) -> pa.Table:
    """Rows sorted by (point, seed) -> an Arrow table with the column order of the module."""
    rows = sorted(rows, key=lambda r: (r["point"], r["seed"]))
    extra = sorted({k for r in rows for k in r} - set(FIXED_COLUMNS))
    arrays, fields = [], []
    for name in (*FIXED_COLUMNS, *extra):
        values = [_plain(r.get(name)) for r in rows]
        if name in _FIXED_TYPES:
            kind, encode = _FIXED_TYPES[name], False
        else:
            kind, encode = _column_type(values)
        if encode:
            values = [None if v is None else json.dumps(v, sort_keys=True) for v in values]
        elif kind == pa.float64():
            values = [None if v is None else float(v) for v in values]
        arrays.append(pa.array(values, type=kind))
        fields.append(pa.field(name, kind, metadata={_JSON_KEY: b"1"} if encode else None))
    meta = {_META_KEY: json.dumps(dict(definition), sort_keys=True).encode()}
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))


def _write_atomic(table: pa.Table, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def campaign_definition(table: pa.Table) -> dict[str, Any] | None:
    """The campaign definition stored in a results table, or None."""
    meta = table.schema.metadata or {}
    return json.loads(meta[_META_KEY]) if _META_KEY in meta else None


def param_columns(table: pa.Table) -> list[str]:
    return [c for c in table.column_names if c.startswith(PARAM)]


def metric_columns(table: pa.Table) -> list[str]:
    return [c for c in table.column_names if c.startswith(METRIC)]


def check_results_target(path: str | os.PathLike, what: str = "--out") -> Path:
    """Checks that campaign results may be written to ``path``: a new file, or the results
    of a campaign (resumed; its definition is checked when the rows are read).

    Raises
    ------
    OutputRefusedError
        ``path`` is a folder, a file that is not campaign results (it is left as it was), or
        cannot be written; or its ``.parts`` folder holds other files.
    """
    path = Path(os.path.abspath(path))
    shown = f"{what} {os.fspath(path)}"
    if path.is_dir():
        raise OutputRefusedError(f"{shown}: is a folder; give a .parquet file name")
    if path.exists():
        try:
            schema = pq.read_schema(path)
        except (OSError, pa.ArrowException) as err:
            raise OutputRefusedError(f"{shown}: exists and is not a Parquet file ({err}); it is "
                                     "not replaced, give another file name") from None
        missing = [c for c in FIXED_COLUMNS if c not in schema.names]
        if missing or _META_KEY not in (schema.metadata or {}):
            raise OutputRefusedError(f"{shown}: exists and is not campaign results (no "
                                     f"{', '.join(missing) or 'campaign definition'}); it is not "
                                     "replaced, give another file name")
    parts = path.with_name(path.name + ".parts")
    if parts.exists() and (not parts.is_dir() or any(
            not (p.name.startswith("part-") and p.name.endswith(".parquet"))
            for p in parts.iterdir())):
        raise OutputRefusedError(f"{shown}: {parts} holds files that are not parts of a "
                                 "campaign; move them away")
    check_writable(path, what)
    return path


def read_results(path: str | os.PathLike) -> pa.Table:
    """A finished campaign's results (Parquet), checked for the fixed columns."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no campaign results (no such file)")
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ValueError(f"{path}: not campaign results (not a readable Parquet file: "
                         f"{reason})") from None
    missing = [c for c in FIXED_COLUMNS if c not in table.column_names]
    if missing:
        raise ValueError(f"{path}: not a campaign result (missing columns {missing})")
    return table


def results_equal(a: pa.Table, b: pa.Table,
                  exclude: Iterable[str] = NONDETERMINISTIC) -> bool:
    """True if both tables hold the same rows, bit for bit, outside ``exclude`` columns.

    Floats compare by their bits (NaN equals NaN), so this is the test of a
    reproducible campaign.
    """
    exclude = set(exclude)
    names = [c for c in a.column_names if c not in exclude]
    if names != [c for c in b.column_names if c not in exclude] or a.num_rows != b.num_rows:
        return False
    for name in names:
        x, y = a.column(name).combine_chunks(), b.column(name).combine_chunks()
        if x.type != y.type:
            return False
        if pa.types.is_floating(x.type):
            xs = np.asarray(x.to_numpy(zero_copy_only=False), float).view(np.uint64)
            ys = np.asarray(y.to_numpy(zero_copy_only=False), float).view(np.uint64)
            if not (np.array_equal(xs, ys) and x.is_null().equals(y.is_null())):
                return False
        elif not x.equals(y):
            return False
    return True


class ResultsStore:
    """The rows of one campaign on disk: the merged file plus the parts of a run.

    Args:
        path: the merged Parquet file (``<out>``); parts go to ``<out>.parts/``.
        definition: the campaign definition (:meth:`Campaign.definition`); rows on
            disk from another definition raise ``ValueError``.
    """

    def __init__(self, path: str | os.PathLike, definition: Mapping[str, Any]):
        self.path = Path(path)
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.definition = dict(definition)
        self._pending: list[dict[str, Any]] = []

    def _check_definition(self, table: pa.Table, where: Path) -> None:
        stored = campaign_definition(table)
        if stored is not None and json.dumps(stored, sort_keys=True) != json.dumps(
                self.definition, sort_keys=True):
            raise ValueError(f"{where}: holds rows of another campaign definition "
                             f"({json.dumps(stored, sort_keys=True)}); give another output "
                             f"file or delete it")

    def load(self) -> list[dict[str, Any]]:
        """Rows already on disk (merged file and parts); :func:`check_results_target` first."""
        check_results_target(self.path, "campaign results")
        files = [self.path] if self.path.is_file() else []
        if self.parts.is_dir():
            files += sorted(self.parts.glob("part-*.parquet"))
        rows = []
        for file in files:
            table = pq.read_table(file)
            self._check_definition(table, file)
            rows += _decoded_rows(table)
        return rows

    def add(self, row: Mapping[str, Any]) -> None:
        """Queues a finished row; :meth:`flush` writes the queue as one part."""
        self._pending.append(dict(row))

    def flush(self) -> None:
        if not self._pending:
            return
        self.parts.mkdir(parents=True, exist_ok=True)
        name = f"part-{uuid.uuid4().hex}.parquet"
        _write_atomic(_to_table(self._pending, self.definition), self.parts / name)
        self._pending = []

    def merge(self, rows: Sequence[Mapping[str, Any]]) -> pa.Table:
        """Writes ``rows`` (all of them) as the merged file and removes the parts."""
        self.flush()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        unique = {(r["point"], r["seed"]): r for r in rows}
        table = _to_table(list(unique.values()), self.definition)
        _write_atomic(table, self.path)
        if self.parts.is_dir():
            for part in self.parts.glob("part-*.parquet"):
                part.unlink()
            self.parts.rmdir()
        return table


def _decoded_rows(table: pa.Table) -> list[dict[str, Any]]:
    """Rows of a results table as dicts, JSON-encoded columns decoded back."""
    rows = table.to_pylist()
    for field in table.schema:
        if (field.metadata or {}).get(_JSON_KEY) == b"1":
            for r in rows:
                if r[field.name] is not None:
                    r[field.name] = json.loads(r[field.name])
    return rows
