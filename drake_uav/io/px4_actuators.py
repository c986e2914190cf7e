"""The ``cmd_*`` channels of a PX4 log, from the topics and parameters the log has.

Which topic (docs/flight_logs.md, PX4 section):

* a VTOL (MAV_TYPE 19-25): ``actuator_controls_1``, the fixed-wing control
  group; never ``actuator_controls_0``, which drives the hover rotors;
* a plane: ``actuator_controls_0``;
* PX4 1.14 and later (no ``actuator_controls``): ``actuator_servos`` for the
  surfaces and ``actuator_motors`` for the throttle, through the control
  allocation parameters (below);
* ``actuators="outputs"``: ``actuator_outputs`` PWM through ``PWM_MAIN_FUNCn``
  (1.14+) or the standard plane mixer's order (older logs);
* a multicopter: no ``cmd_*`` channels (its motors are not surfaces).

Servos to demands (1.14+): servo k's value s_k in -1..1 produces the normalised
torque ``(CA_SV_CSk_TRQ_R, _P, _Y) * s_k`` (or the defaults of its
``CA_SV_CSk_TYPE``), so the roll, pitch and yaw demands are the sums of
``torque_k * s_k`` over the servos, the inverse of PX4's control allocation for
unsaturated servos. Demands become deflections as in
:meth:`ActuatorMapping.px4_controls` (1 = 25 deg; pitch-up -> negative elevator).
Throttle: the mean of the forward-pointing motors (``CA_ROTORn_AX = 1``) of a
VTOL, of every motor of a plane.

Invalid samples (``Stream.valid`` False): every command while
``vehicle_status.arming_state`` says disarmed (the outputs then sit at their
disarmed values ``PWM_MAIN_DISn``, whatever the logged demand; an armed servo
at a disarmed value equal to its centre is a valid sample), a PWM of 0 (output
not driven) or outside ``PWM_MAIN_MINn..MAXn``, a NaN servo or motor value
(PX4's "not driven").
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping

import numpy as np

from drake_uav.io.flight_log import FlightLogError
from drake_uav.io.px4_metadata import MULTICOPTER_TYPES, VTOL_TYPES
from drake_uav.io.px4_ulog import ULogFile, channel_stream
from drake_uav.io.streams import ActuatorMapping, Stream

__all__ = ["ACTUATOR_TOPICS", "actuator_plan", "actuator_streams"]

ACTUATOR_TOPICS = ("actuator_controls_0", "actuator_controls_1", "actuator_servos",
                   "actuator_motors", "actuator_outputs", "vehicle_status")
"""Topics the actuator channels may need."""

_SURFACE_TORQUES = {  # CA_SV_CSn_TYPE -> normalised (roll, pitch, yaw) torque per unit servo
    1: (-0.5, 0.0, 0.0), 2: (0.5, 0.0, 0.0), 3: (0.0, 1.0, 0.0), 4: (0.0, 0.0, 1.0),
    5: (-0.5, 0.5, 0.0), 6: (0.5, 0.5, 0.0), 7: (0.0, 0.5, 0.5), 8: (0.0, 0.5, -0.5),
    15: (1.0, 0.0, 0.0),
}
_AXES = ("cmd_aileron", "cmd_elevator", "cmd_rudder")  # roll, pitch, yaw demand
_TORQUE_PARAMS = ("TRQ_R", "TRQ_P", "TRQ_Y")
_PWM_DEFAULTS = {"MIN": 1000.0, "MAX": 2000.0, "DIS": 900.0}
_PWM_GLOBALS = {"MIN": ("PWM_MAIN_MIN", "PWM_MIN"), "MAX": ("PWM_MAIN_MAX", "PWM_MAX"),
                "DIS": ("PWM_MAIN_DISARMED", "PWM_DISARMED")}
_OUTPUT = re.compile(r"^output\[(\d+)\]$")


@dataclasses.dataclass(frozen=True)
class _Source:
    """Commands of one topic: ``channel = clip(sum(weight * (raw - offset) / scale))``.

    Attributes:
        message: the topic.
        terms: channel -> ((field, offset, scale, weight), ...).
        limits: channel -> (low, high) clip, for the throttle.
        pwm: field -> (min, max, disarmed) [us] of a PWM output (min..max for validity).
    """

    message: str
    terms: dict[str, tuple[tuple[str, float, float, float], ...]]
    limits: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    pwm: dict[str, tuple[float, float, float]] = dataclasses.field(default_factory=dict)

    def describe(self) -> dict:
        return {"terms": {c: [list(t) for t in terms] for c, terms in self.terms.items()},
                "limits": {c: list(v) for c, v in self.limits.items()},
                "pwm_min_max_disarmed": {f: list(v) for f, v in self.pwm.items()}}


def _from_mapping(mapping: ActuatorMapping) -> _Source:
    """A :class:`_Source` of an :class:`ActuatorMapping` (same arithmetic)."""
    terms, limits = {}, {}
    for channel, m in mapping.channels().items():
        terms[channel] = ((m.field, m.neutral, m.full - m.neutral, m.full_value),)
        if m.limits is not None:
            limits[channel] = m.limits
    return _Source(mapping.message, terms, limits)


def _pwm_limits(log: ULogFile, output: int) -> tuple[float, float, float]:
    """(min, max, disarmed) [us] of main output ``output`` (1-based): ``PWM_MAIN_MINn``
    etc., a negative value meaning the global ``PWM_MAIN_MIN`` / ``PWM_MIN`` (older)."""
    out = []
    for key in ("MIN", "MAX", "DIS"):
        value = log.parameter(f"PWM_MAIN_{key}{output}", -1)
        for name in _PWM_GLOBALS[key]:
            if value < 0:
                value = log.parameter(name, -1)
        out.append(float(value) if value >= 0 else _PWM_DEFAULTS[key])
    return tuple(out)


def _with_pwm(log: ULogFile, source: _Source) -> _Source:
    """``source`` with the PWM limits of its ``output[i]`` fields (actuator_outputs)."""
    if source.message != "actuator_outputs":
        return source
    fields = {t[0] for terms in source.terms.values() for t in terms}
    pwm = {f: _pwm_limits(log, int(_OUTPUT.match(f).group(1)) + 1)
           for f in fields if _OUTPUT.match(f)}
    return dataclasses.replace(source, pwm=pwm)


def _servo_torques(log: ULogFile, servos: list[int]) -> dict[int, tuple]:
    """Servo index -> (roll, pitch, yaw) torque: ``CA_SV_CSk_TRQ_*`` where set, else
    the defaults of ``CA_SV_CSk_TYPE``; servos moving no axis are left out."""
    out = {}
    for k in servos:
        torque = tuple(float(log.parameter(f"CA_SV_CS{k}_{p}", 0.0)) for p in _TORQUE_PARAMS)
        if not any(torque):
            torque = _SURFACE_TORQUES.get(int(log.parameter(f"CA_SV_CS{k}_TYPE", 0)),
                                          (0.0, 0.0, 0.0))
        if any(torque):
            out[k] = torque
    return out


def _forward_motors(log: ULogFile, motors: list[int], vtol: bool) -> list[int]:
    """The motors pushing forward: ``CA_ROTORn_AX = 1`` on a VTOL, all on a plane."""
    if not vtol:
        return motors
    forward = [r for r in motors if log.parameter(f"CA_ROTOR{r}_AX", 0.0) > 0.5]
    if not forward:
        raise FlightLogError(
            f"{log.source}: VTOL log without a forward (fixed-wing) motor: no CA_ROTORn_AX = 1 "
            f"among motors {motors}; map the throttle with an ActuatorMapping")
    return forward


def _allocation_terms(log: ULogFile, servos: dict[int, tuple[str, float, float]],
                      motors: dict[int, tuple[str, float, float]], vtol: bool,
                      deflections: Mapping[str, float]) -> tuple:
    """(surface terms, throttle terms) of servos and motors given as index -> (field,
    offset, scale) of their -1..1 (servo) or 0..1 (motor) value."""
    torques = _servo_torques(log, sorted(servos))
    full = {c: m.full_value
            for c, m in ActuatorMapping.px4_controls(**deflections).channels().items()}
    surfaces = {}
    for axis, channel in enumerate(_AXES):
        terms = tuple((*servos[k], full[channel] * t[axis]) for k, t in torques.items()
                      if t[axis])
        if terms:
            surfaces[channel] = terms
    if not surfaces:
        raise FlightLogError(
            f"{log.source}: no servo of servos {sorted(servos)} moves a control axis "
            "(CA_SV_CSn_TYPE 1-8 or 15, or CA_SV_CSn_TRQ_R/P/Y); map the surfaces with an "
            "ActuatorMapping")
    throttle = ()
    if motors:
        forward = _forward_motors(log, sorted(motors), vtol)
        throttle = tuple((*motors[r], 1.0 / len(forward)) for r in forward)
    return surfaces, throttle


def _allocated(log: ULogFile, vtol: bool, deflections: Mapping[str, float]) -> list[_Source]:
    """actuator_servos + actuator_motors (PX4 1.14+) through the CA_* parameters."""
    def controls(topic: str, count: int) -> dict[int, tuple[str, float, float]]:
        fields = log.fields(topic) if log.has(topic) else {}
        return {k: (f"control[{k}]", 0.0, 1.0) for k in range(count) if f"control[{k}]" in fields}

    servos = controls("actuator_servos", int(log.parameter("CA_SV_CS_COUNT", 8)))
    motors = controls("actuator_motors", int(log.parameter("CA_ROTOR_COUNT", 1)))
    surfaces, throttle = _allocation_terms(log, servos, motors, vtol, deflections)
    sources = [_Source("actuator_servos", surfaces)]
    if throttle:
        sources.append(_Source("actuator_motors", {"cmd_throttle": throttle},
                               {"cmd_throttle": (0.0, 1.0)}))
    return sources


def _outputs(log: ULogFile, vtol: bool, deflections: Mapping[str, float]) -> list[_Source]:
    """actuator_outputs through ``PWM_MAIN_FUNCn`` (101-112 motors, 201-208 servos), or
    the standard plane mixer's order (:meth:`ActuatorMapping.px4_outputs`) without it."""
    functions = {n: int(log.parameter(f"PWM_MAIN_FUNC{n}", 0)) for n in range(1, 17)}
    if not any(functions.values()):
        if vtol:  # its main outputs drive the hover rotors, in the mixer file's order
            raise FlightLogError(
                f"{log.source}: actuator outputs of a VTOL without PWM_MAIN_FUNCn parameters "
                "(PX4 < 1.14) cannot be mapped: read the default control group "
                "(actuator_controls_1) or pass an ActuatorMapping")
        return [_with_pwm(log, _from_mapping(ActuatorMapping.px4_outputs(**deflections)))]
    servos, motors, pwm = {}, {}, {}
    for n, function in functions.items():
        low, high, disarmed = pwm[f"output[{n - 1}]"] = _pwm_limits(log, n)
        if 201 <= function <= 208:
            sign = -1.0 if int(log.parameter("PWM_MAIN_REV", 0)) >> (n - 1) & 1 else 1.0
            servos[function - 201] = (f"output[{n - 1}]", (low + high) / 2,
                                      sign * (high - low) / 2)
        elif 101 <= function <= 112:
            motors[function - 101] = (f"output[{n - 1}]", low, high - low)
    surfaces, throttle = _allocation_terms(log, servos, motors, vtol, deflections)
    terms = dict(surfaces, **({"cmd_throttle": throttle} if throttle else {}))
    used = {t[0] for ts in terms.values() for t in ts}
    return [_Source("actuator_outputs", terms, {"cmd_throttle": (0.0, 1.0)},
                    {f: v for f, v in pwm.items() if f in used})]


