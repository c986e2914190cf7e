"""The texts that let the main job's report explain itself.

What a residual that is not white means for the result (:func:`residual_meaning`) and the
glossary of the terms the report uses (:data:`GLOSSARY`); the near-tied alternatives the
report names are computed with the run
(:mod:`~drake_uav.identification.assessment.near_ties`).
"""

from __future__ import annotations

from collections.abc import Mapping

from drake_uav.identification.assessment.near_ties import NEAR_TIE_MARGIN
from drake_uav.identification.statistics.residuals import ResidualDiagnosis

__all__ = ["residual_meaning", "RESIDUAL_MEANING", "SMOOTHING_CORRELATION_FACTOR", "GLOSSARY"]

SMOOTHING_CORRELATION_FACTOR = 1.5
"""A residual correlation time up to this many times the smoothing's own correlation time
of white noise counts as the smoothed sensor noise, not as structure left in the data."""


RESIDUAL_MEANING = (
    "A residual is white when its samples are uncorrelated (Ljung-Box test at 5 %). One "
    "that is not white carries fewer independent samples than its count (the effective "
    "sample size): the sigmas of this report are the long-run (Newey-West) ones and the "
    "F-tests use the effective size, so they stay valid. What it means for the model "
    "depends on how long the correlation lasts. Up to about the smoothing's own "
    "correlation time it is the sensor noise seen through the Savitzky-Golay filter of the "
    "isolation: nothing is missing. A longer correlation time, a spectral peak or a drift "
    "is structure the model does not explain (an effect outside the library, turbulence "
    "the air data did not see, a derivative that changes during the flight): the "
    "derivatives may have absorbed the part of it that correlates with their regressors, "
    "and the reconstruction drifts where it acts.")
"""The paragraph above the per-coefficient lines of :func:`residual_meaning`."""


def residual_meaning(diagnoses: Mapping[str, ResidualDiagnosis],
                     smoothing_time: float, nyquist_hz: float | None = None) -> list[str]:
    """One line per coefficient: is its residual white, and if not, what that says.

    ``smoothing_time`` [s]: the correlation time the isolation's smoothing gives white
    noise (integrated autocorrelation time of the filter). ``nyquist_hz``: the lowest native
    Nyquist frequency [Hz] of the channels the coefficients are measured from; a spectral
    peak above it is the resampling's, not the flight's, and is not named.
    """
    lines = []
    for k, d in diagnoses.items():
        if d.is_white:
            lines.append(f"{k}: white (Ljung-Box p = {d.ljung_box_pvalue:.2g}): the model "
                         "leaves only uncorrelated noise.")
            continue
        time = d.integrated_time / d.sample_rate
        reading = ("the smoothed sensor noise" if time <= SMOOTHING_CORRELATION_FACTOR
                   * smoothing_time else "structure the model does not explain")
        text = (f"{k}: not white, correlation time {time:.2g} s (the smoothing alone gives "
                f"{smoothing_time:.2g} s): {reading}")
        shown = [p for p in d.spectral_peaks if nyquist_hz is None or p.frequency <= nyquist_hz]
        if shown:
            peaks = ", ".join(f"{p.frequency:.3g} Hz" for p in shown[:3])
            text += (f"; spectral peak at {peaks}: a periodic component (vibration, "
                     "propeller, a control limit cycle)")
        if d.drift_significant:
            text += "; a drift over the flight: a bias or a derivative that changes"
        lines.append(text + ".")
    return lines


GLOSSARY: Mapping[str, str] = {
    "equation error": "measured coefficient minus the model's prediction from the measured "
                      "regressors, sample by sample (no integration)",
    "held-out data": "the tail of the flight (the last 30 % by default), which no fit, test "
                     "or choice of effect saw; every before/after error is read there",
    "PSE": "prediction squared error: the mean square equation error on data the fit did "
           "not see; the held-out gain is its relative reduction over the blocked folds",
    "blocked folds": "the training part cut into contiguous blocks (five by default); each "
                     "is predicted by a fit on the others (cross-validation that does not "
                     "leak correlated neighbours)",
    "noise floor": "the held-out equation error that the sensor noise alone gives a model "
                   "that lacks nothing, from the noise estimated from the data; an error "
                   "at the floor has nothing left to explain",
    "excess explained": "share of the error above the noise floor an update removed, "
                        "(before^2 - after^2) / (before^2 - floor^2)",
    "BCLS": "bias-compensated least squares: the normal equations minus the expected "
            "moments of the regressor noise, so noisy air data do not shrink the "
            "derivatives (errors in variables)",
    "p-value": "partial F-test of the candidate's columns with the effective sample size; "
               "small values favour the candidate (the level it must reach, corrected for "
               "the number of candidates, is in docs/main_job.md)",
    "delta BIC": "change of the Bayesian information criterion with the candidate; "
                 "negative favours it",
    "effective sample size": "the number of independent samples a correlated residual is "
                             "worth (N over its integrated autocorrelation time)",
    "white residual": "a residual whose samples are uncorrelated (Ljung-Box test)",
    "near tie": f"another candidate within {NEAR_TIE_MARGIN:.0%} of the accepted one's "
                "held-out gain on the same coefficient: the flight cannot tell the two "
                "apart",
    "alias": "a term of another physical origin (a baseline term or another candidate) "
             "whose column moves with an accepted effect's on this flight (|corr| above "
             "0.95 beyond the rest of the model): the flight cannot say which of the two it "
             "saw",
    "family": "an accepted effect with its aliases and near ties, named by the axes it acts "
              "on (a drag-axis family): the finding is one of its members",
    "catalog value": "the derivative as the aircraft's parameter set gives it, the model "
                     "the flight is compared with",
    "VIF": "variance inflation factor: how much the correlation of a regressor with the "
           "others inflates its derivative's variance (1: none)",
    "reconstruction MAE": "mean absolute error of the outputs integrated with the model "
                          "(output error), reset to the measurement every few seconds",
}
"""Term -> one-line definition, in the order the report lists them."""
