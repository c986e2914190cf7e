"""The main job's report: effects found, errors before and after, figures, parameters.

:func:`write_report` turns an :class:`~drake_uav.identification.pipeline.IdentificationRun`
into a report folder (``report.md``, ``report.html``, figures, ``summary.json``),
written atomically. The report explains itself: every held-out error stands next to its
noise floor (:mod:`~drake_uav.identification.assessment.noise_floor`), implausible, correlated and
unexcited derivatives are warned about (:mod:`~drake_uav.identification.discovery.plausibility`,
:mod:`~drake_uav.identification.assessment.identifiability`), the catalog values stand beside the
identified ones, near-tied alternatives are named, every round of the search is listed and
a glossary closes it (:mod:`~drake_uav.reporting.explanations`).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from drake_uav.diagrams.manoeuvre_design import (
    COMMAND_CSV,
    ManoeuvreDesign,
    command_csv,
    turn_bank,
)
from drake_uav.identification.assessment.near_ties import NEAR_TIE_MARGIN, accepted_evidence
from drake_uav.identification.assessment.noise_floor import NoiseFloor
from drake_uav.identification.discovery.plausibility import DerivativeWarning
from drake_uav.identification.discovery.result import Evidence
from drake_uav.identification.pipeline import RECONSTRUCTED_OUTPUTS as _OUTPUTS
from drake_uav.identification.pipeline import IdentificationRun
from drake_uav.identification.propulsion import THROTTLE_TERM_UNITS, THRUST_COLUMN
from drake_uav.model.coefficients import SIGNALS
from drake_uav.reporting import explanations, figures
from drake_uav.reporting.report import Report
from drake_uav.systems.excitation import Turn

__all__ = ["write_report", "result_warnings", "what_to_fly_next", "ROUND_ROWS"]

_IMU = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r")
"""The channels the coefficients are measured from: their residuals' spectra end at these
channels' native Nyquist frequency."""

_OUTPUT_UNITS = {"airspeed": "m/s", "alpha": "deg", "beta": "deg", "p": "deg/s", "q": "deg/s",
                 "r": "deg/s"}

ROUND_ROWS = 12
"""Rows of each round's table: every candidate that passed, then the strongest others."""

_AT_FLOOR = 1.1
"""A held-out error within 10 % of its noise floor is read as at the floor (the noise
estimated from the data is good to about that)."""


def write_report(run: IdentificationRun, out_dir: str | Path,
                 next_manoeuvre: ManoeuvreDesign | None = None) -> Path:
    """Writes the report folder for ``run``; returns its path.

    The report formats what the run holds; ``summary.json`` is :meth:`IdentificationRun.
    summary` (with the folder's own keys), and ``what_to_fly_next``
    (:func:`what_to_fly_next`) when a manoeuvre is proposed or the log's rates leave terms
    unidentified.

    Parameters
    ----------
    run : IdentificationRun
        The main job's result.
    out_dir : str or Path
        The report folder (replaced atomically).
    next_manoeuvre : ManoeuvreDesign, optional
        The manoeuvre proposed for the run's near ties
        (:func:`~drake_uav.diagrams.manoeuvre_design.propose_manoeuvre`): the section
        "What to fly next" shows it and the folder holds its command file
        (:data:`~drake_uav.diagrams.manoeuvre_design.COMMAND_CSV`).

    Returns
    -------
    Path
        The folder written.
    """
    report = Report(f"Identification report: {run.params.name}")
    d = run.discovery
    report.add_text(
        f"Source: `{run.source}`, {len(run.samples)} samples, held-out data from "
        f"t = {d.holdout_start:.1f} s.\n\n**Result: {d.message}.**")
    _add_data(report, run)
    _add_compatibility(report, run)
    _add_rate_limits(report, run)
    _add_effects(report, run)
    _add_errors(report, run, run.noise_floors)
    _add_warnings(report, run.derivative_warnings)
    _add_figures(report, run, run.noise_floors)
    _add_residual_meaning(report, run)
    report.add_key_values(run.coefficient_sigma, caption="Monte-Carlo standard deviation of "
                          "the measured force coefficients (Vaiopoulos 2017, sec. 5.6) [-]")
    _add_parameters(report, run)
    _add_next_flight(report, run, next_manoeuvre)
    _add_rounds(report, run)
    _add_glossary(report)
    files, summary = {}, run.summary()
    if next_manoeuvre is not None or run.rate_limits:
        summary["what_to_fly_next"] = what_to_fly_next(run, next_manoeuvre)
    if next_manoeuvre is not None:
        files[COMMAND_CSV] = command_csv(next_manoeuvre)
    return report.write(out_dir, summary, files)


