"""Which parts of a flight log the identification may use.

A real log holds more than the fixed-wing flight the model describes: time on the
ground before take-off, the take-off and landing, VTOL hover and transitions, and
logging gaps. :func:`usable_spans` keeps the time spans where

* the log is continuous (the reader's ``metadata["segments"]``, cut at gaps of a
  required stream),
* the aircraft is airborne: pitot airspeed above ``min_airspeed`` and, when a
  barometric altitude is logged, the height above the ground level (the median
  baro altitude while the airspeed is below half of ``min_airspeed``; a log that
  starts and ends in the air has no ground level and no height test) above
  ``min_height``,
* the flight mode is not a take-off, landing or VTOL hover mode
  (:data:`EXCLUDED_MODES`, ArduPilot MODE messages and PX4 ``nav_state``) and a
  VTOL is in fixed-wing flight (``metadata["vtol_state"]``),

each span trimmed by ``margin`` where it starts or ends inside the log (the
settling after a transition) and at least ``min_duration`` long.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_uav.io.flight_log import FlightLog, FlightLogError

__all__ = ["DEFAULT_PHASES", "EXCLUDED_MODES", "PhaseSettings", "usable_spans", "mode_timeline"]

EXCLUDED_MODES = frozenset({
    # ArduPlane: take-off, landing and the quadplane (hover) modes.
    "TAKEOFF", "QSTABILIZE", "QHOVER", "QLOITER", "QLAND", "QRTL", "QAUTOTUNE", "QACRO",
    # PX4 navigation states of take-off and landing.
    "AUTO_TAKEOFF", "AUTO_LAND", "AUTO_VTOL_TAKEOFF", "AUTO_PRECLAND", "DESCEND",
    "TERMINATION",
})
"""Flight modes whose data are left out: the aircraft is on or near the ground, or
hovering."""


@dataclasses.dataclass(frozen=True)
class PhaseSettings:
    """Thresholds of the airborne detection.

    Attributes
    ----------
    min_airspeed : float
        Pitot airspeed above which the aircraft may be flying [m/s].
    min_height : float
        Height above the ground level [m] (used when ``baro_alt`` is logged).
    min_duration : float
        Shortest usable span [s].
    margin : float
        Trimmed from both ends of every span [s].
    """

    min_airspeed: float = 8.0
    min_height: float = 5.0
    min_duration: float = 10.0
    margin: float = 1.0


DEFAULT_PHASES = PhaseSettings()
"""The thresholds the main job uses unless told otherwise."""


def mode_timeline(log: FlightLog) -> list[tuple[float, float, str]]:
    """The spans of the logged flight modes, up to the log's end.

    Parameters
    ----------
    log : FlightLog
        The flight log.

    Returns
    -------
    list of (float, float, str)
        (start [s], end [s], mode name) of each mode.
    """
    entries = [(float(t), str(name)) for t, name in log.metadata.get("flight_modes") or []]
    end = float(log.time[-1])
    return [(t, entries[i + 1][0] if i + 1 < len(entries) else end, name)
            for i, (t, name) in enumerate(entries)]


def _runs(mask: np.ndarray, time: np.ndarray) -> list[tuple[float, float]]:
    """(first, last) times of each run of True samples."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(time[a]), float(time[b])) for a, b in zip(starts, ends, strict=True)]


def _excluded_by_metadata(log: FlightLog) -> np.ndarray:
    """Samples in an excluded flight mode or out of VTOL fixed-wing flight."""
    t = log.time
    out = np.zeros(t.size, bool)
    for start, end, name in mode_timeline(log):
        if name.upper() in EXCLUDED_MODES:
            out |= (t >= start) & (t < end)
    states = log.metadata.get("vtol_state") or []
    for i, (start, state) in enumerate(states):
        end = states[i + 1][0] if i + 1 < len(states) else np.inf
        if state != "fw":
            out |= (t >= start) & (t < end)
    return out


def _airborne(log: FlightLog, settings: PhaseSettings) -> np.ndarray:
    airspeed = log["pitot_airspeed"]
    flying = airspeed >= settings.min_airspeed
    slow = airspeed < 0.5 * settings.min_airspeed
    if "baro_alt" in log and slow.any():
        altitude = log["baro_alt"]
        flying &= altitude - float(np.median(altitude[slow])) >= settings.min_height
    return flying


def usable_spans(log: FlightLog, settings: PhaseSettings = DEFAULT_PHASES,
                 segment: tuple[float, float] | None = None) -> list[tuple[float, float]]:
    """Airborne, continuous fixed-wing spans of ``log``.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    settings : PhaseSettings
        Thresholds of the airborne detection.
    segment : (float, float), optional
        Restricts the spans to this time span [s].

    Returns
    -------
    list of (float, float)
        (start, end) [s] of each span.

    Raises
    ------
    FlightLogError
        With the reason when no span is left ("no airborne segment: ...").
    """
    if "pitot_airspeed" not in log:
        dropped = [s for s in log.metadata.get("dropped_streams") or []
                   if "airspeed" in s.lower() or s.upper().startswith(("ARSP", "ASP"))]
        raise FlightLogError(
            "no airspeed: the log has no channel 'pitot_airspeed'"
            + (f" (stream {', '.join(dropped)} left out: no valid sample)" if dropped else "")
            + "; identify needs a pitot-static airspeed sensor")
    t = log.time
    keep = _airborne(log, settings)
    if not keep.any():
        raise FlightLogError(
            f"no airborne segment: pitot_airspeed never above {settings.min_airspeed:g} m/s "
            f"(highest {np.max(log['pitot_airspeed']):.1f} m/s)")
    keep &= ~_excluded_by_metadata(log)
    if segment is not None:
        keep &= (t >= segment[0]) & (t <= segment[1])
    continuous = log.metadata.get("segments") or [[t[0], t[-1]]]
    spans = []
    for first, last in continuous:
        inside = (t >= first) & (t <= last)
        for start, end in _runs(keep & inside, t):
            # The margin is for the settling after a take-off or a mode change, not for
            # the ends of the log or of a segment.
            start += settings.margin if start > t[inside][0] else 0.0
            end -= settings.margin if end < t[inside][-1] else 0.0
            if end - start >= settings.min_duration:
                spans.append((start, end))
    if not spans:
        where = "" if segment is None else f" inside --segment {segment[0]:g}:{segment[1]:g}"
        raise FlightLogError(
            f"no airborne segment{where}: no span of at least {settings.min_duration:g} s "
            f"with airspeed above {settings.min_airspeed:g} m/s, height above "
            f"{settings.min_height:g} m and a fixed-wing flight mode")
    return spans
