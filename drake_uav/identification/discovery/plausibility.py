"""Plausible signs and magnitudes of the aerodynamic derivatives of a small fixed wing.

A fit may return any number the data support; a derivative far outside what an aircraft of
conventional layout has (a negative lift slope, roll damping that drives the roll, a pitch
rate derivative of 60) says more about the flight or the model than about the aircraft:
too little excitation, regressors that moved together, a missing effect the derivative
absorbed. :data:`PLAUSIBLE_RANGES` holds the one table of those ranges; the main job's report
warns about every value outside them (:func:`implausible_derivatives`), never changes one.

Derivatives are non-dimensional, per rad (angles, surfaces) or per normalised rate
(``b p / 2Va``, ``c q / 2Va``, ``b r / 2Va``), as in :mod:`drake_uav.model.coefficients`.
The bounds are generous: the signs follow from static and dynamic stability of a
tail-aft layout, the magnitudes are a few times the typical small-UAV values of Beard &
McLain 2012, ch. 4 and app. E (Aerosonde: C_L_alpha 5.61, C_L_q 7.95, C_m_alpha -2.74,
C_m_q -38.2, C_Y_beta -0.98, C_l_p -0.51, C_n_beta 0.073, C_n_r -0.095). Surface
derivatives are bounded in magnitude only (catalogs disagree on the deflection sign).
The alpha-dot derivatives are those of the downwash lag (Etkin & Reid 1996, ch. 5):
``C_L_alphadot = 2 a_t V_H d(epsilon)/d(alpha)``, positive, and ``C_m_alphadot`` that
times ``-l_t / c``, negative (tail lift slope ``a_t``, tail volume ``V_H``, tail arm
``l_t``; about 1.6 and -8 for ``a_t = 4``, ``V_H = 0.5``, ``d(epsilon)/d(alpha) = 0.4``,
``l_t = 5 c``).

The same table decides whether the discovery keeps an effect's term
(:class:`~drake_uav.identification.discovery.result.HeldOutCheck`): a term named like a
derivative of the table (``unsteady_alphadot`` on C_L and C_m) is not kept with a value
outside its range, which is not the physics the effect names.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

__all__ = ["PlausibleRange", "PLAUSIBLE_RANGES", "DerivativeWarning", "implausible_derivatives"]

_STABILITY = "Beard & McLain 2012, ch. 4 (stability derivatives of a tail-aft aircraft)"
_TYPICAL = "Beard & McLain 2012, app. E (Aerosonde), a few times over"
_DOWNWASH_LAG = ("Etkin & Reid 1996, ch. 5 (the alpha-dot derivatives: the tail meets the "
                 "downwash of an earlier alpha), typical values a few times over")


@dataclasses.dataclass(frozen=True)
class PlausibleRange:
    """Closed range ``[low, high]`` of one derivative, what lies outside, and the source.

    Attributes
    ----------
    low : float
        Lower bound, in the derivative's unit.
    high : float
        Upper bound.
    meaning : str
        What a value outside the range would mean for the aircraft.
    source : str
        Where the range comes from.
    """

    low: float
    high: float
    meaning: str
    source: str


PLAUSIBLE_RANGES: Mapping[str, PlausibleRange] = {
    "CL_alpha": PlausibleRange(
        2.0, 3.0 * math.pi,
        "lift slope: at most 1.5 x the thin-airfoil 2 pi, at least that of an aspect "
        "ratio 1.5 wing (Helmbold's formula)", "Beard & McLain 2012, ch. 4 (C_L_alpha of a "
        "finite wing); thin-airfoil theory"),
    "CL_q": PlausibleRange(-10.0, 30.0, "lift from pitch rate: tail lift, of order 10",
                           _TYPICAL),
    "CL_elevator": PlausibleRange(-1.0, 1.0, "elevator lift effectiveness", _TYPICAL),
    "CL_alphadot": PlausibleRange(0.0, 10.0, "lift from the downwash lag at the tail: "
                                  "positive", _DOWNWASH_LAG),
    "CD_0": PlausibleRange(0.0, 0.3, "zero-lift drag: positive, a few hundredths",
                           _TYPICAL),
    "CD_alpha2": PlausibleRange(0.0, 5.0, "induced drag grows with alpha^2: positive",
                                _TYPICAL),
    "CY_beta": PlausibleRange(-2.0, 0.0, "side force opposes sideslip: negative",
                              _STABILITY),
    "Cl_beta": PlausibleRange(-0.5, 0.0, "dihedral effect: negative (a positive value rolls "
                              "into the sideslip, spirally divergent)", _STABILITY),
    "Cl_p": PlausibleRange(-1.5, 0.0, "roll damping: negative", _STABILITY),
    "Cm_alpha": PlausibleRange(-5.0, 0.0, "pitch stiffness: negative (positive is statically "
                               "unstable)", _STABILITY),
    "Cm_q": PlausibleRange(-80.0, 0.0, "pitch damping: negative", _STABILITY),
    "Cm_elevator": PlausibleRange(-3.0, 3.0, "elevator pitch effectiveness", _TYPICAL),
    "Cm_alphadot": PlausibleRange(-40.0, 0.0, "pitching moment from the downwash lag at the "
                                  "tail: negative", _DOWNWASH_LAG),
    "Cn_beta": PlausibleRange(0.0, 0.5, "weathercock stability: positive", _STABILITY),
    "Cn_r": PlausibleRange(-1.0, 0.0, "yaw damping: negative", _STABILITY),
}
"""Derivative name -> plausible range (module docstring)."""


@dataclasses.dataclass(frozen=True)
class DerivativeWarning:
    """One warning about identified derivatives.

    Attributes
    ----------
    kind : str
        "implausible", "correlated" or "unexcited".
    derivatives : tuple of str
        The derivative (or the pair) it concerns.
    message : str
        One line: what was found and what it means.
    """

    kind: str
    derivatives: tuple[str, ...]
    message: str


def implausible_derivatives(values: Mapping[str, float],
                            sigma: Mapping[str, float] | None = None
                            ) -> list[DerivativeWarning]:
    """A warning for every value outside :data:`PLAUSIBLE_RANGES`.

    Parameters
    ----------
    values : Mapping[str, float]
        Derivative name -> value.
    sigma : Mapping[str, float], optional
        Name -> standard deviation; a value whose two-sigma interval reaches the range is
        then said to be possibly noise.

    Returns
    -------
    list of DerivativeWarning
        Of kind "implausible".
    """
    out = []
    for name, value in values.items():
        bounds = PLAUSIBLE_RANGES.get(name)
        if bounds is None or bounds.low <= value <= bounds.high:
            continue
        side = "below" if value < bounds.low else "above"
        text = (f"{name} = {value:.4g} is {side} the plausible range [{bounds.low:.3g}, "
                f"{bounds.high:.3g}] ({bounds.meaning})")
        s = None if sigma is None else sigma.get(name)
        if s is not None and math.isfinite(s):
            distance = bounds.low - value if value < bounds.low else value - bounds.high
            text += (f"; {distance / s:.1f} sigma outside" if distance > 2.0 * s else
                     f"; within 2 sigma ({s:.2g}) of it: possibly noise")
        out.append(DerivativeWarning("implausible", (name,), text))
    return out
