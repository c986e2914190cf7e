"""Aerodynamic model identification from flight data (numpy/scipy, no Drake systems).

The main job, from a flight log to the effect the model lacks::

    from drake_uav.identification import identify
    run = identify(log, aerosonde())        # IdentificationRun: run.summary(), run.discovery

Its parts, each a sub-package that imports only the ones below it (an import-linter
contract in ``pyproject.toml`` enforces the order):

* :mod:`.pipeline`: :func:`identify` and :class:`IdentificationRun`, the stages in order
  (samples, thrust, discovery, assessment).
* :mod:`.assessment`: output-error :func:`reconstruct`, the noise floor of the held-out
  error, the identifiability of the derivatives.
* :mod:`.discovery`: the candidate effects (:class:`Effect`, :func:`effect_library`), the
  baseline design (:func:`fit_derivatives`), the evidence rule and :func:`discover`.
* :mod:`.propulsion`: :func:`identify_thrust`, thrust from the motor speed or the throttle,
  identified with C_X (:class:`ThrustModel`).
* :mod:`.samples`: a log -> measured coefficients (:func:`samples_from_log`,
  :func:`isolate_coefficients`, :class:`AeroSamples`); no fits.
* :mod:`.statistics`: batch :func:`ols`, :func:`tls`, :func:`pca_tls`, :func:`bcls`,
  :class:`RecursiveOLS`, :class:`RecursiveTLS`, Cramer-Rao bounds, residual diagnosis
  (:func:`diagnose`); nothing aircraft-specific.
"""

from drake_uav.identification.assessment.reconstruction import Reconstruction, reconstruct
from drake_uav.identification.discovery.coefficient_design import (
    IdentifiedDerivatives,
    baseline_names,
    fit_derivatives,
)
from drake_uav.identification.discovery.effects import Effect, effect_library
from drake_uav.identification.discovery.evidence import Candidate
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.discovery.result import (
    NO_EFFECT_MESSAGE,
    CoefficientFit,
    DiscoveryResult,
    Evidence,
    EvidenceRule,
    Finding,
    FoundEffect,
    HeldOutCheck,
)
from drake_uav.identification.pipeline import (
    IdentificationRun,
    IdentifyOptions,
    coefficient_uncertainty,
    identify,
    identify_derivatives,
    identify_samples,
)
from drake_uav.identification.propulsion import (
    ThrustDiagnostics,
    ThrustModel,
    ThrustPrediction,
    identify_thrust,
)
from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.flight_data import REQUIRED_CHANNELS, samples_from_log
from drake_uav.identification.samples.isolation import (
    isolate_coefficients,
    monte_carlo_sigma,
    monte_carlo_sigmas,
)
from drake_uav.identification.statistics.crlb import (
    crlb_errors_in_variables,
    crlb_ols,
    sample_errors_in_variables,
)
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
from drake_uav.identification.statistics.recursive import (
    RecursiveOLS,
    RecursiveTLS,
    VariableForgetting,
    forgetting_time,
    reconvergence_time,
)
from drake_uav.identification.statistics.regression import (
    IdentificationWarning,
    InsufficientExcitationWarning,
    RegressionResult,
    bcls,
    ols,
    pca_tls,
    tls,
)
from drake_uav.identification.statistics.residuals import (
    ResidualDiagnosis,
    diagnose,
    effective_sample_size,
    long_run_covariance,
)

__all__ = [
    "NO_EFFECT_MESSAGE",
    "REQUIRED_CHANNELS",
    "AeroSamples",
    "CoefficientFit",
    "DiscoveryResult",
    "HeldOutCheck",
    "Effect",
    "Evidence",
    "EvidenceRule",
    "FoundEffect",
    "IdentificationRun",
    "IdentifyOptions",
    "Finding",
    "Candidate",
    "IdentificationWarning",
    "IdentifiedDerivatives",
    "InsufficientExcitationWarning",
    "PropagatedNoise",
    "Reconstruction",
    "RecursiveOLS",
    "RecursiveTLS",
    "RegressionResult",
    "ResidualDiagnosis",
    "ThrustDiagnostics",
    "ThrustModel",
    "ThrustPrediction",
    "VariableForgetting",
    "baseline_names",
    "bcls",
    "coefficient_uncertainty",
    "crlb_errors_in_variables",
    "crlb_ols",
    "diagnose",
    "discover",
    "effect_library",
    "effective_sample_size",
    "fit_derivatives",
    "forgetting_time",
    "identify",
    "identify_derivatives",
    "identify_samples",
    "identify_thrust",
    "isolate_coefficients",
    "long_run_covariance",
    "monte_carlo_sigma",
    "monte_carlo_sigmas",
    "ols",
    "pca_tls",
    "reconstruct",
    "reconvergence_time",
    "samples_from_log",
    "sample_errors_in_variables",
    "tls",
]
