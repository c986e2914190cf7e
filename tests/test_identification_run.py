"""The main job's result: the structure of ``IdentificationRun.summary()`` (summary.json)."""

import dataclasses
import json

import pytest
from synthetic_flight import synthetic_samples

from drake_uav.identification.pipeline import RECONSTRUCTED_OUTPUTS, identify_samples
from drake_uav.reporting.identification_report import write_report
from drake_uav.reporting.report import json_ready

RUN_KEYS = {"source", "aircraft", "data", "message", "findings", "samples", "holdout_start_s",
            "effects", "equation_error_rms_holdout", "reconstruction_mae_holdout",
            "reconstruction_divergences", "measured_coefficient_sigma_monte_carlo",
            "parameters", "dropped_terms", "warnings", "near_ties", "families", "rounds",
            "not_identifiable_at_logged_rates"}
EFFECT_KEYS = {"name", "kind", "explanation", "coefficients", "evidence", "parameters"}


@pytest.fixture(scope="module")
def run():
    """A 40 s flight whose lift bends with alpha^3: the loop finds one effect."""
    params, samples, _ = synthetic_samples(
        increment=lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0), seed=2, duration=40.0)
    return identify_samples(samples, params, source="synthetic")


def test_summary_has_each_run_level_key_once_and_effects_only_their_own(run):
    summary = run.summary()
    assert set(summary) == RUN_KEYS
    assert [e["name"] for e in summary["effects"]] == ["stall_onset"]
    assert summary["findings"] == ["stall_onset"]
    for effect in summary["effects"]:
        assert set(effect) == EFFECT_KEYS
        assert effect["coefficients"] == ["CL"]
        assert set(effect["parameters"]) == {"CL:alpha3", "CL:alpha4"}
        assert all(e["coefficient"] == "CL" for e in effect["evidence"])
    assert summary["reconstruction_divergences"] == {
        "before": run.reconstruction_before.divergences,
        "after": run.reconstruction_after.divergences}
    assert set(summary["measured_coefficient_sigma_monte_carlo"]) == {"CL", "CD", "CY"}
    assert set(summary["reconstruction_mae_holdout"]) == set(RECONSTRUCTED_OUTPUTS)
    assert set(summary["parameters"]) == set(summary["equation_error_rms_holdout"]) == {
        "CL", "CD", "CY", "Cl", "Cm", "Cn"}
    assert summary["parameters"]["CL"]["stall_onset:alpha3"]["significant"]
    # A baseline term the flight does not support: 0 in the parameters, its figures apart.
    dropped = run.discovery.dropped
    assert dropped and summary["dropped_terms"] == {
        k: [dataclasses.asdict(t) for t in terms] for k, terms in dropped.items()}
    for k, terms in dropped.items():
        for t in terms:
            assert summary["parameters"][k][t.term] == {
                "estimate": 0.0, "sigma": 0.0, "significant": False, "dropped": True,
                "catalog": run.params.derivatives.get(t.term)}
            assert t.term not in run.discovery.final[k].names
    text = json.dumps(summary, default=lambda value: value.item())  # numpy scalars
    assert text.count('"reconstruction_divergences"') == 1
    assert text.count('"measured_coefficient_sigma_monte_carlo"') == 1


def test_summary_json_is_exactly_the_run_summary(run, tmp_path):
    """The report adds only its folder's keys: every figure of summary.json is the run's."""
    out = write_report(run, tmp_path / "report")
    written = json.loads((out / "summary.json").read_text())
    assert written.pop("complete") is True
    assert written.pop("report_title").startswith("Identification report")
    assert set(written.pop("report_files")) >= {"report.md", "report.html"}
    assert written == json.loads(json.dumps(json_ready(run.summary())))


def test_the_run_holds_what_the_report_prints(run):
    """Noise floors, derivative warnings and near ties are the run's, one per coefficient
    fitted, the figures of its summary."""
    summary = run.summary()
    assert set(run.noise_floors) == set(run.discovery.final)
    for k, floor in run.noise_floors.items():
        entry = summary["equation_error_rms_holdout"][k]
        assert entry["before"] == floor.before and entry["after"] == floor.after
    assert summary["warnings"] == [dataclasses.asdict(w) for w in run.derivative_warnings]
    assert summary["near_ties"] == [t.summary() for t in run.near_ties]
    assert run.noise_floors is run.noise_floors  # computed once
