"""ESC telemetry: per-motor shaft speed, voltage, current and temperature as channels.

Electronic speed controllers with telemetry (DShot, BLHeli, KISS, UAVCAN) report
each motor's speed, supply voltage, current and temperature a few times a second.
The readers turn them into one channel per quantity and ESC, numbered from 0 in
the autopilot's order:

===========================  ======  =========================================
channel                      unit    meaning
===========================  ======  =========================================
``esc_rpm_<i>``              rad/s   shaft speed of motor ``i`` (logged rev/min)
``esc_voltage_<i>``          V       supply voltage at ESC ``i``
``esc_current_<i>``          A       current drawn through ESC ``i``
``esc_temperature_<i>``      K       temperature of ESC ``i`` (logged deg C)
===========================  ======  =========================================

* PX4 ``.ulg``: topic ``esc_status`` (``esc[i].esc_rpm``, ``esc_voltage``,
  ``esc_current``, ``esc_temperature`` for i < ``esc_count``).
* ArduPilot ``.bin``: message ``ESC`` per ``Instance`` (``RPM``, ``Volt``, ``Curr``,
  ``Temp``), or the separate ``ESC1`` .. ``ESC8`` messages of older firmware.
* MAVLink ``.tlog``: ``ESC_TELEMETRY_1_TO_4`` .. ``_9_TO_12`` (ArduPilot) or
  ``ESC_STATUS`` (PX4).

Each ESC is one stream (``esc_status.esc2``, ``ESC[2]``), so its native rate is in the
log's ``metadata["streams"]`` (:func:`~drake_uav.io.streams.logged_rate`). The streams are
optional extra channels: sparse or gappy, they are left out with a warning; they never
shorten the log. A sample that is not finite is invalid. The shaft speed is in rad/s, the
SI unit of an angular rate (rev/min x pi / 30), like ``motor_speed``.

**The propeller's shaft speed.** A log without an RPM sensor (ArduPilot ``RPM``, PX4
``rpm``: the channel ``motor_speed``) but with one ESC reporting its motor's speed (a
single-propeller aircraft) gets ``motor_speed`` from ``esc_rpm_0`` (:func:`with_motor_speed`),
so that the thrust is identified from the propeller law C_T(J). With several ESCs
reporting, which one drives the propeller the model describes is the user's to say
(export that ESC as ``motor_speed``); the log is left as it is, with a note.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np

from drake_uav.io.flight_log import FlightLog
from drake_uav.io.streams import Stream

__all__ = ["ESC_QUANTITIES", "esc_channel", "esc_channels", "esc_stream", "with_motor_speed"]

ESC_QUANTITIES: dict[str, tuple[str, str]] = {
    "rpm": ("rad/s", "motor shaft speed"),
    "voltage": ("V", "ESC supply voltage"),
    "current": ("A", "current drawn through the ESC"),
    "temperature": ("K", "ESC temperature"),
}
"""ESC quantity -> (SI unit, meaning) of the channels ``esc_<quantity>_<i>``."""

RPM_TO_RAD_S = math.pi / 30.0
"""rev/min -> rad/s."""
CELSIUS_TO_KELVIN = 273.15
"""Added to a temperature in deg C [K]."""

_NAME = re.compile(r"^esc_(?P<quantity>[a-z]+)_(?P<index>\d+)$")


def esc_channel(quantity: str, index: int) -> str:
    """The channel name of ``quantity`` (a key of :data:`ESC_QUANTITIES`) of ESC ``index``
    (0-based): ``esc_rpm_0``."""
    if quantity not in ESC_QUANTITIES:
        raise ValueError(f"quantity: one of {', '.join(ESC_QUANTITIES)}, got {quantity!r}")
    if index < 0:
        raise ValueError(f"index: must be >= 0, got {index}")
    return f"esc_{quantity}_{index}"


def esc_channels(names) -> dict[int, dict[str, str]]:
    """ESC index -> quantity -> channel name of the ESC channels among ``names`` (a
    FlightLog or channel names), in ESC order: what the log holds of each motor."""
    out: dict[int, dict[str, str]] = {}
    for name in getattr(names, "names", names):
        match = _NAME.match(name)
        if match and match["quantity"] in ESC_QUANTITIES:
            out.setdefault(int(match["index"]), {})[match["quantity"]] = name
    return dict(sorted(out.items()))


def esc_stream(name: str, index: int, time: np.ndarray, raw: Mapping[str, np.ndarray],
               fields: Mapping[str, str], valid: np.ndarray | None = None) -> Stream:
    """The optional stream of ESC ``index``.

    Args:
        name: the stream's name (``esc_status.esc0``).
        index: the ESC's number, 0-based.
        time: sample times [s].
        raw: quantity -> logged values in the autopilots' units (rpm in rev/min,
            voltage in V, current in A, temperature in deg C); converted here.
        fields: quantity -> the logged field, for messages.
        valid: samples the autopilot marks valid (None: all); a non-finite sample is
            invalid as well.
    """
    values, units, sources = {}, {}, {}
    for quantity, data in raw.items():
        channel = esc_channel(quantity, index)
        data = np.asarray(data, float)
        if quantity == "rpm":
            data = RPM_TO_RAD_S * data
        elif quantity == "temperature":
            data = data + CELSIUS_TO_KELVIN
        values[channel], units[channel] = data, ESC_QUANTITIES[quantity][0]
        sources[channel] = fields[quantity]
    ok = np.logical_and.reduce([np.isfinite(v) for v in values.values()])
    if valid is not None:
        ok &= np.asarray(valid, bool)
    return Stream(name, np.asarray(time, float), values, units, fields=sources, valid=ok,
                  optional=True, trims=False)


def with_motor_speed(log: FlightLog) -> tuple[FlightLog, str | None]:
    """``log`` with its ESC's shaft speed as ``motor_speed`` where no RPM sensor is logged.

    Parameters
    ----------
    log : FlightLog
        A flight log.

    Returns
    -------
    log : FlightLog
        ``log`` itself when it holds ``motor_speed`` or no single ESC's speed; else a copy
        whose ``esc_rpm_<i>`` is renamed ``motor_speed`` (its stream's native rate kept in
        ``metadata["streams"]``).
    note : str or None
        What was done or why not, for the report; None when the log holds no ESC speed or
        already holds ``motor_speed``.
    """
    if "motor_speed" in log:
        return log, None
    speeds = [q["rpm"] for q in esc_channels(log.measured_names).values() if "rpm" in q]
    if not speeds:
        return log, None
    if len(speeds) > 1:
        return log, (f"{len(speeds)} ESCs report a shaft speed ({', '.join(speeds)}): the "
                     "thrust is not identified from any of them; export the propeller's "
                     "as motor_speed")
    source = speeds[0]
    measured = {("motor_speed" if n == source else n): log[n] for n in log.measured_names}
    units = {("motor_speed" if n == source else n): log.unit(n) for n in log.names}
    streams = {name: {**info, "channels": ["motor_speed" if c == source else c
                                           for c in info.get("channels", ())]}
               for name, info in (log.metadata.get("streams") or {}).items()}
    metadata = {**log.metadata, **({"streams": streams} if streams else {})}
    renamed = FlightLog(log.time, measured, {n: log[n] for n in log.truth_names}, units,
                        metadata)
    return renamed, f"propeller shaft speed from the ESC telemetry ({source})"
