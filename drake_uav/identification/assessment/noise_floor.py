"""The noise floor of a held-out equation error: the part the sensor noise alone explains.

A model that lacked nothing would still leave a held-out equation error: the measured
coefficient and its regressors are built from noisy sensors. With the model's parameters
``theta``, the noise moves the error of sample t by

    e_t = sum_s (dz_t/ds - dx_t/ds . theta) n_(s,t)

over independent noise sources s of variance ``var_s`` (first order), so its expected
square is ``sum_s var_s (dz_t/ds - dx_t/ds . theta)^2``. Two kinds of source enter:

* the noise the errors-in-variables fit carries
  (:class:`~drake_uav.identification.statistics.errors_in_variables.PropagatedNoise` of the held-out
  design, :mod:`~drake_uav.identification.samples.regressor_noise`: air data, gyros and their
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

from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.regressor_noise import (
    ISOLATION_WINDOW,
    noise_variance_per_sample,
    smoothing_gains,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams

if TYPE_CHECKING:
    from drake_uav.identification.discovery.result import DiscoveryResult

__all__ = ["NoiseFloor", "held_out_noise_floor", "smoothing_gains", "ISOLATION_WINDOW"]



@dataclasses.dataclass(frozen=True)
class NoiseFloor:
    """Held-out equation-error RMS of one coefficient before and after, and its floor [-].

    Attributes
    ----------
    coefficient : str
        The coefficient.
    before : float
        Held-out RMS of the baseline fit.
    after : float
        Held-out RMS of the final fit.
    floor : float
        RMS the sensor noise alone gives the final fit's held-out error.
    parts : Mapping[str, float]
        Noise source -> its share of ``floor`` as an RMS (they add in square).
    """

    coefficient: str
    before: float
    after: float
    floor: float
    parts: Mapping[str, float]

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
        """JSON-ready summary: floor, its parts, the excess explained and after/floor.

        Returns
        -------
        dict
            Keys ``noise_floor``, ``noise_floor_parts``, ``excess_explained``,
            ``after_over_floor``.
        """
        return {"noise_floor": self.floor, "noise_floor_parts": dict(self.parts),
                "excess_explained": self.excess_explained,
                "after_over_floor": self.after_over_floor}


def held_out_noise_floor(samples: AeroSamples, discovery: DiscoveryResult,
                         params: FixedWingParams) -> dict[str, NoiseFloor]:
    """The noise floor of every coefficient's held-out error (module docstring).

    Parameters
    ----------
    samples : AeroSamples
        The samples :func:`~drake_uav.identification.discovery.loop.discover` ran on.
    discovery : DiscoveryResult
        Its result.
    params : FixedWingParams
        The aircraft (mass, inertia, geometry of the isolation).

    Returns
    -------
    dict of str to NoiseFloor
        Coefficient -> its floor.
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
