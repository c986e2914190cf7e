"""Monte-Carlo campaigns on Dask, their results in Parquet, and regression checks.

A campaign runs a scenario ``(seed, params) -> metrics`` over seeds and a
parameter grid (:class:`Campaign`); :func:`run_campaign` runs it on a Dask
cluster and streams one row per run to Parquet (resumable); :func:`compare` and
:func:`assert_campaign_matches` check a result against a stored baseline;
:func:`write_campaign_report` writes the HTML summary. See docs/campaigns.md.
"""

from drake_uav.campaigns.definition import Campaign, Distribution, RunSpec, parse_seeds
from drake_uav.campaigns.registry import register_scenario, scenario, scenario_names
from drake_uav.campaigns.regression import (
    CampaignRegression,
    Comparison,
    MetricCheck,
    assert_campaign_matches,
    compare,
    wilson_interval,
)
from drake_uav.campaigns.results import NONDETERMINISTIC, read_results, results_equal
from drake_uav.campaigns.runner import CampaignRun, run_campaign

__all__ = [
    "Campaign",
    "CampaignRegression",
    "CampaignRun",
    "Comparison",
    "Distribution",
    "MetricCheck",
    "NONDETERMINISTIC",
    "RunSpec",
    "assert_campaign_matches",
    "compare",
    "parse_seeds",
    "read_results",
    "register_scenario",
    "results_equal",
    "run_campaign",
    "scenario",
    "scenario_names",
    "wilson_interval",
]
