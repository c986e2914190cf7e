"""The noise floor of a held-out equation error: the part the sensor noise alone explains.

A model that lacked nothing would still leave a held-out equation error: the measured
coefficient and its regressors are built from noisy sensors. With the model's parameters
``theta``, the noise moves the error of sample t by

    e_t = sum_s (dz_t/ds - dx_t/ds . theta) n_(s,t)

over independent noise sources s of variance ``var_s`` (first order), so its expected
square is ``sum_s var_s (dz_t/ds - dx_t/ds . theta)^2``. Two kinds of source enter:

* the noise the errors-in-variables fit carries
  (:class:`~drake_uav.identification.errors_in_variables.PropagatedNoise` of the held-out
  design: air data through the regressors and the coefficient);
* the noise that enters the coefficient alone and so does not bias the fit: the
  accelerometers for the forces (Vaiopoulos 2017, eq. 5.41 is linear in the specific
  force) and the angular accelerations, the Savitzky-Golay derivative of the gyros, for
  the moments.

The floor is the root of the mean of that square over the held-out samples. Every variance
is the one the isolation estimated from the data (or the specs the user declared): never
a simulator's truth. Errors add in square, so the share of the excess error an update
explains is ``(before^2 - after^2) / (before^2 - floor^2)``.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Mapping

import numpy as np

from drake_uav.identification.discovery import CoefficientFit, DiscoveryResult
from drake_uav.identification.isolation import MOMENTS, AeroSamples, isolate_coefficients
from drake_uav.model.isolation import differentiate, force_coefficients, moment_coefficients
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["NoiseFloor", "held_out_noise_floor", "smoothing_gains", "ISOLATION_WINDOW"]

ISOLATION_WINDOW = inspect.signature(isolate_coefficients).parameters[
    "derivative_window"].default
"""Savitzky-Golay window [s] of the isolation (its default, which the main job uses)."""

_FORCES = ("CL", "CD", "CY")
_ACCELEROMETERS = ("ax", "ay", "az")
_GYROS = ("p", "q", "r")


@dataclasses.dataclass(frozen=True)
class NoiseFloor:
    """Held-out equation-error RMS of one coefficient before and after, and its floor [-]."""

    coefficient: str
    before: float
    """Held-out RMS of the baseline fit."""
    after: float
    """Held-out RMS of the final fit."""
    floor: float
    """RMS the sensor noise alone gives the final fit's held-out error."""
    parts: Mapping[str, float]
    """Noise source -> its share of ``floor`` as an RMS (they add in square)."""

    @property
    def excess_explained(self) -> float | None:
        """Share of the error above the floor that the update removed,
        ``(before^2 - after^2) / (before^2 - floor^2)``; None when ``before`` is at or
        below the floor (nothing above the noise to explain)."""
        excess = self.before**2 - self.floor**2
        if excess <= 0.0:
            return None
        return (self.before**2 - self.after**2) / excess

    @property
    def after_over_floor(self) -> float:
        """``after / floor``: 1 means the noise explains the whole held-out error."""
        return self.after / self.floor if self.floor > 0 else float("inf")

    def summary(self) -> dict:
        """JSON-ready: floor, its parts, the excess explained and after/floor."""
        return {"noise_floor": self.floor, "noise_floor_parts": dict(self.parts),
                "excess_explained": self.excess_explained,
                "after_over_floor": self.after_over_floor}


def smoothing_gains(step: float, window: float = ISOLATION_WINDOW) -> tuple[float, float]:
    """``(sum h^2, sum d^2 [1/s^2])`` of the isolation's Savitzky-Golay smoothing ``h`` and
    derivative ``d`` for a sample ``step`` [s]: white noise of variance ``v`` leaves
    ``v sum h^2`` in the smoothed signal and ``v sum d^2`` in its derivative."""
    half = int(round(window / step)) + 2
    time = np.arange(2 * half + 1) * step
    impulse = np.zeros(time.size)
    impulse[half] = 1.0
    return (float(np.sum(differentiate(time, impulse, window, deriv=0) ** 2)),
            float(np.sum(differentiate(time, impulse, window, deriv=1) ** 2)))