def _select(log: ULogFile, actuators, mav_type: int, deflections: Mapping[str, float]
            ) -> tuple[list[_Source], str]:
    """The command sources and why they were chosen (module docstring)."""
    if isinstance(actuators, ActuatorMapping):
        return [_with_pwm(log, _from_mapping(actuators.validate()))], "given mapping"
    if actuators not in (None, "controls", "outputs"):
        raise ValueError(f"actuators: an ActuatorMapping, 'controls' or 'outputs', got "
                         f"{actuators!r}")
    if mav_type in MULTICOPTER_TYPES:
        return [], f"none: a multicopter (MAV_TYPE {mav_type}) has no control surfaces"
    vtol = mav_type in VTOL_TYPES
    if actuators == "outputs":
        return (_outputs(log, vtol, deflections),
                "actuator_outputs as asked (PWM_MAIN_* parameters)")
    group = "actuator_controls_1" if vtol else "actuator_controls_0"
    if log.has(group):
        mapping = dataclasses.replace(ActuatorMapping.px4_controls(**deflections),
                                      message=group)
        why = "fixed-wing control group of a VTOL" if vtol else "control group of a plane"
        return [_from_mapping(mapping)], why
    if vtol and log.has("actuator_controls_0"):
        raise FlightLogError(
            f"{log.source}: VTOL log (MAV_TYPE {mav_type}) without actuator_controls_1 (the "
            "fixed-wing control group); actuator_controls_0 drives the hover rotors: map "
            "the surfaces with an ActuatorMapping")
    if log.has("actuator_servos") or log.has("actuator_motors"):
        return (_allocated(log, vtol, deflections),
                "actuator_servos/actuator_motors (CA_* parameters)")
    if actuators is None and log.has("actuator_outputs"):
        return _outputs(log, vtol, deflections), "actuator_outputs (no control topic in the log)"
    raise FlightLogError(f"{log.source}: no actuator topic (actuator_controls_0/1, "
                         "actuator_servos, actuator_motors or actuator_outputs); map the "
                         "commands of another topic with an ActuatorMapping")


