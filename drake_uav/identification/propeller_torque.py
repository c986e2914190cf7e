"""The propeller's torque coefficient C_Q(J) from a logged motor current and shaft speed.

An electric motor's shaft torque is ``KQ (i - i0)`` (torque constant KQ [N m/A], no-load
current i0 [A]). With the rotor's inertia neglected (its acceleration torque is small
against the propeller's at the few-hertz changes a flight makes), it balances the
propeller's ``Q = rho n^2 D^5 C_Q(J)`` (:mod:`drake_uav.model.propeller`), which is linear
in ``(C_Q0, C_Q1, C_Q2)``: ordinary least squares on the logged samples, the motor
constants the catalog's (:class:`~drake_uav.vehicles.fixed_wing.MotorPropeller`).

The current an ESC reports is its own input current, the battery's share; on a motor
driven at throttle ``dT`` the motor current is that divided by ``dT`` (the ESC's duty
cycle). Pass the motor current.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_uav.model.propeller import revolutions, torque_regressors
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["TorqueFit", "identify_torque_coefficients"]


@dataclasses.dataclass(frozen=True)
class TorqueFit:
    """C_Q(J) fitted from the motor current.

    Attributes
    ----------
    coefficients : numpy.ndarray
        ``(C_Q0, C_Q1, C_Q2)`` [-].
    sigma : numpy.ndarray
        Their standard deviations [-] (ordinary least squares, white residual).
    rms : float
        RMS residual of the torque [N m].
    """

    coefficients: np.ndarray
    sigma: np.ndarray
    rms: float

    def describe(self) -> str:
        """One line for the report.

        Returns
        -------
        str
            The coefficients with their standard errors and the torque residual RMS.
        """
        return ("propeller torque from the motor current: C_Q(J) = "
                + " ".join(f"{c:+.4g} ({s:.2g}){t}" for c, s, t in
                           zip(self.coefficients, self.sigma, ("", " J", " J^2"), strict=True))
                + f", torque residual RMS {self.rms:.3g} N m")


def identify_torque_coefficients(params: FixedWingParams, airspeed, motor_speed,
                                 motor_current) -> TorqueFit:
    """``(C_Q0, C_Q1, C_Q2)`` from the motor's torque ``KQ (i - i0)`` on logged samples.

    Parameters
    ----------
    params : FixedWingParams
        The aircraft; its propulsion must give ``diameter``, ``KQ`` and ``i0`` (a
        :class:`~drake_uav.vehicles.fixed_wing.MotorPropeller`).
    airspeed : array_like
        (N,) [m/s].
    motor_speed : array_like
        (N,) shaft speed [rad/s].
    motor_current : array_like
        (N,) motor current [A].

    Returns
    -------
    TorqueFit

    Raises
    ------
    ValueError
        For a propulsion model without motor constants, arrays of different or too short
        length, non-finite samples, or a shaft speed that hardly varies.
    """
    prop = params.propulsion
    missing = [name for name in ("diameter", "KQ", "i0") if not hasattr(prop, name)]
    if missing:
        raise ValueError(f"identify_torque_coefficients: params.propulsion "
                         f"({type(prop).__name__}) has no {', '.join(missing)}; C_Q from the "
                         "current needs the motor's torque constant and no-load current")
    airspeed, speed, current = (np.asarray(a, dtype=float).ravel()
                                for a in (airspeed, motor_speed, motor_current))
    if not len(airspeed) == len(speed) == len(current) or len(airspeed) < 10:
        raise ValueError("identify_torque_coefficients: airspeed, motor_speed and "
                         "motor_current need the same length, at least 10 samples")
    if not np.all(np.isfinite(np.concatenate([airspeed, speed, current]))):
        raise ValueError("identify_torque_coefficients: a sample is not finite")
    n_d = revolutions(speed) * prop.diameter
    design = np.column_stack(torque_regressors(params.rho, n_d, airspeed, prop.diameter))
    torque = prop.KQ * (current - prop.i0)
    scaled = design / np.linalg.norm(design, axis=0)
    singular = np.linalg.svd(scaled, compute_uv=False)
    if singular[-1] < 1e-6 * singular[0]:
        raise ValueError("identify_torque_coefficients: the shaft speed and airspeed vary too "
                         "little to separate C_Q0, C_Q1 and C_Q2")
    coefficients, *_ = np.linalg.lstsq(design, torque, rcond=None)
    residual = torque - design @ coefficients
    dof = max(len(torque) - 3, 1)
    covariance = np.linalg.inv(design.T @ design) * float(residual @ residual) / dof
    return TorqueFit(coefficients, np.sqrt(np.diag(covariance)),
                     float(np.sqrt(np.mean(residual**2))))
