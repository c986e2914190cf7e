"""The main job's report explains itself: noise floors, derivative warnings, catalog values,
near ties, what the residuals say, a glossary, units, and every round of the search."""

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import savgol_coeffs
from synthetic_flight import NOISE, synthetic_flight

import drake_uav
from drake_uav.identification.assessment.identifiability import (
    correlated_regressors,
    unexcited_derivatives,
)
from drake_uav.identification.assessment.near_ties import near_ties
from drake_uav.identification.assessment.noise_floor import held_out_noise_floor
from drake_uav.identification.discovery.loop import discover
from drake_uav.identification.discovery.plausibility import implausible_derivatives
from drake_uav.identification.discovery.result import DiscoveryResult, Evidence, FoundEffect
from drake_uav.identification.pipeline import identify
from drake_uav.identification.samples.isolation import isolate_coefficients
from drake_uav.identification.statistics.residuals import diagnose
from drake_uav.io.flight_log import FlightLog
from drake_uav.reporting import explanations, figures
from drake_uav.reporting.identification_report import write_report
from drake_uav.vehicles.fixed_wing import aerosonde
from drake_uav.vehicles.loading import load_fixed_wing

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"


@pytest.fixture(scope="module")
def run():
    """The main job on the bundled sample flight."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sample's thrust/C_X confounding note
        return identify(FlightLog.load(SAMPLE), aerosonde(), source="sample")


@pytest.fixture(scope="module")
def report(run, tmp_path_factory):
    out = write_report(run, tmp_path_factory.mktemp("report") / "report")
    return (out / "report.md").read_text(), json.loads((out / "summary.json").read_text())


def _declared_noise_samples(increment, seed, duration):
    """(params, samples) of a synthetic flight whose sensor noise is declared exactly."""
    params, d = synthetic_flight(np.random.default_rng(seed), increment, duration)
    rng = np.random.default_rng(seed + 100)
    force = d["specific_force"] + rng.normal(0, NOISE["specific_force"], (len(d["time"]), 3))
    rates = d["state"][:, 10:13] + rng.normal(0, NOISE["rates"], (len(d["time"]), 3))
    air = d["air_data"] + rng.normal(0, 1, (len(d["time"]), 3)) * np.array(
        [NOISE["airspeed"], NOISE["angles"], NOISE["angles"]])
    variance = {"airspeed": NOISE["airspeed"] ** 2, "alpha": NOISE["angles"] ** 2,
                "beta": NOISE["angles"] ** 2,
                **{k: NOISE["rates"] ** 2 for k in ("p", "q", "r")},
                **{k: NOISE["specific_force"] ** 2 for k in ("ax", "ay", "az")}}
    u = d["controls"]
    samples = isolate_coefficients(
        params, d["time"], force, rates, air, u,
        moment_controls=np.vstack([0.5 * (u[1:] + u[:-1]), u[-1:]]),
        raw_noise_variance=variance,
        signals={"roll": d["euler"][:, 0], "pitch": d["euler"][:, 1],
                 "yaw": d["euler"][:, 2], "height": -d["state"][:, 2]})
    return params, samples


# ----------------------------------------------------------------------------- noise floor


def test_the_floor_is_the_propagated_noise_plus_the_noise_of_the_coefficient_alone(run):
    floors = held_out_noise_floor(run.samples, run.discovery, run.params)
    p = run.params
    n_test = len(run.discovery.final["CL"].holdout_residual)
    test = run.samples.subset(slice(len(run.samples) - n_test, len(run.samples)))
    h, d = savgol_coeffs(11, 3), savgol_coeffs(11, 3, deriv=1, delta=0.02)
    for k, fit in run.discovery.final.items():
        noise, theta = fit.holdout_noise, fit.result.estimate
        for s, J in noise.regressors.items():
            expected = noise.variance[s] * np.mean((noise.observation.get(s, 0.0) - J @ theta)
                                                   ** 2)
            assert floors[k].parts.get(s, 0.0) ** 2 == pytest.approx(expected, rel=1e-9)
        assert floors[k].floor ** 2 == pytest.approx(sum(v**2 for v in floors[k].parts.values()))
    # C_Y = m a_y / (qbar S): the lateral accelerometer's share in closed form.
    qs = test.dynamic_pressure * p.S
    assert floors["CY"].parts["ay"] ** 2 == pytest.approx(
        test.noise_variance["ay"] * np.mean((p.mass / qs) ** 2), rel=1e-9)
    # C_m = (Jy q_dot + ...) / (qbar S c): the pitch acceleration is the gyro's derivative.
    q_dot_variance = test.noise_variance["q"] / (h @ h) * (d @ d)
    m_view = test.aligned("Cm")
    assert floors["Cm"].parts["q_dot"] ** 2 == pytest.approx(
        q_dot_variance * np.mean((p.Jy / (m_view.dynamic_pressure * p.S * p.c)) ** 2),
        rel=1e-6)
    assert all(f.floor < f.before for f in (floors["CD"], floors["CL"], floors["Cm"]))


def test_a_model_that_lacks_nothing_sits_on_its_floor_and_an_update_reaches_it():
    """With the sensor noise declared exactly, held-out error / floor is 0.89-1.14 over
    seeds 0-5 of clean 40 s flights; a lift effect puts C_L at 1.8-2.2 x its floor."""
    params, clean = _declared_noise_samples(None, seed=1, duration=40.0)
    for k, f in held_out_noise_floor(clean, discover(clean, params), params).items():
        assert 0.85 < f.after / f.floor < 1.15, (k, f)
    stall = lambda c: (-30.0 * c.alpha**3, 0, 0, 0, 0, 0)  # noqa: E731
    params, samples = _declared_noise_samples(stall, seed=2, duration=40.0)
    result = discover(samples, params)
    assert [f.name for f in result.found] == ["stall_onset"]
    lift = held_out_noise_floor(samples, result, params)["CL"]
    assert lift.before > 1.5 * lift.floor
    assert lift.excess_explained > 0.85 and lift.after < 1.15 * lift.floor


# ----------------------------------------------------------------------------- warnings


def test_implausible_derivatives_are_named_and_the_catalog_passes():
    for name in ("aerosonde", "aerosonde_mavsim"):
        assert implausible_derivatives(load_fixed_wing(name).derivatives) == []
    # UnATRaP's printed C_Ybeta is positive (the catalog calls it doubtful).
    assert [w.derivatives for w in implausible_derivatives(
        load_fixed_wing("unatrap").derivatives)] == [("CY_beta",)]
    wrong = dict(aerosonde().derivatives, Cm_q=3.0, CL_q=62.7, CL_alpha=1.45, Cl_p=0.2,
                 Cm_alphadot=6.0, CL_alphadot=-3.0)
    named = [w.derivatives[0] for w in implausible_derivatives(wrong)]
    assert sorted(named) == ["CL_alpha", "CL_alphadot", "CL_q", "Cl_p", "Cm_alphadot", "Cm_q"]
    noisy = implausible_derivatives({"Cn_r": 0.01}, {"Cn_r": 0.05})[0].message
    sure = implausible_derivatives({"Cn_r": 0.5}, {"Cn_r": 0.05})[0].message
    assert "possibly noise" in noisy and "10.0 sigma outside" in sure


def test_the_report_warns_about_a_wrong_sign_catalog_value_not_about_the_right_one(
        run, tmp_path):
    plain = [w.message for w in run.derivative_warnings]
    assert not any(m.startswith("catalog:") for m in plain)
    unstable = dataclasses.replace(run, params=run.params.with_derivatives(Cm_alpha=0.4))
    messages = [w.message for w in unstable.derivative_warnings]
    assert [m for m in messages if m.startswith("catalog:")] == [
        m for m in messages if m.startswith("catalog: Cm_alpha = 0.4 is above")]
    assert any("statically unstable" in m for m in messages)
    out = write_report(unstable, tmp_path / "report")
    md = (out / "report.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert [w["message"] for w in summary["warnings"]] == messages
    assert all(set(w) == {"kind", "derivatives", "message"} for w in summary["warnings"])
    assert all(f"- {m}" in md for m in messages)


def test_correlated_and_unexcited_regressors_are_named():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 2000))
    X = np.column_stack([np.ones(2000), a, a + 0.05 * rng.normal(size=2000), b,
                         np.zeros(2000)])
    names = ["CL_0", "CL_alpha", "CL_q", "CL_elevator", "CL_flap"]
    pairs = [w.derivatives for w in correlated_regressors(names, X)]
    assert pairs == [("CL_alpha", "CL_q")]
    assert correlated_regressors([names[0], names[1], names[3]], X[:, [0, 1, 3]]) == []
    estimate = np.array([0.3, 4.0, 1.0, -0.4, 0.0])
    sigma = np.array([1.0, 0.1, 0.9, 0.05, 1.0])
    found = {w.derivatives[0]: w.message for w in unexcited_derivatives(names, X, estimate,
                                                                         sigma)}
    assert set(found) == {"CL_q", "CL_flap"}  # the constant term is no direction
    assert "does not vary" in found["CL_flap"]


# ----------------------------------------------------------------------------- near ties


def _evidence(effect, gain, passed=True, coefficient="CD"):
    return Evidence(effect, coefficient, ("x",), gain, 5, 50.0, 1e-20, -50.0, passed)


def test_near_tied_alternatives_are_named_and_distant_ones_are_not():
    winner = _evidence("thrust_propwash", 0.2262)
    first = (winner, _evidence("constant_body_force", 0.2213),
             _evidence("ned_force", 0.2209, passed=False), _evidence("stall_onset", 0.15),
             _evidence("ground_effect", 0.225, coefficient="CL"))
    second = (_evidence("rate_coupling", 0.01, passed=False),)
    found = FoundEffect("thrust_propwash", "", "aerodynamic", ("CD",), (winner,), {})
    result = DiscoveryResult({}, {}, (found,), (first, second), 100.0)
    (tie,) = near_ties(result)
    assert tie.round == 1 and tie.winner == winner
    assert [e.effect for e in tie.alternatives] == ["constant_body_force", "ned_force"]
    sentence = tie.sentence()
    assert "`constant_body_force` (22.13%)" in sentence and "22.62%" in sentence
    assert "`ned_force` (22.09%, failed the tests)" in sentence
    assert "stall_onset" not in sentence and "ground_effect" not in sentence


# ----------------------------------------------------------------------------- residuals


def test_the_residual_reading_follows_its_correlation():
    rng = np.random.default_rng(3)
    white = rng.normal(size=4000)
    smoothed = np.convolve(white, savgol_coeffs(11, 3), mode="same")
    slow = np.zeros(4000)
    for i in range(1, 4000):
        slow[i] = 0.98 * slow[i - 1] + white[i]
    lines = explanations.residual_meaning(
        {name: diagnose(x, 50.0) for name, x in
         (("white", white), ("smoothed", smoothed), ("slow", slow))}, smoothing_time=0.1)
    assert "white (" in lines[0]
    assert "the smoothed sensor noise" in lines[1]
    assert "structure the model does not explain" in lines[2]


# ----------------------------------------------------------------------------- the report


def test_the_report_shows_floors_catalog_rounds_ties_and_glossary(run, report):
    md, summary = report
    floors = held_out_noise_floor(run.samples, run.discovery, run.params)
    assert "| coefficient | RMS before | RMS after | noise floor |" in md
    for k, f in floors.items():
        entry = summary["equation_error_rms_holdout"][k]
        assert entry["noise_floor"] == pytest.approx(f.floor)
        assert f"| {k} | {f.before:.4g} | {f.after:.4g} | {f.floor:.4g} |" in md
    assert summary["parameters"]["Cm"]["Cm_q"]["catalog"] == run.params.derivatives["Cm_q"]
    assert f"| Cm_q | - | {run.discovery.final['Cm'].result.estimate[2]:.4g} |" in md
    rounds = run.discovery.rounds
    assert [len(r) for r in summary["rounds"]] == [len(r) for r in rounds]
    for i in range(len(rounds)):
        assert f"### Round {i + 1}:" in md
    for tie in run.near_ties:
        assert tie.sentence() in md
        assert all(f"`{e.effect}`" in md for e in tie.alternatives)
    for term in ("PSE", "BCLS", "held-out data", "noise floor", "equation error"):
        assert f"- **{term}:**" in md
    assert "## What the residuals say" in md
    # The catalog terms this flight does not pin down (C_D_alpha2 moves with C_D_alpha,
    # C_L_q, C_D_q, ...) are dropped from the baseline: 0 in the model, no warning left.
    for k, terms in run.discovery.dropped.items():
        for t in terms:
            (row,) = [line for line in md.splitlines() if line.startswith(f"| {t.term} |")]
            assert row.split(" | ")[2:4] == ["0", "-"] and row.endswith(" | dropped |")
            assert summary["parameters"][k][t.term]["dropped"]
    assert "CD_alpha2" in {t.term for t in run.discovery.dropped["CD"]}
    assert summary["warnings"] == [] and "## Warnings on the derivatives\n\nNone:" in md


def test_figure_axes_carry_their_units(run):
    b = run.reconstruction_before
    outputs = ("airspeed", "alpha", "beta", "p", "q", "r")
    fig = figures.reconstruction_plot(b.time, dict(zip(outputs, b.measured.T, strict=True)),
                                      dict(zip(outputs, b.reconstructed.T, strict=True)),
                                      degrees=outputs[1:])
    assert [ax.get_ylabel() for ax in fig.axes] == [
        "airspeed [m/s]", "alpha [deg]", "beta [deg]", "p [deg/s]", "q [deg/s]", "r [deg/s]"]
    d = run.discovery
    fig = figures.residual_time_series(
        b.time, {k: f.holdout_residual[:b.time.size] for k, f in d.final.items()},
        floor={"CL": 0.01})
    assert [ax.get_ylabel() for ax in fig.axes] == [f"{k} [-]" for k in d.final]
    assert "noise floor 0.01" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    fig = figures.autocorrelation_plot({k: f.diagnosis for k, f in d.final.items()})
    assert (fig.axes[0].get_xlabel(), fig.axes[0].get_ylabel()) == ("lag [s]",
                                                                    "autocorrelation [-]")
