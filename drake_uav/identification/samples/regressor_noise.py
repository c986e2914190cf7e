"""The sensor noise in every regressor column and measured coefficient: its sources,
their variances per sample, and the perturbations that give each column's sensitivity.

The isolation (:func:`~drake_uav.identification.samples.isolation.isolate_coefficients`) builds
every signal of the regressions from a few noisy channels through one Savitzky-Golay
filter of window :data:`ISOLATION_WINDOW` (smoothing weights ``h``, derivative weights
``d``). White noise of raw variance ``v`` leaves ``v sum h^2`` in a smoothed signal and
``v sum d^2`` in its derivative (:func:`smoothing_gains`):

===================  ===============================================  ====================
source               what carries it                                   variance per sample
===================  ===============================================  ====================
``airspeed``,        smoothed air data: qbar, the normalised rates,    the isolation's
``alpha``, ``beta``  the thrust coefficient, every coefficient         (smoothed channel)
``p``, ``q``, ``r``  smoothed gyros: normalised rates ``b p / 2Va``,   the isolation's
                     rate products, the moments' gyroscopic terms
``alphadot``         derivative of the vane alpha (``c alpha_dot /    raw alpha ``sum d^2``
                     2Va``)
``p_dot`` ...        derivative of the gyros: the moments' angular     raw gyro ``sum d^2``
                     accelerations, the accelerometer lever arm
``logged:<channel>`` an extra channel of the log (a tension, a        the isolation's
                     voltage), smoothed like the regressors: the       (smoothed channel)
                     candidates built on it
``motor_speed``      a thrust from the logged shaft speed: the         the isolation's
                     thrust coefficient, C_L and C_D                   (smoothed channel)
===================  ===============================================  ====================

The derivative weights of a centred smoothing filter are antisymmetric and its
smoothing weights symmetric, so at one sample a channel's smoothed noise and the noise
of its derivative are uncorrelated: they are separate sources. The moments' interval
filter is the same derivative written on the sample increments, so the derivatives carry
the same noise for forces and moments. The controls are the logged commands (exact); the
thrust coefficient's noise is the airspeed's (the propulsion model's thrust at the
measured airspeed, over qbar), and the shaft speed's when the thrust comes from it.

A column's sensitivity to a source is the central difference of the column over a copy
of the samples with the source moved by :data:`STEPS` (:func:`perturbed`).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Mapping

import numpy as np

from drake_uav.identification.samples.aero_samples import (
    LOGGED,
    MOMENTS,
    SHAFT_SPEED,
    AeroSamples,
)
from drake_uav.identification.samples.isolation import isolate_coefficients
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
from drake_uav.model.isolation import differentiate, force_coefficients, moment_coefficients
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["ISOLATION_WINDOW", "STEPS", "LOGGED_STEP", "AIR_DATA_SOURCES", "DERIVATIVES",
           "smoothing_gains", "source_variances", "noise_sources", "source_step", "perturbed",
           "observation_sensitivity", "noise_variance_per_sample"]

_FORCES = ("CL", "CD", "CY")
_ACCELEROMETERS = ("ax", "ay", "az")

ISOLATION_WINDOW = inspect.signature(isolate_coefficients).parameters[
    "derivative_window"].default
"""Savitzky-Golay window [s] of the isolation (its default, which the main job uses)."""

STEPS = {"airspeed": 1e-3, "alpha": 1e-5, "beta": 1e-5, "alphadot": 1e-5,
         "p": 1e-5, "q": 1e-5, "r": 1e-5, "p_dot": 1e-4, "q_dot": 1e-4, "r_dot": 1e-4,
         SHAFT_SPEED: 1e-2}
"""Every noise source with its finite-difference step [m/s, rad, rad/s, rad/s^2]."""

LOGGED_STEP = 1e-4
"""Finite-difference step of a logged extra channel [its unit]: the candidates are linear
in it, so the central difference is exact but for rounding."""

AIR_DATA_SOURCES = ("airspeed", "alpha", "beta")
"""Sources nearly every column and coefficient depends on (through qbar and the axes)."""

DERIVATIVES = {"alphadot": "alpha", "p_dot": "p", "q_dot": "q", "r_dot": "r"}
"""Differentiated sources -> the channel they are the derivative of."""

_RATES = ("p", "q", "r")


@functools.lru_cache(maxsize=32)
def smoothing_gains(step: float, window: float = ISOLATION_WINDOW) -> tuple[float, float]:
    """Noise gains of the isolation's Savitzky-Golay smoothing ``h`` and derivative ``d``.

    White noise of variance ``v`` leaves ``v sum h^2`` in the smoothed signal and
    ``v sum d^2`` in its derivative.

    Parameters
    ----------
    step : float
        Sample step [s].
    window : float
        Filter length [s].

    Returns
    -------
    sum_h2 : float
        ``sum h^2`` [-].
    sum_d2 : float
        ``sum d^2`` [1/s^2].
    """
    half = int(round(window / step)) + 2
    time = np.arange(2 * half + 1) * step
    impulse = np.zeros(time.size)
    impulse[half] = 1.0
    return (float(np.sum(differentiate(time, impulse, window, deriv=0) ** 2)),
            float(np.sum(differentiate(time, impulse, window, deriv=1) ** 2)))


def source_variances(samples: AeroSamples, coefficient: str) -> dict[str, float]:
    """Noise variance per sample of every source as the signals of ``coefficient`` carry it.

    The smoothed channels' variances are those of the view the coefficient uses
    (:meth:`AeroSamples.aligned`: the moments' interval filter changes them); a
    derivative's is the raw channel's (the force view's over ``sum h^2``) times
    ``sum d^2``.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    coefficient : str
        The measured coefficient.

    Returns
    -------
    dict of str to float
        Source (module table) -> variance [unit^2]; sources without noise are left out.
    """
    view = samples.aligned(coefficient).noise_variance
    out = {s: float(view[s]) for s in (*AIR_DATA_SOURCES, *_RATES, SHAFT_SPEED) if s in view}
    out.update((s, float(v)) for s, v in view.items() if s.startswith(LOGGED))
    smooth, derivative = smoothing_gains(float(np.median(np.diff(samples.time))))
    for source, channel in DERIVATIVES.items():
        if channel in samples.noise_variance:
            out[source] = float(samples.noise_variance[channel]) / smooth * derivative
    return {s: v for s, v in out.items() if v > 0.0}


def noise_sources(variance: Mapping[str, float]) -> tuple[str, ...]:
    """The sources of ``variance`` in :data:`STEPS` order, the logged channels after.

    Parameters
    ----------
    variance : Mapping[str, float]
        Source -> noise variance.

    Returns
    -------
    tuple of str
        The source names.
    """
    return (*(s for s in STEPS if s in variance), *(s for s in variance if s not in STEPS))


def source_step(source: str) -> float:
    """Finite-difference step of a source: :data:`STEPS`, else :data:`LOGGED_STEP`.

    Parameters
    ----------
    source : str
        The source name.

    Returns
    -------
    float
        The step, in the source's unit.
    """
    return STEPS.get(source, LOGGED_STEP)


def perturbed(samples: AeroSamples, source: str, delta: float) -> AeroSamples:
    """A copy of ``samples`` (both views) with ``delta`` added to one source's signal.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    source : str
        An air-data source, a rate derivative, the shaft speed or a logged channel (module
        table).
    delta : float
        The step, in the source's unit.

    Returns
    -------
    AeroSamples
        The perturbed copy.
    """
    if source.startswith(LOGGED):
        return dataclasses.replace(
            samples.with_moments(lambda m: dataclasses.replace(
                m, logged={**m.logged, source: m.logged[source] + delta})),
            signals={**samples.signals, source: samples.signals[source] + delta})
    if source not in DERIVATIVES or source == "alphadot":
        return samples.perturbed(source, delta)
    axis = _RATES.index(source[0])

    def moved(rates):
        rates = rates.copy()
        rates[:, axis] += delta
        return rates

    return dataclasses.replace(
        samples.with_moments(lambda m: dataclasses.replace(
            m, rate_derivatives=moved(m.rate_derivatives))),
        rate_derivatives=moved(samples.rate_derivatives))


def observation_sensitivity(samples: AeroSamples, coefficient: str,
                            params: FixedWingParams) -> dict[str, np.ndarray]:
    """d(measured coefficient)/d(source) per sample.

    The air data's from :meth:`AeroSamples.observation_sensitivity`; a moment
    coefficient also moves with the gyros (the gyroscopic term ``w x J w``) and with the
    angular accelerations (Vaiopoulos 2017, eq. 5.41), by central differences of
    :func:`~drake_uav.model.isolation.moment_coefficients` (exact: it is quadratic in the
    rates and linear in their derivatives). The accelerometers enter the force
    coefficients alone and are not sources of the regressors.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    coefficient : str
        The measured coefficient.
    params : FixedWingParams
        The aircraft (inertia and reference lengths).

    Returns
    -------
    dict of str to numpy.ndarray
        Source -> (N,) sensitivity [1/unit].
    """
    view = samples.aligned(coefficient)
    out = view.observation_sensitivity(coefficient)
    if coefficient not in MOMENTS:
        return out
    index = MOMENTS.index(coefficient)
    rates = np.column_stack([view.condition.p, view.condition.q, view.condition.r])

    def value(w_dot, w):
        return moment_coefficients(w_dot, w, params.inertia, 0.0, view.dynamic_pressure,
                                   params.S, params.b, params.c)[index]

    for axis, name in enumerate(_RATES):
        step = np.zeros(3)
        step[axis] = STEPS[name]
        out[name] = (value(view.rate_derivatives, rates + step)
                     - value(view.rate_derivatives, rates - step)) / (2.0 * STEPS[name])
        step[axis] = 1.0
        out[f"{name}_dot"] = (value(view.rate_derivatives + step, rates)
                              - value(view.rate_derivatives, rates))
    return out


def noise_variance_per_sample(samples: AeroSamples, coefficient: str, params: FixedWingParams,
                              noise: PropagatedNoise | None, theta: np.ndarray
                              ) -> dict[str, np.ndarray]:
    """Source -> variance of the equation error of the fit ``theta`` that its noise gives.

    ``var_s (dz/ds - dx/ds . theta)^2`` at each sample, summed as
    :mod:`~drake_uav.identification.assessment.noise_floor` explains; the accelerometers'
    noise, which enters the force coefficients alone, is added.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    coefficient : str
        The measured coefficient.
    params : FixedWingParams
        The aircraft.
    noise : PropagatedNoise or None
        The noise the fit's design carries on ``samples`` (None: the coefficient's own,
        without regressors).
    theta : numpy.ndarray of shape (n,)
        The fit.

    Returns
    -------
    dict of str to numpy.ndarray
        Source -> (N,) variance [-].
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
