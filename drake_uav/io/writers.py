"""Writers of ArduPilot DataFlash (``.bin``) and PX4 ULog (``.ulg``) files.

Written from the published file layouts, independently of the readers, so that
files made here test the readers against the format rather than against themselves
(and real tools, pymavlink and pyulog, read them).

* DataFlash: every message is ``0xA3 0x95 <type>`` followed by its packed fields
  (little-endian). Type 128 is ``FMT`` (Type B, Length B, Name 4s, Format 16s,
  Columns 64s) and defines the other types. Scaled integer formats: ``c``/``C``
  int16/uint16 x 0.01, ``e``/``E`` int32/uint32 x 0.01, ``L`` int32 x 1e-7.
* ULog: a 16-byte header (``ULog`` magic, version, start time in us), then
  messages ``uint16 size, uint8 type, payload``: ``B`` flag bits, ``F`` formats,
  ``I`` info, ``P`` parameters, then ``A`` subscriptions, ``D`` data (``uint16 msg_id``
  + fields) and ``L`` logged text.

Both writers collect messages as numpy byte rows and write them sorted by time
(a stable sort: messages of one time keep the order they were added in).
After ``to_bytes``, ``body_offset`` is the byte offset of the first time-ordered
message and ``record_sizes`` the length of each of them in file order (to cut a
file inside a chosen message, as a power loss during writing does).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

__all__ = ["DataFlashWriter", "ULogWriter"]

# DataFlash format character -> (numpy dtype, multiplier of the stored integer).
_DF_TYPES = {
    "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None),
    "i": ("<i4", None), "I": ("<u4", None), "q": ("<i8", None), "Q": ("<u8", None),
    "f": ("<f4", None), "d": ("<f8", None), "M": ("u1", None),
    "n": ("S4", None), "N": ("S16", None), "Z": ("S64", None),
    "c": ("<i2", 100.0), "C": ("<u2", 100.0), "e": ("<i4", 100.0), "E": ("<u4", 100.0),
    "L": ("<i4", 1e7),
}

_FMT_TYPE = 0x80


class _TimeOrderedWriter:
    """Messages kept as (time [us], rows of bytes) blocks, written in time order after a
    head of definitions."""

    def __init__(self):
        self._blocks: list[tuple[np.ndarray, np.ndarray]] = []
        self.body_offset, self.record_sizes = 0, np.zeros(0, np.int64)

    def _assemble(self, head: bytes) -> bytes:
        rows = _sorted_rows(self._blocks)
        self.body_offset, self.record_sizes = len(head), np.array([len(r) for r in rows])
        return head + b"".join(rows)

    def to_bytes(self) -> bytes:
        raise NotImplementedError

    def save(self, path: str | Path) -> Path:
        """Writes :meth:`to_bytes` to ``path``; returns the path."""
        path = Path(path)
        path.write_bytes(self.to_bytes())
        return path


class DataFlashWriter(_TimeOrderedWriter):
    """Collects DataFlash messages and writes them (definitions first, then by time)."""

    def __init__(self):
        super().__init__()
        self._formats: dict[str, tuple[int, str, tuple[str, ...], np.dtype]] = {}
        self._definitions: list[bytes] = []

    def define(self, name: str, fmt: str, columns: str) -> None:
        """Declares message ``name`` with format characters ``fmt`` and comma-separated columns."""
        cols = tuple(columns.split(","))
        if not (len(cols) == len(fmt) <= 16 and len(columns) <= 64 and len(name) <= 4):
            raise ValueError(f"message {name}: format '{fmt}' and columns '{columns}' do not "
                             "fit a FMT message (name <= 4, 16 fields, 64 characters)")
        type_id = _FMT_TYPE + 1 + len(self._formats)
        dtype = np.dtype([("h1", "u1"), ("h2", "u1"), ("type", "u1")]
                         + [(c, _DF_TYPES[f][0]) for c, f in zip(cols, fmt, strict=True)])
        self._formats[name] = (type_id, fmt, cols, dtype)
        self._definitions.append(
            struct.pack("<BBBBB4s16s64s", 0xA3, 0x95, _FMT_TYPE, type_id, dtype.itemsize,
                        name.encode(), fmt.encode(), columns.encode()))

    def add(self, name: str, at=None, **columns) -> None:
        """Adds messages of ``name``: each column is a scalar or an array (physical units).

        The messages go into the file in the order of ``at`` [us] (default: TimeUS).
        """
        type_id, fmt, cols, dtype = self._formats[name]
        n = max(np.size(v) for v in columns.values())
        rows = np.zeros(n, dtype)
        rows["h1"], rows["h2"], rows["type"] = 0xA3, 0x95, type_id
        for col, f in zip(cols, fmt, strict=True):
            if col not in columns:
                continue
            values = np.broadcast_to(columns[col], (n,))
            mult = _DF_TYPES[f][1]
            if mult is not None:
                values = np.round(np.asarray(values, float) * mult)
            rows[col] = values
        order = columns.get("TimeUS", 0) if at is None else at
        time_us = np.broadcast_to(np.asarray(order, np.uint64), (n,))
        self._blocks.append((time_us, rows.view(np.uint8).reshape(n, dtype.itemsize)))

    def to_bytes(self) -> bytes:
        """The FMT messages, then every message in time order."""
        return self._assemble(b"".join(self._definitions))


# ULog field type -> numpy dtype.
_ULOG_TYPES = {
    "int8_t": "i1", "uint8_t": "u1", "int16_t": "<i2", "uint16_t": "<u2",
    "int32_t": "<i4", "uint32_t": "<u4", "int64_t": "<i8", "uint64_t": "<u8",
    "float": "<f4", "double": "<f8", "bool": "u1", "char": "u1",
}


# ULog scalar type of a Python info or parameter value.
_ULOG_VALUE = {int: ("int32_t", "<i"), float: ("float", "<f")}


def _ulog_message(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _sorted_rows(blocks: list[tuple[np.ndarray, np.ndarray]]) -> list[bytes]:
    """The byte rows of all blocks ordered by their times (stable)."""
    if not blocks:
        return []
    times = np.concatenate([t for t, _ in blocks])
    rows = [r for _, block in blocks for r in block]
    return [rows[i].tobytes() for i in np.argsort(times, kind="stable")]


class ULogWriter(_TimeOrderedWriter):
    """Collects ULog formats, subscriptions and data; writes them in timestamp order."""

    def __init__(self, start_us: int = 0):
        super().__init__()
        self._start_us = start_us
        self._definitions: list[bytes] = []
        self._topics: dict[str, np.dtype] = {}
        self._structures: dict[str, np.dtype] = {}
        self._subscriptions: list[bytes] = []
        self._next_id = 0

    def format(self, name: str, fields: str) -> None:
        """Declares topic ``name`` with fields ``"uint64_t timestamp;float[3] x;..."``; a
        field's type may be a structure declared before (:meth:`structure`)."""
        self._topics[name] = np.dtype([("msg_id", "<u2"), *self._fields(fields)])
        self._definitions.append(_ulog_message("F", f"{name}:{fields}".encode()))

    def structure(self, name: str, fields: str) -> None:
        """Declares the nested type ``name`` (``esc_report``), fields as :meth:`format`."""
        self._structures[name] = np.dtype(self._fields(fields))
        self._definitions.append(_ulog_message("F", f"{name}:{fields}".encode()))

    def _fields(self, fields: str) -> list[tuple]:
        parts = []
        for item in filter(None, fields.split(";")):
            type_str, field = item.split()
            size = 0
            if "[" in type_str:
                type_str, size = type_str[:-1].split("[")
                size = int(size)
            kind = self._structures.get(type_str) or _ULOG_TYPES[type_str]
            parts.append((field, kind, (size,) if size else ()))
        return parts

    def info(self, key: str, value: str | int, type_name: str = "uint32_t") -> None:
        """Adds an info message: a string (``char[len] key``) or an integer of
        ``type_name`` (e.g. ``uint32_t ver_sw_release``)."""
        if isinstance(value, str):
            type_key, packed = f"char[{len(value)}] {key}", value.encode()
        else:
            type_key = f"{type_name} {key}"
            packed = np.array([value], _ULOG_TYPES[type_name]).tobytes()
        self._definitions.append(_ulog_message(
            "I", bytes([len(type_key)]) + type_key.encode() + packed))

    def parameter(self, name: str, value: int | float) -> None:
        """Adds an initial parameter: ``int32_t`` for a Python int, else ``float``."""
        type_name, code = _ULOG_VALUE[int if isinstance(value, int | np.integer) else float]
        type_key = f"{type_name} {name}".encode()
        self._definitions.append(_ulog_message(
            "P", bytes([len(type_key)]) + type_key + struct.pack(code, value)))

    def text(self, timestamp_us: int, message: str, level: str = "6") -> None:
        """Adds a logged text message (``L``) at ``timestamp_us``; ``level`` is the
        syslog level character ('3' error, '4' warning, '6' info)."""
        payload = struct.pack("<BQ", ord(level), timestamp_us) + message.encode()
        row = np.frombuffer(_ulog_message("L", payload), np.uint8)[None, :]
        self._blocks.append((np.array([timestamp_us], np.uint64), row))

    def subscribe(self, name: str, multi_id: int = 0) -> int:
        """Adds an ``A`` message for topic ``name``; returns its message id."""
        msg_id = self._next_id
        self._next_id += 1
        self._subscriptions.append(
            _ulog_message("A", struct.pack("<BH", multi_id, msg_id) + name.encode()))
        return msg_id

    def data(self, name: str, msg_id: int, **columns) -> None:
        """Adds ``D`` messages of topic ``name``; ``timestamp`` [us] is required. A field of
        a nested structure is named ``field.member`` (``esc.esc_rpm``: (N, 8) values)."""
        dtype = self._topics[name]
        n = len(columns["timestamp"])
        rows = np.zeros(n, dtype)
        rows["msg_id"] = msg_id
        for key, value in columns.items():
            outer, _, member = key.partition(".")
            if member:
                rows[outer][member] = value
            else:
                rows[key] = value
        header = np.zeros(n, [("size", "<u2"), ("type", "u1")])
        header["size"], header["type"] = dtype.itemsize, ord("D")
        packed = np.concatenate([header.view(np.uint8).reshape(n, 3),
                                 rows.view(np.uint8).reshape(n, dtype.itemsize)], axis=1)
        self._blocks.append((np.asarray(columns["timestamp"], np.uint64), packed))

    def to_bytes(self) -> bytes:
        """Header, flag bits, definitions, subscriptions, then data and text in time order."""
        header = b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", self._start_us)
        flags = _ulog_message("B", bytes(16) + bytes(24))
        return self._assemble(header + flags + b"".join(self._definitions)
                              + b"".join(self._subscriptions))
