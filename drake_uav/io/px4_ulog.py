"""A PX4 ULog (``.ulg``) file as numpy topics, parameters and info, through pyulog.

pyulog reads only the topics asked for (its message filter) into numpy arrays.
Time is ``timestamp_sample`` where a topic has it (the sensor sample time) and
it increases strictly, else ``timestamp`` (publication time), in us since boot
-> s: a controller that publishes twice for one gyro sample repeats its
``timestamp_sample`` (``actuator_controls_1`` of PX4 1.11). A file cut inside a
message (an SD-card log whose last write did not finish) keeps the messages
before the cut, with a warning; a file cut before its first data message is an
error.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from pathlib import Path

import numpy as np
from pyulog import ULog
from pyulog.core import ULogException

from drake_uav.io.flight_log import FlightLogError
from drake_uav.io.streams import CHANNELS, Stream

__all__ = ["ULogFile", "channel_stream"]


class _ShortReads(io.BufferedReader):
    """A file that remembers the first read returning fewer bytes than asked.

    pyulog stops quietly where a file is cut; a clean end of file shows only as
    an empty 3-byte header read, anything else short is a truncated message.
    """

    short: tuple[int, int, int] | None = None  # (position, asked, got)

    def read(self, size=-1, _read=io.BufferedReader.read):
        data = _read(self, size)
        got = len(data)
        if got < size and (got or size != 3) and self.short is None:
            self.short = (self.tell() - got, size, got)
        return data


class ULogFile:
    """The topics of a ULog file as (time [s], fields) per (topic, multi-id).

    Attributes:
        source: the file name, for messages.
        data: (topic, multi-id) -> numeric field name -> values.
        parameters: the parameters at the start of the log (name -> value).
        parameter_changes: (time [s], name, value) of the changes during the log.
        info: the log's information messages (``ver_sw_release``, ``sys_name``, ...).
    """

    def __init__(self, path: Path, topics: list[str], allow_truncated: bool):
        self.source = str(path)
        handle = _ShortReads(io.FileIO(path, "r"))
        printed = io.StringIO()  # pyulog prints a line per corrupt message it skips
        try:
            with contextlib.redirect_stdout(printed):
                ulog = ULog(handle, message_name_filter_list=topics)
        except ULogException as err:
            raise FlightLogError(f"{path}: not a PX4 ULog file ({err})") from None
        finally:
            handle.close()
        # Numeric fields only: a field of another type in a topic the readers use comes
        # from a corrupt format definition, and is then reported as missing.
        self.data = {(d.name, d.multi_id): {f: v for f, v in d.data.items()
                                            if v.dtype.kind in "biuf"}
                     for d in ulog.data_list}
        if handle.short is not None:
            position, asked, got = handle.short
            message = (f"{path}: truncated file: a message at byte {position} needs {asked} "
                       f"bytes, {got} remain")
            if not allow_truncated or not self.data:
                raise FlightLogError(message + (" (allow_truncated=True drops it)"
                                                if self.data else " (no data before it)"))
            # stacklevel 4: the caller of read_log (read_px4 builds this object).
            warnings.warn(message + "; dropped", stacklevel=4)
        elif ulog.file_corruption or printed.getvalue():
            reports = len(printed.getvalue().splitlines())
            warnings.warn(f"{path}: corrupt data skipped by the ULog parser"
                          + (f" ({reports} report(s))" if reports else ""), stacklevel=4)
        # A parameter's value is a number; another type comes from a corrupt definition.
        self.parameters = {k: _plain(v) for k, v in ulog.initial_parameters.items()
                           if isinstance(v, _NUMBERS)}
        self.parameter_changes = [(t / 1e6, name, _plain(v))
                                  for t, name, v in ulog.changed_parameters
                                  if isinstance(v, _NUMBERS)]
        self.info = dict(ulog.msg_info_dict)

    def has(self, topic: str, instance: int = 0) -> bool:
        return (topic, instance) in self.data

    def instances(self, topic: str) -> list[int]:
        """The multi-ids the log has of ``topic``."""
        return sorted(i for name, i in self.data if name == topic)

    def fields(self, topic: str, instance: int = 0) -> dict[str, np.ndarray]:
        return self.data[(topic, instance)]

    def get(self, topic: str, fields: list[str], instance: int = 0
            ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(time [s], field -> float values) of one topic instance."""
        data = self.fields(topic, instance)
        missing = [f for f in ("timestamp", *fields) if f not in data]
        if missing:
            raise FlightLogError(f"{self.source}: topic {topic} has no field {missing[0]} "
                                 f"(fields: {', '.join(data)})")
        stamp = data.get("timestamp_sample")
        if stamp is None or not np.all(stamp) or np.any(np.diff(stamp.astype(np.int64)) <= 0):
            stamp = data["timestamp"]
        return stamp.astype(float) / 1e6, {f: data[f].astype(float) for f in fields}

    def parameter(self, name: str, default=None):
        """The parameter's value at the start of the log, else ``default``."""
        return self.parameters.get(name, default)


_NUMBERS = (int, float, np.integer, np.floating)


def _plain(value):
    """A parameter value as a JSON-ready int or float."""
    return int(value) if isinstance(value, (int, np.integer)) else float(value)


def channel_stream(name: str, time: np.ndarray, channels: dict[str, np.ndarray],
                   fields: dict[str, str], **kwargs) -> Stream:
    """A :class:`Stream` of canonical channels (units from :data:`CHANNELS`);
    ``fields`` names each channel's logged field (``topic.field`` in messages)."""
    topic = name.split(".")[0]
    return Stream(name, time, channels, {n: CHANNELS[n][0] for n in channels},
                  fields={c: f"{topic}.{f}" for c, f in fields.items()}, **kwargs)