def what_to_fly_next(run: IdentificationRun, design: ManoeuvreDesign | None) -> dict:
    """``summary.json``'s ``what_to_fly_next``: the proposed manoeuvre and the log rates.

    Parameters
    ----------
    run : IdentificationRun
        The main job's result.
    design : ManoeuvreDesign or None
        The manoeuvre proposed for its near ties.

    Returns
    -------
    dict
        ``manoeuvre`` (:meth:`ManoeuvreDesign.summary` with its ``command_file``; None
        without one) and ``log_rates`` (each term not identifiable at the logged rates with
        the rate it needs [Hz], from ``not_identifiable_at_logged_rates``).
    """
    return {"manoeuvre": None if design is None
            else design.summary() | {"command_file": COMMAND_CSV},
            "log_rates": [{"term": r.term, "channel": r.channel,
                           "needed_rate_hz": r.needed_rate_hz} for r in run.rate_limits]}


def _add_next_flight(report: Report, run: IdentificationRun,
                     design: ManoeuvreDesign | None) -> None:
    """What to fly next: the manoeuvre that separates the near ties, and the rates to log."""
    if design is None and not run.rate_limits:
        return
    report.add_heading("What to fly next")
    lines = []
    if design is not None:
        peaks = design.summary()["peaks"]
        lines.append(
            f"A {design.duration:.0f} s manoeuvre of orthogonal multisines (Morelli 2003) "
            f"that separates the near ties: `{COMMAND_CSV}` in this folder holds its commands "
            "(time [s], then each input's trim plus its signal, in rad or a throttle "
            "fraction). Inputs that move the columns telling the rivals apart, flown at "
            f"their limit: {', '.join(design.selected) or 'none'}; peaks "
            + ", ".join(f"{k} {v:.3g}" for k, v in peaks.items())
            + ". Predicted on the identified model, each rival taken as the truth with the "
            "size this flight gave it: the share of its held-out gain the other would reach "
            f"(a near tie from {1 - NEAR_TIE_MARGIN:.0%}), the correlation of their columns "
            "after the baseline, and the expected partial F-statistic of one against the "
            "other (about 1: no evidence either way; it grows with the length flown, so a "
            "long flight may give a large F to a pair the near-tie rule still ties; a pair is "
            "separated when the share falls below the tie and the F reaches what a powerful "
            "test needs):\n")
        lines += [f"- {s.sentence()}" for s in design.separations]
        if design.turn is not None:
            lines.append("\n" + _turn_sentence(design.turn, run))
    if run.rate_limits:
        lines.append("\nLog the channels of 'Not identifiable at the logged rates' at the "
                     "rates given there: "
                     + ", ".join(f"{r.channel} at {r.needed_rate_hz:.3g} Hz for {r.term}"
                                 for r in run.rate_limits) + ".")
    report.add_text("\n".join(lines))


def _turn_sentence(turn: Turn, run: IdentificationRun) -> str:
    """How the manoeuvre's steady turn is flown: its rate and the bank it needs."""
    airspeed = float(np.median(run.samples.condition.airspeed))
    bank = math.degrees(turn_bank(turn, airspeed))
    return ("The manoeuvre is flown in a steady turn (a rival depends on the heading or the "
            "attitude, which a straight flight does not move): the heading turns at "
            f"{math.degrees(turn.rate):.1f} deg/s from {turn.start:g} s to {turn.end:g} s, "
            f"about {bank:.0f} deg of bank at {airspeed:.1f} m/s; the autopilot's heading hold "
            "follows the `heading_rad` column (the change from the heading at the start) while "
            "the surfaces play theirs.")


def result_warnings(run: IdentificationRun) -> list[str]:
    """The report's warnings that change what the result means, one line each, for the
    console: what was done to the data (glitches drawn over, an estimate not used:
    :attr:`IdentificationRun.warnings`), each implausible derivative, and how many
    derivatives the flight moved together or did not excite."""
    found = run.derivative_warnings
    lines = list(run.warnings) + [w.message for w in found if w.kind == "implausible"]
    others = {kind: sum(w.kind == kind for w in found) for kind in ("correlated", "unexcited")}
    if any(others.values()):
        lines.append(", ".join(f"{n} {kind}" for kind, n in others.items() if n)
                     + " derivative warning(s): see the report's Warnings on the derivatives")
    return lines


