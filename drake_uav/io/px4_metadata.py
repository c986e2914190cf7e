"""What a PX4 log says about its vehicle: type, firmware, flight modes, VTOL state.

The keys are those every autopilot reader writes (docs/flight_logs.md):
``vehicle_type`` (MAVLink ``MAV_TYPE`` numbering), ``firmware``,
``flight_modes`` (``[[t_s, "MODE"], ...]`` at each change of
``vehicle_status.nav_state``), ``vtol_state`` (VTOLs only: ``"mc"``,
``"transition"``, ``"fw"`` at each change) and ``parameters``; ``imu_position`` when the
log sets ``EKF2_IMU_POS_X/Y/Z`` (where the IMU sits from the centre of gravity, [m] body
axes FRD).
"""

from __future__ import annotations

import numpy as np

from drake_uav.io.px4_ulog import ULogFile
from drake_uav.io.streams import imu_position_metadata

__all__ = ["MULTICOPTER_TYPES", "VTOL_TYPES", "px4_metadata", "vehicle_type"]

MAV_TYPE_NAMES = {
    0: "generic", 1: "fixed wing", 2: "quadrotor", 3: "coaxial helicopter", 4: "helicopter",
    13: "hexarotor", 14: "octorotor", 15: "tricopter", 19: "VTOL tailsitter duorotor",
    20: "VTOL tailsitter quadrotor", 21: "VTOL tiltrotor", 22: "VTOL standard (fixed rotors)",
    23: "VTOL tailsitter", 24: "VTOL tiltwing",
}
"""MAVLink MAV_TYPE values of aircraft -> name."""
MULTICOPTER_TYPES = frozenset({2, 3, 4, 13, 14, 15})
"""MAV_TYPE values without wings (no control surfaces)."""
VTOL_TYPES = frozenset(range(19, 26))
"""MAV_TYPE values of VTOLs (hover rotors and a wing)."""

NAV_STATES = {
    0: "MANUAL", 1: "ALTCTL", 2: "POSCTL", 3: "AUTO_MISSION", 4: "AUTO_LOITER", 5: "AUTO_RTL",
    10: "ACRO", 12: "DESCEND", 13: "TERMINATION", 14: "OFFBOARD", 15: "STAB",
    17: "AUTO_TAKEOFF", 18: "AUTO_LAND", 19: "AUTO_FOLLOW_TARGET", 20: "AUTO_PRECLAND",
    21: "ORBIT", 22: "AUTO_VTOL_TAKEOFF",
}
"""PX4 ``vehicle_status.nav_state`` -> flight mode name."""

_VTOL_STATES = {1: "transition", 2: "transition", 3: "mc", 4: "fw"}
"""``vtol_vehicle_status.vehicle_vtol_state`` (PX4 1.12+): 1 transition to FW,
2 transition to MC, 3 MC, 4 FW (0 undefined)."""
_RELEASE_TYPES = ((255, ""), (192, " rc"), (128, " beta"), (64, " alpha"), (0, " dev"))


def vehicle_type(log: ULogFile) -> dict:
    """``{"mav_type": int, "name": str}`` from the MAV_TYPE parameter, else from
    ``vehicle_status`` (is_vtol -> 22, fixed wing -> 1, rotary wing -> 2), else 0."""
    mav_type = log.parameter("MAV_TYPE")
    suffix = ""
    if mav_type is None and log.has("vehicle_status"):
        status = log.fields("vehicle_status")
        suffix = " (from vehicle_status)"
        if "is_vtol" in status and np.any(status["is_vtol"]):
            mav_type = 22
        elif "vehicle_type" in status:  # PX4's own numbering: 1 rotary wing, 2 fixed wing
            mav_type = {1: 2, 2: 1}.get(int(status["vehicle_type"][-1]), 0)
        elif "is_rotary_wing" in status:
            mav_type = 2 if status["is_rotary_wing"][-1] else 1
    mav_type = int(mav_type or 0)
    return {"mav_type": mav_type, "name": MAV_TYPE_NAMES.get(mav_type, f"MAV_TYPE {mav_type}")
            + suffix}


