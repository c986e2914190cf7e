"""Fixed-pitch propeller thrust and torque from the advance ratio, scalar-generic.

A propeller turning at ``n`` revolutions per second in an axial flow ``Va`` [m/s] has the
advance ratio ``J = Va / (n D)`` and gives, in the classical non-dimensional form
(Brandt & Selig 2011; with McLain's quadratic fits of C_T and C_Q in J, used with the
simulator of Beard & McLain, 2nd ed.)::

    T = rho n^2 D^4 C_T(J),  Q = rho n^2 D^5 C_Q(J),  C(J) = c0 + c1 J + c2 J^2

Written out in ``n D`` [m/s] the polynomial becomes
``rho D^(p-2) (c0 (n D)^2 + c1 (n D) Va + c2 Va^2)`` (p = 4 for thrust, 5 for torque),
finite at ``n = 0`` and linear in the coefficients: :func:`thrust_regressors` are the three
columns that multiply ``(c0, c1, c2)``, what identification from a logged motor speed
regresses on. The pure ``Va^2`` column (``c2``) has the same shape as the drag of a
constant force coefficient, ``qbar S C_X0``: flight data cannot tell the two apart.

:func:`throttle_thrust_regressors` are the terms of a thrust correction in throttle and
airspeed for logs without a motor speed; they vanish at zero throttle, where a
propeller windmills and its thrust again scales with ``Va^2`` only.

Every function works for float, ``AutoDiffXd``, symbolic ``Expression`` and, elementwise,
numpy arrays.
"""

from __future__ import annotations

import math

__all__ = [
    "revolutions",
    "advance_ratio",
    "coefficient_polynomial",
    "propeller_thrust",
    "propeller_torque",
    "thrust_regressors",
    "torque_regressors",
    "thrust_regressor_airspeed_slopes",
    "throttle_thrust_regressors",
    "throttle_thrust_airspeed_slopes",
    "THROTTLE_TERMS",
]


def revolutions(shaft_speed):
    """Revolutions per second n [1/s] of a shaft speed Omega [rad/s]."""
    return shaft_speed / (2.0 * math.pi)


def advance_ratio(airspeed, shaft_speed, diameter: float):
    """Advance ratio ``J = Va / (n D)`` [-] of airspeed [m/s], shaft speed [rad/s] and
    propeller diameter [m] (undefined at zero shaft speed)."""
    return airspeed / (revolutions(shaft_speed) * diameter)


def coefficient_polynomial(advance_ratio, coefficients):
    """``C(J) = c0 + c1 J + c2 J^2`` [-]: C_T or C_Q at the advance ratio ``J`` of
    ``coefficients`` ``(c0, c1, c2)``."""
    c0, c1, c2 = coefficients
    return c0 + (c1 + c2 * advance_ratio) * advance_ratio


def _polynomial_force(rho: float, speed_diameter, airspeed, diameter: float, power: int,
                      coefficients):
    """``rho D^power (c0 (nD)^2 + c1 (nD) Va + c2 Va^2)``: ``rho n^2 D^(power+2) C(J)``."""
    c0, c1, c2 = coefficients
    return rho * diameter**power * (c0 * speed_diameter * speed_diameter
                                    + c1 * speed_diameter * airspeed
                                    + c2 * airspeed * airspeed)


def propeller_thrust(rho: float, speed_diameter, airspeed, diameter: float, coefficients):
    """Thrust ``T = rho n^2 D^4 C_T(J)`` [N].

    ``rho`` air density [kg/m^3], ``speed_diameter`` n D [m/s] (revolutions per second
    times the diameter), ``airspeed`` [m/s], ``diameter`` D [m], ``coefficients``
    ``(C_T0, C_T1, C_T2)`` of ``C_T(J) = C_T0 + C_T1 J + C_T2 J^2``.
    """
    return _polynomial_force(rho, speed_diameter, airspeed, diameter, 2, coefficients)


def propeller_torque(rho: float, speed_diameter, airspeed, diameter: float, coefficients):
    """Shaft torque ``Q = rho n^2 D^5 C_Q(J)`` [N m]; arguments as :func:`propeller_thrust`
    with ``coefficients`` ``(C_Q0, C_Q1, C_Q2)``."""
    return _polynomial_force(rho, speed_diameter, airspeed, diameter, 3, coefficients)


def thrust_regressors(rho: float, speed_diameter, airspeed, diameter: float) -> tuple:
    """The three columns [N] multiplying ``(C_T0, C_T1, C_T2)`` in :func:`propeller_thrust`:
    ``rho D^2 ((nD)^2, (nD) Va, Va^2)``."""
    scale = rho * diameter**2
    return (scale * speed_diameter * speed_diameter, scale * speed_diameter * airspeed,
            scale * airspeed * airspeed)


def torque_regressors(rho: float, speed_diameter, airspeed, diameter: float) -> tuple:
    """The three columns [N m] multiplying ``(C_Q0, C_Q1, C_Q2)`` in
    :func:`propeller_torque`: ``rho D^3 ((nD)^2, (nD) Va, Va^2)``."""
    return tuple(diameter * column
                 for column in thrust_regressors(rho, speed_diameter, airspeed, diameter))


def thrust_regressor_airspeed_slopes(rho: float, speed_diameter, airspeed,
                                     diameter: float) -> tuple:
    """d/dVa [N/(m/s)] of :func:`thrust_regressors` at a fixed (measured) shaft speed."""
    scale = rho * diameter**2
    return (0.0 * airspeed, scale * speed_diameter + 0.0 * airspeed, 2.0 * scale * airspeed)


THROTTLE_TERMS = ("throttle", "throttle2", "throttle_airspeed")
"""Names of :func:`throttle_thrust_regressors`, in order."""


def throttle_thrust_regressors(throttle, airspeed) -> tuple:
    """Thrust-correction terms of throttle dT [0..1] and airspeed [m/s]:
    ``(dT, dT^2, dT Va)`` (units 1, 1, m/s), each zero at zero throttle."""
    return (throttle, throttle * throttle, throttle * airspeed)


def throttle_thrust_airspeed_slopes(throttle, airspeed) -> tuple:
    """d/dVa of :func:`throttle_thrust_regressors`: ``(0, 0, dT)``."""
    zero = 0.0 * throttle * airspeed
    return (zero, zero, throttle + 0.0 * airspeed)
