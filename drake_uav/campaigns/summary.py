"""HTML summary of a campaign (and of its comparison with a baseline).

:func:`write_campaign_report` writes a report folder
(:class:`~drake_uav.reporting.report.Report`): the runs and errors, every rate
with its Wilson interval, a histogram per distribution (the baseline's overlaid
when given), the comparison's checks, and the error messages.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow as pa
from matplotlib.figure import Figure

from drake_uav.campaigns.regression import Comparison, compare, group_rows, wilson_interval
from drake_uav.campaigns.results import METRIC, campaign_definition
from drake_uav.reporting.report import Report

__all__ = ["write_campaign_report"]


def _values(group: dict[str, list], column: str) -> np.ndarray:
    v = np.array([x for x in group.get(column, []) if x is not None], dtype=float)
    return v[np.isfinite(v)]


def _histogram(metric: str, result: dict, baseline: dict | None):
    def draw():
        fig = Figure(figsize=(6.0, 3.2))
        ax = fig.add_subplot()
        column = METRIC + metric
        samples = {"result": _values(result, column)}
        if baseline is not None:
            samples = {"baseline": _values(baseline, column), **samples}
        pooled = np.concatenate(list(samples.values()))
        bins = np.histogram_bin_edges(pooled, bins="auto") if pooled.size else 10
        for label, v in samples.items():
            ax.hist(v, bins=bins, alpha=0.55, label=f"{label} (n={v.size})")
        ax.set_xlabel(metric)
        ax.set_ylabel("runs")
        ax.legend()
        fig.tight_layout()
        return fig

    return draw


def _rate_rows(table: pa.Table, groups: dict) -> list[dict]:
    rows = []
    rates = [c for c in table.column_names
             if c.startswith(METRIC) and pa.types.is_boolean(table.schema.field(c).type)]
    for point, group in groups.items():
        n_runs = len(group["status"])
        errors = sum(s != "ok" for s in group["status"])
        low, high = wilson_interval(errors, n_runs)
        rows.append({"grid point": point, "rate": "error_rate", "k/n": f"{errors}/{n_runs}",
                     "value": errors / n_runs, "95 % low": low, "95 % high": high})
        for column in rates:
            v = _values(group, column)
            k = int(v.sum())
            low, high = wilson_interval(k, v.size)
            rows.append({"grid point": point, "rate": column[len(METRIC):],
                         "k/n": f"{k}/{v.size}", "value": k / v.size if v.size else np.nan,
                         "95 % low": low, "95 % high": high})
    return rows


def _check_rows(comparison: Comparison) -> list[dict]:
    return [{"grid point": c.point, "metric": c.metric, "kind": c.kind,
             "baseline": c.baseline, "result": c.result, "n": f"{c.n_baseline}/{c.n_result}",
             "p": c.p_value, "threshold": c.threshold, "flag": "REGRESSION" if c.flagged else ""}
            for c in comparison.checks]


def write_campaign_report(result: pa.Table, out_dir: str | os.PathLike,
                          baseline: pa.Table | None = None, *, alpha: float = 0.05,
                          title: str | None = None) -> Path:
    """Writes the campaign's report folder (``report.html`` and friends) to ``out_dir``."""
    definition = campaign_definition(result) or {}
    report = Report(title or f"Campaign: {definition.get('scenario', 'results')}")
    statuses = Counter(result.column("status").to_pylist())
    report.add_key_values({"scenario": definition.get("scenario", "?"),
                           "runs": result.num_rows, "errors": statuses.get("error", 0),
                           "grid": str(definition.get("grid", {})) or "-",
                           "distributions": str(definition.get("distributions", {})) or "-",
                           "fixed": str(definition.get("fixed", {})) or "-"})
    groups = group_rows(result)
    base_groups = group_rows(baseline) if baseline is not None else {}
    comparison = compare(baseline, result, alpha=alpha) if baseline is not None else None
    if comparison is not None:
        report.add_heading("Comparison with the baseline")
        report.add_text(("**No regression.** " if comparison.ok else "**Regression.** ")
                        + comparison.message().splitlines()[0]
                        + "".join(f"; metric {m} missing" for m in comparison.missing))
        report.add_table(_check_rows(comparison), float_format=".4g")
    report.add_heading("Rates (Wilson 95 % intervals)")
    report.add_table(_rate_rows(result, groups), float_format=".3f")
    report.add_heading("Distributions")
    for column in result.column_names:
        kind = result.schema.field(column).type
        if column.startswith(METRIC) and (pa.types.is_integer(kind)
                                          or pa.types.is_floating(kind)):
            for point, group in groups.items():
                report.add_figure(_histogram(column[len(METRIC):], group, base_groups.get(point)),
                                  f"{column[len(METRIC):]} [{point}]")
    errors = [(r["point"], r["seed"], r["error"]) for r in result.to_pylist()
              if r["status"] != "ok"]
    if errors:
        report.add_heading("Errors")
        report.add_table([{"point": p, "seed": s, "error": e} for p, s, e in errors])
    summary = {"runs": result.num_rows, "errors": len(errors),
               "regression": None if comparison is None else not comparison.ok}
    return report.write(out_dir, summary)