def firmware(log: ULogFile) -> str:
    """``"PX4 v1.11.2 dev (v1.11.2_w_rc_sysid, 8583f1da)"`` from the info messages
    (``ver_sw_release`` is 0xMMmmppTT: major, minor, patch, release type)."""
    name = str(log.info.get("sys_name", "PX4"))
    release = log.info.get("ver_sw_release")
    if isinstance(release, (int, np.integer)) and release:  # else a corrupt definition
        release = int(release)
        kind = next(label for limit, label in _RELEASE_TYPES if release & 0xFF >= limit)
        name += (f" v{release >> 24 & 0xFF}.{release >> 16 & 0xFF}.{release >> 8 & 0xFF}"
                 + kind)
    details = [str(log.info[k]) for k in ("ver_sw_branch",) if k in log.info]
    if "ver_sw" in log.info:
        details.append(str(log.info["ver_sw"])[:8])
    return name + (f" ({', '.join(details)})" if details else "")


def _changes(time: np.ndarray, labels: list[str]) -> list[list]:
    """``[[t_s, label], ...]`` at the first sample and at each change of label."""
    out = []
    for t, label in zip(time, labels, strict=True):
        if not out or out[-1][1] != label:
            out.append([float(t), label])
    return out


def flight_modes(log: ULogFile) -> list[list]:
    """The ``vehicle_status.nav_state`` timeline; ``[]`` without the topic."""
    if not log.has("vehicle_status"):
        return []
    time, f = log.get("vehicle_status", ["nav_state"])
    states = f["nav_state"].astype(int)
    return _changes(time, [NAV_STATES.get(s, f"NAV_STATE {s}") for s in states])


def vtol_state(log: ULogFile) -> list[list]:
    """The VTOL state timeline from ``vtol_vehicle_status`` (``vehicle_vtol_state``,
    or before PX4 1.12 ``vtol_in_trans_mode`` / ``in_transition_mode`` and
    ``vtol_in_rw_mode``), else from ``vehicle_status`` (``in_transition_mode``,
    ``vehicle_type`` 1 rotary wing); ``[]`` without either."""
    for topic, rotary in (("vtol_vehicle_status", "vtol_in_rw_mode"),
                          ("vehicle_status", "vehicle_type")):
        if not log.has(topic):
            continue
        data = log.fields(topic)
        time, _ = log.get(topic, [])
        if "vehicle_vtol_state" in data:
            labels = [_VTOL_STATES.get(int(s), "mc") for s in data["vehicle_vtol_state"]]
            return _changes(time, labels)
        transition = next((data[k] for k in ("vtol_in_trans_mode", "in_transition_mode")
                           if k in data), None)
        if transition is None or rotary not in data:
            continue
        hover = data[rotary] == 1  # vtol_in_rw_mode true, or PX4 vehicle_type 1 (rotary)
        labels = ["transition" if tr else "mc" if rw else "fw"
                  for tr, rw in zip(transition, hover, strict=True)]
        return _changes(time, labels)
    return []


def px4_metadata(log: ULogFile) -> dict:
    """The shared reader keys (module docstring) of a PX4 log; ``vtol_state`` for
    VTOLs only. ``parameters`` holds the values at the start of the log (and the
    first value of one set only during the log); ``parameter_changes`` lists
    ``[t_s, name, value]`` of every change during the log."""
    kind = vehicle_type(log)
    parameters = dict(log.parameters)
    for _, name, value in log.parameter_changes:
        parameters.setdefault(name, value)
    meta = {"vehicle_type": kind, "firmware": firmware(log), "flight_modes": flight_modes(log),
            "parameters": dict(sorted(parameters.items())),
            "parameter_changes": [list(change) for change in log.parameter_changes]}
    if kind["mav_type"] in VTOL_TYPES:
        meta["vtol_state"] = vtol_state(log)
    meta.update(imu_position_metadata(parameters, [f"EKF2_IMU_POS_{a}" for a in "XYZ"],
                                      "EKF2_IMU_POS_X/Y/Z"))
    return meta
