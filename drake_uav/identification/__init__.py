"""Aerodynamic model identification from flight data (numpy/scipy, no Drake systems).

The main job, from a flight log to the effect the model lacks::

    from drake_uav.identification import identify
    run = identify(log, aerosonde())        # IdentificationRun: run.summary(), run.discovery

and its parts, each usable alone:

* :mod:`.flight_data` and :mod:`.isolation`: a log -> measured coefficients
  (:func:`samples_from_log`, :func:`isolate_coefficients`, :class:`AeroSamples`).
* :mod:`.regression`: batch :func:`ols`, :func:`tls` (GTLS with error stds),
  :func:`pca_tls`, :func:`bcls`, one :class:`RegressionResult`.
* :mod:`.errors_in_variables`: the core those estimators share (noise moments,
  bias compensation, sandwich covariance).
* :mod:`.recursive`: :class:`RecursiveOLS`, :class:`RecursiveTLS`, :class:`VariableForgetting`.
* :mod:`.residuals`: :func:`diagnose` a residual (whiteness, spectrum, drift, candidates).
* :mod:`.effects` and :mod:`.discovery`: named effects, :func:`discover`,
  :func:`fit_derivatives`.
* :mod:`.reconstruction`: output-error :func:`reconstruct`.
* :mod:`.propulsion`: :func:`identify_thrust`, thrust from the motor speed or the throttle,
  identified with C_X (:class:`ThrustModel`).
* :mod:`.crlb`: Cramer-Rao bounds.
"""

from drake_uav.identification.coefficient_design import (
    IdentifiedDerivatives,
    baseline_names,
    fit_derivatives,
)
from drake_uav.identification.crlb import (
    crlb_errors_in_variables,
    crlb_ols,
    sample_errors_in_variables,
)
from drake_uav.identification.discovery import discover
from drake_uav.identification.discovery_result import (
    NO_EFFECT_MESSAGE,
    CoefficientFit,
    DiscoveryResult,
    Evidence,
    EvidenceRule,
    FoundEffect,
    HeldOutCheck,
)
from drake_uav.identification.effects import Effect, effect_library
from drake_uav.identification.errors_in_variables import PropagatedNoise
from drake_uav.identification.flight_data import REQUIRED_CHANNELS, samples_from_log
from drake_uav.identification.isolation import (
    AeroSamples,
    isolate_coefficients,
    monte_carlo_sigma,
    monte_carlo_sigmas,
)
from drake_uav.identification.main_job import (
    IdentificationRun,
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
from drake_uav.identification.reconstruction import Reconstruction, reconstruct
from drake_uav.identification.recursive import (
    RecursiveOLS,
    RecursiveTLS,
    VariableForgetting,
    forgetting_time,
    reconvergence_time,
)
from drake_uav.identification.regression import (
    IdentificationWarning,
    InsufficientExcitationWarning,
    RegressionResult,
    bcls,
    ols,
    pca_tls,
    tls,
)
from drake_uav.identification.residuals import (
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
