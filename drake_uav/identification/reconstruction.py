"""Output-error validation: reconstruct airspeed, alpha and beta with an identified model.

Seed S0 sec. 6.5.2 integrates the wind-axis force equations (eq. 6.4-6.6),
driven by the logged rates, attitude, thrust and surfaces, with the identified
coefficients, and corrects the integration periodically from GPS because the
gyros are noisy. Here the same dynamics are integrated in their body-axis form
(equal to eq. 6.4-6.6 for a constant wind, digest E.1 item 4)::

    d v_r / dt = (qbar S [C_X, C_Y, C_Z] + [T, 0, 0]) / m + g_body(phi, theta) - w x v_r

with (C_X, C_Z) from the identified (C_L, C_D) and the stability triplet from
:func:`air_data_from_velocity`. Every ``reset_interval`` seconds the state is
reset to the measured air data (the periodic correction; the seed does not give
its law or period). Baseline terms are evaluated at the reconstructed air data;
columns of added effects are evaluated on the logged signals, and effects of
kind ``"sensor"`` are left out (they describe the data, not the aircraft).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping

import numpy as np

from drake_uav.identification.isolation import AeroSamples
from drake_uav.systems.aerodynamics import (
    AeroCondition,
    air_data_from_velocity,
    lift_drag_to_body,
    signal_values,
    split_derivative_name,
    velocity_from_air_data,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["Reconstruction", "reconstruct"]


@dataclasses.dataclass(frozen=True)
class Reconstruction:
    """Measured and reconstructed air data and their mean absolute errors."""

    time: np.ndarray
    measured: np.ndarray
    """(N, 3) Va [m/s], alpha, beta [rad] from the log."""
    reconstructed: np.ndarray
    """(N, 3) the integrated model."""
    reset_interval: float
    """[s]."""

    @property
    def mae(self) -> np.ndarray:
        """Mean absolute error of Va [m/s], alpha [rad], beta [rad]."""
        return np.mean(np.abs(self.reconstructed - self.measured), axis=0)


def _split_terms(names, estimate, design, exclude_prefixes):
    """Baseline (signal, theta) terms and the exogenous sum of effect columns."""
    baseline = []
    exogenous = np.zeros(design.shape[0])
    for i, name in enumerate(names):
        if ":" in name:
            if not any(name.startswith(p + ":") for p in exclude_prefixes):
                exogenous += estimate[i] * design[:, i]
        else:
            baseline.append((split_derivative_name(name)[1], float(estimate[i])))
    return baseline, exogenous


def reconstruct(samples: AeroSamples, params: FixedWingParams,
                models: Mapping[str, tuple[tuple[str, ...], np.ndarray, np.ndarray]],
                exclude_prefixes: Collection[str] = (), reset_interval: float = 5.0
                ) -> Reconstruction:
    """Integrates the air-relative velocity with the identified force model.

    ``models`` maps ``"CL"``, ``"CD"``, ``"CY"`` to ``(names, estimate,
    design)``: the term names, their values and the (N, n) regressor matrix
    on ``samples`` (used for effect columns). ``samples.signals`` must hold
    ``roll`` and ``pitch`` [rad].
    """
    for key in ("roll", "pitch"):
        if key not in samples.signals:
            raise ValueError(f"reconstruct: samples.signals lacks '{key}'")
    if not reset_interval > 0:
        raise ValueError(f"reconstruct: reset_interval must be positive, got {reset_interval}")
    terms = {k: _split_terms(*models[k], exclude_prefixes) for k in ("CL", "CD", "CY")}
    c = samples.condition
    n = len(samples)
    t = samples.time
    measured = np.column_stack([c.airspeed, c.alpha, c.beta])
    rates = np.column_stack([c.p, c.q, c.r])
    controls = np.column_stack([c.elevator, c.aileron, c.rudder, c.flap])
    thrust = samples.thrust
    g = params.gravity
    roll, pitch = samples.signals["roll"], samples.signals["pitch"]
    gravity = np.column_stack([-g * np.sin(pitch), g * np.cos(pitch) * np.sin(roll),
                               g * np.cos(pitch) * np.cos(roll)])
    k_force = 0.5 * params.rho * params.S / params.mass

    def acceleration(i: int, v):
        Va, alpha, beta = air_data_from_velocity(*v)
        cond = AeroCondition(Va, alpha, beta, rates[i, 0], rates[i, 1], rates[i, 2],
                             controls[i, 0], controls[i, 1], controls[i, 2], controls[i, 3],
                             c.alphadot[i], thrust[i] / (0.5 * params.rho * Va * Va * params.S))
        signals = signal_values(cond, params.b, params.c)
        coef = {}
        for k, (baseline, exogenous) in terms.items():
            coef[k] = exogenous[i] + sum(theta * signals[s] for s, theta in baseline)
        CX, CZ = lift_drag_to_body(coef["CL"], coef["CD"], alpha)
        q = k_force * Va * Va
        p_, q_, r_ = rates[i]
        return np.array([
            q * CX + thrust[i] / params.mass + gravity[i, 0] - (q_ * v[2] - r_ * v[1]),
            q * coef["CY"] + gravity[i, 1] - (r_ * v[0] - p_ * v[2]),
            q * CZ + gravity[i, 2] - (p_ * v[1] - q_ * v[0]),
        ])

    out = np.empty((n, 3))
    next_reset = t[0]
    v = None
    for i in range(n):
        if t[i] >= next_reset - 1e-9:
            v = np.array(velocity_from_air_data(*measured[i]))
            next_reset += reset_interval
        out[i] = air_data_from_velocity(*v)
        if i + 1 < n:
            dt = t[i + 1] - t[i]
            k1 = acceleration(i, v)
            k2 = acceleration(i + 1, v + dt * k1)
            v = v + 0.5 * dt * (k1 + k2)
    return Reconstruction(time=t.copy(), measured=measured, reconstructed=out,
                          reset_interval=reset_interval)
