"""Decisions of the discovery loop that cannot contradict the held-out data: an effect is
kept on a coefficient only where it does not worsen the held-out error and where its
contribution matters; a coefficient that does not vary is skipped with a note;
``--coefficients`` chooses them."""

import dataclasses
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from synthetic_flight import synthetic_samples

import drake_uav
from drake_uav.cli import main
from drake_uav.diagrams import fly
from drake_uav.identification.discovery.loop import check_coefficients, discover
from drake_uav.identification.discovery.result import NO_EFFECT_MESSAGE, EvidenceRule
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.testing.discovery_cases import measured_only
from drake_uav.vehicles.loading import load_fixed_wing
from drake_uav.vehicles.sensors import SensorSuiteParams

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
LATERAL_CHANNELS = ("imu_ay", "imu_p", "imu_r", "vane_beta", "att_roll", "cmd_aileron",
                    "cmd_rudder")


def _with_increment(samples, coefficient, values):
    """``samples`` whose measured ``coefficient`` has ``values`` added (an effect put into
    the data directly, where the test needs one the physics cannot give)."""
    coefficients = dict(samples.coefficients)
    coefficients[coefficient] = coefficients[coefficient] + values
    return dataclasses.replace(samples, coefficients=coefficients)


def test_negligible_effects_of_noiseless_data_are_never_found():
    """Exact sensors: the smoothing leaves an equation error of about 1e-5, and terms that
    move a coefficient by 1e-6..1e-5 pass every statistical test. None matters: each is far
    below 1 % of the coefficient's variation over the flight."""
    params, samples, _ = synthetic_samples(seed=101, duration=60.0, noise=False)
    without_the_rule = discover(samples, params, rule=EvidenceRule(
        min_share_of_variation=0.0, min_share_of_error=0.0))
    assert without_the_rule.found  # the case is one where the rule decides
    result = discover(samples, params)
    assert result.message == NO_EFFECT_MESSAGE, result.message
    rejected = [c for c in result.checks if not c.kept]
    assert rejected
    for check in rejected:
        scale = np.std(samples.coefficients[check.coefficient])
        assert check.contribution < 0.01 * scale, check
        assert check.threshold >= 0.01 * scale
        assert check.reason  # the contribution, or the held-out error rising first
    assert any("contribution" in c.reason for c in rejected)
    # The notes: the baseline terms dropped (identification.parsimony), then every rejection.
    assert list(result.notes) == [t.line for terms in result.dropped.values() for t in terms] \
        + [f"{c.effect} not kept on {c.coefficient}: {c.reason}" for c in rejected]


def test_an_effect_must_also_hold_against_the_pruned_model_the_report_gives():
    """A clean flight isolated at 100 Hz (seed 508, default sensors): against the catalog's
    whole C_Y structure an accelerometer lever arm of about 1 cm halves the held-out error,
    but the flight does not support C_Y_p, C_Y_r and the aileron term, and against the model
    without them (the one reported) its contribution is below what matters: it is dropped."""
    params = load_fixed_wing("aerosonde")
    flight = fly(params, "light", seed=508, duration=120.0,
                 sensors=SensorSuiteParams.seed_table7(air_density=params.rho))
    log = measured_only(flight)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = identify(log, params, rate_hz=100.0, seed=508)
    assert list(run.findings) == []
    pruned = {t.term for t in run.discovery.dropped["CY"]}
    assert {"CY_p", "CY_r", "CY_aileron"} <= pruned
    lever = [c for c in run.discovery.checks if c.effect == "accelerometer_lever_arm"]
    assert [(c.coefficient, c.stage, c.kept) for c in lever] == [("CY", "round", True),
                                                                ("CY", "final", False)]
    round_check, final_check = lever
    assert round_check.rms_with < 0.6 * round_check.rms_without
    assert final_check.rms_with > 0.95 * final_check.rms_without
    assert "contribution" in final_check.reason


def test_an_effect_that_worsens_one_held_out_error_is_kept_only_on_the_others():
    """Propwash lift over the whole flight, propwash drag only in the training part: the
    effect passes the evidence tests on both, but on C_D it makes the held-out error worse."""
    params, samples, _ = synthetic_samples(seed=101, duration=60.0)
    n = len(samples)
    tc = samples.condition.thrust_coefficient
    training = np.arange(n) < int(round(0.7 * n))
    data = _with_increment(_with_increment(samples, "CL", 0.3 * tc), "CD",
                           0.05 * tc * training)
    result = discover(data, params)
    assert [(f.name, f.coefficients) for f in result.found] == [("thrust_propwash", ("CL",))]
    assert [e.coefficient for e in result.found[0].evidence] == ["CL"]
    assert set(result.found[0].parameters) == {"CL:Tc"}
    on_cd = [c for c in result.checks if c.effect == "thrust_propwash" and c.coefficient == "CD"]
    assert len(on_cd) == 1 and not on_cd[0].kept
    assert on_cd[0].rms_with > on_cd[0].rms_without
    assert "thrust_propwash not kept on CD: its held-out error rises" in "\n".join(result.notes)
    before, after = result.rms_change()["CD"]
    assert after == pytest.approx(before)  # C_D keeps its baseline fit
    for k, (before, after) in result.rms_change().items():
        assert after <= before, k


