"""Monte-Carlo campaigns on Dask, their results in Parquet, and regression checks.

A campaign runs a scenario ``(seed, params) -> metrics`` over seeds and a
parameter grid (:class:`Campaign`); :func:`run_campaign` runs it on a Dask
cluster and streams one row per run to Parquet (resumable); :func:`compare` and
:func:`assert_campaign_matches` check a result against a stored baseline;
:func:`write_campaign_report` writes the HTML summary. See docs/campaigns.md.
"""

import importlib

_HOMES = {
    "Campaign": "drake_uav.campaigns.definition",
    "CampaignRegression": "drake_uav.campaigns.regression",
    "CampaignRun": "drake_uav.campaigns.runner",
    "Comparison": "drake_uav.campaigns.regression",
    "Distribution": "drake_uav.campaigns.definition",
    "MetricCheck": "drake_uav.campaigns.regression",
    "NONDETERMINISTIC": "drake_uav.campaigns.results",
    "RunSpec": "drake_uav.campaigns.definition",
    "assert_campaign_matches": "drake_uav.campaigns.regression",
    "compare": "drake_uav.campaigns.regression",
    "parse_seeds": "drake_uav.campaigns.definition",
    "read_results": "drake_uav.campaigns.results",
    "register_scenario": "drake_uav.campaigns.registry",
    "results_equal": "drake_uav.campaigns.results",
    "run_campaign": "drake_uav.campaigns.runner",
    "scenario": "drake_uav.campaigns.registry",
    "scenario_names": "drake_uav.campaigns.registry",
    "wilson_interval": "drake_uav.campaigns.regression",
}
"""Where each exported name lives: the submodules load on first use, so that building the
``drake-uav`` parser does not import Dask and SciPy."""


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


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'drake_uav.campaigns' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name]), name)
