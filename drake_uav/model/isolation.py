"""Isolation formulas: the measured aerodynamic coefficients from flight signals.

Newton-Euler solved for the coefficients (Vaiopoulos 2017, eq. 5.41)::

    C_X = (m a_x - T) / (qbar S),  C_Y = m a_y / (qbar S),  C_Z = m a_z / (qbar S)
    (C_L, C_D) from (C_X, C_Z) by the wind-axis rotation (Vaiopoulos 2017, eq. 3.25-3.26)
    [C_l b, C_m c, C_n b] qbar S = J w_dot + w x J w - [tau_p, 0, 0]

:func:`force_coefficients` and :func:`moment_coefficients` are written once for every
scalar kind (float, ``AutoDiffXd``, ``symbolic.Expression``) and, elementwise, for
arrays of samples (vectors along the last axis). The batch isolation of a flight
(``drake_uav.identification.samples.isolation``) and the Monte-Carlo uncertainty of the
measured coefficients both call them.

:func:`lever_arm_specific_force` is what an accelerometer away from the centre of gravity
reads more than the specific force there: ``w_dot x r + w x (w x r)``.

:func:`differentiate` is the derivative of a sampled signal by a Savitzky-Golay
filter (the angular accelerations of the moment equations; Vaiopoulos 2017, sec. 5.5).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from drake_uav.model.coefficients import body_to_lift_drag

__all__ = ["differentiate", "force_coefficients", "moment_coefficients",
           "lever_arm_specific_force"]


def force_coefficients(specific_force, thrust, dynamic_pressure, alpha, mass, wing_area):
    """Measured ``(C_L, C_D, C_Y)`` [-] from the body specific force (Vaiopoulos 2017, eq. 5.41).

    ``specific_force`` [m/s^2] holds (a_x, a_y, a_z) along its last axis, ``thrust`` [N]
    acts along body x, ``dynamic_pressure`` qbar [Pa], ``alpha`` [rad], ``mass`` [kg],
    ``wing_area`` S [m^2]. The side force needs no rotation: C_Y is the body-axis one.
    """
    f = np.asarray(specific_force)
    q_bar_s = dynamic_pressure * wing_area
    cx = (mass * f[..., 0] - thrust) / q_bar_s
    cy = mass * f[..., 1] / q_bar_s
    cz = mass * f[..., 2] / q_bar_s
    lift, drag = body_to_lift_drag(cx, cz, alpha)
    return lift, drag, cy


def moment_coefficients(rate_derivatives, rates, inertia, propeller_torque, dynamic_pressure,
                        wing_area, span, chord):
    """Measured ``(C_l, C_m, C_n)`` [-] from the body rates (Vaiopoulos 2017, eq. 5.41).

    ``rate_derivatives`` w_dot [rad/s^2] and ``rates`` w [rad/s] hold (p, q, r) along
    their last axis; ``inertia`` J [kg m^2] (3, 3); ``propeller_torque`` tau_p [N m]
    about body x (the reaction of the propeller, not aerodynamic); ``dynamic_pressure``
    [Pa], ``wing_area`` [m^2], ``span`` b and ``chord`` c [m].
    """
    w_dot, w, J = np.asarray(rate_derivatives), np.asarray(rates), np.asarray(inertia)
    moment = w_dot @ J.T + np.cross(w, w @ J.T)
    q_bar_s = dynamic_pressure * wing_area
    return ((moment[..., 0] - propeller_torque) / (q_bar_s * span),
            moment[..., 1] / (q_bar_s * chord),
            moment[..., 2] / (q_bar_s * span))


def lever_arm_specific_force(rate_derivatives, rates):
    """Extra specific force [m/s^2] an accelerometer reads per metre of offset from the
    centre of gravity along each body axis: ``out[..., i, :] = w_dot x e_i + w x (w x
    e_i)`` for (p, q, r) ``rates`` [rad/s] and their ``rate_derivatives`` [rad/s^2] along
    the last axis, so that an offset ``r`` [m] reads ``r @ out`` more."""
    w_dot, w = np.asarray(rate_derivatives), np.asarray(rates)
    return np.stack([np.cross(w_dot, e) + np.cross(w, np.cross(w, e)) for e in np.eye(3)],
                    axis=-2)


def differentiate(time: np.ndarray, values: np.ndarray, window: float = 0.2,
                  polyorder: int = 3, deriv: int = 1) -> np.ndarray:
    """Time derivative of uniformly sampled ``values`` (along axis 0) by Savitzky-Golay.

    ``window`` is the filter length [s]; ``deriv=0`` gives the smoothed signal
    itself. Raises ``ValueError`` for non-uniform sampling or a window shorter
    than the polynomial needs.
    """
    time = np.asarray(time, dtype=float)
    dt = np.diff(time)
    if len(time) < 3 or np.any(dt <= 0):
        raise ValueError("differentiate: time must be strictly increasing with >= 3 samples")
    step = float(np.median(dt))
    if np.max(np.abs(dt - step)) > 1e-6 * max(step, 1e-12) + 1e-9:
        raise ValueError("differentiate: samples must be uniform in time (resample first)")
    length = int(round(window / step)) | 1
    if length <= polyorder:
        raise ValueError(
            f"differentiate: window {window} s holds {length} samples, needs > {polyorder}")
    length = min(length, len(time) - (1 - len(time) % 2))
    return savgol_filter(values, length, polyorder, deriv=deriv, delta=step, axis=0,
                         mode="interp")
