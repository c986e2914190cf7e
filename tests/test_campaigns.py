"""Campaigns: reproducible rows on any number of workers, resume, error rows, regression checks."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from drake_uav.campaigns import (
    NONDETERMINISTIC,
    Campaign,
    CampaignRegression,
    assert_campaign_matches,
    compare,
    read_results,
    results_equal,
    run_campaign,
    wilson_interval,
)
from drake_uav.cli import main

HERE = Path(__file__).parent
INTERRUPT = "DRAKE_UAV_TEST_INTERRUPT_AT_SEED"


def noisy_fit(seed: int, params: dict) -> dict:
    """A synthetic scenario with some floating-point work whose cost varies with the seed
    (so runs finish out of order on several workers); raises on ``fail_seed``."""
    if seed == params.get("fail_seed"):
        raise RuntimeError(f"broken on seed {seed}")
    if os.environ.get(INTERRUPT) == str(seed):
        raise KeyboardInterrupt
    rng = np.random.default_rng(seed)
    n = 200 + 150 * (seed % 4)
    A = rng.normal(size=(n, 6)) * params["scale"]
    x = np.linalg.lstsq(A, A @ np.arange(6.0) + rng.normal(size=n), rcond=None)[0]
    time.sleep(params.get("sleep", 0.0))
    return {"error": float(np.linalg.norm(x - np.arange(6.0))), "samples": n,
            "converged": bool(x[0] < 0.05), "gain": params["gain"]}


def rates(seed: int, params: dict) -> dict:
    """A synthetic detector: detects with probability ``p``; a normal error."""
    rng = np.random.default_rng([seed, 7])
    return {"detected": bool(rng.random() < params["p"]), "error": float(rng.normal())}


def _campaign(**fixed) -> Campaign:
    return Campaign(noisy_fit, seeds=range(12), grid={"scale": [1.0, 3.0]},
                    distributions={"gain": ("uniform", 0.5, 2.0)}, fixed=fixed)


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    return run_campaign(_campaign(), tmp_path_factory.mktemp("c") / "r.parquet", workers=0,
                        progress=False)


def test_rows_are_sorted_and_carry_parameters_seed_status_version(in_process):
    table = in_process.table
    assert table.num_rows == 24 and in_process.errors == 0
    assert table.column_names[:6] == ["point", "seed", "status", "error", "wall_time_s",
                                      "version"]
    keys = list(zip(table["point"].to_pylist(), table["seed"].to_pylist(), strict=True))
    assert keys == sorted(keys)
    assert set(table["param.scale"].to_pylist()) == {1.0, 3.0}
    # A drawn parameter depends on the seed only, not on the grid point.
    gains = table["param.gain"].to_pylist()
    assert gains[:12] == gains[12:] and len(set(gains[:12])) == 12
    assert table["metric.gain"].to_pylist() == gains
    assert not in_process.path.with_name("r.parquet.parts").exists()


def test_bit_identical_rows_on_one_and_two_workers(tmp_path, in_process):
    one = run_campaign(_campaign(), tmp_path / "one.parquet", workers=1, progress=False)
    two = run_campaign(_campaign(), tmp_path / "two.parquet", workers=2, progress=False)
    assert results_equal(one.table, two.table)
    assert results_equal(one.table, in_process.table)
    # Only the wall time differs: with it dropped the Parquet files are the same bytes.
    for name in ("one", "two"):
        pq.write_table(read_results(tmp_path / f"{name}.parquet").drop_columns("wall_time_s"),
                       tmp_path / f"{name}_cmp.parquet")
    one_bytes, two_bytes = ((tmp_path / f"{n}_cmp.parquet").read_bytes() for n in ("one", "two"))
    assert one_bytes == two_bytes


def test_interrupted_and_resumed_equals_uninterrupted(tmp_path, monkeypatch, in_process):
    out = tmp_path / "r.parquet"
    monkeypatch.setenv(INTERRUPT, "7")
    with pytest.raises(KeyboardInterrupt):
        run_campaign(_campaign(), out, workers=0, progress=False)
    assert not out.exists() and len(list(out.with_name("r.parquet.parts").iterdir())) == 7
    monkeypatch.delenv(INTERRUPT)
    resumed = run_campaign(_campaign(), out, workers=0, progress=False)
    assert (resumed.ran, resumed.resumed) == (17, 7)
    assert results_equal(resumed.table, in_process.table)
    again = run_campaign(_campaign(), out, workers=0, progress=False)
    assert again.ran == 0 and results_equal(again.table, in_process.table)


def test_more_seeds_extend_a_finished_campaign(tmp_path):
    out = tmp_path / "r.parquet"
    run_campaign(Campaign(rates, seeds=range(5), fixed={"p": 0.5}), out, workers=0,
                 progress=False)
    more = run_campaign(Campaign(rates, seeds=range(8), fixed={"p": 0.5}), out, workers=0,
                        progress=False)
    assert (more.ran, more.resumed, more.table.num_rows) == (3, 5, 8)


def test_another_definition_is_refused(tmp_path):
    out = tmp_path / "r.parquet"
    run_campaign(Campaign(rates, seeds=range(3), fixed={"p": 0.5}), out, workers=0,
                 progress=False)
    with pytest.raises(ValueError, match="another campaign definition"):
        run_campaign(Campaign(rates, seeds=range(3), fixed={"p": 0.7}), out, workers=0,
                     progress=False)


@pytest.mark.parametrize("workers", [0, 2])
def test_a_scenario_that_raises_gives_one_error_row(tmp_path, workers):
    done = run_campaign(_campaign(fail_seed=5), tmp_path / "r.parquet", workers=workers,
                        progress=False)
    rows = [r for r in done.table.to_pylist() if r["point"] == 0]
    failed = [r for r in rows if r["status"] == "error"]
    assert len(rows) == 12 and done.errors == 2  # seed 5 at both grid points
    assert [r["seed"] for r in failed] == [5]
    assert failed[0]["error"] == "RuntimeError: broken on seed 5"
    assert failed[0]["metric.error"] is None and failed[0]["param.scale"] == 1.0
    assert all(r["error"] is None for r in rows if r["status"] == "ok")


def test_an_unknown_scenario_raises_on_a_cluster_too(tmp_path):
    # On a cluster a worker checks the name (this process does not load the scenarios):
    # the error still comes before any row is written.
    out = tmp_path / "r.parquet"
    with pytest.raises(ValueError, match="unknown"):
        run_campaign(Campaign("no_such_scenario", seeds=range(3)), out, workers=1,
                     progress=False)
    assert not out.exists()


def test_progress_bar_counts_runs_and_errors(tmp_path, capsys):
    run_campaign(_campaign(fail_seed=5), tmp_path / "r.parquet", workers=0,
                 progress=sys.stdout)
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "24/24 runs, 2 errors" in last


def test_wilson_interval():
    low, high = wilson_interval(36, 40)
    assert low == pytest.approx(0.7695, abs=1e-3) and high == pytest.approx(0.9604, abs=1e-3)
    assert wilson_interval(0, 40)[0] == 0.0 and wilson_interval(40, 40)[1] == 1.0


def _rates(tmp_path, name: str, p: float, seeds) -> object:
    return run_campaign(Campaign(rates, seeds=seeds, fixed={"p": p}), tmp_path / name,
                        workers=0, progress=False, flush_every=1000).table


def test_compare_flags_a_detection_rate_drop_from_0_9_to_0_6(tmp_path):
    baseline = _rates(tmp_path, "b.parquet", 0.9, range(40))
    dropped = _rates(tmp_path, "d.parquet", 0.6, range(100, 140))
    comparison = compare(baseline, dropped)
    assert [c.metric for c in comparison.regressions] == ["detected"]
    check = comparison.regressions[0]
    print(f"\n{check.describe()}")
    with pytest.raises(CampaignRegression, match="detected"):
        assert_campaign_matches(baseline, dropped)
    assert_campaign_matches(baseline, _rates(tmp_path, "s.parquet", 0.9, range(100, 140)))


def test_false_alarm_rate_and_power_over_repeats(tmp_path):
    """Same code, other seeds: flags at most about alpha of the time; a 0.9 -> 0.6 drop over
    40 seeds is flagged in most repeats (the power of 40 + 40 runs, module docstring of
    drake_uav.campaigns.regression)."""
    repeats, false_alarms, detections = 30, 0, 0
    for r in range(repeats):
        seeds = range(1000 * r, 1000 * r + 40)
        others = range(1000 * r + 500, 1000 * r + 540)
        baseline = _rates(tmp_path, f"b{r}.parquet", 0.9, seeds)
        false_alarms += not compare(baseline, _rates(tmp_path, f"s{r}.parquet", 0.9, others)).ok
        detections += not compare(baseline, _rates(tmp_path, f"d{r}.parquet", 0.6, others)).ok
    print(f"\nfalse alarms {false_alarms}/{repeats}, detections {detections}/{repeats}")
    # alpha = 0.05: 30 repeats give 1.5 false alarms on average, 5+ with probability < 0.02.
    assert false_alarms <= 4
    assert detections >= 0.7 * repeats


def test_command_line_run_compare_report(tmp_path, capsys):
    sys.path.insert(0, str(HERE))  # the scenario lives in this module
    base, worse = tmp_path / "base.parquet", tmp_path / "worse.parquet"
    for out, p, seeds in ((base, 0.9, "0:40"), (worse, 0.6, "100:140")):
        assert main(["campaign", "run", "test_campaigns:rates", "--seeds", seeds, "--param",
                     f"p={p}", "--out", str(out), "--workers", "0", "--quiet"]) == 0
    assert main(["campaign", "compare", str(base), str(base)]) == 0
    assert main(["campaign", "compare", str(base), str(worse), "--report",
                 str(tmp_path / "cmp")]) == 1
    out = capsys.readouterr().out
    assert "1 flagged" in out and "detected" in out
    html = (tmp_path / "cmp" / "report.html").read_text()
    assert "REGRESSION" in html and html.count("<img") == 1
    assert main(["campaign", "report", str(base), "--out", str(tmp_path / "rep")]) == 0
    rates_table = (tmp_path / "rep" / "report.md").read_text()
    assert "| all | detected | 38/40 | 0.950 | 0.835 | 0.986 |" in rates_table  # Wilson 95 %
    assert main(["campaign", "compare", str(base), str(tmp_path / "none.parquet")]) == 2


_KILLED_RUN = """
import sys
sys.path.insert(0, {here!r})
from test_campaigns import _campaign
from drake_uav.campaigns import run_campaign
if __name__ == "__main__":
    run_campaign(_campaign(sleep=0.4), {out!r}, workers=2, progress=False)
