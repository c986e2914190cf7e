"""Campaign ``motor_fault``: random failure sets at random times on the ch. 6 missions
(Argyropoulos 2020): no exception, every run classified, and no run below the outcome its
category promised (track > land safely > avoid the unsafe area > impact)."""

import collections

import pytest

from drake_uav.campaigns.definition import Campaign
from drake_uav.campaigns.motor_fault import motor_fault
from drake_uav.campaigns.runner import run_campaign

SEEDS = 10
"""Runs per target category in the slow suite; the acceptance campaign flies 50
(docs/faults.md, "Campaign")."""


def test_one_run_of_each_target_is_classified_and_scored():
    for target, seed in (("I", 0), ("IV", 3)):
        metrics = motor_fault(seed, {"target": target, "coarse_tube": True,
                                     "duration": 6.0})
        print(target, metrics)
        assert 1 <= metrics["category"] <= 4
        assert (metrics["category"] == 1) == (target == "I")
        assert not metrics["priority_violated"]


@pytest.mark.slow
def test_motor_fault_campaign(tmp_path):
    campaign = Campaign("motor_fault", seeds=range(SEEDS),
                        grid={"target": ["I", "II", "III", "IV"]})
    result = run_campaign(campaign, tmp_path / "motor_fault.parquet", progress=False)
    rows = result.table.to_pylist()
    counts = collections.Counter((r["param.target"], r.get("metric.category"),
                                  r.get("metric.priority_violated")) for r in rows)
    for key, count in sorted(counts.items(), key=str):
        print(f"target {key[0]:3s} category {key[1]} priority violated {key[2]}: {count}")
    assert result.errors == 0
    assert len(rows) == 4 * SEEDS
    assert all(1 <= r["metric.category"] <= 4 for r in rows)
    assert not any(r["metric.priority_violated"] for r in rows)
