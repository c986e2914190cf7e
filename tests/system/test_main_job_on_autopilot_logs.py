"""The main job on realistic autopilot logs (issue acceptance seeds 0-4, 180 s flights,
light turbulence, default sensors, an elevator rolling moment C_l += 0.02 delta_e).

What holds and is asserted here: the vaneless alpha and beta stay within 0.5 deg mean
absolute error of the truth on every seed; the vane CSV of the same flight gives
exactly the injected effect on at least 4 of 5 seeds; the .bin and .ulg name the
injected effect first on every seed. What does not hold yet, measured by
``benchmarks/bench_realistic_logs.py``: on the .bin and .ulg an extra
``actuator_time_delay`` (on CY, Cn) is named on 4 of these 5 seeds, so the exact
finding of the CSV is matched on 1 of 5.
"""

import pytest

from drake_uav.campaigns.realistic_logs import realistic_logs

SEEDS = range(5)


@pytest.fixture(scope="module")
def runs():
    return [realistic_logs(seed, {"effect": "elevator_roll"}) for seed in SEEDS]


@pytest.mark.slow
def test_vaneless_air_data_within_half_a_degree(runs):
    for seed, run in zip(SEEDS, runs, strict=True):
        assert run["alpha_mae_deg"] < 0.5 and run["beta_mae_deg"] < 0.5, (seed, run)


@pytest.mark.slow
def test_the_vane_csv_finds_exactly_the_injected_effect(runs):
    exact = [run["exact_csv"] for run in runs]
    assert sum(exact) >= 4, [run["found_csv"] for run in runs]  # tolerates 1 miss in 5


@pytest.mark.slow
def test_the_autopilot_logs_name_the_injected_effect_first(runs):
    for kind in ("bin", "ulg"):
        firsts = [run[f"found_{kind}"].split(",")[0] for run in runs]
        assert firsts == ["control_cross_coupling"] * len(runs), (kind, firsts)
