"""Where the main job's angle of attack and sideslip come from.

=========  ===================================================================
mode       flow angles
=========  ===================================================================
vanes      the logged vanes ``vane_alpha, vane_beta`` (a sensor, white noise)
estimate   estimated offline from the IMU, attitude, GPS velocity and pitot by a
           forward filter and a backward smoother
           (:func:`~drake_uav.estimation.estimate_air_data`); their error is the
           smoother's standard deviation, which enters the errors-in-variables
           fits in place of a vane's noise
ahrs       the autopilot's own estimate (ArduPlane ``AOA`` message: channels
           ``ahrs_alpha, ahrs_beta``), an estimate, never taken for a sensor; its
           error is unknown, so the vane noise of the default sensor suite stands in
auto       ``vanes`` when the log holds them, else ``estimate``
=========  ===================================================================
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.air_data import dynamic_pressure

__all__ = ["AIR_DATA_MODES", "FlowAngles", "flow_angles", "choose_air_data"]

AIR_DATA_MODES = ("auto", "vanes", "estimate", "ahrs")
"""Accepted ``air_data`` modes."""

_CHANNELS = {"vanes": ("vane_alpha", "vane_beta"), "estimate": ("est_alpha", "est_beta"),
             "ahrs": ("ahrs_alpha", "ahrs_beta")}
_DESCRIPTION = {
    "vanes": "alpha and beta from the logged vanes",
    "estimate": "alpha, beta and wind estimated from IMU, attitude, GPS and pitot "
                "(forward filter and backward smoother; no vanes)",
    "ahrs": "alpha and beta from the autopilot's own AHRS estimate (AOA message), "
            "not a sensor",
}


@dataclasses.dataclass(frozen=True)
class FlowAngles:
    """The flow angles of one log segment, as channels of its log.

    Attributes
    ----------
    mode : str
        "vanes", "estimate" or "ahrs".
    log : FlightLog
        The segment's log, holding ``channels``.
    channels : (str, str)
        Alpha and beta channels [rad].
    error_variance : dict of str to float or None
        Mean error variance of ``alpha, beta`` [rad^2] of an estimate (None: a sensor,
        whose noise the isolation reads from the data).
    warnings : tuple of str
        What the estimate could not determine (a wind the segment does not observe).
    """

    mode: str
    log: FlightLog
    channels: tuple[str, str]
    error_variance: dict[str, float] | None
    warnings: tuple[str, ...] = ()

    @property
    def description(self) -> str:
        """One line for the report."""
        return _DESCRIPTION[self.mode]


def choose_air_data(log: FlightLog, mode: str, source: str = "flight log") -> str:
    """The air-data mode ``auto`` resolves to for ``log``; checks the channels a mode needs.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    mode : str
        One of :data:`AIR_DATA_MODES` ("auto" picks the vanes when logged, else the
        estimate).
    source : str
        What to call the log in messages (its file name).

    Returns
    -------
    str
        The resolved mode.

    Raises
    ------
    ValueError
        For an unknown mode.
    FlightLogError
        Naming the missing channel of the mode.
    """
    if mode not in AIR_DATA_MODES:
        raise ValueError(f"air_data: unknown mode {mode!r} (known: {', '.join(AIR_DATA_MODES)})")
    if mode == "auto":
        return "vanes" if all(c in log for c in _CHANNELS["vanes"]) else "estimate"
    if mode == "estimate":
        missing = [c for c in ("pitot_airspeed", "gps_vn", "gps_ve", "gps_vd") if c not in log]
        if missing:
            raise FlightLogError(
                f"{source}: cannot estimate alpha and beta without {', '.join(missing)}; "
                "log vanes and use --air-data vanes")
        return mode
    for channel in _CHANNELS[mode]:
        if channel not in log:
            other = "--air-data estimate" if mode == "vanes" else "--air-data auto"
            raise FlightLogError(f"{source}: missing channel '{channel}' for --air-data "
                                 f"{mode}; use {other}")
    return mode


def flow_angles(log: FlightLog, params, mode: str,
                noise_std: dict[str, float] | None = None) -> FlowAngles:
    """The flow angles of one continuous segment ``log`` by a resolved ``mode``.

    Parameters
    ----------
    log : FlightLog
        One continuous segment.
    params : FixedWingParams
        The aircraft (the estimate's model).
    mode : str
        A resolved mode (:func:`choose_air_data`).
    noise_std : dict of str to float, optional
        Log channel -> noise standard deviation for the estimator; None lets it use its
        documented defaults.

    Returns
    -------
    FlowAngles
        The flow-angle channels and, for an estimate, their error variance.

    Raises
    ------
    FlightLogError
        When the air data cannot be estimated (no GPS velocity).
    """
    if mode != "estimate":
        return FlowAngles(mode, log, _CHANNELS[mode], None)
    from drake_uav.estimation.air_data_estimate import NOISE_CHANNELS, estimate_air_data

    declared = {k: v for k, v in (noise_std or {}).items() if k in NOISE_CHANNELS} or None
    estimate = estimate_air_data(_with_dynamic_pressure(log, params.rho), params,
                                 noise_std=declared,
                                 segments=[[log.time[0], log.time[-1]]])
    valid = np.flatnonzero(estimate.valid)
    if valid.size < 2:
        raise FlightLogError("the air data could not be estimated (no GPS velocity "
                             "together with airspeed); log vanes and use --air-data vanes")
    keep = slice(valid[0], valid[-1] + 1)
    with_estimate = log.slice(log.time[valid[0]], log.time[valid[-1]]).with_measured(
        {"est_alpha": estimate.alpha[keep], "est_beta": estimate.beta[keep]},
        {"est_alpha": "rad", "est_beta": "rad"})
    variance = {"alpha": float(np.mean(estimate.alpha_std[keep] ** 2)),
                "beta": float(np.mean(estimate.beta_std[keep] ** 2))}
    return FlowAngles(mode, with_estimate, _CHANNELS[mode], variance, estimate.notes)


def _with_dynamic_pressure(log: FlightLog, rho: float) -> FlightLog:
    """``log`` with ``pitot_qbar`` [Pa] from ``pitot_airspeed`` when only the airspeed is
    logged (PX4 logs the differential pressure at 1 Hz, if at all)."""
    if "pitot_qbar" in log or "pitot_airspeed" not in log:
        return log
    return log.with_measured({"pitot_qbar": dynamic_pressure(log["pitot_airspeed"], rho)},
                             {"pitot_qbar": "Pa"})