def _add_data(report: Report, run: IdentificationRun) -> None:
    """Which parts of the log were used and where the air data came from."""
    if run.data is None:
        return
    report.add_heading("Data used")
    report.add_text("\n".join([f"- **Warning:** {w}" for w in run.warnings]
                              + [f"- {note}" for note in run.notes]))


def _add_compatibility(report: Report, run: IdentificationRun) -> None:
    """The data-compatibility check: each calibration error, and what was corrected."""
    if run.compatibility is None:
        return
    report.add_heading("Data compatibility")
    applied = run.compatibility.applied
    head = ("Corrected before fitting: " + ", ".join(e.name for e in applied) + "."
            if applied else "No significant calibration error: the log was used as logged.")
    report.add_text(f"{head} Sensor biases, scale factors and time skews from the "
                    "redundancy of IMU, attitude, GPS, baro and air data (flight-path "
                    "reconstruction; docs/compatibility.md):\n\n"
                    + "\n".join(f"- {line}" for line in run.compatibility.lines()))


def _add_rate_limits(report: Report, run: IdentificationRun) -> None:
    """The terms the log's native rates cannot support, with the rates they need."""
    if not run.rate_limits:
        return
    report.add_heading("Not identifiable at the logged rates")
    report.add_text(
        "Each channel is judged on the rate it was logged at, not on the grid the analysis "
        "resamples it onto. The effects below were not tested, the calibration errors not "
        "claimed, and the derivatives are not fitted: the identified model keeps their "
        "catalog values (docs/logged_rates.md). A coefficient these terms act on may show a "
        "held-out error above its noise floor: the slow channels lose the band the terms act "
        "in, so neither the catalog values nor any fitted ones would match the measured "
        "coefficient there; the reconstruction, which integrates the model, is the check. "
        "Log the channels at the rates given.")
    report.add_table([
        {"term": r.term, "what": r.what, "channel": r.channel,
         "logged [Hz]": r.native_rate_hz, "needed [Hz]": r.needed_rate_hz, "why": r.reason}
        for r in run.rate_limits], formats={"logged [Hz]": ".3g", "needed [Hz]": ".3g"})


def _add_effects(report: Report, run: IdentificationRun) -> None:
    """The effects found, with their strongest evidence, explanation and near ties."""
    report.add_heading("Effects found")
    if not run.discovery.found:
        report.add_text("No candidate effect passed the evidence tests: the baseline model "
                        "explains the data as well as any candidate.")
    else:
        report.add_table([
            {"effect": f.name, "kind": f.kind, "coefficients": ", ".join(f.coefficients),
             "held-out PSE reduction": max(e.pse_reduction for e in f.evidence),
             "p-value": min(e.p_value for e in f.evidence), "explanation": f.explanation}
            for f in run.discovery.found],
            formats={"held-out PSE reduction": ".1%", "p-value": ".2g"})
    if run.families:
        report.add_text("**Families** (each finding with the alternatives this flight cannot "
                        "tell apart from it: terms of another origin whose columns move with "
                        "its own, and near ties):\n\n"
                        + "\n".join(f"- {f.sentence()}" for f in run.families))
    ties = run.near_ties
    if ties:
        report.add_text(
            "**Near-tied alternatives** (held-out gain within "
            f"{NEAR_TIE_MARGIN:.0%} of the accepted effect's):\n\n"
            + "\n".join(f"- {t.sentence()}" for t in ties))


def _reading(floor: NoiseFloor) -> str:
    """A few words on one coefficient's errors against its floor."""
    if floor.before <= _AT_FLOOR * floor.floor:
        return "at the noise floor: nothing to explain"
    if floor.after <= _AT_FLOOR * floor.floor:
        return "the update reached the noise floor"
    share = floor.excess_explained
    left = f"{floor.after_over_floor:.2g} x the floor left"
    if share <= 0.0:
        return f"unexplained, {left}"
    return f"{share:.0%} of the excess explained, {left}"


def _shown_share(floor: NoiseFloor) -> float | None:
    """The excess explained in [0, 1]; None when the error before is at the floor."""
    if floor.before <= _AT_FLOOR * floor.floor:
        return None
    return min(max(floor.excess_explained, 0.0), 1.0)


