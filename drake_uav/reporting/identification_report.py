"""The main job's report: effects found, errors before and after, figures, parameters.

:func:`write_report` turns an :class:`~drake_uav.identification.main_job.IdentificationRun`
into a report folder (``report.md``, ``report.html``, figures, ``summary.json``),
written atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_uav.identification.main_job import RECONSTRUCTED_OUTPUTS as _OUTPUTS
from drake_uav.identification.main_job import IdentificationRun
from drake_uav.reporting import figures
from drake_uav.reporting.report import Report

__all__ = ["write_report"]

_OUTPUT_UNITS = {"airspeed": "m/s", "alpha": "deg", "beta": "deg", "p": "deg/s", "q": "deg/s",
                 "r": "deg/s"}


def write_report(run: IdentificationRun, out_dir: str | Path) -> Path:
    """Writes the report folder for ``run``; returns its path."""
    report = Report(f"Identification report: {run.params.name}")
    d = run.discovery
    report.add_text(
        f"Source: `{run.source}`, {len(run.samples)} samples, held-out data from "
        f"t = {d.holdout_start:.1f} s.\n\n**Result: {d.message}.**")
    _add_data(report, run)
    _add_effects(report, run)
    _add_errors(report, run)
    _add_figures(report, run)
    report.add_key_values(run.coefficient_sigma, caption="Monte-Carlo standard deviation of "
                          "the measured force coefficients (Vaiopoulos 2017, sec. 5.6)")
    _add_parameters(report, run)
    _add_evidence(report, run)
    return report.write(out_dir, run.summary())


def _add_data(report: Report, run: IdentificationRun) -> None:
    """Which parts of the log were used and where the air data came from."""
    if run.data is None:
        return
    report.add_heading("Data used")
    report.add_text("\n".join(f"- {note}" for note in run.notes))


def _add_effects(report: Report, run: IdentificationRun) -> None:
    """The effects found, with their strongest evidence and explanation."""
    report.add_heading("Effects found")
    if not run.discovery.found:
        report.add_text("No candidate effect passed the evidence tests: the baseline model "
                        "explains the data as well as any candidate.")
        return
    report.add_table([
        {"effect": f.name, "kind": f.kind, "coefficients": ", ".join(f.coefficients),
         "held-out PSE reduction": max(e.pse_reduction for e in f.evidence),
         "p-value": min(e.p_value for e in f.evidence), "explanation": f.explanation}
        for f in run.discovery.found], formats={"held-out PSE reduction": ".1%", "p-value": ".2g"})


def _add_errors(report: Report, run: IdentificationRun) -> None:
    """Equation-error RMS and output-error MAE before and after, on the held-out data."""
    report.add_heading("Error before and after (held-out data)")
    report.add_table([{"coefficient": k, "RMS before": b, "RMS after": a,
                       "change": (a - b) / b if b else 0.0}
                      for k, (b, a) in run.discovery.rms_change().items()],
                     formats={"change": "+.1%"})
    before, after = run.reconstruction_before, run.reconstruction_after
    report.add_table([{"variable": f"{name} [{_OUTPUT_UNITS[name]}]",
                       "MAE before": b * (1.0 if name == "airspeed" else np.degrees(1.0)),
                       "MAE after": a * (1.0 if name == "airspeed" else np.degrees(1.0))}
                      for name, b, a in zip(_OUTPUTS, before.mae, after.mae, strict=True)],
                     caption="Output-error reconstruction (Vaiopoulos 2017, Table 11 reports "
                             "1.2 m/s, 0.87 deg, 0.52 deg on its flight); integrations "
                             f"restarted early after blowing up: {before.divergences} before, "
                             f"{after.divergences} after")


def _add_figures(report: Report, run: IdentificationRun) -> None:
    """Held-out residuals, their whiteness and normality, and the reconstruction."""
    d = run.discovery
    test_time = run.samples.time[run.samples.time >= d.holdout_start]
    report.add_figure(lambda: figures.residual_time_series(
        test_time, {k: f.holdout_residual for k, f in d.baseline.items()},
        {k: f.holdout_residual for k, f in d.final.items()}), "Held-out residuals before "
        "(grey) and after (blue) the update", name="residuals")
    report.add_figure(lambda: figures.autocorrelation_plot(
        {k: f.diagnosis for k, f in d.final.items()}), "Residual autocorrelation after the "
        "update, with 95% bounds", name="autocorrelation")
    report.add_figure(lambda: figures.normal_probability_plot(
        {k: f.diagnosis for k, f in d.final.items()}), "Normal probability plots of the "
        "residuals after the update", name="normal_probability")
    before, after = run.reconstruction_before, run.reconstruction_after
    report.add_figure(lambda: figures.reconstruction_plot(
        before.time, dict(zip(_OUTPUTS, before.measured.T, strict=True)),
        dict(zip(_OUTPUTS, before.reconstructed.T, strict=True)),
        dict(zip(_OUTPUTS, after.reconstructed.T, strict=True)),
        units=_OUTPUT_UNITS, degrees=("alpha", "beta", "p", "q", "r")),
        f"Reconstruction with periodic resets every {before.reset_interval:g} s",
        name="reconstruction")


def _add_parameters(report: Report, run: IdentificationRun) -> None:
    """One table of estimates, sigmas and t statistics per coefficient fit."""
    report.add_heading("Identified parameters")
    for k, fit in run.discovery.final.items():
        r = fit.result
        report.add_table([{"parameter": n, "estimate": r.estimate[i], "sigma": r.sigma[i],
                           "t": r.t_statistic[i], "significant": bool(r.significant[i])}
                          for i, n in enumerate(fit.names)],
                         caption=f"{k} ({r.method}, R^2 = {r.r_squared:.3f})")


def _add_evidence(report: Report, run: IdentificationRun) -> None:
    """The first discovery round's 25 strongest candidates (passed first, then by PSE drop)."""
    report.add_heading("Evidence of every candidate (first round)")
    if not run.discovery.rounds:
        return
    report.add_table([{"effect": e.effect, "coefficient": e.coefficient,
                       "PSE reduction": e.pse_reduction, "folds improved": e.folds_improved,
                       "p-value": e.p_value, "delta BIC": e.delta_bic, "passed": e.passed}
                      for e in run.discovery.rounds[0][:25]],
                     formats={"PSE reduction": "+.2%", "p-value": ".2g", "delta BIC": ".1f"})
