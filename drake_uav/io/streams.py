"""The canonical log channels, field and actuator mappings, and stream alignment.

Every reader turns its format into :class:`Stream` objects and aligns them with
:func:`align_streams` into a :class:`~drake_uav.io.flight_log.FlightLog` whose
measured channels carry the canonical names and SI units of :data:`CHANNELS`.

Autopilot logs keep each message stream (IMU, attitude, GPS, ...) on its own
time base. :func:`align_streams` puts them on the IMU's time base:

* continuous signals by linear interpolation between the two neighbouring samples;
* angles that wrap (yaw) unwrapped first, interpolated, wrapped back to [-pi, pi);
* commands (servo outputs, actuator controls) by previous-sample hold, because
  the autopilot holds an output until it writes the next one;
* invalid samples (``Stream.valid`` False) are removed first;
* the IMU and the required streams cut the log into segments at every interval
  longer than ``max_gap`` between valid samples and at every hole of invalid
  samples; the log keeps the IMU samples inside the segments;
* an optional stream (air data, GPS, RPM) that is sparse or has a gap is
  dropped with a warning instead of cutting the log;
* a time that does not increase or a non-finite valid value raises
  :class:`FlightLogError` naming the stream, the message index and the time.

See docs/flight_logs.md for the field-by-field mappings.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from drake_uav.io.flight_log import UNITS, FlightLog, FlightLogError

__all__ = [
    "CHANNELS",
    "FORMATS",
    "ActuatorChannel",
    "ActuatorMapping",
    "FieldSource",
    "MIN_IMU_RATE_HZ",
    "Stream",
    "align_streams",
    "imu_position_metadata",
    "logged_rate",
    "require_channels",
]

CHANNELS: dict[str, tuple[str, str]] = {
    "imu_ax": ("m/s^2", "specific force along body x (forward)"),
    "imu_ay": ("m/s^2", "specific force along body y (right)"),
    "imu_az": ("m/s^2", "specific force along body z (down); about -9.81 level at rest"),
    "imu_p": ("rad/s", "body roll rate"),
    "imu_q": ("rad/s", "body pitch rate"),
    "imu_r": ("rad/s", "body yaw rate"),
    "att_roll": ("rad", "roll angle (3-2-1 Euler)"),
    "att_pitch": ("rad", "pitch angle (3-2-1 Euler)"),
    "att_yaw": ("rad", "yaw angle (3-2-1 Euler), in [-pi, pi)"),
    "pitot_airspeed": ("m/s", "airspeed from the pitot-static probe"),
    "pitot_qbar": ("Pa", "pitot differential (dynamic) pressure"),
    "vane_alpha": ("rad", "angle of attack from a vane"),
    "vane_beta": ("rad", "sideslip angle from a vane"),
    "cmd_elevator": ("rad", "elevator command; positive gives a nose-down moment"),
    "cmd_aileron": ("rad", "aileron command; positive gives a right-wing-down moment"),
    "cmd_rudder": ("rad", "rudder command; positive gives a nose-left moment"),
    "cmd_throttle": ("1", "throttle command, 0..1"),
    "baro_alt": ("m", "barometric altitude, up positive"),
    "gps_pn": ("m", "position north of the origin"),
    "gps_pe": ("m", "position east of the origin"),
    "gps_pd": ("m", "position down from the origin"),
    "gps_vn": ("m/s", "velocity north"),
    "gps_ve": ("m/s", "velocity east"),
    "gps_vd": ("m/s", "velocity down"),
    "est_wind_n": ("m/s", "autopilot's own wind estimate, north component"),
    "est_wind_e": ("m/s", "autopilot's own wind estimate, east component"),
    "motor_speed": ("rad/s", "engine or motor shaft speed"),
}
"""Canonical measured channels: name -> (SI unit, meaning). Surface signs follow
the aircraft parameters (Cm_elevator < 0, Cl_aileron > 0, Cn_rudder < 0)."""

FORMATS = {".csv": "csv", ".bin": "bin", ".ulg": "ulg", ".parquet": "parquet", ".pq": "parquet",
           ".tlog": "tlog"}
"""File suffix (lower case) -> format name accepted by :func:`read_log`."""

MIN_IMU_RATE_HZ = 100.0
"""Below this IMU logging rate [Hz] every reader warns: the fast dynamics are aliased
(the rate rounded to 1 mHz, so that a 100 Hz clock's rounding never warns)."""

_HINTS = {
    "vane_alpha": "autopilot logs carry no vane angles unless mapped: pass "
                  "extra={'vane_alpha': FieldSource(...)}, or estimate them",
    "vane_beta": "autopilot logs carry no vane angles unless mapped: pass "
                 "extra={'vane_beta': FieldSource(...)}, or estimate them",
}


# --------------------------------------------------------------------- mappings
@dataclasses.dataclass(frozen=True)
class FieldSource:
    """A logged field mapped onto a channel: ``value = scale * raw + offset``.

    Attributes:
        message: ArduPilot message name (``"CUR2"``) or PX4 topic (``"vane_data"``).
        field: field name within it (``"Volt"``, ``"angle[0]"``).
        unit: unit of the resulting channel, from the FlightLog registry [e.g. rad].
        scale: multiplier applied to the raw value [unit per raw unit].
        offset: added after scaling [unit].
        instance: ArduPilot instance (``I``/``C`` field; None: every message) or PX4
            multi-id (None: the reader's ``instance``).
        hold: previous-sample hold instead of linear interpolation (commands).
    """

    message: str
    field: str
    unit: str
    scale: float = 1.0
    offset: float = 0.0
    instance: int | None = None
    hold: bool = False

    def validate(self) -> FieldSource:
        """Raises ValueError naming the invalid field; returns self."""
        for name in ("message", "field"):
            if not getattr(self, name):
                raise ValueError(f"FieldSource.{name}: must be a non-empty string")
        if self.unit not in UNITS:
            raise ValueError(f"FieldSource.unit: unknown unit {self.unit!r}")
        for name in ("scale", "offset"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"FieldSource.{name}: must be finite")
        return self

    def apply(self, raw: np.ndarray) -> np.ndarray:
        """The channel values of the raw field values."""
        return self.scale * np.asarray(raw, float) + self.offset


@dataclasses.dataclass(frozen=True)
class ActuatorChannel:
    """A logged actuator output mapped (piecewise) linearly onto a command.

    ``command = full_value * (raw - neutral) / (full - neutral)`` on the side of
    ``full``; on the other side, when ``full_low`` is given, ``command =
    full_value * (raw - neutral) / (neutral - full_low)`` (so ``full_low`` gives
    ``-full_value``: a servo whose trim is not centred between its limits). Then
    clipped to ``limits`` when given. For a servo PWM: ``neutral`` is the trim
    [us], ``full`` the PWM of full deflection ``full_value`` [rad] (its sign
    sets the direction); for a throttle: ``neutral`` is the idle PWM and
    ``full_value`` 1. A raw value outside ``valid_range`` is an invalid sample
    (an output not driven, PWM 0), never a command.

    Attributes:
        field: field holding the raw output (``"C2"`` in RCOU, ``"output[1]"``
            in actuator_outputs, ``"control[1]"`` in actuator_controls_0).
        neutral: raw value of a zero command [us or normalised].
        full: raw value of the command ``full_value`` [us or normalised].
        full_value: command at ``full`` [rad for surfaces, 1 for throttle].
        limits: (low, high) clip of the command, or None.
        full_low: raw value of the command ``-full_value`` (other side of
            ``neutral``), or None for one slope.
        valid_range: (low, high) of plausible raw values [us or normalised], or None.
    """

    field: str
    neutral: float
    full: float
    full_value: float
    limits: tuple[float, float] | None = None
    full_low: float | None = None
    valid_range: tuple[float, float] | None = None

    def validate(self, where: str = "ActuatorChannel") -> ActuatorChannel:
        """Raises ValueError naming ``where.field``; returns self."""
        if not self.field:
            raise ValueError(f"{where}.field: must be a non-empty string")
        for name in ("neutral", "full", "full_value"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{where}.{name}: must be finite")
        if self.full == self.neutral:
            raise ValueError(f"{where}.full: must differ from neutral ({self.neutral})")
        if self.full_low is not None and not (self.full_low - self.neutral) * (
                self.full - self.neutral) < 0:
            raise ValueError(f"{where}.full_low: must lie on the other side of neutral "
                             f"({self.neutral}) from full ({self.full}), got {self.full_low}")
        if self.full_value == 0.0:
            raise ValueError(f"{where}.full_value: must be non-zero")
        for name in ("limits", "valid_range"):
            pair = getattr(self, name)
            if pair is not None and not pair[0] < pair[1]:
                raise ValueError(f"{where}.{name}: need low < high, got {pair}")
        return self

    def apply(self, raw: np.ndarray) -> np.ndarray:
        """Commands of the raw output values."""
        offset = np.asarray(raw, float) - self.neutral
        value = self.full_value * offset / (self.full - self.neutral)
        if self.full_low is not None:
            low_side = offset * (self.full - self.neutral) < 0
            value = np.where(low_side, self.full_value * offset / (self.neutral - self.full_low),
                             value)
        if self.limits is not None:
            value = np.clip(value, *self.limits)
        return value

    def valid(self, raw: np.ndarray) -> np.ndarray:
        """Per sample: the raw value lies in ``valid_range`` (all True without one)."""
        raw = np.asarray(raw, float)
        if self.valid_range is None:
            return np.ones(raw.shape, bool)
        return (raw >= self.valid_range[0]) & (raw <= self.valid_range[1])


_SURFACES = ("elevator", "aileron", "rudder")
_DEFAULT_DEFLECTION = math.radians(25.0)
_DEFAULT_PWM_RANGE = (950.0, 2050.0)
"""Plausible servo PWM of the default ArduPilot mapping: 1500 +- (500 + 50) us."""


@dataclasses.dataclass(frozen=True)
class ActuatorMapping:
    """Where the commands come from: one message and a channel per command.

    The presets follow the autopilots' conventions: a positive pitch demand is
    nose-up, so it maps onto a *negative* elevator here (nose-down positive);
    likewise a positive (nose-right) yaw demand onto a negative rudder. Flip
    the sign of ``full_value`` for a servo reversed in the autopilot
    (ArduPilot ``SERVOn_REVERSED = 1``). ``elevator``, ``aileron`` and
    ``rudder`` arguments of the presets are full deflections [rad]. A command
    the aircraft has no output for (no rudder servo) is None: its channel is
    left out.
    """

    message: str
    elevator: ActuatorChannel | None
    aileron: ActuatorChannel | None
    rudder: ActuatorChannel | None
    throttle: ActuatorChannel | None

    def validate(self) -> ActuatorMapping:
        """Raises ValueError naming the invalid field; returns self."""
        if not self.message:
            raise ValueError("ActuatorMapping.message: must be a non-empty string")
        for name, channel in self._present().items():
            channel.validate(f"ActuatorMapping.{name}")
        return self

    def _present(self) -> dict[str, ActuatorChannel]:
        return {name: getattr(self, name) for name in (*_SURFACES, "throttle")
                if getattr(self, name) is not None}

    def describe(self) -> dict:
        """The mapping as JSON-ready values (for log metadata)."""
        out = dataclasses.asdict(self)
        for name in self._present():
            for key in ("limits", "valid_range"):
                pair = out[name][key]
                out[name][key] = None if pair is None else list(pair)
        return out

    def channels(self) -> dict[str, ActuatorChannel]:
        """Canonical command channel -> its mapping (commands without an output left out)."""
        return {f"cmd_{name}": channel for name, channel in self._present().items()}

    @classmethod
    def _pwm(cls, message, fields, throttle_range, elevator, aileron, rudder, valid_range=None):
        signs = {"elevator": -1.0, "aileron": 1.0, "rudder": -1.0}
        limits = {"elevator": elevator, "aileron": aileron, "rudder": rudder}
        surfaces = {name: ActuatorChannel(fields[name], 1500.0, 2000.0, signs[name] * limits[name],
                                          valid_range=valid_range)
                    for name in _SURFACES}
        throttle = ActuatorChannel(fields["throttle"], *throttle_range, 1.0, (0.0, 1.0),
                                   valid_range=valid_range)
        return cls(message, throttle=throttle, **surfaces).validate()

    @classmethod
    def ardupilot(cls, message: str = "RCOU", elevator: float = _DEFAULT_DEFLECTION,
                  aileron: float = _DEFAULT_DEFLECTION,
                  rudder: float = _DEFAULT_DEFLECTION) -> ActuatorMapping:
        """ArduPlane outputs: C1 aileron, C2 elevator, C3 throttle, C4 rudder.

        Surfaces: 1500 us trim, +-500 us for full deflection; throttle 1100..1900 us
        -> 0..1 (clipped). A PWM outside 950..2050 us (0: output not driven) is
        invalid. ``message`` may be ``"RCIN"`` for the pilot's sticks. The reader
        uses this only for a log without SERVOn parameters.
        """
        fields = {"aileron": "C1", "elevator": "C2", "throttle": "C3", "rudder": "C4"}
        return cls._pwm(message, fields, (1100.0, 1900.0), elevator, aileron, rudder,
                        _DEFAULT_PWM_RANGE)

    @classmethod
    def _demands(cls, message, fields, full, throttle_full, elevator, aileron, rudder):
        """Roll, pitch, yaw demands about 0 (``full`` = full deflection; pitch-up and
        yaw-right positive, so negative elevator and rudder) and a 0..throttle_full
        throttle."""
        return cls(
            message,
            elevator=ActuatorChannel(fields["elevator"], 0.0, full, -elevator),
            aileron=ActuatorChannel(fields["aileron"], 0.0, full, aileron),
            rudder=ActuatorChannel(fields["rudder"], 0.0, full, -rudder),
            throttle=ActuatorChannel(fields["throttle"], 0.0, throttle_full, 1.0, (0.0, 1.0)),
        ).validate()

    @classmethod
    def ardupilot_aetr(cls, elevator: float = _DEFAULT_DEFLECTION,
                       aileron: float = _DEFAULT_DEFLECTION,
                       rudder: float = _DEFAULT_DEFLECTION) -> ActuatorMapping:
        """ArduPlane's ``AETR`` demands: Ail, Elev, Rudd in -4500..4500 (4500 = full
        deflection; positive = roll right, pitch up, yaw right), Thr 0..100 -> 0..1."""
        fields = {"aileron": "Ail", "elevator": "Elev", "rudder": "Rudd", "throttle": "Thr"}
        return cls._demands("AETR", fields, 4500.0, 100.0, elevator, aileron, rudder)

    @classmethod
    def px4_outputs(cls, elevator: float = _DEFAULT_DEFLECTION,
                    aileron: float = _DEFAULT_DEFLECTION,
                    rudder: float = _DEFAULT_DEFLECTION) -> ActuatorMapping:
        """PX4 ``actuator_outputs`` of the standard plane mixer (AERT).

        output[0] aileron, output[1] elevator, output[2] rudder (1500 us trim,
        +-500 us full), output[3] throttle 1000..2000 us -> 0..1 (clipped).
        """
        fields = {"aileron": "output[0]", "elevator": "output[1]", "rudder": "output[2]",
                  "throttle": "output[3]"}
        return cls._pwm("actuator_outputs", fields, (1000.0, 2000.0), elevator, aileron, rudder)

    @classmethod
    def px4_controls(cls, elevator: float = _DEFAULT_DEFLECTION,
                     aileron: float = _DEFAULT_DEFLECTION,
                     rudder: float = _DEFAULT_DEFLECTION) -> ActuatorMapping:
        """PX4 ``actuator_controls_0``: control[0..2] roll, pitch, yaw demands in -1..1
        (1 = full deflection), control[3] throttle 0..1."""
        fields = {"aileron": "control[0]", "elevator": "control[1]", "rudder": "control[2]",
                  "throttle": "control[3]"}
        return cls._demands("actuator_controls_0", fields, 1.0, 1.0, elevator, aileron, rudder)


# -------------------------------------------------------------------- alignment
@dataclasses.dataclass(frozen=True)
class Stream:
    """One logged message stream on its own time base.

    Attributes:
        name: the message or topic, for error messages (``"ATT"``, ``"airspeed"``).
        time: sample times [s].
        channels: canonical channel -> samples (SI units of ``units``).
        units: channel -> unit symbol.
        hold: previous-sample hold (commands) instead of linear interpolation.
        angles: channels that wrap at +-pi (interpolated unwrapped, then wrapped).
        fields: channel -> logged field it came from (``"ATT.Yaw"``), for messages.
        valid: per sample, False for an invalid sample (servo PWM 0 or out of
            range, PX4 ``xy_valid = 0``, negative airspeed, GPS without a 3-D
            fix); None: every sample valid. Invalid samples are removed before
            alignment and leave a hole.
        optional: a stream the log can do without (air data, GPS, RPM): when it
            is sparse or has gaps it is dropped with a warning instead of
            cutting the log.
        trims: an optional stream's segments are trimmed to its data (False: an
            extra channel, which never moves the canonical channels' segments; over
            the at most ``max_gap`` it misses at a segment's end it holds its first
            or last value).
    """

    name: str
    time: np.ndarray
    channels: dict[str, np.ndarray]
    units: dict[str, str]
    hold: bool = False
    angles: tuple[str, ...] = ()
    fields: dict[str, str] = dataclasses.field(default_factory=dict)
    valid: np.ndarray | None = None
    optional: bool = False
    trims: bool = True

    def check(self, source: str) -> None:
        """Raises FlightLogError for an empty stream, time not increasing, a ``valid``
        mask of the wrong length or non-finite values in valid samples."""
        t = self.time
        if t.size == 0:
            raise FlightLogError(f"{source}: stream '{self.name}' has no messages")
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise FlightLogError(f"{source}: stream '{self.name}': non-finite time at message "
                                 f"{bad[0]}")
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            what = "repeats" if t[i] == t[i - 1] else "goes backwards"
            raise FlightLogError(
                f"{source}: stream '{self.name}': time {what} at message {i} "
                f"(t = {t[i]:.6f} s after {t[i - 1]:.6f} s)")
        if self.valid is not None and np.shape(self.valid) != t.shape:
            raise FlightLogError(f"{source}: stream '{self.name}': valid mask of shape "
                                 f"{np.shape(self.valid)} for {t.size} messages")
        valid = self.mask()
        for channel, values in self.channels.items():
            bad = np.flatnonzero(~np.isfinite(values) & valid)
            if bad.size:
                i = int(bad[0])
                raise FlightLogError(
                    f"{source}: {self.fields.get(channel, channel)} is {values[i]} at message "
                    f"{i} of stream '{self.name}' (t = {t[i]:.6f} s), {bad.size} bad in total")

    def mask(self) -> np.ndarray:
        """The per-sample validity (all True when ``valid`` is None)."""
        if self.valid is None:
            return np.ones(self.time.size, bool)
        return np.asarray(self.valid, bool)

    def valid_only(self) -> Stream:
        """This stream without its invalid samples."""
        if self.valid is None:
            return self
        keep = self.mask()
        return dataclasses.replace(self, time=self.time[keep], valid=None,
                                   channels={n: v[keep] for n, v in self.channels.items()})

    def pieces(self, max_gap: float, split_holes: bool) -> np.ndarray:
        """(k, 2) array of [start, end] [s] of the runs of valid samples: a run ends at
        an interval longer than ``max_gap`` between valid samples and, with
        ``split_holes``, at any invalid sample."""
        valid = self.mask()
        index = np.flatnonzero(valid)
        if index.size == 0:
            return np.empty((0, 2))
        t = self.time[index]
        cut = np.diff(t) > max_gap
        if split_holes:
            cut |= np.diff(index) > 1
        ends = np.flatnonzero(cut)
        return np.column_stack([t[np.r_[0, ends + 1]], t[np.r_[ends, t.size - 1]]])

    def on(self, time: np.ndarray) -> dict[str, np.ndarray]:
        """The channels at ``time`` (inside the stream's span) by the stream's method."""
        if self.hold:
            index = np.searchsorted(self.time, time, side="right") - 1
            return {n: v[np.clip(index, 0, v.size - 1)] for n, v in self.channels.items()}
        out = {}
        for name, values in self.channels.items():
            if name in self.angles:
                out[name] = _wrap_angle(np.interp(time, self.time, np.unwrap(values)))
            else:
                out[name] = np.interp(time, self.time, values)
        return out


def _wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles [rad] wrapped into [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


_MIN_OPTIONAL_RATE_HZ = 2.0
"""An optional stream logged slower than this (median) is dropped [Hz]."""


def _intersect(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection of two sorted lists of disjoint closed intervals ((k, 2) arrays)."""
    out, i, j = [], 0, 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i, 0], b[j, 0]), min(a[i, 1], b[j, 1])
        if lo <= hi:
            out.append((lo, hi))
        if a[i, 1] < b[j, 1]:
            i += 1
        else:
            j += 1
    return np.asarray(out, float).reshape(-1, 2)


def _segments(time: np.ndarray, intervals: np.ndarray) -> np.ndarray:
    """The intervals ((k, 2) [s]) holding at least 2 samples of ``time``."""
    lo = np.searchsorted(time, intervals[:, 0], side="left")
    hi = np.searchsorted(time, intervals[:, 1], side="right")
    return intervals[hi - lo >= 2].reshape(-1, 2)


def _describe_pieces(stream: Stream, pieces: np.ndarray) -> str:
    """What a required stream covers, for the error when no segment remains."""
    n_bad = int(np.count_nonzero(~stream.mask()))
    if pieces.size == 0:
        return f"has no valid samples ({n_bad} invalid of {stream.time.size})"
    longest = pieces[np.argmax(pieces[:, 1] - pieces[:, 0])]
    return (f"has valid data in {len(pieces)} piece(s) ({n_bad} invalid samples), the "
            f"longest t = {longest[0]:.3f} s to {longest[1]:.3f} s, none of them overlapping "
            f"the other required streams for 2 samples")


def _required_segments(base: Stream, required: Sequence[Stream], source: str,
                       max_gap: float, span: tuple[float, float] | None) -> np.ndarray:
    """Segments [s] inside ``span`` where the base and every required stream have valid
    data without a gap longer than ``max_gap`` or a hole; FlightLogError naming the
    stream without any."""
    intervals = np.array([span if span is not None else (-math.inf, math.inf)], float)
    inside = "" if span is None else f", span t = {span[0]:g} s to {span[1]:g} s"
    for stream in (base, *required):
        pieces = stream.pieces(max_gap, split_holes=True)
        intervals = _intersect(intervals, pieces)
        if len(_segments(base.time, intervals)) == 0:
            raise FlightLogError(
                f"{source}: no segment of at least 2 samples where every required stream "
                f"has data: stream '{stream.name}' {_describe_pieces(stream, pieces)} "
                f"(max_gap = {max_gap:g} s{inside})")
    return _segments(base.time, intervals)


def _fit_optional(stream: Stream, segments: np.ndarray, max_gap: float
                  ) -> tuple[np.ndarray | None, str]:
    """(segments trimmed to the stream, "") when the optional stream covers every
    segment, up to ``max_gap`` at a segment's ends; else (None, why it is dropped)."""
    valid_time = stream.time[stream.mask()]
    if valid_time.size < 2:
        return None, f"{valid_time.size} valid sample(s)"
    rate = 1.0 / float(np.median(np.diff(valid_time)))
    if rate < _MIN_OPTIONAL_RATE_HZ:
        return None, f"sparse: logged at {rate:.3g} Hz (< {_MIN_OPTIONAL_RATE_HZ:g} Hz)"
    pieces = stream.pieces(max_gap, split_holes=False)
    out = []
    for t0, t1 in segments:
        inside = pieces[(pieces[:, 1] >= t0 - max_gap) & (pieces[:, 0] <= t1 + max_gap)]
        if len(inside) != 1:
            if len(inside) == 0:
                return None, f"no valid data in the segment t = {t0:.3f} s to {t1:.3f} s"
            gap = inside[0, 1], inside[1, 0]
            return None, (f"a gap of {gap[1] - gap[0]:.3f} s (t = {gap[0]:.3f} s to "
                          f"{gap[1]:.3f} s), longer than max_gap = {max_gap:g} s")
        p0, p1 = inside[0]
        if p0 - t0 > max_gap or t1 - p1 > max_gap:
            return None, (f"valid only from t = {p0:.3f} s to {p1:.3f} s of the segment "
                          f"t = {t0:.3f} s to {t1:.3f} s")
        out.append((max(t0, p0), min(t1, p1)))
    return np.asarray(out, float).reshape(-1, 2), ""


def _stream_info(stream: Stream, base: Stream) -> dict:
    """Metadata of one aligned stream: valid messages, rate, method, channels."""
    time = stream.time[stream.mask()]
    rate = 1.0 / float(np.median(np.diff(time))) if time.size > 1 else 0.0
    info = {"messages": int(time.size), "rate_hz": round(rate, 6),
            "method": "time base" if stream.name == base.name
            else "previous-sample hold" if stream.hold else "linear",
            "channels": list(stream.channels)}
    if stream.valid is not None:
        info["invalid"] = int(stream.time.size - time.size)
    return info


def align_streams(base: Stream, streams: Sequence[Stream], *, source: str, max_gap: float = 0.5,
                  metadata: Mapping[str, object] | None = None,
                  span: tuple[float, float] | None = None) -> FlightLog:
    """One FlightLog on the time base of ``base`` (the IMU) from several streams.

    When the commands (a ``hold`` stream) are logged faster than ``base``, their
    samples are the time base instead, and ``base`` is interpolated: every command
    the aircraft flew stays in the log. Streams slower than
    :data:`SLOW_SENSOR_FRACTION` of the time base are held, the others interpolated.

    Invalid samples are removed first. The base and the required streams cut
    the log into segments at every interval longer than ``max_gap`` [s]
    between valid samples and at every hole of invalid samples; the log keeps
    the base samples inside the segments (``metadata["segments"]``, [[t0, t1],
    ...] [s]). An optional stream that is sparse (median rate below 2 Hz), has
    a gap longer than ``max_gap`` inside a segment, or misses more than
    ``max_gap`` at a segment's end is dropped with a warning naming ``source``
    and the stream (``metadata["dropped_streams"]``); otherwise the segments
    are trimmed to its data (but an extra channel's: :attr:`Stream.trims`). ``span`` =
    (t0, t1) [s] keeps only that part of
    the log, before optional streams are judged (a GPS fixed after the log's
    start but before ``t0`` is kept).

    Raises:
        FlightLogError (naming ``source`` and the stream): a stream is empty,
        its time does not increase, a valid value is not finite, a channel is
        mapped twice, or no segment of at least 2 samples remains.
    """
    if not max_gap > 0:
        raise ValueError(f"max_gap: must be positive, got {max_gap}")
    if span is not None and not span[0] < span[1]:
        raise ValueError(f"span: need t0 < t1, got {span}")
    for stream in (base, *streams):
        stream.check(source)
    segments = _required_segments(base, [s for s in streams if not s.optional], source,
                                  max_gap, span)
    kept, dropped = [base], []
    for stream in streams:
        if stream.optional:
            fitted, why = _fit_optional(stream, segments, max_gap)
            if fitted is None or len(_segments(base.time, fitted)) == 0:
                warnings.warn(f"{source}: optional stream '{stream.name}' dropped: "
                              f"{why or 'nothing left'}", stacklevel=3)
                dropped.append(stream.name)
                continue
            if stream.trims:
                segments = _segments(base.time, fitted)
        kept.append(stream)
    return _aligned_log(base, kept, segments, source, max_gap, dict(metadata or {}),
                        dropped)


def _rate(stream: Stream) -> float:
    """Median rate of a stream's valid samples [Hz] (0 for fewer than two)."""
    time = stream.time[stream.mask()]
    return 1.0 / float(np.median(np.diff(time))) if time.size > 1 else 0.0


SLOW_SENSOR_FRACTION = 0.45
"""A sensor stream logged below this fraction of the time base's rate (GPS, airspeed,
baro) is aligned by previous-sample hold, as the simulated sensors log it: a new value
marks when a sample arrived, which the filters need
(:func:`drake_uav.estimation.signals.fresh_samples`); the identification draws straight
lines between the samples again (:func:`drake_uav.estimation.signals.unheld`)."""


def _held_as_logged(stream: Stream, base: Stream, clock_rate: float) -> bool:
    """A slow sensor stream (not the IMU) that is aligned by hold."""
    return (not stream.hold and stream.name != base.name
            and _rate(stream) < SLOW_SENSOR_FRACTION * clock_rate)


def _clock(base: Stream, kept: Sequence[Stream]) -> Stream:
    """The stream whose samples are the log's times: ``base`` (the IMU), or a command
    stream logged at least 1.5 times faster, so that no command the aircraft flew is
    lost to the previous-sample hold (the IMU is then interpolated)."""
    faster = [s for s in kept if s.hold and _rate(s) > 1.5 * _rate(base)]
    return max(faster, key=_rate) if faster else base


def _aligned_log(base: Stream, kept: Sequence[Stream], segments: np.ndarray, source: str,
                 max_gap: float, meta: dict, dropped: list[str]) -> FlightLog:
    """The FlightLog of the clock's samples inside ``segments`` with every kept stream."""
    clock = _clock(base, kept).valid_only()
    if clock.name != base.name:  # the IMU is interpolated, never extrapolated
        covered = base.valid_only().time
        segments = np.clip(segments, covered[0], covered[-1])
    lo = np.searchsorted(clock.time, segments[:, 0], side="left")
    hi = np.searchsorted(clock.time, segments[:, 1], side="right")
    index = np.concatenate([np.arange(a, b) for a, b in zip(lo, hi, strict=True)])
    time = clock.time[index]
    measured, units, info = {}, {}, {}
    rate = _rate(clock)
    for stream in kept:
        if _held_as_logged(stream, base, rate):
            stream = dataclasses.replace(stream, hold=True)
        values = ({n: v[index] for n, v in clock.channels.items()}
                  if stream.name == clock.name else stream.valid_only().on(time))
        for name in values:
            if name in measured:
                raise FlightLogError(f"{source}: channel '{name}' mapped twice "
                                     f"(again from stream '{stream.name}')")
        measured.update(values)
        units.update(stream.units)
        info[stream.name] = _stream_info(stream, clock)
    meta.update({"source": source, "time_base": clock.name, "max_gap_s": max_gap,
                 "trimmed_s": [float(segments[0, 0] - base.time[0]),
                               float(base.time[-1] - segments[-1, 1])],
                 "segments": segments.tolist(), "dropped_streams": dropped,
                 "streams": info})
    return FlightLog(time, measured, units=units, metadata=meta)


def imu_position_metadata(parameters: Mapping[str, float], names: Sequence[str],
                          source: str) -> dict:
    """``{"imu_position": {"position": [x, y, z], "source": source}}`` [m, body axes FRD]
    from the autopilot ``parameters`` ``names`` (x, y, z; a missing one is 0), or ``{}``
    when the log sets none of them: the readers' metadata key the main job moves the
    accelerometers by (:mod:`drake_uav.estimation.imu_position`)."""
    if not any(n in parameters for n in names):
        return {}
    return {"imu_position": {"position": [float(parameters.get(n, 0.0)) for n in names],
                             "source": source}}


def logged_rate(log: FlightLog, channel: str) -> float | None:
    """Rate [Hz] of the stream ``channel`` was read from (``metadata["streams"]`` of the
    autopilot readers), or None when the log does not say (CSV, simulated logs)."""
    for info in (log.metadata.get("streams") or {}).values():
        if channel in info.get("channels", ()):
            return float(info["rate_hz"])
    return None


def require_channels(log: FlightLog, required: Iterable[str], source: str) -> FlightLog:
    """Raises :class:`FlightLogError` naming ``source`` and the first missing channel."""
    for name in required:
        if name not in log:
            hint = _HINTS.get(name)
            raise FlightLogError(
                f"{source}: missing channel '{name}' (present: {', '.join(log.names)})"
                + (f"; {hint}" if hint else ""))
    return log