"""


@pytest.mark.slow
def test_a_killed_campaign_resumes_to_the_same_file(tmp_path, in_process):
    """The campaign process (and its local cluster) is killed once a few rows are on disk."""
    out = tmp_path / "r.parquet"
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(_KILLED_RUN.format(here=str(HERE), out=str(out))))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True,
                            stderr=subprocess.DEVNULL)
    parts = out.with_name("r.parquet.parts")
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(list(parts.glob("part-*"))) < 4:
            assert proc.poll() is None, "the campaign ended before it was killed"
            time.sleep(0.1)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert not out.exists()
    resumed = run_campaign(_campaign(sleep=0.4), out, workers=0, progress=False)
    assert resumed.resumed >= 4 and resumed.ran + resumed.resumed == 24
    resumed_table = resumed.table.drop_columns(["param.sleep"])
    assert results_equal(resumed_table.replace_schema_metadata(None),
                         in_process.table.replace_schema_metadata(None))


@pytest.mark.slow
def test_main_job_scenario_bit_identical_on_one_and_two_workers(tmp_path):
    campaign = Campaign("main_job", seeds=[1, 2], fixed={"duration": 30.0})
    one = run_campaign(campaign, tmp_path / "one.parquet", workers=1, progress=False)
    two = run_campaign(campaign, tmp_path / "two.parquet", workers=2, progress=False)
    assert one.errors == 0 and results_equal(one.table, two.table)
    assert {"metric.detected", "metric.false_discoveries", "metric.rms_before",
            "metric.rms_after"} <= set(one.table.column_names)


def test_built_in_scenarios_return_their_metrics():
    from drake_uav.campaigns import scenario, scenario_names

    assert {"main_job", "air_data_ekf", "tracking_nmpc"} <= set(scenario_names())
    ekf = scenario("air_data_ekf")(1, {"duration": 30.0})
    assert set(ekf) == {"nees", "nis_per_dof", "mae_airspeed", "mae_alpha_deg", "mae_beta_deg",
                        "mae_wind", "rejected"}
    assert 0.5 < ekf["nis_per_dof"] < 2.0 and ekf["mae_airspeed"] < 0.5
    with pytest.raises(ValueError, match="effect 'gremlins' unknown"):
        scenario("main_job")(1, {"effect": "gremlins"})
    with pytest.raises(ValueError, match="unknown"):
        scenario("no_such_scenario")


@pytest.mark.slow
def test_tracking_nmpc_scenario_reproducible_but_for_its_clock_metrics(tmp_path):
    from drake_uav.campaigns.scenarios import TRACKING_TIMING_METRICS

    campaign = Campaign("tracking_nmpc", seeds=[3, 4], fixed={"duration": 2.5})
    first = run_campaign(campaign, tmp_path / "a.parquet", workers=0, progress=False)
    again = run_campaign(campaign, tmp_path / "b.parquet", workers=0, progress=False)
    assert first.errors == 0
    clock = tuple(f"metric.{name}" for name in TRACKING_TIMING_METRICS)
    assert results_equal(first.table, again.table, exclude=NONDETERMINISTIC + clock)
    rows = first.table.to_pylist()
    assert all(r["metric.bounds_respected"] and r["metric.fallback_steps"] == 0 for r in rows)
    assert all(r["metric.terminal_ratio_max"] <= 1.0 + 1e-3 for r in rows)
    assert all(r["metric.rmse_cm"] < 5.0 for r in rows)
