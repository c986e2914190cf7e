"""What an ArduPilot log's own parameters and messages say about the vehicle.

* :func:`servo_mapping`: the RCOU channel of each surface and the throttle from
  ``SERVOn_FUNCTION`` (4 aileron, 19 elevator, 21 rudder, 70 throttle) and its
  PWM scaling from ``SERVOn_MIN``, ``SERVOn_MAX``, ``SERVOn_TRIM``,
  ``SERVOn_REVERSED``.
* :func:`vehicle_type`: the MAV_TYPE from the firmware string (``MSG``) and the
  frame parameters (``Q_ENABLE``, ``FRAME_CLASS``).
* :func:`mode_name`: ``MODE.ModeNum`` -> the firmware's mode name.
* :func:`imu_position`: where the IMU sits from the centre of gravity
  (``INS_POS<n>_X/Y/Z``).

ArduPilot drives a surface servo at ``TRIM + servo * (MAX - TRIM)`` for a
positive normalised demand ``servo`` (roll right, pitch up, yaw right) and at
``TRIM + servo * (TRIM - MIN)`` for a negative one, mirrored about the trim when
``REVERSED = 1``; the throttle at ``MIN + throttle * (MAX - MIN)``. The library's
signs (positive elevator nose-down, positive rudder nose-left) turn pitch-up
and yaw-right demands into negative commands.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from drake_uav.io.flight_log import FlightLogError
from drake_uav.io.streams import ActuatorChannel, ActuatorMapping, imu_position_metadata

__all__ = ["PWM_MARGIN", "imu_position", "mode_name", "servo_mapping", "vehicle_type"]

PWM_MARGIN = 50.0
"""A PWM further than this outside ``SERVOn_MIN..SERVOn_MAX`` is an invalid sample [us]."""

_FUNCTIONS = {4: "aileron", 19: "elevator", 21: "rudder", 70: "throttle"}
_MIXED = {77: "elevon left", 78: "elevon right", 79: "V-tail left", 80: "V-tail right"}
_DEMAND_SIGN = {"aileron": 1.0, "elevator": -1.0, "rudder": -1.0}
"""Library command sign of a positive ArduPilot demand (roll right, pitch up, yaw right)."""
_RCOU_CHANNELS = 14  # RCOU carries C1..C14

_PLANE_MODES = {
    0: "MANUAL", 1: "CIRCLE", 2: "STABILIZE", 3: "TRAINING", 4: "ACRO", 5: "FBWA", 6: "FBWB",
    7: "CRUISE", 8: "AUTOTUNE", 10: "AUTO", 11: "RTL", 12: "LOITER", 13: "TAKEOFF",
    14: "AVOID_ADSB", 15: "GUIDED", 17: "QSTABILIZE", 18: "QHOVER", 19: "QLOITER",
    20: "QLAND", 21: "QRTL", 22: "QAUTOTUNE", 23: "QACRO", 24: "THERMAL", 25: "LOITER_ALT_QLAND",
}
_COPTER_MODES = {
    0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
    7: "CIRCLE", 9: "LAND", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE",
    16: "POSHOLD", 17: "BRAKE", 18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS",
    21: "SMART_RTL", 22: "FLOWHOLD", 23: "FOLLOW", 24: "ZIGZAG", 25: "SYSTEMID",
    26: "AUTOROTATE", 27: "AUTO_RTL",
}
_ROVER_MODES = {
    0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
    10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED",
}
_MODES = {"ArduPlane": _PLANE_MODES, "ArduCopter": _COPTER_MODES, "Rover": _ROVER_MODES,
          "ArduRover": _ROVER_MODES}

_COPTER_FRAMES = {1: (2, "quadrotor"), 2: (13, "hexarotor"), 3: (14, "octorotor"),
                  4: (14, "octorotor (octaquad)"), 5: (13, "hexarotor (Y6)"),
                  6: (4, "helicopter"), 7: (15, "tricopter"), 11: (4, "helicopter (dual)"),
                  12: (29, "dodecarotor"), 13: (4, "helicopter (quad)"), 14: (35, "decarotor")}


def _firmware_name(firmware: str) -> str:
    """``"ArduPlane"`` of ``"ArduPlane V4.3.7 (abc)"``; "" when not recognised."""
    name = firmware.split(" ", 1)[0]
    return name if name in _MODES or name in ("ArduSub", "Blimp", "AntennaTracker") else ""


def vehicle_type(firmware: str, params: Mapping[str, float]) -> dict | None:
    """``{"mav_type": int, "name": str}`` (MAVLink MAV_TYPE numbering) of a log, or None
    when neither the firmware string nor the parameters tell.

    ArduPlane is a fixed wing (1) unless ``Q_ENABLE = 1`` (a quadplane: 20
    tailsitter, 21 tiltrotor, 22 fixed-rotor VTOL, or ``Q_MAV_TYPE`` when set);
    ArduCopter takes its type from ``FRAME_CLASS`` (2 quadrotor by default);
    Rover is a ground rover (10). Without a firmware string, ``Q_ENABLE`` marks
    ArduPlane and ``FRAME_CLASS`` ArduCopter (parameters only those firmwares have).
    """
    name = _firmware_name(firmware)
    if not name:
        name = ("ArduPlane" if "Q_ENABLE" in params
                else "ArduCopter" if "FRAME_CLASS" in params else "")
    if name == "ArduPlane":
        if params.get("Q_ENABLE", 0.0) < 1.0:
            return {"mav_type": 1, "name": "fixed wing"}
        if params.get("Q_MAV_TYPE", 0.0) > 0.0:
            return {"mav_type": int(params["Q_MAV_TYPE"]), "name": "VTOL (Q_MAV_TYPE)"}
        if params.get("Q_TAILSIT_ENABLE", 0.0) > 0.0:
            return {"mav_type": 20, "name": "VTOL tailsitter"}
        if params.get("Q_TILT_ENABLE", 0.0) > 0.0 or params.get("Q_TILT_MASK", 0.0) > 0.0:
            return {"mav_type": 21, "name": "VTOL tiltrotor"}
        return {"mav_type": 22, "name": "VTOL (quadplane)"}
    if name == "ArduCopter":
        mav_type, label = _COPTER_FRAMES.get(int(params.get("FRAME_CLASS", 1)),
                                             (2, "multicopter"))
        return {"mav_type": mav_type, "name": label}
    if name in ("Rover", "ArduRover"):
        return {"mav_type": 10, "name": "ground rover"}
    if name == "ArduSub":
        return {"mav_type": 12, "name": "submarine"}
    return None


def mode_name(firmware: str, mode_number: int) -> str:
    """The mode name of ``MODE.ModeNum`` for the firmware (``"MODE 42"`` if unknown)."""
    return _MODES.get(_firmware_name(firmware), {}).get(mode_number, f"MODE {mode_number}")


def _servo_params(params: Mapping[str, float], n: int, source: str) -> tuple[float, ...]:
    """(MIN, MAX, TRIM, REVERSED) of servo ``n``; FlightLogError naming a bad one."""
    values = []
    for key in ("MIN", "MAX", "TRIM", "REVERSED"):
        name = f"SERVO{n}_{key}"
        if name not in params or not math.isfinite(params[name]):
            raise FlightLogError(f"{source}: parameter {name} missing or not finite "
                                 f"(SERVO{n}_FUNCTION = {params[f'SERVO{n}_FUNCTION']:g})")
        values.append(float(params[name]))
    low, high, trim, _ = values
    if not low < high:
        raise FlightLogError(f"{source}: SERVO{n}_MIN = {low:g} is not below "
                             f"SERVO{n}_MAX = {high:g}")
    return tuple(values)


def _servo_channel(params, n: int, command: str, deflection: float,
                   source: str) -> ActuatorChannel:
    """The mapping of RCOU C<n> onto ``cmd_<command>`` from the SERVOn parameters."""
    low, high, trim, reversed_ = _servo_params(params, n, source)
    valid = (low - PWM_MARGIN, high + PWM_MARGIN)
    if command == "throttle":
        idle, full = (high, low) if reversed_ >= 1.0 else (low, high)
        return ActuatorChannel(f"C{n}", idle, full, 1.0, (0.0, 1.0), valid_range=valid)
    if not low < trim < high:
        raise FlightLogError(f"{source}: SERVO{n}_TRIM = {trim:g} of the {command} is not "
                             f"between SERVO{n}_MIN = {low:g} and SERVO{n}_MAX = {high:g}")
    sign = _DEMAND_SIGN[command] * (-1.0 if reversed_ >= 1.0 else 1.0)
    return ActuatorChannel(f"C{n}", trim, high, sign * deflection, (-deflection, deflection),
                           full_low=low, valid_range=valid)


def _functions(params: Mapping[str, float]) -> dict[int, int]:
    """Servo number -> SERVOn_FUNCTION for every SERVOn_FUNCTION parameter."""
    out = {}
    for name, value in params.items():
        if name.startswith("SERVO") and name.endswith("_FUNCTION"):
            number = name[5:-9]
            if number.isdigit():
                out[int(number)] = int(value)
    return dict(sorted(out.items()))


def servo_mapping(params: Mapping[str, float], deflections: Mapping[str, float],
                  source: str) -> tuple[ActuatorMapping | None, list[str]]:
    """The RCOU mapping of the log's SERVOn parameters and the notes to warn about.

    Args:
        params: the log's parameters.
        deflections: surface ("elevator", "aileron", "rudder") -> full deflection
            [rad] reached at SERVOn_MAX (or MIN, reversed).
        source: the file, for messages.

    Returns:
        (mapping, notes): the mapping is None when the log has no
        SERVOn_FUNCTION parameters or none of the four functions (a
        multicopter); a command without a servo is left out of the mapping,
        with a note. With several servos of one function the lowest-numbered
        one is used. Elevon and V-tail mixes are not unmixed: a note says so
        and the surfaces they drive are left out.
    """
    functions = _functions(params)
    notes = []
    channels: dict[str, ActuatorChannel] = {}
    for n, function in functions.items():
        command = _FUNCTIONS.get(function)
        if function in _MIXED:
            notes.append(f"SERVO{n}_FUNCTION = {function} ({_MIXED[function]}): elevon and "
                         "V-tail mixes are not unmixed; pass actuators='aetr' (the AETR "
                         "demands) or an ActuatorMapping")
        if command is None or command in channels:
            continue
        if n > _RCOU_CHANNELS:
            notes.append(f"SERVO{n} ({command}) is beyond RCOU's C1..C{_RCOU_CHANNELS}; "
                         f"cmd_{command} left out")
            continue
        channels[command] = _servo_channel(params, n, command,
                                           deflections.get(command, 0.0), source)
    if not channels:
        return None, notes
    missing = [c for c in ("elevator", "aileron", "rudder", "throttle") if c not in channels]
    if missing:
        notes.append("no SERVOn_FUNCTION for " + ", ".join(missing) + "; "
                     + ", ".join(f"cmd_{c}" for c in missing) + " left out")
    mapping = ActuatorMapping("RCOU", **{c: channels.get(c) for c in
                                         ("elevator", "aileron", "rudder", "throttle")})
    return mapping.validate(), notes


def imu_position(params: Mapping[str, float], instance: int) -> dict:
    """The reader's ``imu_position`` metadata (:func:`~.streams.imu_position_metadata`) of
    IMU ``instance`` (0-based) from ``INS_POS<instance + 1>_X/Y/Z``."""
    names = [f"INS_POS{instance + 1}_{axis}" for axis in "XYZ"]
    return imu_position_metadata(params, names, f"INS_POS{instance + 1}_X/Y/Z")
