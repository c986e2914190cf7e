"""Samples of several flight segments as one regression data set.

Each continuous airborne segment of a log is isolated on its own (smoothing and
differentiation never cross a logging gap or a take-off); the segments are then
joined in time order. The joined samples keep their absolute times, so a gap
between segments stays visible, and the held-out part of the discovery (the end
of the flight) falls in the last segment(s).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drake_uav.identification.samples.aero_samples import AeroSamples, MomentInputs
from drake_uav.model.coefficients import AeroCondition
from drake_uav.model.propeller import THROTTLE_TERMS

__all__ = ["concatenate_samples", "delayed", "span_starts"]


def span_starts(time: np.ndarray) -> np.ndarray:
    """Indices of the first sample of each span of joined samples.

    0, then every sample after a gap longer than 1.5 sampling periods.

    Parameters
    ----------
    time : numpy.ndarray of shape (N,)
        Sample times [s], increasing.

    Returns
    -------
    numpy.ndarray of int
        The start indices.
    """
    step = np.diff(time)
    return np.concatenate([[0], np.flatnonzero(step > 1.5 * np.median(step)) + 1])


def delayed(time: np.ndarray, values: np.ndarray, delay: float) -> np.ndarray:
    """``values`` at ``time - delay``, straight lines between samples.

    Within the first ``delay`` of each span of the samples (joined spans keep their gaps)
    the span's first value, since what came before is not in the log.

    Parameters
    ----------
    time : numpy.ndarray of shape (N,)
        Sample times [s].
    values : numpy.ndarray of shape (N,)
        The signal.
    delay : float
        The delay [s].

    Returns
    -------
    numpy.ndarray of shape (N,)
        The delayed signal.
    """
    starts = span_starts(time)
    span_start = time[starts][np.searchsorted(starts, np.arange(len(time)), side="right") - 1]
    return np.interp(np.maximum(time - delay, span_start), time, values)


def _joined(parts: Sequence, pick) -> np.ndarray:
    return np.concatenate([np.broadcast_to(pick(p), p.time.shape) for p in parts])


def concatenate_samples(parts: Sequence[AeroSamples]) -> AeroSamples:
    """One :class:`AeroSamples` of the segments ``parts``, in time order.

    Noise variances are the sample-weighted means of the segments' estimates.

    Parameters
    ----------
    parts : sequence of AeroSamples
        The segments' samples, in time order.

    Returns
    -------
    AeroSamples
        The joined samples (``parts[0]`` itself when there is one part).

    Raises
    ------
    ValueError
        When the parts overlap in time or differ in what they hold.
    """
    parts = sorted(parts, key=lambda p: p.time[0])
    if len(parts) == 1:
        return parts[0]
    for before, after in zip(parts, parts[1:], strict=False):
        if after.time[0] <= before.time[-1]:
            raise ValueError(f"segments overlap: one ends at {before.time[-1]:.3f} s, the "
                             f"next starts at {after.time[0]:.3f} s")
    first = parts[0]
    if any((p.moments is None) != (first.moments is None)
           or (p.thrust_airspeed_slope is None) != (first.thrust_airspeed_slope is None)
           or (p.thrust_speed_slope is None) != (first.thrust_speed_slope is None)
           or set(p.signals) != set(first.signals) for p in parts):
        raise ValueError("segments differ in their signals, thrust model or moment view")
    weights = np.array([len(p) for p in parts], float)
    noise = {name: float(np.average([p.noise_variance[name] for p in parts], weights=weights))
             for name in first.noise_variance}
    slope, speed_slope = (None if getattr(first, name) is None
                          else _joined(parts, lambda p, name=name: getattr(p, name))
                          for name in ("thrust_airspeed_slope", "thrust_speed_slope"))
    moments = None if first.moments is None else _joined_moments(parts, weights)
    return AeroSamples(
        time=_joined(parts, lambda p: p.time),
        condition=AeroCondition(*(_joined(parts, lambda p, i=i: p.condition[i])
                                  for i in range(len(first.condition)))),
        coefficients={k: _joined(parts, lambda p, k=k: p.coefficients[k])
                      for k in first.coefficients},
        dynamic_pressure=_joined(parts, lambda p: p.dynamic_pressure),
        throttle=_joined(parts, lambda p: p.throttle),
        thrust=_joined(parts, lambda p: p.thrust),
        rate_derivatives=np.concatenate([p.rate_derivatives for p in parts]),
        specific_force=np.concatenate([p.specific_force for p in parts]),
        signals={k: _joined(parts, lambda p, k=k: p.signals[k]) for k in first.signals},
        noise_variance=noise,
        thrust_airspeed_slope=slope,
        thrust_correction_terms=tuple(t for t in THROTTLE_TERMS if any(
            t in p.thrust_correction_terms for p in parts)),
        thrust_from_shaft_speed=all(p.thrust_from_shaft_speed for p in parts),
        thrust_speed_slope=speed_slope,
        reference_area=first.reference_area,
        moments=moments,
        signal_units=dict(first.signal_units),
    )


def _joined_moments(parts: Sequence[AeroSamples], weights: np.ndarray) -> MomentInputs:
    """The moments' inputs of the segments ``parts`` joined as :func:`concatenate_samples`
    joins the samples (noise variances weighted by ``weights``)."""
    first = parts[0].moments
    return MomentInputs(
        condition=AeroCondition(*(_joined(parts, lambda p, i=i: p.moments.condition[i])
                                  for i in range(len(first.condition)))),
        dynamic_pressure=_joined(parts, lambda p: p.moments.dynamic_pressure),
        throttle=_joined(parts, lambda p: p.moments.throttle),
        thrust=_joined(parts, lambda p: p.moments.thrust),
        thrust_airspeed_slope=(None if first.thrust_airspeed_slope is None
                               else _joined(parts, lambda p: p.moments.thrust_airspeed_slope)),
        thrust_speed_slope=(None if first.thrust_speed_slope is None
                            else _joined(parts, lambda p: p.moments.thrust_speed_slope)),
        rate_derivatives=np.concatenate([p.moments.rate_derivatives for p in parts]),
        logged={k: _joined(parts, lambda p, k=k: p.moments.logged[k]) for k in first.logged},
        noise_variance={name: float(np.average([p.moments.noise_variance[name] for p in parts],
                                               weights=weights))
                        for name in first.noise_variance})