def _add_errors(report: Report, run: IdentificationRun, floors: dict[str, NoiseFloor]) -> None:
    """Equation-error RMS before and after with the noise floor; output-error MAE."""
    report.add_heading("Error before and after (held-out data)")
    report.add_table(
        [{"coefficient": k, "RMS before": f.before, "RMS after": f.after,
          "noise floor": f.floor, "change": (f.after - f.before) / f.before if f.before else 0.0,
          "excess explained": _shown_share(f),
          "reading": _reading(f)} for k, f in floors.items()],
        formats={"change": "+.1%", "excess explained": lambda v: "-" if v is None
                 else f"{v:.0%}"},
        caption="Equation error of the dimensionless coefficients [-]. Noise floor: the "
                "error the sensor noise estimated from the data gives a model that lacks "
                "nothing; excess explained: (before^2 - after^2) / (before^2 - floor^2), "
                "capped at 100 %; within 10 % of the floor counts as at the floor")
    before, after = run.reconstruction_before, run.reconstruction_after
    report.add_table([{"variable": f"{name} [{_OUTPUT_UNITS[name]}]",
                       "MAE before": b * (1.0 if name == "airspeed" else np.degrees(1.0)),
                       "MAE after": a * (1.0 if name == "airspeed" else np.degrees(1.0))}
                      for name, b, a in zip(_OUTPUTS, before.mae, after.mae, strict=True)],
                     caption="Output-error reconstruction (Vaiopoulos 2017, Table 11 reports "
                             "1.2 m/s, 0.87 deg, 0.52 deg on its flight); integrations "
                             f"restarted early after blowing up: {before.divergences} before, "
                             f"{after.divergences} after")


_WARNING_TITLES = {
    "implausible": "Implausible signs or magnitudes (ranges of "
                   "`drake_uav.identification.discovery.plausibility`, Beard & McLain 2012, ch. 4)",
    "correlated": "Regressors the flight moved together",
    "unexcited": "Derivatives the flight does not pin down",
}


def _add_warnings(report: Report, warnings: list[DerivativeWarning]) -> None:
    """The derivative warnings, grouped by kind."""
    report.add_heading("Warnings on the derivatives")
    if not warnings:
        report.add_text("None: every identified derivative is plausible, well excited and "
                        "not confounded with another.")
        return
    for kind, title in _WARNING_TITLES.items():
        lines = [w.message for w in warnings if w.kind == kind]
        if lines:
            report.add_text(f"**{title}:**\n\n" + "\n".join(f"- {m}" for m in lines))


def _add_figures(report: Report, run: IdentificationRun,
                 floors: dict[str, NoiseFloor]) -> None:
    """Held-out residuals, their whiteness and normality, and the reconstruction."""
    d = run.discovery
    test_time = run.samples.time[run.samples.time >= d.holdout_start]
    report.add_figure(lambda: figures.residual_time_series(
        test_time, {k: f.holdout_residual for k, f in d.baseline.items()},
        {k: f.holdout_residual for k, f in d.final.items()},
        floor={k: f.floor for k, f in floors.items()}), "Held-out residuals before "
        "(grey) and after (blue) the update, dashed: +- the noise floor", name="residuals")
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
        f"Reconstruction with periodic resets every {before.reset_interval:g} s (angles in "
        "deg, rates in deg/s)", name="reconstruction")


def _add_residual_meaning(report: Report, run: IdentificationRun) -> None:
    """What the whiteness of each residual says about the result."""
    report.add_heading("What the residuals say")
    lines = explanations.residual_meaning(
        {k: f.diagnosis for k, f in run.discovery.final.items()}, run.smoothing_correlation_time,
        None if run.logged_rates is None else run.logged_rates.nyquist(_IMU))
    report.add_text(explanations.RESIDUAL_MEANING + "\n\n"
                    + "\n".join(f"- {line}" for line in lines))


_UNIT = re.compile(r"\[([^\]]*)\]$")


def _derivative_unit(name: str) -> str:
    """Unit of a derivative: 1 / its regressor's unit (dimensionless for the constant and
    the normalised rates); a thrust term's own; "effect" for an effect's column (see the
    effect)."""
    if name.startswith(THRUST_COLUMN):
        return THROTTLE_TERM_UNITS[name.removeprefix(THRUST_COLUMN)]
    coefficient, _, signal = name.partition("_")
    if ":" in name or signal not in SIGNALS:
        return "effect"
    match = _UNIT.search(SIGNALS[signal])
    unit = match.group(1) if match else "-"
    return "-" if unit == "-" else f"1/{unit}"


