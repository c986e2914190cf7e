"""ArduPilot DataFlash (``.bin``) files: format table, message offsets, vectorised decoding.

pymavlink's ``DFReader_binary`` indexes the file (the FMT messages and the byte
offset of every message); each message type is then decoded at once as a numpy
structured array with pymavlink's format table and multipliers. Time is
``TimeUS / 1e6`` [s since boot].

SD-card logs often end in a half-written record followed by block padding:
that last record is dropped with a warning (``allow_truncated``). Bytes that
cannot be parsed although complete messages follow them are corrupt data, an
error whatever ``allow_truncated`` says. pymavlink reports every byte it skips on
standard error; those reports become one warning per file.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from pymavlink.DFReader import FORMAT_TO_STRUCT, DFReader_binary

from drake_uav.io.flight_log import FlightLogError

__all__ = ["DataFlash"]

_HEAD = (0xA3, 0x95, 0x80)  # every DataFlash log starts with a FMT message
_TRAILING_SLACK = 528
"""Bytes at the end of a log that may be block padding (pymavlink's allowance)."""
_PADDING_RUN = 8
"""Shortest run of 0x00 or 0xFF bytes at the end of a file taken for block padding."""


@contextlib.contextmanager
def _printed_into(sink: io.StringIO):
    """Collects what is printed meanwhile on standard output and error, by Python code and
    by C code (pymavlink's compiled indexer prints on file descriptor 2), into ``sink``."""
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile() as scratch:
        saved = [os.dup(1), os.dup(2)]
        os.dup2(scratch.fileno(), 1)
        os.dup2(scratch.fileno(), 2)
        try:
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                yield
        finally:
            for fd, copy in zip((1, 2), saved, strict=True):
                os.dup2(copy, fd)
                os.close(copy)
            scratch.seek(0)
            sink.write(scratch.read().decode(errors="replace"))


class _Index(DFReader_binary):
    """pymavlink's DataFlash index (formats, message offsets) without its clock.

    Every message read here carries ``TimeUS``, so the clock search, which
    parses the whole log message by message when there is no GPS, is skipped.
    """

    def init_clock(self):
        self.clock = None


def _dtype(fmt) -> np.dtype:
    """numpy dtype of the payload of DataFlash format ``fmt`` (pymavlink's table)."""
    fields = []
    for column, char in zip(fmt.columns, fmt.format, strict=True):
        code = FORMAT_TO_STRUCT[char][0]
        fields.append((column, f"S{code[:-1]}" if code.endswith("s") else f"<{code}"))
    return np.dtype(fields)


class DataFlash:
    """A DataFlash file: its formats, message offsets and vectorised decoding.

    Args:
        path: the ``.bin`` file.
        allow_truncated: drop a half-written last record and unparsable block
            padding at the end with a warning instead of raising.

    Raises:
        FlightLogError: not a DataFlash log, malformed formats, corrupt data
            followed by complete messages, or (strict) a truncated end.
    """

    def __init__(self, path: Path, allow_truncated: bool = True):
        self.source = str(path)
        self.data = np.fromfile(path, dtype=np.uint8)
        if self.data.size < 3 or tuple(self.data[:3]) != _HEAD:
            raise FlightLogError(f"{path}: not an ArduPilot DataFlash log (no FMT message at "
                                 "the start of the file)")
        skipped = io.StringIO()
        try:
            with _printed_into(skipped):  # pymavlink prints a line per skipped byte
                index = _Index(str(path))
        except Exception as err:  # pymavlink raises bare Exceptions on malformed formats
            raise FlightLogError(f"{path}: unreadable DataFlash log ({err})") from None
        try:
            self.formats = {f.name: f for f in index.formats.values()}
            self.offsets = {name: np.asarray(index.offsets[f.type], np.int64)
                            for name, f in self.formats.items()}
        finally:
            index.close()
        if not self._check_coverage(allow_truncated):
            self._report_skipped(skipped.getvalue())

    def _report_skipped(self, report: str) -> None:
        """One warning for what pymavlink printed while indexing that the coverage check
        did not account for (a bad header inside the trailing slack, an unknown message
        type, a malformed format)."""
        lines = [line.strip() for line in report.splitlines() if line.strip()]
        bad = sum(line.startswith("bad header") for line in lines)
        other = [line for line in lines if not line.startswith("bad header")]
        what = ([f"{bad} corrupt byte(s) skipped"] if bad else []) + (
            [f"the DataFlash parser reported '{other[0]}'"
             + (f" and {len(other) - 1} more line(s)" if len(other) > 1 else "")]
            if other else [])
        if what:
            warnings.warn(f"{self.source}: {'; '.join(what)}", stacklevel=4)

    def _truncated(self, message: str, allow_truncated: bool) -> None:
        if not allow_truncated:
            raise FlightLogError(message + " (allow_truncated=True drops it)")
        warnings.warn(message + "; dropped", stacklevel=5)

    def _check_coverage(self, allow_truncated: bool) -> bool:
        """Truncated last message, unparsed tail, skipped corrupt bytes (pymavlink resyncs);
        True when a warning reported one of them."""
        size, end, covered, where, reported = self.data.size, 0, 0, None, False
        padding = self._padding_start()
        for name, offsets in self.offsets.items():
            if not offsets.size:
                continue
            length = self.formats[name].len
            last = int(offsets[-1])
            cut = self._cut_short(name, last, length, padding)
            if cut:
                self._truncated(f"{self.source}: truncated file: the last {name} message "
                                f"(byte {last}) {cut}", allow_truncated)
                reported = True
                self.offsets[name] = offsets = offsets[:-1]
                if not offsets.size:
                    continue
                last = int(offsets[-1])
            covered += offsets.size * length
            if last + length > end:
                end, where = last + length, name
        if size - end > _TRAILING_SLACK:
            message = (f"{self.source}: the {size - end} bytes from byte {end} on (after the "
                       f"last complete message, {where}) could not be parsed")
            if self._message_in(end):
                raise FlightLogError(message + ": corrupt data in the log")
            self._truncated(message + ": a truncated log", allow_truncated)
            reported = True
        if covered < end:
            warnings.warn(f"{self.source}: {end - covered} bytes of corrupt data skipped",
                          stacklevel=4)
            reported = True
        return reported

    def _cut_short(self, name: str, last: int, length: int, padding: int) -> str:
        """Why the last message ``name`` (at byte ``last``) is incomplete, or ""."""
        size = self.data.size
        if last + length > size:
            return f"needs {length} bytes, {size - last} remain"
        if last < padding < last + length < size:
            return f"runs into the block padding that ends the file (from byte {padding})"
        return ""

    def _padding_start(self) -> int:
        """Start of the run of >= 8 equal 0x00 or 0xFF bytes that ends the file (block
        padding after a power loss), or the file size when there is none."""
        data, window = self.data, 4096
        if data[-1] not in (0x00, 0xFF):
            return data.size
        while True:  # look back from the end only: the padding is a block or so
            tail = data[max(data.size - window, 0):]
            other = np.flatnonzero(tail != data[-1])
            if other.size or tail.size == data.size:
                break
            window *= 8
        start = data.size - tail.size + (int(other[-1]) + 1 if other.size else 0)
        return start if data.size - start >= _PADDING_RUN else data.size

    def _message_in(self, start: int) -> bool:
        """Whether a complete message of a known type starts at or after byte ``start``."""
        tail = self.data[start:]
        at = np.flatnonzero((tail[:-2] == 0xA3) & (tail[1:-1] == 0x95))
        lengths = {f.type: f.len for f in self.formats.values()}
        return any(int(tail[i + 2]) in lengths and i + lengths[int(tail[i + 2])] <= tail.size
                   for i in at)

    def has(self, name: str) -> bool:
        """Whether the log holds at least one message ``name``."""
        return name in self.formats and self.offsets[name].size > 0

    def fields(self, name: str) -> list[str]:
        """The columns of message ``name``."""
        return list(self.formats[name].columns)

    def records(self, name: str) -> np.ndarray:
        """Every message ``name`` as a numpy structured array (raw stored values)."""
        fmt = self.formats[name]
        if len(fmt.columns) != len(fmt.format):
            raise FlightLogError(f"{self.source}: FMT of {name} gives {len(fmt.format)} types "
                                 f"for {len(fmt.columns)} columns (a corrupt FMT message)")
        dtype = _dtype(fmt)
        if dtype.itemsize != fmt.len - 3:
            raise FlightLogError(f"{self.source}: FMT of {name} gives length {fmt.len}, its "
                                 f"format '{fmt.format}' needs {dtype.itemsize + 3}")
        windows = np.lib.stride_tricks.sliding_window_view(self.data, dtype.itemsize)
        return windows[self.offsets[name] + 3].view(dtype)[:, 0]

    def check_time(self, name: str) -> None:
        """Raises FlightLogError for a message timed in ms (firmware before TimeUS)."""
        columns = self.formats[name].colhash
        if "TimeUS" not in columns and "TimeMS" in columns:
            raise FlightLogError(f"{self.source}: unsupported firmware (TimeMS log): message "
                                 f"{name} is timed in ms; ArduPilot logs with TimeUS (3.4 and "
                                 "later) are read")

    def read(self, name: str, fields: list[str], instance_column: str | None = None,
             instance: int | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        """(time [s], field -> values) of message ``name`` (multipliers applied), keeping
        the messages whose ``instance_column`` equals ``instance`` when the message has
        that column; None when there is no such message."""
        if not self.has(name):
            return None
        self.check_time(name)
        fmt = self.formats[name]
        missing = [f for f in ("TimeUS", *fields) if f not in fmt.colhash]
        if missing:
            raise FlightLogError(f"{self.source}: message {name} has no field {missing[0]} "
                                 f"(fields: {', '.join(fmt.columns)})")
        records = self.records(name)
        if instance is not None and instance_column in fmt.colhash:
            records = records[records[instance_column] == instance]
            if records.size == 0:
                return None
        out = {}
        for field in fields:
            values = self._numbers(name, records, field)
            mult = fmt.msg_mults[fmt.colhash[field]]
            if mult is not None:
                # Divide by the inverse of a fractional multiplier, as pymavlink does:
                # 1234 / 100 is exact to the last bit where 1234 * 0.01 is not.
                values = values / (1.0 / mult) if 0.0 < mult < 1.0 else values * mult
            out[field] = values
        return self._numbers(name, records, "TimeUS") / 1e6, out

    def _numbers(self, name: str, records: np.ndarray, field: str) -> np.ndarray:
        """Field ``field`` of message ``name``'s ``records`` as floats; FlightLogError when
        the log's format gives it as text (a corrupt FMT message)."""
        if records.dtype[field].kind not in "biuf":
            raise FlightLogError(f"{self.source}: message {name}: field {field} is "
                                 f"'{records.dtype[field]}', not a number (a corrupt FMT "
                                 "message)")
        return records[field].astype(float)

    def strings(self, name: str, field: str) -> tuple[np.ndarray, list[str]] | None:
        """(time [s], decoded text) of a text field of message ``name``, or None."""
        if not self.has(name) or field not in self.formats[name].colhash:
            return None
        records = self.records(name)
        if records.dtype[field].kind != "S":
            raise FlightLogError(f"{self.source}: message {name}: field {field} is "
                                 f"'{records.dtype[field]}', not text (a corrupt FMT message)")
        text = [raw.split(b"\0", 1)[0].decode("ascii", "replace") for raw in records[field]]
        time = (self._numbers(name, records, "TimeUS") / 1e6
                if "TimeUS" in records.dtype.names else np.zeros(len(text)))
        return time, text

    def parameters(self) -> dict[str, float]:
        """The log's parameters (PARM Name -> last Value)."""
        got = self.strings("PARM", "Name")
        if got is None:
            return {}
        if "Value" not in self.formats["PARM"].colhash:
            raise FlightLogError(f"{self.source}: message PARM has no field Value (fields: "
                                 f"{', '.join(self.formats['PARM'].columns)})")
        values = self._numbers("PARM", self.records("PARM"), "Value")
        return dict(zip(got[1], values.tolist(), strict=True))
