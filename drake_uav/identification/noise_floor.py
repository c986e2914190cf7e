"""The noise floor of a held-out equation error: the part the sensor noise alone explains.

A model that lacked nothing would still leave a held-out equation error: the measured
coefficient and its regressors are built from noisy sensors. With the model's parameters
``theta``, the noise moves the error of sample t by

    e_t = sum_s (dz_t/ds - dx_t/ds . theta) n_(s,t)

over independent noise sources s of variance ``var_s`` (first order), so its expected
square is ``sum_s var_s (dz_t/ds - dx_t/ds . theta)^2``. Two kinds of source enter:

* the noise the errors-in-variables fit carries
  (:class:`~drake_uav.identification.errors_in_variables.PropagatedNoise` of the held-out
  design, :mod:`~drake_uav.identification.regressor_noise`: air data, gyros and their
  derivatives through the regressors and the coefficient; the angular accelerations,
  the Savitzky-Golay derivative of the gyros, make the moments);
* the noise that enters the coefficient alone and so does not bias the fit: the
  accelerometers for the forces (Vaiopoulos 2017, eq. 5.41 is linear in the specific
  force).

The floor is the root of the mean of that square over the held-out samples. Every variance
is the one the isolation estimated from the data (or the specs the user declared): never
a simulator's truth. Errors add in square, so the share of the excess error an update
explains is ``(before^2 - after^2) / (before^2 - floor^2)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from drake_uav.identification.errors_in_variables import PropagatedNoise
from drake_uav.identification.isolation import AeroSamples
from drake_uav.identification.regressor_noise import (
    ISOLATION_WINDOW,
    observation_sensitivity,
    smoothing_gains,
    source_variances,
)
from drake_uav.model.isolation import force_coefficients
from drake_uav.vehicles.fixed_wing import FixedWingParams

if TYPE_CHECKING:
    from drake_uav.identification.discovery_result import DiscoveryResult

__all__ = ["NoiseFloor", "held_out_noise_floor", "noise_variance_per_sample",
           "smoothing_gains", "ISOLATION_WINDOW"]

_FORCES = ("CL", "CD", "CY")
_ACCELEROMETERS = ("ax", "ay", "az")


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


def held_out_noise_floor(samples: AeroSamples, discovery: DiscoveryResult,
                         params: FixedWingParams) -> dict[str, NoiseFloor]:
    """The noise floor of every coefficient's held-out error (module docstring).

    ``samples`` are those :func:`~drake_uav.identification.discovery.discover` ran on,
    ``params`` the aircraft (mass, inertia, geometry of the isolation).
    """
    out = {}
    for k, fit in discovery.final.items():
        test = samples.subset(slice(len(samples) - len(fit.holdout_residual), len(samples)))
        variance = noise_variance_per_sample(test, k, params, fit.holdout_noise,
                                             fit.result.estimate)
        parts = {s: float(np.mean(v)) for s, v in variance.items()}
        parts = {s: v for s, v in parts.items() if v > 0}
        floor = float(np.sqrt(sum(v for v in parts.values())))
        out[k] = NoiseFloor(k, discovery.baseline[k].rms_holdout, fit.rms_holdout, floor,
                            {s: float(np.sqrt(v)) for s, v in parts.items()})
    return out


def noise_variance_per_sample(samples: AeroSamples, coefficient: str, params: FixedWingParams,
                              noise: PropagatedNoise | None, theta: np.ndarray
                              ) -> dict[str, np.ndarray]:
    """Source -> (N,) variance of the equation error of the fit ``theta`` that the source's
    noise gives at each sample of ``samples`` (module docstring).

    ``noise`` is the noise the fit's design carries on ``samples`` (None: the coefficient's
    own, without regressors); the accelerometers' noise, which enters the force
    coefficients alone, is added.
    """
    if noise is None:
        noise = PropagatedNoise(len(theta), {}, observation_sensitivity(
            samples, coefficient, params), source_variances(samples, coefficient))
    out = {}
    for s in dict.fromkeys((*noise.regressors, *noise.observation)):
        if s not in noise.variance:
            continue
        J = noise.regressors.get(s)
        error = noise.observation.get(s, 0.0) - (0.0 if J is None else J @ theta)
        out[s] = noise.variance[s] * np.broadcast_to(error, samples.time.shape) ** 2
    if coefficient in _FORCES:
        for s, v in _accelerometer_terms(samples, coefficient, params).items():
            out.setdefault(s, v)
    return out


def _accelerometer_terms(test: AeroSamples, coefficient: str, params: FixedWingParams
                         ) -> dict[str, np.ndarray]:
    """Accelerometer -> (N,) variance its noise gives the force coefficient
    ``coefficient``: the coefficients are linear in the specific force (Vaiopoulos 2017,
    eq. 5.41), so a unit step gives their exact sensitivity."""
    index = _FORCES.index(coefficient)

    def value(specific_force):
        return force_coefficients(specific_force, test.thrust, test.dynamic_pressure,
                                  test.condition.alpha, params.mass, params.S)[index]

    out = {}
    for axis, name in enumerate(_ACCELEROMETERS):
        variance = test.noise_variance.get(name, 0.0)
        if variance <= 0.0:
            continue
        step = np.zeros(3)
        step[axis] = 1.0
        out[name] = variance * (value(test.specific_force + step)
                                - value(test.specific_force)) ** 2
    return out
