"""The main job: flight log -> fitted model -> residual -> missing effect.

:func:`identify` runs the whole loop on a :class:`FlightLog` and returns an
:class:`IdentificationRun`; :func:`drake_uav.reporting.write_report` turns it
into a report folder.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from drake_uav.estimation.channel_checks import (
    CheckedLog,
    ImplausibleChannelError,
    check_channels,
)
from drake_uav.estimation.compatibility import CompatibilityResult, check_compatibility
from drake_uav.estimation.imu_position import (
    ImuPosition,
    accelerometers_at_cg,
    logged_imu_position,
)
from drake_uav.identification.air_data_source import choose_air_data, flow_angles
from drake_uav.identification.coefficient_design import (
    IdentifiedDerivatives,
    baseline_names,
    fit_derivatives,
)
from drake_uav.identification.discovery import check_coefficients, discover
from drake_uav.identification.discovery_result import DiscoveryResult, EvidenceRule, FoundEffect
from drake_uav.identification.effects import Effect, effect_library
from drake_uav.identification.flight_data import samples_from_log, usable_extras
from drake_uav.identification.flight_phases import DEFAULT_PHASES, PhaseSettings, usable_spans
from drake_uav.identification.isolation import AeroSamples, monte_carlo_sigmas
from drake_uav.identification.reconstruction import Reconstruction, reconstruct
from drake_uav.identification.segments import concatenate_samples
from drake_uav.identification.vector_effects import VectorEffect, vector_effect_library
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.model.isolation import force_coefficients
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["IdentificationRun", "LogSelection", "identify", "identify_samples",
           "identify_derivatives", "select_samples", "check_fixed_wing",
           "testable_effects", "testable_vector_effects", "measured_command_delay",
           "ESTIMATE_CONFOUNDED",
           "coefficient_uncertainty", "check_log_compatibility", "check_log_channels"]

RECONSTRUCTED_OUTPUTS = ("airspeed", "alpha", "beta", "p", "q", "r")
"""Reconstructed outputs, in the order of :class:`Reconstruction` columns."""
RECONSTRUCTED_UNITS = ("m/s", "rad", "rad", "rad/s", "rad/s", "rad/s")
"""Units of :data:`RECONSTRUCTED_OUTPUTS`."""


@dataclasses.dataclass(frozen=True)
class LogSelection:
    """The parts of a log the main job used, and how it read their air data."""

    spans: tuple[tuple[float, float], ...]
    """Airborne fixed-wing spans (start, end) [s] (:func:`usable_spans`)."""
    air_data: str
    """"vanes", "estimate" or "ahrs" (:mod:`~drake_uav.identification.air_data_source`)."""
    air_data_description: str
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    """What the job did to the data that changes what the result means: glitches drawn
    over (:func:`check_log_channels`), an estimate it could not use (a wind the flight
    does not observe)."""

    def summary(self) -> dict:
        """JSON-ready: spans, air data, notes and warnings."""
        return {"spans_s": [list(s) for s in self.spans], "air_data": self.air_data,
                "air_data_description": self.air_data_description, "notes": list(self.notes),
                "warnings": list(self.warnings)}


@dataclasses.dataclass(frozen=True)
class IdentificationRun:
    """Result of the main job on one flight log."""

    params: FixedWingParams
    samples: AeroSamples
    discovery: DiscoveryResult
    reconstruction_before: Reconstruction
    reconstruction_after: Reconstruction
    source: str
    coefficient_sigma: dict
    """Monte-Carlo standard deviation of the measured C_L, C_D, C_Y (Vaiopoulos 2017, sec. 5.6)."""
    data: LogSelection | None = None
    """What the job used of the log: spans, air data, notes (None: samples given directly)."""
    compatibility: CompatibilityResult | None = None
    """The data-compatibility check of the airborne spans (docs/compatibility.md), whose
    significant calibration errors were removed before the isolation (None: samples given
    directly, or nothing to check)."""

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
    def findings(self) -> tuple[str, ...]:
        """Everything the job found the model or the data lacked, by name: the calibration
        errors the data-compatibility check corrected (``air_data_time_skew``, ...), then
        the effects the discovery loop found."""
        corrected = () if self.compatibility is None else tuple(
            e.name for e in self.compatibility.applied)
        return corrected + tuple(f.name for f in self.discovery.found)

    def summary(self) -> dict:
        """JSON-ready summary: effects with evidence, errors before/after, parameters.

        Run-level keys: ``source, aircraft, data (spans, air data, notes), message,
        findings (:attr:`findings`), samples, holdout_start_s, effects,
        equation_error_rms_holdout (with each coefficient's ``adequacy``: its error against
        the noise floor, whether the model is incomplete there and where,
        :class:`~drake_uav.identification.adequacy.Adequacy`), reconstruction_mae_holdout,
        reconstruction_divergences, measured_coefficient_sigma_monte_carlo, parameters,
        dropped_terms``; each entry of ``effects`` has ``name, kind, explanation,
        coefficients, evidence, parameters``. ``parameters`` lists a baseline term the
        flight does not support as 0 (``dropped``: true); ``dropped_terms`` gives, per
        coefficient, the figures that dropped each
        (:class:`~drake_uav.identification.parsimony.DroppedTerm`).
        """
        d = self.discovery
        rms = {k: {"before": b, "after": a, "change": (a - b) / b if b else 0.0,
                   **({"adequacy": d.adequacy[k].summary()} if k in d.adequacy else {})}
               for k, (b, a) in d.rms_change().items()}
        mae_b, mae_a = self.reconstruction_before.mae, self.reconstruction_after.mae
        return {
            "source": self.source,
            "aircraft": self.params.name,
            "data": None if self.data is None else self.data.summary(),
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
                        "significant": bool(fit.result.significant[i])}
                    for i, n in enumerate(fit.names)}
                | {t.term: {"estimate": 0.0, "sigma": 0.0, "significant": False, "dropped": True}
                   for t in d.dropped.get(k, ())}
                for k, fit in d.final.items()
            },
            "dropped_terms": {k: [dataclasses.asdict(t) for t in terms]
                              for k, terms in d.dropped.items()},
        }


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
    models = {k: (fits[k].names, fits[k].result.estimate, fits[k].holdout_design)
              for k in fits}
    for k in COEFFICIENTS:
        if k not in models:
            names = tuple(baseline_names(params, k))
            models[k] = (names, np.array([params.derivatives.get(n, 0.0) for n in names]),
                         np.zeros((len(test), len(names))))
    return reconstruct(test, params, models, exclude_prefixes=sensor_effects,
                       reset_interval=reset_interval)


def coefficient_uncertainty(samples: AeroSamples, params: FixedWingParams, seed: int = 0,
                            draws: int = 200_000) -> dict[str, float]:
    """Monte-Carlo error std of the measured force coefficients (Vaiopoulos 2017, sec. 5.6).

    Inputs (airspeed, alpha, specific force) vary over their flight ranges with
    their observed correlation; their errors are the noise the isolation estimated.
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
    (:func:`~drake_uav.identification.coefficient_design.fit_derivatives`). Raises
    :class:`~drake_uav.io.flight_log.FlightLogError` naming the problem when the log
    cannot be used.
    """
    return fit_derivatives(select_samples(log, params, rate_hz=rate_hz)[0], params)


def identify(log: FlightLog, params: FixedWingParams, *, rate_hz: float = 50.0,
             rule: EvidenceRule | None = None, reset_interval: float = 5.0,
             progress: Callable[[str], None] | None = None,
             source: str = "flight log", seed: int = 0, air_data: str = "auto",
             segment: tuple[float, float] | None = None,
             sensor_noise_std: dict[str, float] | None = None,
             propulsion: str = "data",
             phases: PhaseSettings = DEFAULT_PHASES,
             coefficients: Sequence[str] = COEFFICIENTS,
             imu_position: Sequence[float] | None = None) -> IdentificationRun:
    """Runs the main job on ``log`` for the aircraft ``params``.

    Only what a real log holds is read: the airborne fixed-wing spans
    (:func:`~drake_uav.identification.flight_phases.usable_spans`, within
    ``segment`` [s] when given) are isolated one by one and joined; ``air_data``
    picks the flow angles (:mod:`~drake_uav.identification.air_data_source`);
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

    Raises :class:`~drake_uav.io.flight_log.FlightLogError` (a ``ValueError``)
    naming the problem when the log cannot be used
    (:class:`~drake_uav.estimation.channel_checks.ImplausibleChannelError` for a channel
    or a calibration that is physically impossible), ``ValueError`` for an unknown
    coefficient.
    """
    check_coefficients(coefficients)
    say = progress or (lambda message: None)
    checked = check_log_channels(log, params, source=source, segment=segment, phases=phases)
    log = checked.log
    position = (logged_imu_position(log) if imu_position is None
                else ImuPosition.given(imu_position))
    moved = position is not None and any(position.position)
    if moved:
        log = accelerometers_at_cg(log, position.position)
    compatibility = check_log_compatibility(log, params, source=source, segment=segment,
                                            phases=phases, progress=say)
    if compatibility is not None:
        log = compatibility.corrected(log)
    command_delay = measured_command_delay(compatibility)
    samples, selection = select_samples(log, params, rate_hz=rate_hz, source=source,
                                        air_data=air_data, segment=segment,
                                        sensor_noise_std=sensor_noise_std, phases=phases,
                                        propulsion=propulsion, progress=say,
                                        throttle_delay=command_delay)
    run = identify_samples(samples, params, rule=rule, reset_interval=reset_interval,
                           progress=say, source=source, seed=seed,
                           effects=testable_effects(selection.air_data, command_delay),
                           vector_effects=testable_vector_effects(selection.air_data),
                           coefficients=coefficients)
    notes = ((position.note(),) if moved else ()) + selection.notes + run.discovery.notes
    selection = dataclasses.replace(selection, notes=notes,
                                    warnings=checked.notes + selection.warnings)
    return dataclasses.replace(run, data=selection, compatibility=compatibility)


def check_log_channels(log: FlightLog, params: FixedWingParams, *,
                       source: str = "flight log",
                       segment: tuple[float, float] | None = None,
                       phases: PhaseSettings = DEFAULT_PHASES) -> CheckedLog:
    """Every channel of ``log`` against its physical range over the airborne spans, and the
    airspeed against the GPS ground speed
    (:func:`~drake_uav.estimation.channel_checks.check_channels`; see :func:`identify` for
    the arguments): the log with its glitches drawn over, and a warning for each channel
    that had any. The log as it is when it has no usable span (:func:`select_samples`
    then says why).

    Raises :class:`~drake_uav.estimation.channel_checks.ImplausibleChannelError` naming
    ``source``, the channel and the likely cause for a channel that is physically
    impossible.
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
    """The data-compatibility check (:func:`~drake_uav.estimation.compatibility.
    check_compatibility`) on the samples of the airborne spans of ``log`` (see
    :func:`identify` for the arguments).

    None when the log has no usable span or too little for the check (the IMU and the
    attitude over 8 s): :func:`select_samples` then says what is wrong, or the job goes on
    with the log as recorded. Raises :class:`~drake_uav.estimation.channel_checks.
    ImplausibleChannelError` naming ``source`` for a calibration far outside what a
    calibration can be.
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
    """The servo delay [s] the data-compatibility check measured: a significant command
    time skew it left to the model (a late one, shorter than its ``max_actuator_delay``);
    None when it measured none."""
    if compatibility is None:
        return None
    skew = next((e for e in compatibility.effects if e.name == "command_time_skew"), None)
    if skew is None or not skew.significant or skew.applied:
        return None
    return float(skew.estimate)


def testable_effects(air_data: str, command_delay: float | None = None) -> list[Effect]:
    """The named effects the data of an ``air_data`` mode can tell from its errors;
    ``command_delay`` [s], the servo delay the data-compatibility check measured
    (:func:`measured_command_delay`), shapes ``actuator_time_delay``."""
    library = effect_library(command_delay)
    if air_data != "estimate":
        return library
    return [e for e in library if e.name not in ESTIMATE_CONFOUNDED]


def testable_vector_effects(air_data: str) -> list[VectorEffect]:
    """The vector effects the data of an ``air_data`` mode can tell from its errors: without
    vanes, not the force towards a point the data locate, which then takes up the error of
    the estimated wind as a pull towards some far point (2 of 40 clean flights)."""
    return vector_effect_library(located_point=air_data != "estimate")


def select_samples(log: FlightLog, params: FixedWingParams, *, rate_hz: float = 50.0,
                   source: str = "flight log", air_data: str = "auto",
                   segment: tuple[float, float] | None = None,
                   sensor_noise_std: dict[str, float] | None = None,
                   phases: PhaseSettings = DEFAULT_PHASES,
                   propulsion: str = "data",
                   progress: Callable[[str], None] | None = None,
                   throttle_delay: float | None = None,
                   ) -> tuple[AeroSamples, LogSelection]:
    """Regression samples of the usable spans of ``log`` and what was used (see
    :func:`identify` for the arguments; ``throttle_delay`` [s], a measured servo delay
    the thrust fit accounts for, :func:`~drake_uav.identification.flight_data.
    samples_from_log`)."""
    check_fixed_wing(log, source)
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
            part = samples_from_log(angles.log, params, rate_hz=rate_hz,
                                    flow_channels=angles.channels,
                                    sensor_noise_std=sensor_noise_std, propulsion=propulsion,
                                    extras=extras, throttle_delay=throttle_delay)
        except FlightLogError as err:
            raise FlightLogError(f"{source}: span {start:.1f}-{end:.1f} s: {err}") from None
        parts.append(_with_flow_error(part, angles.error_variance))
    parts, gps_notes = _common_signals(parts, spans)
    selection = LogSelection(tuple(spans), mode, angles.description,
                             _selection_notes(log, spans, mode, angles.description)
                             + extra_notes + gps_notes, tuple(warnings))
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
        view = None if samples.moment_view is None else kept(samples.moment_view)
        return dataclasses.replace(samples, moment_view=view, signals={
            k: v for k, v in samples.signals.items() if k in common})
    return [kept(p) for p in parts], (note,)


_AIR_DATA_STEP = {"vanes": "vane air data", "estimate": "air data estimated without vanes",
                  "ahrs": "AHRS air data"}

_FIXED_WING_TYPES = {1, 19, 20, 21, 22, 23, 24, 25}
"""MAV_TYPE of aircraft with a wing: fixed wing and the VTOL types."""


def check_fixed_wing(log: FlightLog, source: str) -> None:
    """Raises FlightLogError for a log whose vehicle type is not a fixed wing or VTOL."""
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
    view = None if samples.moment_view is None else dataclasses.replace(
        samples.moment_view, noise_variance=noise)
    return dataclasses.replace(samples, noise_variance=noise, moment_view=view)


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


def identify_samples(samples: AeroSamples, params: FixedWingParams, *,
                     rule: EvidenceRule | None = None, reset_interval: float = 5.0,
                     progress: Callable[[str], None] | None = None,
                     source: str = "flight samples", seed: int = 0,
                     effects: Sequence[Effect] | None = None,
                     vector_effects: Sequence[VectorEffect] | None = None,
                     coefficients: Sequence[str] = COEFFICIENTS) -> IdentificationRun:
    """The main job after the isolation: discovery, reconstruction, uncertainty.

    :func:`identify` with the measured coefficients already in ``samples``
    (:func:`~drake_uav.identification.flight_data.samples_from_log` or
    :func:`~drake_uav.identification.isolation.isolate_coefficients`); the
    ``samples.signals`` must hold ``roll`` and ``pitch`` [rad]. ``effects``
    defaults to the whole :func:`~drake_uav.identification.effects.effect_library`,
    ``vector_effects`` to :func:`~drake_uav.identification.vector_effects.
    vector_effect_library`. The coefficients skipped and the effects not kept are in
    ``discovery.notes``.
    """
    say = progress or (lambda message: None)
    result = discover(samples, params, effects=effects, vector_effects=vector_effects,
                      rule=rule, progress=say, coefficients=coefficients)
    say("reconstructing airspeed, alpha and beta (output error)")
    before = _reconstruct(samples, params, result, result.baseline, reset_interval)
    after = _reconstruct(samples, params, result, result.final, reset_interval)
    say("Monte-Carlo uncertainty of the measured coefficients")
    sigma = coefficient_uncertainty(samples, params, seed)
    return IdentificationRun(params, samples, result, before, after, source, sigma)
