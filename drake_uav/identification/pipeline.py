"""The main job: flight log -> fitted model -> residual -> missing effect.

:func:`identify` runs the whole loop on a :class:`FlightLog` and returns an
:class:`IdentificationRun`; :func:`drake_uav.reporting.write_report` turns it
into a report folder.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Collection, Mapping, Sequence

import numpy as np

from drake_uav.estimation.channel_checks import (
    CheckedLog,
    ImplausibleChannelError,
    check_channels,
)
from drake_uav.estimation.compatibility import CompatibilityResult, check_compatibility
from drake_uav.estimation.compatibility_result import CalibrationEffect
from drake_uav.estimation.imu_position import (
    ImuPosition,
    accelerometers_at_cg,
    logged_imu_position,
)
from drake_uav.identification.assessment.families import EffectFamily, families
from drake_uav.identification.assessment.identifiability import derivative_warnings
from drake_uav.identification.assessment.logged_rates import LoggedRates, RateLimit, logged_rates
from drake_uav.identification.assessment.near_ties import NearTie, accepted_evidence, near_ties
from drake_uav.identification.assessment.noise_floor import NoiseFloor, held_out_noise_floor
from drake_uav.identification.assessment.rate_needs import (
    calibration_needs,
    derivative_needs,
    effect_needs,
    product_needs,
    without_unsupported,
)
from drake_uav.identification.assessment.reconstruction import Reconstruction, reconstruct
from drake_uav.identification.discovery.clock_offset import correct_clock_offsets, force_channels
from drake_uav.identification.discovery.coefficient_design import (
    IdentifiedDerivatives,
    baseline_names,
    fit_derivatives,
)
from drake_uav.identification.discovery.effects import Effect, effect_library
from drake_uav.identification.discovery.loop import check_coefficients, discover
from drake_uav.identification.discovery.plausibility import DerivativeWarning
from drake_uav.identification.discovery.result import (
    CoefficientFit,
    DiscoveryResult,
    EvidenceRule,
    Finding,
    FoundEffect,
)
from drake_uav.identification.discovery.vector_effects import VectorEffect, vector_effect_library
from drake_uav.identification.propulsion import declared_thrust, thrust_from_gridded_log
from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.air_data_source import (
    AIR_DATA_MODES,
    choose_air_data,
    flow_angles,
)
from drake_uav.identification.samples.flight_data import (
    gridded_log,
    isolated_samples,
    usable_extras,
)
from drake_uav.identification.samples.flight_phases import (
    DEFAULT_PHASES,
    PhaseSettings,
    usable_spans,
)
from drake_uav.identification.samples.isolation import monte_carlo_sigmas
from drake_uav.identification.samples.regressor_noise import smoothing_gains
from drake_uav.identification.samples.segments import concatenate_samples
from drake_uav.io.esc import with_motor_speed
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.propeller_table import PropellerTable
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.model.isolation import force_coefficients
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["IdentificationRun", "IdentifyOptions", "LogSelection", "identify",
           "identify_samples", "calibration_finding",
           "identify_derivatives", "select_samples", "check_fixed_wing",
           "testable_effects", "testable_vector_effects", "measured_command_delay",
           "ESTIMATE_CONFOUNDED",
           "coefficient_uncertainty", "check_log_compatibility", "check_log_channels"]

RECONSTRUCTED_OUTPUTS = ("airspeed", "alpha", "beta", "p", "q", "r")
"""Reconstructed outputs, in the order of :class:`Reconstruction` columns."""
RECONSTRUCTED_UNITS = ("m/s", "rad", "rad", "rad/s", "rad/s", "rad/s")
"""Units of :data:`RECONSTRUCTED_OUTPUTS`."""


@dataclasses.dataclass(frozen=True)
class IdentifyOptions:
    """The settings of the main job (:func:`identify`), checked when made.

    Every field has the default the ``drake-uav identify`` command uses; make one with the
    fields to change, or change an existing one with :meth:`replace`.

    Attributes
    ----------
    rate_hz : float
        Rate of the regression samples [Hz]; faster logs are block-averaged down to it.
    rule : EvidenceRule or None
        The evidence rule of the discovery (None:
        :class:`~drake_uav.identification.discovery.result.EvidenceRule` with its defaults).
    reset_interval : float
        [s] between the restarts of the output-error reconstruction from the measured
        state.
    source : str
        The log's name in the messages and the report.
    seed : int
        Seed of the Monte-Carlo uncertainty of the measured coefficients; everything else
        is deterministic.
    air_data : str
        Where the flow angles come from: one of
        :data:`~drake_uav.identification.samples.air_data_source.AIR_DATA_MODES` (``auto``,
        ``vanes``, ``estimate``, ``ahrs``).
    segment : (float, float) or None
        (start, end) [s] of the log to use (None: every airborne span).
    sensor_noise_std : Mapping[str, float] or None
        Declared sensor specs, log channel -> standard deviation [channel unit, SI]; the
        noise of the channels left out is read from the data.
    propulsion : str
        ``data``: the thrust identified with C_X where the flight allows it (else the
        catalog model, with a warning), from the propeller law C_T(J) when the shaft speed
        is logged (``motor_speed``, or the one ESC's ``esc_rpm_0``); ``catalog``: the
        aircraft's propulsion model.
    phases : PhaseSettings
        Thresholds of the airborne detection (airspeed [m/s], height [m], duration [s]).
    coefficients : tuple of str
        The coefficients fitted (names of
        :data:`~drake_uav.model.coefficients.COEFFICIENTS`).
    imu_position : (float, float, float) or None
        (x, y, z) [m, body axes FRD] of the IMU from the centre of gravity (None: the one
        the log's autopilot parameters record, else the centre of gravity).
    propeller : PropellerTable or None
        A declared propeller table (:func:`~drake_uav.io.propeller_table.read_propeller_table`):
        the thrust is ``rho n^2 D^4 C_T(J)`` from the logged shaft speed and the table,
        nothing of it fitted (needs ``propulsion="data"`` and a logged ``motor_speed`` or
        one ESC's ``esc_rpm_0``). None: identified from the data.

    Raises
    ------
    ValueError
        On construction, naming the field and what it accepts.

    Examples
    --------
    >>> options = IdentifyOptions(air_data="vanes", coefficients=("CL", "CD"))
    >>> options.replace(seed=3).seed
    3
    >>> IdentifyOptions(propulsion="measured")
    Traceback (most recent call last):
    ...
    ValueError: propulsion: 'catalog' or 'data', got 'measured'
    """

    rate_hz: float = 50.0
    rule: EvidenceRule | None = None
    reset_interval: float = 5.0
    source: str = "flight log"
    seed: int = 0
    air_data: str = "auto"
    segment: tuple[float, float] | None = None
    sensor_noise_std: Mapping[str, float] | None = None
    propulsion: str = "data"
    phases: PhaseSettings = DEFAULT_PHASES
    coefficients: tuple[str, ...] = COEFFICIENTS
    imu_position: tuple[float, float, float] | None = None
    propeller: PropellerTable | None = None

    def __post_init__(self):
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f"rate_hz: a positive rate [Hz], got {self.rate_hz!r}")
        if not (math.isfinite(self.reset_interval) and self.reset_interval > 0.0):
            raise ValueError(f"reset_interval: a positive time [s], got "
                             f"{self.reset_interval!r}")
        if self.air_data not in AIR_DATA_MODES:
            raise ValueError(f"air_data: unknown mode {self.air_data!r} (known: "
                             f"{', '.join(AIR_DATA_MODES)})")
        if self.propulsion not in ("catalog", "data"):
            raise ValueError(f"propulsion: 'catalog' or 'data', got {self.propulsion!r}")
        if self.propeller is not None and self.propulsion != "data":
            raise ValueError("propeller: a declared propeller table gives the thrust from the "
                             "logged shaft speed; it needs propulsion='data', not "
                             f"{self.propulsion!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer):
            raise ValueError(f"seed: an integer, got {self.seed!r}")
        check_coefficients(self.coefficients)
        object.__setattr__(self, "coefficients", tuple(self.coefficients))
        for channel, std in (self.sensor_noise_std or {}).items():
            if not (math.isfinite(std) and std >= 0.0):
                raise ValueError(f"sensor_noise_std: {channel}: a standard deviation >= 0 "
                                 f"in the channel's unit, got {std!r}")
        if self.imu_position is not None:
            object.__setattr__(self, "imu_position",
                               ImuPosition.given(self.imu_position).position)

    def replace(self, **changes) -> IdentifyOptions:
        """A copy with ``changes``, checked again.

        Parameters
        ----------
        **changes
            Field -> new value.

        Returns
        -------
        IdentifyOptions
            The copy.

        Raises
        ------
        ValueError
            For an unknown field or a value it does not accept.
        """
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            raise ValueError(f"unknown option {', '.join(unknown)} (known: "
                             f"{', '.join(f.name for f in dataclasses.fields(self))})")
        return dataclasses.replace(self, **changes)


def _options(options: IdentifyOptions | None, changes: dict) -> IdentifyOptions:
    """``options`` (None: the defaults) with the keyword ``changes`` of a call."""
    options = options or IdentifyOptions()
    return options.replace(**changes) if changes else options


@dataclasses.dataclass(frozen=True)
class LogSelection:
    """The parts of a log the main job used, and how it read their air data.

    Attributes
    ----------
    spans : tuple of (float, float)
        Airborne fixed-wing spans (start, end) [s] (:func:`usable_spans`).
    air_data : str
        "vanes", "estimate" or "ahrs"
        (:mod:`~drake_uav.identification.samples.air_data_source`).
    air_data_description : str
        One line on where the flow angles came from.
    notes : tuple of str
        What the job chose (spans left out, extra channels).
    warnings : tuple of str
        What the job did to the data that changes what the result means: glitches drawn
        over (:func:`check_log_channels`), an estimate it could not use (a wind the flight
        does not observe).
    """

    spans: tuple[tuple[float, float], ...]
    air_data: str
    air_data_description: str
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def summary(self) -> dict:
        """JSON-ready summary: spans, air data, notes and warnings.

        Returns
        -------
        dict
            Keys ``spans_s``, ``air_data``, ``air_data_description``, ``notes``, ``warnings``.
        """
        return {"spans_s": [list(s) for s in self.spans], "air_data": self.air_data,
                "air_data_description": self.air_data_description, "notes": list(self.notes),
                "warnings": list(self.warnings)}


@dataclasses.dataclass(frozen=True)
class IdentificationRun:
    """Result of the main job on one flight log: everything its report prints.

    Attributes
    ----------
    params : FixedWingParams
        The aircraft's catalog model.
    samples : AeroSamples
        The measured coefficients and their regressors.
    discovery : DiscoveryResult
        The search for missing effects.
    reconstruction_before : Reconstruction
        Output-error reconstruction with the baseline model.
    reconstruction_after : Reconstruction
        The same with the effects found.
    source : str
        The log's name.
    coefficient_sigma : dict of str to float
        Monte-Carlo standard deviation of the measured C_L, C_D, C_Y (Vaiopoulos 2017,
        sec. 5.6).
    data : LogSelection or None
        What the job used of the log: spans, air data, notes (None: samples given
        directly).
    compatibility : CompatibilityResult or None
        The data-compatibility check of the airborne spans (docs/compatibility.md), whose
        significant calibration errors were removed before the isolation (None: samples
        given directly, or nothing to check).
    logged_rates : LoggedRates or None
        The log's native rates against the analysis grid (None: samples given directly).
    rate_limits : tuple of RateLimit
        The terms the log cannot support at its native rates, with the rates they need
        (:mod:`~drake_uav.identification.assessment.logged_rates`): the effects among them
        were not tested, the calibration errors not claimed.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> run = identify(log, aerosonde(), segment=(0.0, 30.0), propulsion="catalog")
    >>> run.findings, run.discovery.message
    (('thrust_propwash',), 'missing effect(s) found: thrust_propwash (CD)')
    >>> run.data.spans, run.data.air_data
    (((0.0, 29.0),), 'vanes')
    >>> "findings" in run.summary()                      # what summary.json holds
    True
    """

    params: FixedWingParams
    samples: AeroSamples
    discovery: DiscoveryResult
    reconstruction_before: Reconstruction
    reconstruction_after: Reconstruction
    source: str
    coefficient_sigma: dict
    data: LogSelection | None = None
    compatibility: CompatibilityResult | None = None
    logged_rates: LoggedRates | None = None
    rate_limits: tuple[RateLimit, ...] = ()

    @functools.cached_property
    def noise_floors(self) -> dict[str, NoiseFloor]:
        """Coefficient -> its held-out equation error before and after and the floor the
        sensor noise alone gives it (:func:`~drake_uav.identification.assessment.
        noise_floor.held_out_noise_floor`)."""
        return held_out_noise_floor(self.samples, self.discovery, self.params)

    @functools.cached_property
    def derivative_warnings(self) -> tuple[DerivativeWarning, ...]:
        """Implausible catalog values, then implausible, correlated and unexcited identified
        derivatives (:func:`~drake_uav.identification.assessment.identifiability.
        derivative_warnings`)."""
        return tuple(derivative_warnings(self.params.derivatives, self.discovery.final))

    @property
    def smoothing_correlation_time(self) -> float:
        """[s] the correlation time the isolation's smoothing gives white sensor noise: the
        sample step over the smoothing's noise gain
        (:func:`~drake_uav.identification.samples.regressor_noise.smoothing_gains`)."""
        step = float(np.median(np.diff(self.samples.time)))
        return step / smoothing_gains(step)[0]

    @functools.cached_property
    def near_ties(self) -> tuple[NearTie, ...]:
        """The accepted effects another candidate explains almost as well
        (:func:`~drake_uav.identification.assessment.near_ties.near_ties`)."""
        return tuple(near_ties(self.discovery))

    @functools.cached_property
    def families(self) -> tuple[EffectFamily, ...]:
        """Each accepted effect this flight cannot tell apart from others, with its aliases
        and near ties (:func:`~drake_uav.identification.assessment.families.families`)."""
        return tuple(families(self.discovery))

    @property
    def notes(self) -> tuple[str, ...]:
        """What the job did with the log that the user should know (one line each)."""
        return () if self.data is None else self.data.notes

    @property
    def warnings(self) -> tuple[str, ...]:
        """The data warnings that change what the result means (:attr:`LogSelection.
        warnings`), one line each."""
        return () if self.data is None else self.data.warnings

    @property
    def found(self) -> tuple[Finding, ...]:
        """Everything the job found the model or the data lacked: the calibration errors
        the data-compatibility check corrected (``air_data_time_skew``, ...,
        :func:`calibration_finding`), then the effects the discovery loop found."""
        corrected = () if self.compatibility is None else tuple(
            calibration_finding(e) for e in self.compatibility.applied)
        return corrected + tuple(self.discovery.found)

    @property
    def findings(self) -> tuple[str, ...]:
        """The names of :attr:`found`."""
        return tuple(f.name for f in self.found)

    def summary(self) -> dict:
        """JSON-ready summary: exactly what the report's ``summary.json`` holds (the report
        adds only ``complete``, ``report_title`` and ``report_files``).

        Returns
        -------
        dict
            Run-level keys: ``source, aircraft, data`` (spans, air data, notes),
            ``message, findings`` (:attr:`findings`), ``samples, holdout_start_s,
            effects, equation_error_rms_holdout`` (each coefficient's error before and
            after, its ``adequacy``, :class:`~drake_uav.identification.discovery.adequacy.
            Adequacy`, and its noise floor, :attr:`noise_floors`),
            ``reconstruction_mae_holdout, reconstruction_divergences,
            measured_coefficient_sigma_monte_carlo, parameters`` (with each one's catalog
            value; a baseline term the flight does not support as 0, ``dropped``: true; a
            derivative the log's rates cannot support at its catalog value, ``fixed``: true,
            ``sigma``: null),
            ``dropped_terms`` (per coefficient, the figures that dropped each,
            :class:`~drake_uav.identification.discovery.parsimony.DroppedTerm`),
            ``warnings`` (:attr:`derivative_warnings`), ``near_ties`` (:attr:`near_ties`),
            ``families`` (:attr:`families`),
            ``rounds`` (every candidate's evidence, ``accepted`` or not),
            ``not_identifiable_at_logged_rates`` (:attr:`rate_limits`) and, when the
            data-compatibility check ran, ``compatibility``. Each entry of ``effects`` has
            ``name, kind, explanation, coefficients, evidence, parameters``.
        """
        d = self.discovery
        rms = {k: {"before": b, "after": a, "change": (a - b) / b if b else 0.0,
                   **({"adequacy": d.adequacy[k].summary()} if k in d.adequacy else {}),
                   **self.noise_floors[k].summary()}
               for k, (b, a) in d.rms_change().items()}
        mae_b, mae_a = self.reconstruction_before.mae, self.reconstruction_after.mae
        catalog = self.params.derivatives
        accepted = accepted_evidence(d)
        summary = {
            "source": self.source,
            "aircraft": self.params.name,
            "data": None if self.data is None else self.data.summary(),
            "not_identifiable_at_logged_rates": [r.summary() for r in self.rate_limits],
            "message": d.message,
            "findings": list(self.findings),
            "samples": len(self.samples),
            "holdout_start_s": d.holdout_start,
            "effects": [_effect_summary(f) for f in d.found],
            "equation_error_rms_holdout": rms,
            "reconstruction_mae_holdout": {
                name: {"before": float(b), "after": float(a), "unit": unit}
                for name, unit, b, a in zip(RECONSTRUCTED_OUTPUTS, RECONSTRUCTED_UNITS,
                                            mae_b, mae_a, strict=True)
            },
            "reconstruction_divergences": {"before": self.reconstruction_before.divergences,
                                           "after": self.reconstruction_after.divergences},
            "measured_coefficient_sigma_monte_carlo": self.coefficient_sigma,
            "parameters": {
                k: {n: {"estimate": float(fit.result.estimate[i]),
                        "sigma": float(fit.result.sigma[i]),
                        "significant": bool(fit.result.significant[i]),
                        "catalog": catalog.get(n)}
                    for i, n in enumerate(fit.names)}
                | {t.term: {"estimate": 0.0, "sigma": 0.0, "significant": False, "dropped": True,
                            "catalog": catalog.get(t.term)}
                   for t in d.dropped.get(k, ())}
                | {n: {"estimate": v, "sigma": None, "significant": False, "fixed": True,
                       "catalog": catalog.get(n)}
                   for n, v in d.fixed.get(k, {}).items()}
                for k, fit in d.final.items()
            },
            "dropped_terms": {k: [dataclasses.asdict(t) for t in terms]
                              for k, terms in d.dropped.items()},
            "warnings": [dataclasses.asdict(w) for w in self.derivative_warnings],
            "near_ties": [t.summary() for t in self.near_ties],
            "families": [f.summary() for f in self.families],
            "rounds": [[{**dataclasses.asdict(e), "accepted": e in accepted} for e in r]
                       for r in d.rounds],
        }
        if self.compatibility is not None:
            summary["compatibility"] = self.compatibility.summary()
        return summary


def calibration_finding(error: CalibrationEffect) -> Finding:
    """A calibration error of the data-compatibility check as a finding of the job.

    Parameters
    ----------
    error : CalibrationEffect
        The error the check estimated (and removed).

    Returns
    -------
    Finding
        Kind ``"calibration"``, no coefficient, its estimate and standard error as the
        parameter ``"<name> [<unit>]"``.
    """
    return Finding(error.name, error.explanation, "calibration", (), (),
                   {f"{error.name} [{error.unit}]": (error.estimate, error.sigma)})


def _effect_summary(found: FoundEffect) -> dict:
    """JSON-ready entry of one found effect: what it is, its evidence and parameters."""
    return {"name": found.name, "kind": found.kind, "explanation": found.explanation,
            "coefficients": list(found.coefficients),
            "evidence": [dataclasses.asdict(e) for e in found.evidence],
            "parameters": {k: {"estimate": v[0], "sigma": v[1]}
                           for k, v in found.parameters.items()}}


def _reconstruct(samples: AeroSamples, params, discovery: DiscoveryResult, fits,
                 reset_interval: float) -> Reconstruction:
    """Reconstruction on the held-out tail; a coefficient without a fit (not asked for, or
    constant in the log) keeps the aircraft's own derivatives."""
    start = int(np.searchsorted(samples.time, discovery.holdout_start))
    test = samples.subset(slice(start, len(samples)))
    sensor_effects = [f.name for f in discovery.found if f.kind == "sensor"]
    models = {k: _with_fixed_terms(fits[k], discovery.fixed.get(k, {})) for k in fits}
    for k in COEFFICIENTS:
        if k not in models:
            names = tuple(baseline_names(params, k))
            models[k] = (names, np.array([params.derivatives.get(n, 0.0) for n in names]),
                         np.zeros((len(test), len(names))))
    return reconstruct(test, params, models, exclude_prefixes=sensor_effects,
                       reset_interval=reset_interval)


def _with_fixed_terms(fit: CoefficientFit, fixed: Mapping[str, float]):
    """``(names, values, held-out design)`` of a fit with its fixed catalog terms added
    (their columns are recomputed by the reconstruction: zeros here)."""
    design = fit.holdout_design
    return ((*fit.names, *fixed), np.concatenate([fit.result.estimate, list(fixed.values())]),
            np.hstack([design, np.zeros((len(design), len(fixed)))]))


def coefficient_uncertainty(samples: AeroSamples, params: FixedWingParams, seed: int = 0,
                            draws: int = 200_000) -> dict[str, float]:
    """Monte-Carlo error std of the measured force coefficients (Vaiopoulos 2017, sec. 5.6).

    Inputs (airspeed, alpha, specific force) vary over their flight ranges with their
    observed correlation; their errors are the noise the isolation estimated
    (:func:`~drake_uav.identification.samples.isolation.monte_carlo_sigmas`).

    Parameters
    ----------
    samples : AeroSamples
        The measured coefficients and their noise variances.
    params : FixedWingParams
        The aircraft (mass, wing area).
    seed : int
        Seed of the draws.
    draws : int
        Number of draws.

    Returns
    -------
    dict of str to float
        ``CL``, ``CD``, ``CY`` -> normal-equivalent standard deviation [-].

    Examples
    --------
    >>> from drake_uav.identification import samples_from_log
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde())
    >>> sigma = coefficient_uncertainty(samples, aerosonde(), draws=20_000)
    >>> sorted(sigma), bool(sigma["CL"] < 0.01)
    (['CD', 'CL', 'CY'], True)
    """
    c = samples.condition
    inputs = np.column_stack([c.airspeed, c.alpha, *samples.specific_force.T])
    names = ("airspeed", "alpha", "ax", "ay", "az")
    error_std = np.sqrt([samples.noise_variance.get(n, 0.0) for n in names])
    ranges = np.column_stack([inputs.min(axis=0), inputs.max(axis=0)])
    correlation = np.corrcoef(inputs.T)
    thrust = float(np.mean(samples.thrust))

    def coefficients(va, alpha, ax, ay, az):
        lift, drag, side = force_coefficients(np.stack([ax, ay, az], axis=-1), thrust,
                                              dynamic_pressure(va, params.rho), alpha,
                                              params.mass, params.S)
        return {"CL": lift, "CD": drag, "CY": side}

    return monte_carlo_sigmas(coefficients, ranges, error_std, correlation=correlation,
                              samples=draws, seed=seed)


def identify_derivatives(log: FlightLog, params: FixedWingParams, *,
                         rate_hz: float = 50.0) -> IdentifiedDerivatives:
    """The aircraft model's derivatives identified from ``log``, with their uncertainty.

    The first steps of :func:`identify` without the search for missing effects: the
    log is isolated into coefficients (:func:`select_samples`) and each coefficient
    is fitted on the aircraft's own derivative names over the whole flight
    (:func:`~drake_uav.identification.discovery.coefficient_design.fit_derivatives`).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    params : FixedWingParams
        The aircraft's catalog model (its derivative names).
    rate_hz : float
        Rate of the samples [Hz].

    Returns
    -------
    IdentifiedDerivatives
        The fits, their estimates and joint covariance.

    Raises
    ------
    FlightLogError
        Naming the problem when the log cannot be used.

    Examples
    --------
    >>> import warnings
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> with warnings.catch_warnings(record=True):   # the thrust: the catalog model kept
    ...     derivatives = identify_derivatives(log.slice(0.0, 15.0), aerosonde(), rate_hz=20.0)
    >>> derivatives.names[:2], derivatives["CL"].method
    (('CL_0', 'CL_alpha'), 'BCLS')
    """
    return fit_derivatives(select_samples(log, params, rate_hz=rate_hz)[0], params)


def identify(log: FlightLog, params: FixedWingParams, options: IdentifyOptions | None = None,
             *, progress: Callable[[str], None] | None = None,
             **changes) -> IdentificationRun:
    """Runs the main job on ``log`` for the aircraft ``params``.

    The names below are the fields of ``options`` (:class:`IdentifyOptions`). Only what a
    real log holds is read: the airborne fixed-wing spans
    (:func:`~drake_uav.identification.samples.flight_phases.usable_spans`, within
    ``segment`` [s] when given) are isolated one by one and joined; ``air_data``
    picks the flow angles (:mod:`~drake_uav.identification.samples.air_data_source`);
    ``sensor_noise_std`` (channel -> std, SI) are declared sensor specs, else the
    noise comes from the data; ``propulsion`` "data" identifies the thrust with C_X
    where the flight allows it (else the catalog model, with a warning), "catalog"
    keeps the aircraft's propulsion model. ``seed`` drives the Monte-Carlo uncertainty of the
    measured coefficients; everything else is deterministic. ``coefficients`` are the ones
    fitted (names of :data:`~drake_uav.model.coefficients.COEFFICIENTS`); one that does
    not vary in the log is skipped with a note (:attr:`IdentificationRun.notes`). Before
    the isolation, the data-compatibility check of the airborne spans
    (:func:`check_log_compatibility`) removes the significant sensor biases, scale
    factors and time skews it finds (:attr:`IdentificationRun.compatibility`). Before
    both, the accelerometers are moved to the centre of gravity from the IMU position
    (:mod:`~drake_uav.estimation.imu_position`): ``imu_position`` (x, y, z) [m, body axes
    FRD] when given, else the one the log's autopilot parameters record (ArduPilot
    ``INS_POS<n>_*``, PX4 ``EKF2_IMU_POS_*``), with a note. First of all, every channel
    is checked against its physical range and the airspeed against the GPS ground speed
    (:func:`check_log_channels`): glitches are drawn over with a warning
    (:attr:`IdentificationRun.warnings`), a channel that is physically impossible stops
    the job.

    Parameters
    ----------
    log : FlightLog
        The flight log (:func:`~drake_uav.io.readers.read_log`).
    params : FixedWingParams
        The aircraft's catalog model.
    options : IdentifyOptions, optional
        The job's settings (None: the defaults).
    progress : callable, optional
        Called with one line at each stage.
    **changes
        Fields of :class:`IdentifyOptions` to change for this call
        (``identify(log, params, air_data="vanes")``).

    Returns
    -------
    IdentificationRun
        Findings, discovery, reconstructions, uncertainty and what was used of the log.

    Raises
    ------
    FlightLogError
        (a ``ValueError``) naming the problem when the log cannot be used
        (:class:`~drake_uav.estimation.channel_checks.ImplausibleChannelError` for a
        channel or a calibration that is physically impossible).
    ValueError
        For an unknown option or a value it does not accept (an unknown coefficient).

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.loading import load_fixed_wing
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> run = identify(log, load_fixed_wing("aerosonde"),
    ...                IdentifyOptions(air_data="vanes", segment=(0.0, 30.0)),
    ...                propulsion="catalog")
    >>> run.findings
    ('thrust_propwash',)
    """
    options = _options(options, changes)
    source, segment, phases = options.source, options.segment, options.phases
    say = progress or (lambda message: None)
    checked = check_log_channels(log, params, source=source, segment=segment, phases=phases)
    log = checked.log
    position = (logged_imu_position(log) if options.imu_position is None
                else ImuPosition.given(options.imu_position))
    moved = position is not None and any(position.position)
    if moved:
        log = accelerometers_at_cg(log, position.position)
    rates = logged_rates(log, options.rate_hz)
    compatibility = without_unsupported(
        check_log_compatibility(log, params, source=source, segment=segment, phases=phases,
                                progress=say), rates.limits(calibration_needs()))
    if compatibility is not None:
        log = compatibility.corrected(log)
    command_delay = measured_command_delay(compatibility)
    samples, selection = select_samples(log, params, options, progress=say,
                                        throttle_delay=command_delay)
    limits = rates.limits([*calibration_needs(), *effect_needs(selection.air_data),
                           *derivative_needs(n for k in options.coefficients
                                             for n in baseline_names(params, k))])
    products = rates.limits(product_needs())
    if force_channels(samples):
        say("estimating the clock offsets of the logged force channels")
        samples, offsets = correct_clock_offsets(samples, params, options.rule)
        compatibility = (CompatibilityResult(offsets) if compatibility is None else
                         dataclasses.replace(compatibility,
                                             effects=compatibility.effects + offsets))
    run = identify_samples(samples, params, options, progress=say,
                           effects=testable_effects(selection.air_data, command_delay),
                           vector_effects=testable_vector_effects(
                               selection.air_data, force_channels(samples)),
                           untested={limit.term for limit in (*limits, *products)},
                           fixed={limit.term: params.derivatives[limit.term] for limit in limits
                                  if limit.term in params.derivatives})
    notes = ((position.note(),) if moved else ()) + selection.notes \
        + _rate_notes(limits, len(products)) + run.discovery.notes
    selection = dataclasses.replace(selection, notes=notes,
                                    warnings=checked.notes + selection.warnings)
    return dataclasses.replace(run, data=selection, compatibility=compatibility,
                               logged_rates=rates, rate_limits=limits)


def _rate_notes(limits: Sequence[RateLimit], products: int) -> tuple[str, ...]:
    """One note naming the terms the log cannot support (none: no note)."""
    if not limits:
        return ()
    untested = f"; nor {products} data-driven products of their signals" if products else ""
    terms = ", ".join(r.term for r in limits)
    return (f"not identifiable at the logged rates (effects not tested, calibration errors "
            f"not claimed, derivatives fixed at the catalog's values): {terms}{untested}; "
            "the channels and the rates they need are listed in the report",)


def check_log_channels(log: FlightLog, params: FixedWingParams, *,
                       source: str = "flight log",
                       segment: tuple[float, float] | None = None,
                       phases: PhaseSettings = DEFAULT_PHASES) -> CheckedLog:
    """Every channel of ``log`` against its physical range over the airborne spans.

    And the airspeed against the GPS ground speed
    (:func:`~drake_uav.estimation.channel_checks.check_channels`): the log with its
    glitches drawn over, and a warning for each channel that had any. The log as it is
    when it has no usable span (:func:`select_samples` then says why).

    Parameters
    ----------
    log : FlightLog
        The flight log.
    params : FixedWingParams
        The aircraft (its physical ranges).
    source : str
        The log's name in the messages.
    segment : (float, float), optional
        (start, end) [s] of the log to use.
    phases : PhaseSettings
        Thresholds of the airborne detection.

    Returns
    -------
    CheckedLog
        The log with its glitches drawn over, and the warnings.

    Raises
    ------
    ImplausibleChannelError
        Naming ``source``, the channel and the likely cause for a channel that is
        physically impossible.
    """
    check_fixed_wing(log, source)
    try:
        spans = usable_spans(log, phases, segment)
    except FlightLogError:
        return CheckedLog(log, ())
    return check_channels(log, params, _inside(log, spans), source)


def _inside(log: FlightLog, spans) -> np.ndarray:
    """Rows of ``log`` inside the ``spans`` [s] (bool)."""
    inside = np.zeros(len(log), bool)
    for start, end in spans:
        inside |= (log.time >= start) & (log.time <= end)
    return inside


def check_log_compatibility(log: FlightLog, params: FixedWingParams, *,
                            source: str = "flight log",
                            segment: tuple[float, float] | None = None,
                            phases: PhaseSettings = DEFAULT_PHASES,
                            progress: Callable[[str], None] | None = None
                            ) -> CompatibilityResult | None:
    """The data-compatibility check on the samples of the airborne spans of ``log``.

    :func:`~drake_uav.estimation.compatibility.check_compatibility`; see :func:`identify`
    for the arguments.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    params : FixedWingParams
        The aircraft.
    source : str
        The log's name in the messages.
    segment : (float, float), optional
        (start, end) [s] of the log to use.
    phases : PhaseSettings
        Thresholds of the airborne detection.
    progress : callable, optional
        Called with one line per stage.

    Returns
    -------
    CompatibilityResult or None
        None when the log has no usable span or too little for the check (the IMU and the
        attitude over 8 s): :func:`select_samples` then says what is wrong, or the job goes
        on with the log as recorded.

    Raises
    ------
    ImplausibleChannelError
        Naming ``source`` for a calibration far outside what a calibration can be.
    """
    check_fixed_wing(log, source)
    try:
        spans = usable_spans(log, phases, segment)
    except FlightLogError:
        return None
    inside = _inside(log, spans)
    names = log.measured_names
    airborne = FlightLog(log.time[inside], {n: log[n][inside] for n in names}, None,
                         {n: log.unit(n) for n in names})
    if progress is not None:
        progress("checking data compatibility (sensor biases, scale factors, time skews)")
    try:
        return check_compatibility(airborne, params)
    except ImplausibleChannelError as err:
        raise ImplausibleChannelError(f"{source}: {err}") from None
    except FlightLogError:
        return None


ESTIMATE_CONFOUNDED = ("ned_force", "steady_wind_in_air_data")
"""Effects fixed in the NED frame. With air data estimated from GPS and pitot, the wind
estimate's own error is fixed in the NED frame too and moves the measured coefficients
the same way (through alpha, beta and the airspeed): the data cannot tell the two
apart, so these effects are not tested then."""


def measured_command_delay(compatibility: CompatibilityResult | None) -> float | None:
    """The servo delay the data-compatibility check measured.

    A significant command time skew it left to the model (a late one, shorter than its
    ``max_actuator_delay``).

    Parameters
    ----------
    compatibility : CompatibilityResult or None
        The check's result.

    Returns
    -------
    float or None
        The delay [s]; None when it measured none.
    """
    if compatibility is None:
        return None
    skew = next((e for e in compatibility.effects if e.name == "command_time_skew"), None)
    if skew is None or not skew.significant or skew.applied:
        return None
    return float(skew.estimate)


def testable_effects(air_data: str, command_delay: float | None = None) -> list[Effect]:
    """The named effects the data of an ``air_data`` mode can tell from its errors.

    Parameters
    ----------
    air_data : str
        The resolved air-data mode.
    command_delay : float, optional
        The servo delay [s] the data-compatibility check measured
        (:func:`measured_command_delay`), which shapes ``actuator_time_delay``.

    Returns
    -------
    list of Effect
        The effect library, without those an estimate of the flow angles confounds.
    """
    library = effect_library(command_delay)
    if air_data != "estimate":
        return library
    return [e for e in library if e.name not in ESTIMATE_CONFOUNDED]


def testable_vector_effects(air_data: str, magnitudes: Sequence[str] = ()
                            ) -> list[VectorEffect]:
    """The vector effects the data of an ``air_data`` mode can tell from its errors.

    Without vanes, not the force towards a point the data locate, which then takes up the
    error of the estimated wind as a pull towards some far point.

    Parameters
    ----------
    air_data : str
        The resolved air-data mode.
    magnitudes : sequence of str
        Logged force channels (``logged:<channel>`` in N): each adds the forces
        proportional to it (:func:`~drake_uav.identification.discovery.clock_offset.
        force_channels`).

    Returns
    -------
    list of VectorEffect
        The vector effects.
    """
    return vector_effect_library((None, *magnitudes), located_point=air_data != "estimate")


def select_samples(log: FlightLog, params: FixedWingParams,
                   options: IdentifyOptions | None = None, *,
                   progress: Callable[[str], None] | None = None,
                   throttle_delay: float | None = None,
                   **changes) -> tuple[AeroSamples, LogSelection]:
    """Regression samples of the usable spans of ``log`` and what was used.

    Parameters
    ----------
    log : FlightLog
        The flight log.
    params : FixedWingParams
        The aircraft.
    options : IdentifyOptions, optional
        The job's settings; ``rate_hz, source, air_data, segment, sensor_noise_std,
        phases, propulsion`` are used here.
    progress : callable, optional
        Called with one line per stage.
    throttle_delay : float, optional
        A measured servo delay [s] the thrust fit accounts for
        (:func:`~drake_uav.identification.propulsion.thrust_from_gridded_log`).
    **changes
        Fields of :class:`IdentifyOptions` to change for this call.

    Returns
    -------
    tuple
        The samples of every span joined, and :class:`LogSelection`.

    Raises
    ------
    FlightLogError
        Naming the span and the problem when the log cannot be used.
    """
    options = _options(options, changes)
    source, air_data, segment = options.source, options.air_data, options.segment
    phases, sensor_noise_std, rate_hz = (options.phases, options.sensor_noise_std,
                                         options.rate_hz)
    check_fixed_wing(log, source)
    shaft_note = None
    if options.propulsion == "data":
        log, shaft_note = with_motor_speed(log)
    mode = choose_air_data(log, air_data, source)
    try:
        spans = usable_spans(log, phases, segment)
    except FlightLogError as err:
        raise FlightLogError(f"{source}: {err}") from None
    if progress is not None:
        progress(f"isolating aerodynamic coefficients ({len(spans)} airborne span"
                 f"{'s' if len(spans) > 1 else ''}, {_AIR_DATA_STEP[mode]})")
    parts, warnings = [], []
    extras, extra_notes = usable_extras(log)  # one set for every span
    for start, end in spans:
        try:
            angles = flow_angles(log.slice(start, end), params, mode, sensor_noise_std)
            warnings += [f"span {start:.1f}-{end:.1f} s: {w}" for w in angles.warnings]
            grid = gridded_log(angles.log, params, rate_hz=rate_hz,
                               flow_channels=angles.channels,
                               sensor_noise_std=sensor_noise_std, extras=extras)
            thrust = None
            if options.propeller is not None:
                thrust = declared_thrust(grid, params, options.propeller)
            elif options.propulsion == "data":
                thrust = thrust_from_gridded_log(grid, params, throttle_delay)
            part = isolated_samples(grid, params, thrust)
        except FlightLogError as err:
            raise FlightLogError(f"{source}: span {start:.1f}-{end:.1f} s: {err}") from None
        parts.append(_with_flow_error(part, angles.error_variance))
    parts, gps_notes = _common_signals(parts, spans)
    selection = LogSelection(tuple(spans), mode, angles.description,
                             _selection_notes(log, spans, mode, angles.description)
                             + extra_notes + gps_notes + ((shaft_note,) if shaft_note else ())
                             + ((f"thrust from the {options.propeller.describe()}",)
                                if options.propeller is not None else ()),
                             tuple(warnings))
    return concatenate_samples(parts), selection


def _common_signals(parts: list[AeroSamples], spans) -> tuple[list[AeroSamples], tuple]:
    """The parts with only the signals every one holds (a span without a GPS fix has no
    GPS velocity or position), and a note naming what was left out and where."""
    common = set.intersection(*(set(p.signals) for p in parts))
    left_out = sorted(set().union(*(set(p.signals) for p in parts)) - common)
    if not left_out:
        return parts, ()
    missing = [f"{a:.1f}-{b:.1f} s" for (a, b), p in zip(spans, parts, strict=True)
               if not set(left_out) <= set(p.signals)]
    note = (f"left out {', '.join(left_out)}: not in the span(s) {', '.join(missing)} "
            "(no GPS fix there); the effects that need them are not tested")

    def kept(samples):
        return dataclasses.replace(
            samples.with_moments(lambda m: dataclasses.replace(
                m, logged={k: v for k, v in m.logged.items() if k in common})),
            signals={k: v for k, v in samples.signals.items() if k in common})
    return [kept(p) for p in parts], (note,)


_AIR_DATA_STEP = {"vanes": "vane air data", "estimate": "air data estimated without vanes",
                  "ahrs": "AHRS air data"}

_FIXED_WING_TYPES = {1, 19, 20, 21, 22, 23, 24, 25}
"""MAV_TYPE of aircraft with a wing: fixed wing and the VTOL types."""


def check_fixed_wing(log: FlightLog, source: str) -> None:
    """Check that the log is of a fixed wing or a VTOL.

    Parameters
    ----------
    log : FlightLog
        The flight log (its ``vehicle_type`` metadata).
    source : str
        The log's name in the message.

    Raises
    ------
    FlightLogError
        For a log whose vehicle type is another.
    """
    vehicle = log.metadata.get("vehicle_type") or {}
    kind = vehicle.get("mav_type")
    if kind is not None and int(kind) not in _FIXED_WING_TYPES | {0}:  # 0: generic
        name = vehicle.get("name", "")
        raise FlightLogError(f"{source}: not a fixed-wing log (MAV_TYPE {int(kind)}"
                             f"{f', {name}' if name else ''}); identify works on fixed-wing "
                             "and VTOL flights")


def _with_flow_error(samples: AeroSamples, variance: dict[str, float] | None) -> AeroSamples:
    """Samples whose alpha/beta error variance is an estimate's, not a sensor's."""
    if variance is None:
        return samples
    noise = {**samples.noise_variance, **variance}
    return dataclasses.replace(
        samples.with_moments(lambda m: dataclasses.replace(m, noise_variance=noise)),
        noise_variance=noise)


def _selection_notes(log: FlightLog, spans, mode: str, air_data: str) -> tuple[str, ...]:
    used = sum(end - start for start, end in spans)
    notes = [f"used {used:.0f} s of {log.time[-1] - log.time[0]:.0f} s: "
             + ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in spans),
             f"air data: {air_data}"]
    if mode == "estimate":
        notes.append(f"not tested: {', '.join(ESTIMATE_CONFOUNDED)} (fixed in the NED frame "
                     "like the error of the estimated wind, so the data cannot tell them "
                     "apart)")
    for stream in log.metadata.get("dropped_streams") or []:
        notes.append(f"stream {stream} left out (sparse or with gaps)")
    return tuple(notes)


def identify_samples(samples: AeroSamples, params: FixedWingParams,
                     options: IdentifyOptions | None = None, *,
                     progress: Callable[[str], None] | None = None,
                     effects: Sequence[Effect] | None = None,
                     vector_effects: Sequence[VectorEffect] | None = None,
                     untested: Collection[str] = (),
                     fixed: Mapping[str, float] | None = None,
                     **changes) -> IdentificationRun:
    """The main job after the isolation: discovery, reconstruction, uncertainty.

    :func:`identify` with the measured coefficients already in ``samples``
    (:func:`~drake_uav.identification.samples.flight_data.samples_from_log` or
    :func:`~drake_uav.identification.samples.isolation.isolate_coefficients`); the
    ``samples.signals`` must hold ``roll`` and ``pitch`` [rad]. ``effects``
    defaults to the whole :func:`~drake_uav.identification.discovery.effects.effect_library`,
    ``vector_effects`` to :func:`~drake_uav.identification.discovery.vector_effects.
    vector_effect_library`. The coefficients skipped and the effects not kept are in
    ``discovery.notes``.

    Parameters
    ----------
    samples : AeroSamples
        The measured coefficients and their regressors.
    params : FixedWingParams
        The aircraft's catalog model.
    options : IdentifyOptions, optional
        The job's settings; ``rule, reset_interval, source, seed, coefficients`` are used
        here.
    progress : callable, optional
        Called with one line per stage.
    effects, vector_effects : sequence, optional
        The candidate effects (None: the libraries).
    untested : collection of str
        Candidates not to test, by name (:func:`~drake_uav.identification.discovery.loop.
        discover`).
    fixed : Mapping[str, float], optional
        Catalog derivatives fixed at these values instead of fitted (:func:`~drake_uav.
        identification.discovery.loop.discover`): those the log's rates cannot support.
    **changes
        Fields of :class:`IdentifyOptions` to change for this call.

    Returns
    -------
    IdentificationRun
        The discovery, the reconstructions before and after, and the uncertainty.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> run = identify_samples(samples, aerosonde(), coefficients=("CD",))
    >>> run.findings, run.data is None
    (('thrust_propwash',), True)

    Raises
    ------
    ValueError
        For an unknown option or coefficient, or samples too few for the evidence tests.
    """
    options = _options(options, changes)
    reset_interval = options.reset_interval
    say = progress or (lambda message: None)
    result = discover(samples, params, effects=effects, vector_effects=vector_effects,
                      rule=options.rule, progress=say, coefficients=options.coefficients,
                      untested=untested, fixed=fixed)
    say("reconstructing airspeed, alpha and beta (output error)")
    before = _reconstruct(samples, params, result, result.baseline, reset_interval)
    after = _reconstruct(samples, params, result, result.final, reset_interval)
    say("Monte-Carlo uncertainty of the measured coefficients")
    sigma = coefficient_uncertainty(samples, params, options.seed)
    return IdentificationRun(params, samples, result, before, after, options.source, sigma)
