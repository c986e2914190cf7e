"""The fixed-wing job's terms that need bandwidth, and the log channels each is built from.

:mod:`~drake_uav.identification.assessment.logged_rates` judges terms on channel names
and rates alone; this module names the main job's terms for it
(:func:`derivative_needs`, :func:`effect_needs`, :func:`calibration_needs`) and applies
the verdict to the data-compatibility check (:func:`without_unsupported`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence

from drake_uav.estimation.compatibility_result import CompatibilityResult
from drake_uav.identification.assessment.logged_rates import BAND, TIMING, RateLimit, RateNeed
from drake_uav.identification.discovery.effects import PRODUCT_KEYS
from drake_uav.identification.discovery.loop import DATA_DRIVEN

__all__ = ["derivative_needs", "effect_needs", "calibration_needs", "product_needs",
           "without_unsupported", "ALPHA_CHANNELS"]

_GYROS = ("imu_p", "imu_q", "imu_r")
_SURFACES = ("cmd_elevator", "cmd_aileron", "cmd_rudder")
_SIGNALS = {"p": ("imu_p", "damping derivative"), "q": ("imu_q", "damping derivative"),
            "r": ("imu_r", "damping derivative"),
            "elevator": ("cmd_elevator", "control derivative"),
            "aileron": ("cmd_aileron", "control derivative"),
            "rudder": ("cmd_rudder", "control derivative")}
"""Regressor signal of a derivative -> (the channel it is built from, what it is)."""

ALPHA_CHANNELS = {"vanes": ("vane_alpha",), "ahrs": ("ahrs_alpha",),
                  "estimate": ("imu_az", "imu_q")}
"""Air-data mode -> the channels alpha's fast variation comes from: the vane, the AHRS
estimate, or for the offline estimate the IMU that propagates it between GPS and pitot
updates."""


def derivative_needs(names: Iterable[str]) -> list[RateNeed]:
    """The control and damping derivatives among the baseline's term names.

    Parameters
    ----------
    names : iterable of str
        Term names ``<coefficient>_<signal>`` (``Cl_p``, ``Cm_elevator``).

    Returns
    -------
    list of RateNeed
        One band need per derivative on a body rate or a surface command.
    """
    out = []
    for name in dict.fromkeys(names):
        signal = name.split("_", 1)[1] if "_" in name else ""
        if signal in _SIGNALS:
            channel, what = _SIGNALS[signal]
            out.append(RateNeed(name, what, (channel,), BAND))
    return out


def effect_needs(air_data: str) -> list[RateNeed]:
    """The candidate effects of the discovery loop that need bandwidth.

    Parameters
    ----------
    air_data : str
        The resolved air-data mode (``vanes``, ``estimate``, ``ahrs``).

    Returns
    -------
    list of RateNeed
        Alpha-dot, rate coupling and the lever arm (band terms of their channels), the
        surfaces' nonlinearity and cross coupling (control derivatives), the slipstream
        (its thrust coefficient follows the throttle command, and so does the thrust the
        isolation removes from the drag: a held throttle's lag lands on that very column)
        and the servo delay (a timing term of every command).
    """
    return [
        RateNeed("unsteady_alphadot", "alpha-dot term", ALPHA_CHANNELS[air_data], BAND),
        RateNeed("rate_coupling", "rate coupling", _GYROS, BAND),
        RateNeed("accelerometer_lever_arm", "angular acceleration at the IMU", _GYROS, BAND),
        RateNeed("control_nonlinearity", "control derivatives", _SURFACES, BAND),
        RateNeed("control_cross_coupling", "control derivatives", _SURFACES, BAND),
        RateNeed("thrust_propwash", "throttle derivative (slipstream)", ("cmd_throttle",),
                 BAND),
        RateNeed("actuator_time_delay", "time delay", (*_SURFACES, "cmd_throttle"), TIMING),
    ]


_PRODUCT_SIGNALS = {"p_hat": ("imu_p",), "q_hat": ("imu_q",), "r_hat": ("imu_r",),
                    "elevator": ("cmd_elevator",), "aileron": ("cmd_aileron",),
                    "rudder": ("cmd_rudder",), "Tc": ("cmd_throttle",)}
"""Base signal of the data-driven products -> the channels whose variation it carries
(alpha and beta enter as values, like the static derivatives: none)."""


def product_needs() -> list[RateNeed]:
    """The data-driven products (``data_driven:<a>*<b>``) built from a body rate, a surface
    command or the throttle: band terms of those channels, as the named effects of the same
    columns are (``p_hat*r_hat`` is a rate coupling, ``elevator*Tc`` a control derivative).

    Returns
    -------
    list of RateNeed
    """
    out = []
    for a, b in PRODUCT_KEYS:
        channels = tuple(dict.fromkeys(_PRODUCT_SIGNALS.get(a, ()) + _PRODUCT_SIGNALS.get(b, ())))
        if channels:
            out.append(RateNeed(f"{DATA_DRIVEN}{a}*{b}", "data-driven product", channels, BAND))
    return out


def calibration_needs() -> list[RateNeed]:
    """The calibration errors of the data-compatibility check that need bandwidth: the
    commands' time skew (the other skews are tolerated up to their channels' own sample
    period by the check itself, docs/compatibility.md).

    Returns
    -------
    list of RateNeed
    """
    return [RateNeed("command_time_skew", "time skew", _SURFACES, TIMING)]


def without_unsupported(compatibility: CompatibilityResult | None,
                        limits: Sequence[RateLimit]) -> CompatibilityResult | None:
    """``compatibility`` with the effects ``limits`` name marked not observable.

    Not observable, an effect is neither significant nor corrected, nor taken as the
    servo delay; its note says why.

    Parameters
    ----------
    compatibility : CompatibilityResult or None
        The check's result.
    limits : sequence of RateLimit
        The terms the log cannot support.

    Returns
    -------
    CompatibilityResult or None
        The result (None for None).
    """
    if compatibility is None:
        return None
    by_term = {limit.term: limit for limit in limits}
    effects = tuple(
        dataclasses.replace(e, observable=False, note=by_term[e.name].message())
        if e.name in by_term else e for e in compatibility.effects)
    return dataclasses.replace(compatibility, effects=effects)