def held_out_noise_floor(samples: AeroSamples, discovery: DiscoveryResult,
                         params: FixedWingParams) -> dict[str, NoiseFloor]:
    """The noise floor of every coefficient's held-out error (module docstring).

    ``samples`` are those :func:`~drake_uav.identification.discovery.discover` ran on,
    ``params`` the aircraft (mass, inertia, geometry of the isolation).
    """
    out = {}
    for k, fit in discovery.final.items():
        test = samples.subset(slice(len(samples) - len(fit.holdout_residual), len(samples)))
        parts = {s: v for s, v in {**_propagated(fit),
                                   **_coefficient_only(test, k, params, fit)}.items() if v > 0}
        floor = float(np.sqrt(sum(v for v in parts.values())))
        out[k] = NoiseFloor(k, discovery.baseline[k].rms_holdout, fit.rms_holdout, floor,
                            {s: float(np.sqrt(v)) for s, v in parts.items()})
    return out


def _propagated(fit: CoefficientFit) -> dict[str, float]:
    """Source -> mean square error the fit's propagated noise gives (module docstring)."""
    noise = fit.holdout_noise
    if noise is None:
        return {}
    theta = fit.result.estimate
    return {s: float(noise.variance[s] * np.mean((noise.observation.get(s, 0.0) - J @ theta) ** 2))
            for s, J in noise.regressors.items()}


def _coefficient_only(test: AeroSamples, coefficient: str, params: FixedWingParams,
                      fit: CoefficientFit) -> dict[str, float]:
    """Source -> mean square error of the noise that enters the coefficient alone.

    The coefficients are linear in the specific force and in the angular accelerations,
    so a unit step gives their exact sensitivity. A source the fit's own noise model
    already carries is not counted twice.
    """
    carried = set() if fit.holdout_noise is None else set(fit.holdout_noise.observation)
    terms = _force_terms if coefficient in _FORCES else _moment_terms
    signal, variances, value = terms(test, coefficient, params)
    out = {}
    for axis, (name, variance) in enumerate(variances.items()):
        if name in carried or variance <= 0.0:
            continue
        step = np.zeros(3)
        step[axis] = 1.0
        sensitivity = value(signal + step) - value(signal)
        out[name] = float(variance * np.mean(sensitivity**2))
    return out


def _force_terms(test: AeroSamples, coefficient: str, params: FixedWingParams):
    """The specific force (N, 3) [m/s^2], its noise variances, and the force coefficient
    ``coefficient`` as a function of it (Vaiopoulos 2017, eq. 5.41)."""
    index = _FORCES.index(coefficient)

    def value(specific_force):
        return force_coefficients(specific_force, test.thrust, test.dynamic_pressure,
                                  test.condition.alpha, params.mass, params.S)[index]

    return (test.specific_force,
            {ch: test.noise_variance.get(ch, 0.0) for ch in _ACCELEROMETERS}, value)


def _moment_terms(test: AeroSamples, coefficient: str, params: FixedWingParams):
    """The angular accelerations (N, 3) [rad/s^2], their noise variances, and the moment
    coefficient ``coefficient`` as a function of them (Vaiopoulos 2017, eq. 5.41).

    The accelerations are the Savitzky-Golay derivative of the gyros: the force view's
    gyro variance is the raw one times ``sum h^2``, the derivative's the raw one times
    ``sum d^2`` (:func:`smoothing_gains`).
    """
    view, index = test.aligned(coefficient), MOMENTS.index(coefficient)
    rates = np.column_stack([view.condition.p, view.condition.q, view.condition.r])
    smooth, derivative = smoothing_gains(float(np.median(np.diff(test.time))))

    def value(rate_derivatives):
        return moment_coefficients(rate_derivatives, rates, params.inertia, 0.0,
                                   view.dynamic_pressure, params.S, params.b, params.c)[index]

    return (view.rate_derivatives,
            {f"{ch}_dot": test.noise_variance.get(ch, 0.0) / smooth * derivative
             for ch in _GYROS}, value)
