"""The clock offset of a force channel logged by a separate logger.

A tension, a load cell or a tow force is often logged by a logger of its own (a load cell's
data logger, a winch controller), whose clock is not the autopilot's: written onto the
autopilot's time base, its channel lags (or leads) the force the aircraft felt by a
constant offset. A force proportional to the channel then fits the coefficients only when
the channel is read on the corrected clock.

The offset is estimated from the force coefficients' residual by a scan. For every trial
offset ``tau`` the channel read ``tau`` later, ``m(t + tau)``, times a direction that may
be any of the usual ones (the three body axes, and the three NED axes each times a
polynomial of degree :data:`DIRECTION_DEGREE` in time: a direction fixed in the body, or
one that turns slowly in the NED frame as towards a point seen from a flight path), is
fitted jointly to the residuals of the catalog models of ``C_L, C_D, C_Y`` (each
coefficient weighted by the inverse variance of its residual, its own columns eliminated:
Frisch-Waugh-Lovell). The profile of the weighted residual sum of squares over ``tau``
(steps of :data:`SCAN_STEP` within +-:data:`MAX_CLOCK_OFFSET`, then one sample about the
best, a parabola through its neighbours) gives the offset; its curvature gives the
standard error (the likelihood's, with the residuals' effective sample size), or, when
larger, the likelihood ratio against no offset does (the standard error whose Wald
statistic equals it: the profile is no parabola over a scan this wide). The offset is
significant at the compatibility check's level divided by the number of trial offsets
(Bonferroni over the scan). The channel
is *observable* when, at the best offset, its columns remove a significant share of the
residual: a partial F-test at :data:`OBSERVABLE_LEVEL`, Bonferroni over the scan's trial
offsets. A channel that moves no coefficient has no offset to estimate.

Only the training part is read (the discovery's held-out tail stays unseen).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from drake_uav.estimation.compatibility_result import SIGNIFICANCE, CalibrationEffect
from drake_uav.identification.discovery.coefficient_design import baseline_design
from drake_uav.identification.discovery.fitted_point import ned_to_body
from drake_uav.identification.discovery.result import EvidenceRule
from drake_uav.identification.discovery.vector_effects import force_coefficient_change
from drake_uav.identification.samples.aero_samples import ATTITUDE, LOGGED, AeroSamples
from drake_uav.identification.samples.segments import span_starts
from drake_uav.identification.statistics.residuals import effective_sample_size
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["MAX_CLOCK_OFFSET", "SCAN_STEP", "DIRECTION_DEGREE", "OBSERVABLE_LEVEL",
           "FORCE_UNITS", "ClockOffset", "force_channels", "estimate_clock_offset",
           "read_later", "correct_clock_offsets"]

MAX_CLOCK_OFFSET = 5.0
"""[s]: the offsets scanned, +-this (loggers started by hand, clocks set by hand)."""
SCAN_STEP = 0.1
"""[s]: step of the coarse scan (a fifth of the period of a 2 Hz force)."""
DIRECTION_DEGREE = 3
"""Degree of the time polynomials of the slowly turning NED direction."""
OBSERVABLE_LEVEL = 1e-3
"""Family-wise level of the test that the channel moves the force coefficients at all."""
FORCE_UNITS = ("N",)
"""Units of a logged channel that is a force magnitude."""
_FORCES = ("CL", "CD", "CY")


@dataclasses.dataclass(frozen=True)
class ClockOffset:
    """The offset of a logged force channel's clock, as the scan measured it.

    Attributes
    ----------
    channel : str
        The log channel.
    estimate : float
        [s] how much later the channel must be read: the channel lags the force the
        aircraft felt by this time (negative: it leads).
    sigma : float
        Standard error [s].
    dof : int
        Degrees of freedom of its t statistic (the effective sample size less the
        parameters).
    p_value : float
        Of the channel's force on the coefficients at the best offset (partial F-test,
        times the number of trial offsets).
    tolerance : float
        [s] one sample period: a smaller offset is within the grid's resolution.
    trials : int
        Trial offsets of the coarse scan: the offset's test is at the compatibility
        check's level over this many (Bonferroni).
    """

    channel: str
    estimate: float
    sigma: float
    dof: int
    p_value: float
    tolerance: float
    trials: int = 1

    @property
    def observable(self) -> bool:
        """The channel moves the force coefficients (:data:`OBSERVABLE_LEVEL`)."""
        return self.p_value < OBSERVABLE_LEVEL and math.isfinite(self.sigma)

    def calibration_effect(self) -> CalibrationEffect:
        """The offset as a calibration effect of the data-compatibility check.

        ``<channel>_clock_offset``, a time skew of the channel: corrected (the channel
        read that much later) when observable, significant and beyond one sample.

        Returns
        -------
        CalibrationEffect
            The effect.
        """
        note = "" if self.observable else (
            f"the channel moves no force coefficient (p = {min(self.p_value, 1.0):.2g}): "
            "no offset to estimate")
        return CalibrationEffect(
            f"{self.channel}_clock_offset", (self.channel,), self.estimate, self.sigma,
            self.dof, "s", 0.0, self.tolerance,
            "the logged force channel lags the force the aircraft felt by this time (a "
            "separate logger's clock)", observable=self.observable, note=note,
            significance=SIGNIFICANCE / self.trials)


def force_channels(samples: AeroSamples) -> list[str]:
    """The ``logged:<channel>`` signals of ``samples`` that are forces (:data:`FORCE_UNITS`).

    Parameters
    ----------
    samples : AeroSamples
        The samples.

    Returns
    -------
    list of str
        Their keys in ``samples.signals``.
    """
    return [k for k in samples.signals if k.startswith(LOGGED)
            and samples.signal_units.get(k) in FORCE_UNITS]


def read_later(samples: AeroSamples, key: str, offset: float) -> AeroSamples:
    """``samples`` with the signal ``key`` read ``offset`` [s] later, span by span.

    Linear between samples; the span's first or last value held beyond its ends.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    key : str
        A ``logged:<channel>`` signal.
    offset : float
        [s].

    Returns
    -------
    AeroSamples
        The samples with the signal shifted (the moments' copy too).
    """
    def shifted(time, values):
        out = np.empty_like(values)
        edges = [*span_starts(time), len(time)]
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            out[a:b] = np.interp(time[a:b] + offset, time[a:b], values[a:b])
        return out

    signals = {**samples.signals, key: shifted(samples.time, samples.signals[key])}
    out = dataclasses.replace(samples, signals=signals)
    if samples.moments is None or key not in samples.moments.logged:
        return out
    return out.with_moments(lambda m: dataclasses.replace(
        m, logged={**m.logged, key: shifted(samples.time, m.logged[key])}))


def _direction_bases(samples: AeroSamples) -> list[np.ndarray]:
    """(N, 3) body-axis unit vectors: the body axes, then the NED axes times the time
    polynomials."""
    n = len(samples)
    bases = [np.broadcast_to(e, (n, 3)) for e in np.eye(3)]
    if not all(s in samples.signals for s in ATTITUDE):
        return bases
    s = np.linspace(-1.0, 1.0, n)
    for axis in np.eye(3):
        along = ned_to_body(samples, np.broadcast_to(axis, (n, 3)))
        bases += [along * np.polynomial.legendre.Legendre.basis(d)(s)[:, None]
                  for d in range(DIRECTION_DEGREE + 1)]
    return bases


def estimate_clock_offset(samples: AeroSamples, params: FixedWingParams, key: str,
                          rule: EvidenceRule | None = None,
                          max_offset: float = MAX_CLOCK_OFFSET) -> ClockOffset:
    """The clock offset of the logged force channel ``key`` (module docstring).

    Parameters
    ----------
    samples : AeroSamples
        The samples the discovery will run on (the training part is read).
    params : FixedWingParams
        The aircraft (its catalog structure, wing area).
    key : str
        A ``logged:<channel>`` signal in N.
    rule : EvidenceRule, optional
        Its ``holdout_fraction`` says where the training part ends.
    max_offset : float
        [s] the scan's half range.

    Returns
    -------
    ClockOffset
        The offset and its standard error.

    Raises
    ------
    ValueError
        For a ``key`` the samples do not hold.
    """
    if key not in samples.signals:
        raise ValueError(f"clock offset: no logged channel {key!r} in the samples (have: "
                         f"{', '.join(k for k in samples.signals if k.startswith(LOGGED))})")
    rule = rule or EvidenceRule()
    train = samples.subset(slice(0, int(round(len(samples) * (1.0 - rule.holdout_fraction)))))
    period = float(np.median(np.diff(train.time)))
    max_offset = min(max_offset, 0.1 * (train.time[-1] - train.time[0]))
    residuals, eliminate, weights, own = {}, {}, {}, 0
    for k in _FORCES:
        design = baseline_design(train, params, k)
        q, _ = np.linalg.qr(design.X)
        r = design.z - q @ (q.T @ design.z)
        residuals[k], eliminate[k], weights[k] = r, q, 1.0 / float(np.mean(r**2))
        own += design.X.shape[1]
    bases = _direction_bases(train)
    total = sum(weights[k] * float(r @ r) for k, r in residuals.items())

    def profile(offset, effective=False):
        """(weighted SSE, reduction, effective sample size of the residuals with the
        channel, or None) with the channel read ``offset`` later."""
        shifted = read_later(train, key, offset)
        magnitude = shifted.signals[key][:, None]
        normal, moment, columns = 0.0, 0.0, {}
        for k, r in residuals.items():
            view = shifted.aligned(k)
            V = np.column_stack([force_coefficient_change(view, params, k, magnitude * b)
                                 for b in bases])
            V -= eliminate[k] @ (eliminate[k].T @ V)
            normal = normal + weights[k] * V.T @ V
            moment = moment + weights[k] * V.T @ r
            columns[k] = V
        phi = np.linalg.lstsq(normal, moment, rcond=None)[0]
        reduction = float(phi @ moment)
        n_eff = (sum(effective_sample_size(r - columns[k] @ phi) for k, r in residuals.items())
                 if effective else None)
        return total - reduction, reduction, n_eff

    coarse = np.arange(-max_offset, max_offset + 0.5 * SCAN_STEP, SCAN_STEP)
    sse = np.array([profile(t)[0] for t in coarse])
    best = float(coarse[np.argmin(sse)])
    fine = best + period * np.arange(-5, 6)
    fine_sse = np.array([profile(t)[0] for t in fine])
    i = int(np.clip(np.argmin(fine_sse), 1, len(fine) - 2))
    a, b, _ = np.polyfit(fine[i - 1:i + 2] - fine[i], fine_sse[i - 1:i + 2], 2)
    estimate = float(fine[i] - b / (2.0 * a)) if a > 0 else float(fine[i])
    estimate = float(np.clip(estimate, fine[i - 1], fine[i + 1]))
    sse_min, reduction, n_eff = profile(estimate, effective=True)
    rows = len(train) * len(_FORCES)
    q_count = len(bases)
    dof = max(int(n_eff) - own - q_count - 1, 1)
    information = n_eff / rows
    variance = sse_min / rows
    f_statistic = information * (reduction / q_count) / variance
    p_value = float(stats.f.sf(f_statistic, q_count, dof)) * len(coarse)
    # The profile's curvature over a few samples about the optimum; far from zero, where
    # the profile is no parabola, the standard error whose Wald statistic is the
    # likelihood ratio against no offset (never smaller).
    curve = np.polyfit(fine - estimate, fine_sse, 2)[0]
    sigma = (math.sqrt(2.0 * variance / (2.0 * curve) / information) if curve > 0
             else math.inf)
    ratio = information * (profile(0.0)[0] - sse_min) / variance
    if ratio > 0.0:
        sigma = max(sigma, abs(estimate) / math.sqrt(ratio))
    return ClockOffset(key.removeprefix(LOGGED), estimate, sigma, dof, p_value, period,
                       len(coarse))


def correct_clock_offsets(samples: AeroSamples, params: FixedWingParams,
                          rule: EvidenceRule | None = None
                          ) -> tuple[AeroSamples, tuple[CalibrationEffect, ...]]:
    """Every logged force channel's clock offset, and the samples on the corrected clocks.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    params : FixedWingParams
        The aircraft.
    rule : EvidenceRule, optional
        Where the training part ends.

    Returns
    -------
    tuple
        The samples with each channel whose offset is significant
        (:attr:`~drake_uav.estimation.compatibility_result.CalibrationEffect.applied`) read
        on the corrected clock, and one calibration effect per channel
        (:meth:`ClockOffset.calibration_effect`).
    """
    effects = []
    for key in force_channels(samples):
        effect = estimate_clock_offset(samples, params, key, rule).calibration_effect()
        if effect.applied:
            samples = read_later(samples, key, effect.estimate)
        effects.append(effect)
    return samples, tuple(effects)
