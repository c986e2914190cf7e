"""Stability-derivative coefficient model, linear in its parameters.

One source of truth for the aerodynamic coefficients: the plant, the estimators,
the identification regressors and the linearisation all evaluate the functions
below. They work on scalars (float, AutoDiffXd, symbolic Expression) and,
elementwise, on numpy arrays of samples (batch identification).

Model: Vaiopoulos 2017, eq. 3.31 (the structure of Beard & McLain), with the
alpha-dot and flap terms of Ortiz & Gutierrez 2009, eq. 29-35 and the
thrust-coefficient drag term of Vaiopoulos 2017, eq. 6.2::

    C_k = sum_j  theta_{k,j} * xi_j,        k in (CL, CD, CY, Cl, Cm, Cn)

A derivative is named ``<coefficient>_<signal>``; the signal selects the
regressor ``xi``. Rates are normalised with the span for p and r and the chord
for q and alpha-dot (Ortiz & Gutierrez 2009, sec. 5.1 prints b for q:
docs/references.md), so every derivative is non-dimensional:

============  ======================================  =====
signal        regressor                               unit
============  ======================================  =====
``0``         1                                       -
``alpha``     angle of attack                         rad
``alpha2``    alpha^2                                 rad^2
``alphadot``  c alpha_dot / (2 Va)                    -
``beta``      sideslip                                rad
``p``         b p / (2 Va)                            -
``q``         c q / (2 Va)                            -
``r``         b r / (2 Va)                            -
``elevator``  elevator deflection                     rad
``aileron``   aileron deflection                      rad
``rudder``    rudder deflection                       rad
``flap``      flap deflection                         rad
``Tc``        thrust coefficient T / (qbar S)         -
============  ======================================  =====

Body-axis coefficients follow from lift and drag by Vaiopoulos 2017, eq. A'.12-A'.14:
``C_X = -C_D cos(alpha) + C_L sin(alpha)``, ``C_Z = -C_D sin(alpha) - C_L cos(alpha)``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from pydrake.math import cos, sin

from drake_uav.model.scalar import smax

__all__ = [
    "COEFFICIENTS",
    "LONGITUDINAL_COEFFICIENTS",
    "LATERAL_COEFFICIENTS",
    "SIGNALS",
    "AeroCondition",
    "CoefficientModel",
    "signal_value",
    "signal_values",
    "regressor_matrix",
    "split_derivative_name",
    "validate_derivative_names",
    "lift_drag_to_body",
    "body_to_lift_drag",
]

COEFFICIENTS: tuple[str, ...] = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
"""Coefficient names: lift, drag, side force, rolling, pitching, yawing moment."""
LONGITUDINAL_COEFFICIENTS: tuple[str, ...] = ("CL", "CD", "Cm")
"""Coefficients of the longitudinal motion (Ortiz & Gutierrez 2009, eq. 48)."""
LATERAL_COEFFICIENTS: tuple[str, ...] = ("CY", "Cl", "Cn")
"""Coefficients of the lateral-directional motion (Ortiz & Gutierrez 2009, eq. 43)."""

SIGNALS: dict[str, str] = {
    "0": "constant term",
    "alpha": "angle of attack [rad]",
    "alpha2": "angle of attack squared [rad^2]",
    "alphadot": "normalised angle-of-attack rate c*alpha_dot/(2 Va) [-]",
    "beta": "sideslip angle [rad]",
    "p": "normalised roll rate b*p/(2 Va) [-]",
    "q": "normalised pitch rate c*q/(2 Va) [-]",
    "r": "normalised yaw rate b*r/(2 Va) [-]",
    "elevator": "elevator deflection [rad]",
    "aileron": "aileron deflection [rad]",
    "rudder": "rudder deflection [rad]",
    "flap": "flap deflection [rad]",
    "Tc": "thrust coefficient T/(qbar S) [-]",
}
"""Regressor signals a derivative may multiply, with their meaning and unit."""

MIN_NORMALISING_AIRSPEED = 1e-3
"""Airspeed floor [m/s] used only to normalise rates, so a body at rest stays finite."""


class AeroCondition(NamedTuple):
    """Air data, rates and controls at which the coefficients are evaluated.

    Fields are scalars (any Drake scalar type) or equally shaped numpy arrays.
    """

    airspeed: Any
    """Airspeed Va [m/s]."""
    alpha: Any
    """Angle of attack [rad]."""
    beta: Any
    """Sideslip angle [rad]."""
    p: Any
    """Body roll rate [rad/s]."""
    q: Any
    """Body pitch rate [rad/s]."""
    r: Any
    """Body yaw rate [rad/s]."""
    elevator: Any = 0.0
    """Elevator deflection [rad]."""
    aileron: Any = 0.0
    """Aileron deflection [rad]."""
    rudder: Any = 0.0
    """Rudder deflection [rad]."""
    flap: Any = 0.0
    """Flap deflection [rad]."""
    alphadot: Any = 0.0
    """Angle-of-attack rate [rad/s]."""
    thrust_coefficient: Any = 0.0
    """Thrust coefficient T / (qbar S) [-]."""


def split_derivative_name(name: str) -> tuple[str, str]:
    """``"CL_alpha" -> ("CL", "alpha")``; raises ``ValueError`` for unknown names."""
    coefficient, sep, signal = name.partition("_")
    if not sep or coefficient not in COEFFICIENTS or signal not in SIGNALS:
        raise ValueError(
            f"unknown aerodynamic derivative name '{name}': expected '<coefficient>_<signal>' "
            f"with coefficient in {COEFFICIENTS} and signal in {tuple(SIGNALS)}"
        )
    return coefficient, signal


def validate_derivative_names(names: Iterable[str], owner: str = "derivatives") -> None:
    """Raises ``ValueError`` naming ``owner[name]`` for the first unknown derivative."""
    for name in names:
        try:
            split_derivative_name(name)
        except ValueError as err:
            raise ValueError(f"{owner}['{name}']: {err}") from None


def _normalising_speed(airspeed):
    if isinstance(airspeed, np.ndarray):
        return np.maximum(airspeed, MIN_NORMALISING_AIRSPEED)
    return smax(airspeed, MIN_NORMALISING_AIRSPEED)


def signal_values(cond: AeroCondition, b: float, c: float) -> dict:
    """All regressor signals (see the module table) at ``cond``, by name.

    ``b`` is the wingspan [m] and ``c`` the mean chord [m].
    """
    half_inverse_speed = 0.5 / _normalising_speed(cond.airspeed)
    alpha = cond.alpha
    return {
        "0": alpha * 0.0 + 1.0,
        "alpha": alpha,
        "alpha2": alpha * alpha,
        "alphadot": c * cond.alphadot * half_inverse_speed,
        "beta": cond.beta,
        "p": b * cond.p * half_inverse_speed,
        "q": c * cond.q * half_inverse_speed,
        "r": b * cond.r * half_inverse_speed,
        "elevator": cond.elevator,
        "aileron": cond.aileron,
        "rudder": cond.rudder,
        "flap": cond.flap,
        "Tc": cond.thrust_coefficient,
    }


def signal_value(signal: str, cond: AeroCondition, b: float, c: float):
    """Value of one regressor signal (see the module table) at ``cond``."""
    if signal not in SIGNALS:
        raise ValueError(f"unknown regressor signal '{signal}'")
    return signal_values(cond, b, c)[signal]


def regressor_matrix(names: Sequence[str], cond: AeroCondition, b: float, c: float) -> np.ndarray:
    """Regressor columns for the derivatives ``names`` (one column per name).

    With array fields in ``cond`` the result is ``(N, len(names))``; with
    scalar fields it is a row of length ``len(names)``.
    """
    signals = signal_values(cond, b, c)
    columns = [signals[split_derivative_name(n)[1]] for n in names]
    if isinstance(cond.alpha, np.ndarray):
        shape = np.shape(cond.alpha)
        return np.column_stack([np.broadcast_to(col, shape) for col in columns])
    return np.array(columns)


class CoefficientModel:
    """The six coefficients as named linear-in-parameter sums.

    Built once from a ``{name: value}`` mapping; evaluating it only loops over
    the terms that are present.
    """

    def __init__(self, derivatives: Mapping[str, float]):
        validate_derivative_names(derivatives)
        self.derivatives = dict(derivatives)
        terms: dict[str, list[tuple[str, float]]] = {k: [] for k in COEFFICIENTS}
        for name, value in self.derivatives.items():
            coefficient, signal = split_derivative_name(name)
            terms[coefficient].append((signal, value))
        self._terms = {k: tuple(v) for k, v in terms.items()}
        self.has_alphadot = any(
            signal == "alphadot" and value != 0.0
            for entries in self._terms.values()
            for signal, value in entries
        )

    def term_names(self, coefficient: str) -> list[str]:
        """Names of the derivatives that enter ``coefficient``."""
        return [f"{coefficient}_{signal}" for signal, _ in self._terms[coefficient]]

    def coefficient(self, coefficient: str, cond: AeroCondition, b: float, c: float):
        """One coefficient (``"CL"``, ...) at ``cond``."""
        signals = signal_values(cond, b, c)
        total = 0.0
        for signal, value in self._terms[coefficient]:
            total = total + value * signals[signal]
        return total

    def evaluate(self, cond: AeroCondition, b: float, c: float) -> tuple:
        """``(CL, CD, CY, Cl, Cm, Cn)`` at ``cond``; each signal is computed once."""
        signals = signal_values(cond, b, c)
        out = []
        for k in COEFFICIENTS:
            total = 0.0
            for signal, value in self._terms[k]:
                total = total + value * signals[signal]
            out.append(total)
        return tuple(out)

    def alphadot_sensitivity(self, coefficient: str, airspeed, c: float):
        """d(coefficient)/d(alpha_dot) [s/rad]: the alpha-dot term divided by alpha_dot."""
        total = 0.0
        for signal, value in self._terms[coefficient]:
            if signal == "alphadot":
                total = total + value * c / (2.0 * _normalising_speed(airspeed))
        return total


def lift_drag_to_body(CL, CD, alpha) -> tuple:
    """``(C_X, C_Z)`` from lift and drag coefficients (Vaiopoulos 2017, eq. A'.12-A'.14)."""
    ca, sa = (np.cos(alpha), np.sin(alpha)) if isinstance(alpha, np.ndarray) else (
        cos(alpha), sin(alpha))
    return -CD * ca + CL * sa, -CD * sa - CL * ca


def body_to_lift_drag(CX, CZ, alpha) -> tuple:
    """``(C_L, C_D)`` from body-axis force coefficients (Vaiopoulos 2017, eq. 3.25-3.26)."""
    ca, sa = (np.cos(alpha), np.sin(alpha)) if isinstance(alpha, np.ndarray) else (
        cos(alpha), sin(alpha))
    return -CZ * ca + CX * sa, -CX * ca - CZ * sa
