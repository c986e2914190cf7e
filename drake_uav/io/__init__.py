"""Flight logs: the FlightLog container, the canonical channels and the readers.

* :class:`FlightLog`: time-indexed channels with units, measured and truth kept
  apart; ``FlightLog.save`` / ``FlightLog.load`` write and read ``.csv`` and
  ``.parquet`` (a CSV round trip is exact).
* :func:`read_log`: one entry point for CSV, ArduPilot DataFlash ``.bin``, PX4
  ``.ulg``, MAVLink telemetry ``.tlog`` and Parquet; the measured channels get the
  canonical names and SI units of :data:`CHANNELS`, and the autopilot readers record
  each stream's native rate (``metadata["streams"]``). The ``.bin``, ``.ulg`` and
  ``.tlog`` readers (:mod:`drake_uav.io.ardupilot`, :mod:`drake_uav.io.px4`,
  :mod:`drake_uav.io.tlog`) load on first use, because pymavlink and pyulog are slow
  to import. :func:`drake_uav.io.tlog_writer.write_tlog` writes a FlightLog as a
  ``.tlog``, :func:`drake_uav.io.grouped_csv_writer.write_grouped_csv` as a CSV with a
  time column per group; :mod:`drake_uav.io.esc` names the ESC telemetry channels.
* :func:`extra_channels`: the measured channels beyond the canonical ones (a tension,
  a battery voltage, ...) with their units; every non-canonical CSV column, a default
  set of physical signals of ``.bin`` and ``.ulg`` logs and the fields named with
  ``extra_channels=`` (:mod:`drake_uav.io.extras`).
* :class:`FieldSource` (a custom logged field as a channel) and
  :class:`ActuatorMapping` (servo outputs to surface deflections and throttle)
  configure the binary readers.

See docs/flight_logs.md.
"""

from drake_uav.io.csv_log import read_csv
from drake_uav.io.extras import extra_channels
from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError, register_unit
from drake_uav.io.readers import read_log
from drake_uav.io.streams import (
    CHANNELS,
    FORMATS,
    ActuatorChannel,
    ActuatorMapping,
    FieldSource,
    Stream,
    align_streams,
    require_channels,
)

__all__ = [
    "CHANNELS",
    "FORMATS",
    "UNITS",
    "ActuatorChannel",
    "ActuatorMapping",
    "FieldSource",
    "FlightLog",
    "FlightLogError",
    "Stream",
    "align_streams",
    "extra_channels",
    "read_csv",
    "read_log",
    "register_unit",
    "require_channels",
]