def _add_parameters(report: Report, run: IdentificationRun) -> None:
    """One table per coefficient: estimate, sigma, catalog value and their distance; the
    baseline terms dropped, as 0."""
    report.add_heading("Identified parameters")
    catalog = run.params.derivatives
    report.add_text("Catalog: the aircraft's parameter set (`" + run.params.name + "`); "
                    "(estimate - catalog) / sigma measures how far the flight disagrees. "
                    "A catalog term marked *dropped* improved neither the held-out "
                    "prediction nor the extrapolation to the flight's edges: it is 0 in the "
                    "identified model (its figures: the notes under Data used, `dropped_terms` in "
                    "summary.json; docs/main_job.md, \"Baseline\"). C_D's `thrust:` rows, where "
                    "the thrust was identified from the flight: by how much that thrust exceeds "
                    "the one the data now give, per unit of each throttle term, fitted again "
                    "with the effects on the drag axis."
                    + (" A term marked *fixed: not at the logged rates* needs channels logged "
                       "faster than this log's (Not identifiable at the logged rates): it is "
                       "not fitted, and the identified model keeps its catalog value."
                       if run.rate_limits else ""))
    for k, fit in run.discovery.final.items():
        r = fit.result
        report.add_table(
            [{"parameter": n, "unit": _derivative_unit(n), "estimate": r.estimate[i],
              "sigma": r.sigma[i], "catalog": catalog.get(n),
              "(estimate - catalog) / sigma": (None if n not in catalog or not r.sigma[i]
                                               else (r.estimate[i] - catalog[n]) / r.sigma[i]),
              "t": r.t_statistic[i], "significant": bool(r.significant[i])}
             for i, n in enumerate(fit.names)]
            + [{"parameter": t.term, "unit": _derivative_unit(t.term), "estimate": 0.0,
                "catalog": catalog.get(t.term), "significant": "dropped"}
               for t in run.discovery.dropped.get(k, ())]
            + [{"parameter": n, "unit": _derivative_unit(n), "estimate": value,
                "catalog": catalog.get(n), "significant": "fixed: not at the logged rates"}
               for n, value in run.discovery.fixed.get(k, {}).items()],
            formats={"(estimate - catalog) / sigma": lambda v: "-" if v is None
                     else f"{v:+.1f}"},
            caption=f"{k} ({r.method}, R^2 = {r.r_squared:.3f})")


def _evidence_row(e: Evidence, accepted: bool) -> dict:
    return {"effect": e.effect, "coefficient": e.coefficient, "held-out gain": e.pse_reduction,
            "folds improved": e.folds_improved, "p-value": e.p_value,
            "delta BIC": e.delta_bic, "passed": bool(e.passed), "accepted": accepted}


def _add_rounds(report: Report, run: IdentificationRun) -> None:
    """A table per round of the search: every candidate that passed, the strongest others."""
    report.add_heading("Every round of the search")
    accepted = accepted_evidence(run.discovery)
    for index, evidence in enumerate(run.discovery.rounds):
        passed = [e for e in evidence if e.passed]
        shown = passed + [e for e in evidence if not e.passed][:max(ROUND_ROWS - len(passed),
                                                                    0)]
        if not evidence:
            report.add_heading(f"Round {index + 1}: no candidate left to test", level=3)
            continue
        winners = sorted({e.effect for e in evidence if e in accepted})
        outcome = (f"accepted {', '.join(winners)}" if winners else
                   "nothing accepted: the search stopped")
        report.add_heading(f"Round {index + 1}: {outcome}", level=3)
        hidden = len(evidence) - len(shown)
        report.add_table(
            [_evidence_row(e, e in accepted) for e in shown],
            formats={"held-out gain": "+.2%", "p-value": ".2g", "delta BIC": ".1f"},
            caption=f"{len(evidence)} candidates tested, {len(passed)} passed"
                    + (f"; {hidden} weaker ones not shown (all in summary.json)"
                       if hidden else ""))


def _add_glossary(report: Report) -> None:
    report.add_heading("Glossary")
    report.add_text("\n".join(f"- **{term}:** {text}"
                              for term, text in explanations.GLOSSARY.items()))