def _disarmed(log: ULogFile, time: np.ndarray) -> np.ndarray:
    """True where ``vehicle_status.arming_state`` (held) is not armed (2); False
    without the topic or before its first message."""
    if not log.has("vehicle_status"):
        return np.zeros(time.size, bool)
    t, f = log.get("vehicle_status", ["arming_state"])
    index = np.searchsorted(t, time, side="right") - 1
    return (index >= 0) & (f["arming_state"][np.maximum(index, 0)] != 2)


def _stream(log: ULogFile, source: _Source) -> Stream:
    """The held command stream of one source, invalid samples flagged."""
    fields = sorted({t[0] for terms in source.terms.values() for t in terms})
    time, raw = log.get(source.message, fields)
    valid = ~_disarmed(log, time)
    for field in fields:
        valid &= np.isfinite(raw[field])
        if field in source.pwm:
            low, high, _ = source.pwm[field]
            valid &= (raw[field] != 0) & (raw[field] >= low) & (raw[field] <= high)
    channels = {}
    for channel, terms in source.terms.items():
        value = sum(w * (raw[f] - offset) / scale for f, offset, scale, w in terms)
        channels[channel] = np.clip(value, *source.limits[channel]) \
            if channel in source.limits else value
    return channel_stream(source.message, time, channels,
                          {c: "+".join(t[0] for t in ts) for c, ts in source.terms.items()},
                          hold=True, valid=None if valid.all() else valid)