def test_an_effect_the_final_fit_no_longer_needs_is_dropped():
    """Lift growing with (Tc - mean)^2: the first round takes stall_onset as a stand-in;
    once the Tc^2 product and the Tc term are in, it changes the held-out prediction by
    less than a tenth of the error left and is dropped."""
    params, samples, _ = synthetic_samples(seed=102, duration=60.0)
    tc = samples.condition.thrust_coefficient
    result = discover(_with_increment(samples, "CL", 0.5 * (tc - tc.mean()) ** 2), params)
    found = {f.name: f.coefficients for f in result.found}
    assert found == {"data_driven:Tc*Tc": ("CL",), "thrust_propwash": ("CL",)}, found
    assert [(c.effect, c.stage, c.kept) for c in result.checks
            if c.effect == "stall_onset"] == [("stall_onset", "round", True),
                                              ("stall_onset", "final", False)]
    assert not any(n.startswith("stall_onset") for n in result.final["CL"].names)


@pytest.fixture(scope="module")
def longitudinal_log(tmp_path_factory):
    """The first 90 s of the bundled flight with every lateral channel held at zero: a
    purely longitudinal log, whose C_Y, C_l and C_n are identically zero."""
    log = FlightLog.load(SAMPLE).slice(0.0, 90.0)
    channels = {n: np.array(log[n], dtype=float) for n in log.measured_names}
    for name in LATERAL_CHANNELS:
        channels[name][:] = 0.0
    channels["att_yaw"][:] = channels["att_yaw"][0]
    path = tmp_path_factory.mktemp("longitudinal") / "glide.csv"
    FlightLog(log.time, channels, units=log.units).save(path)
    return path


def test_a_longitudinal_log_skips_the_lateral_coefficients_with_a_note(longitudinal_log,
                                                                       tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["identify", str(longitudinal_log), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    for k in ("CY", "Cl", "Cn"):
        assert f"note: {k} skipped: it does not vary over the flight" in printed
        assert any(note.startswith(f"{k} skipped") for note in summary["data"]["notes"])
        assert f"  {k}: equation-error RMS" not in printed
    assert set(summary["parameters"]) == set(summary["equation_error_rms_holdout"]) == {
        "CL", "CD", "Cm"}
    assert "skipped" in (out / "report.md").read_text()


def test_coefficients_restrict_the_fit(longitudinal_log, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["identify", str(longitudinal_log), "--out", str(out),
                 "--coefficients", "Cm, CL,Cm"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["parameters"]) == ["CL", "Cm"]  # model order, each once
    assert "skipped" not in printed  # the lateral ones were not asked for
    for effect in summary["effects"]:
        assert set(effect["coefficients"]) <= {"CL", "Cm"}


def test_the_python_api_chooses_and_checks_the_coefficients():
    params, samples, _ = synthetic_samples(seed=101, duration=40.0)
    result = discover(samples, params, coefficients=("Cm", "CL"), fallback=False)
    assert list(result.final) == list(result.baseline) == ["CL", "Cm"]
    assert not result.skipped
    for bad in (("CL", "cx"), (), "CL"):
        with pytest.raises(ValueError, match="coefficient"):
            discover(samples, params, coefficients=bad)
    flat = _with_increment(samples, "Cn", -samples.coefficients["Cn"] + 0.01)
    result = discover(flat, params, coefficients=("Cn", "Cm"), fallback=False)
    assert list(result.final) == ["Cm"] and set(result.skipped) == {"Cn"}
    assert result.notes[0].startswith("Cn skipped: it does not vary over the flight")
    with pytest.raises(ValueError, match="nothing to identify"):
        discover(flat, params, coefficients=("Cn",))


@pytest.mark.parametrize("value, message", [
    ("CL,cx", "--coefficients CL,cx: unknown cx;"),
    ("cl", "--coefficients cl: unknown cl;"),
    (",", "--coefficients ,: expected names of CL,CD,CY,Cl,Cm,Cn"),
])
def test_bad_coefficients_fail_fast_without_a_traceback(value, message, tmp_path):
    """Checked before the analysis stack loads: exit 2, one line, no report."""
    log = tmp_path / "flight.bin"
    log.write_bytes(b"\xa3\x95\x80")
    out = tmp_path / "out"
    code = ("import sys; from drake_uav.cli import main; "
            f"rc = main(['identify', {str(log)!r}, '--out', {str(out)!r}, "
            f"'--coefficients', {value!r}]); print(rc, 'pydrake' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.split() == ["2", "False"], done
    assert message in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_the_cli_coefficient_names_are_the_models():
    from drake_uav.cli import _COEFFICIENTS
    from drake_uav.model.coefficients import COEFFICIENTS

    assert _COEFFICIENTS == COEFFICIENTS
    check_coefficients(COEFFICIENTS)