def actuator_plan(log: ULogFile, actuators, mav_type: int,
                  deflections: Mapping[str, float] | None = None) -> tuple[list, dict]:
    """(the command sources, their description for ``metadata["actuators"]``).

    Args:
        log: the ULog file.
        actuators: an :class:`ActuatorMapping`, ``"controls"``, ``"outputs"`` or
            None (the module docstring's choice).
        mav_type: the vehicle's MAV_TYPE (0 when unknown: treated as a plane).
        deflections: surface ("elevator", "aileron", "rudder") -> full deflection
            [rad] at a demand of 1 (full servo throw); 25 deg unless given.

    Raises:
        FlightLogError: a VTOL without its fixed-wing group or forward motor, or a
            log without any actuator topic (a plane's or VTOL's), naming the file.
    """
    deflections = {**dict.fromkeys(("elevator", "aileron", "rudder"), math.radians(25.0)),
                   **(deflections or {})}
    sources, why = _select(log, actuators, mav_type, deflections)
    description = {"message": sources[0].message if sources else None, "selected": why,
                   "deflections_rad": deflections,
                   "sources": {s.message: s.describe() for s in sources}}
    if isinstance(actuators, ActuatorMapping):
        description.update(actuators.describe())
    return sources, description


def actuator_streams(log: ULogFile, sources: list) -> list[Stream]:
    """The held ``cmd_*`` streams of the sources of :func:`actuator_plan`."""
    return [_stream(log, s) for s in sources]
