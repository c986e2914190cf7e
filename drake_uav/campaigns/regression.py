"""Regression checks: a campaign result against a stored baseline, sample size aware.

Each grid point (matched by its grid parameter values) and each metric gives
one check:

* a **rate** (a bool metric, and the error rate of every campaign): the two
  proportions are compared with Boschloo's exact unconditional test (Boschloo
  1970; Fisher's exact test where Boschloo's is undefined), and each rate is shown
  with its Wilson score interval (Wilson 1927);
* a **distribution** (an int or float metric): the two samples are compared with
  the two-sample Kolmogorov-Smirnov test (exact for small samples), and the shift
  of the mean is shown with a percentile bootstrap interval (Efron & Tibshirani
  1993, sec. 13.3) drawn from a fixed seed.

A check flags when its p-value falls below the Holm-Bonferroni threshold (Holm
1979) of the whole family at ``alpha``: the chance that two campaigns of the same
code flag anything is at most ``alpha`` whatever the number of checks. A metric
with one value in both campaigns (no errors anywhere, say) cannot reach any
significance and is left out of the family (Tarone 1990). The
tests account for the sample sizes; with few runs only large changes can flag
(the power of a 0.9 -> 0.6 drop of a rate over 40 + 40 runs is about 0.89 at
``alpha`` = 0.05 with one check).
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import pyarrow as pa
from scipy import stats

from drake_uav.campaigns.results import METRIC, PARAM, campaign_definition, metric_columns

__all__ = ["MetricCheck", "Comparison", "wilson_interval", "compare", "assert_campaign_matches",
           "CampaignRegression", "group_rows", "comparison_json"]

ERROR_RATE = "error_rate"
"""Name of the rate of error rows, checked in every comparison."""


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (Wilson 1927); (0, 1) when n = 0."""
    if n == 0:
        return (0.0, 1.0)
    z = stats.norm.ppf(0.5 + 0.5 * confidence)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


def _rate_p_value(k1: int, n1: int, k2: int, n2: int) -> float:
    if k1 * n2 == k2 * n1 or n1 == 0 or n2 == 0:
        return 1.0
    table = [[k1, k2], [n1 - k1, n2 - k2]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        p = stats.boschloo_exact(table).pvalue
    return float(p) if np.isfinite(p) else float(stats.fisher_exact(table).pvalue)


def _bootstrap_shift(a: np.ndarray, b: np.ndarray, draws: int = 2000,
                     confidence: float = 0.95) -> tuple[float, float]:
    """Percentile bootstrap interval of mean(b) - mean(a), from a fixed seed."""
    rng = np.random.default_rng(0)
    shifts = (rng.choice(b, (draws, b.size)).mean(axis=1)
              - rng.choice(a, (draws, a.size)).mean(axis=1))
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(shifts, [tail, 100.0 - tail])
    return (float(low), float(high))


@dataclasses.dataclass(frozen=True)
class MetricCheck:
    """One metric at one grid point, baseline against result."""

    point: str
    """The grid point, as ``name=value`` text ("all" without a grid)."""
    metric: str
    kind: str
    """"rate" or "distribution"."""
    n_baseline: int
    n_result: int
    baseline: float
    """Rate, or mean of the distribution."""
    result: float
    baseline_interval: tuple[float, float]
    """Wilson interval of the rate, or the (min, max) of the distribution."""
    result_interval: tuple[float, float]
    shift_interval: tuple[float, float] | None
    """Bootstrap interval of the mean shift (distributions)."""
    p_value: float
    threshold: float = float("nan")
    """Holm-Bonferroni threshold this p-value was held to."""
    flagged: bool = False
    """The change is beyond chance (Holm-Bonferroni at the comparison's alpha)."""

    def describe(self) -> str:
        what = "rate" if self.kind == "rate" else "mean"
        return (f"{self.metric} [{self.point}]: {what} {self.baseline:.4g} (n={self.n_baseline})"
                f" -> {self.result:.4g} (n={self.n_result}), p = {self.p_value:.3g}"
                f" (threshold {self.threshold:.3g})")


@dataclasses.dataclass(frozen=True)
class Comparison:
    """All checks of a comparison (:func:`compare`)."""

    checks: tuple[MetricCheck, ...]
    alpha: float
    missing: tuple[str, ...]
    """Metrics of the baseline absent from the result (a regression too)."""

    @property
    def regressions(self) -> tuple[MetricCheck, ...]:
        return tuple(c for c in self.checks if c.flagged)

    @property
    def ok(self) -> bool:
        return not self.regressions and not self.missing

    def message(self) -> str:
        lines = [f"{len(self.checks)} checks at family-wise alpha = {self.alpha:g}: "
                 f"{len(self.regressions)} flagged"]
        lines += ["  " + c.describe() for c in self.regressions]
        lines += [f"  metric {m} is missing from the result" for m in self.missing]
        return "\n".join(lines)


def group_rows(table: pa.Table) -> dict[str, dict[str, list]]:
    """Rows grouped by grid point: point label -> column -> values."""
    definition = campaign_definition(table) or {}
    grid = [PARAM + name for name in definition.get("grid", {})
            if PARAM + name in table.column_names]
    data = table.to_pydict()
    groups: dict[str, dict[str, list]] = {}
    for i in range(table.num_rows):
        label = ", ".join(f"{c[len(PARAM):]}={data[c][i]}" for c in grid) or "all"
        group = groups.setdefault(label, {c: [] for c in table.column_names})
        for c in table.column_names:
            group[c].append(data[c][i])
    return groups


def _metric_kind(table: pa.Table, column: str) -> str:
    kind = table.schema.field(column).type
    if pa.types.is_boolean(kind):
        return "rate"
    if pa.types.is_integer(kind) or pa.types.is_floating(kind):
        return "distribution"
    return "other"


def _check(point: str, metric: str, kind: str, a: Sequence, b: Sequence) -> MetricCheck | None:
    a = np.array([v for v in a if v is not None], dtype=float)
    b = np.array([v for v in b if v is not None], dtype=float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0 or np.ptp(np.concatenate([a, b])) == 0.0:
        return None  # one value in both samples: no test can flag it (Tarone 1990)
    if kind == "rate":
        ka, kb = int(a.sum()), int(b.sum())
        return MetricCheck(point, metric, kind, a.size, b.size, ka / a.size, kb / b.size,
                           wilson_interval(ka, a.size), wilson_interval(kb, b.size), None,
                           _rate_p_value(ka, a.size, kb, b.size))
    if np.array_equal(np.sort(a), np.sort(b)):
        p = 1.0
    else:
        p = float(stats.ks_2samp(a, b).pvalue)
    return MetricCheck(point, metric, kind, a.size, b.size, float(a.mean()), float(b.mean()),
                       (float(a.min()), float(a.max())), (float(b.min()), float(b.max())),
                       _bootstrap_shift(a, b), p)


def _holm(checks: list[MetricCheck], alpha: float) -> list[MetricCheck]:
    """Holm-Bonferroni: the i-th smallest of m p-values (from 0) is held to alpha / (m - i);
    checks flag in that order until the first one that does not."""
    order = sorted(range(len(checks)), key=lambda i: checks[i].p_value)
    out = list(checks)
    going = True
    for rank, i in enumerate(order):
        threshold = alpha / (len(checks) - rank)
        going = going and checks[i].p_value < threshold
        out[i] = dataclasses.replace(checks[i], threshold=threshold, flagged=going)
    return out


def compare(baseline: pa.Table, result: pa.Table, *, alpha: float = 0.05,
            metrics: Sequence[str] | None = None) -> Comparison:
    """Checks ``result`` against ``baseline`` (module docstring).

    Args:
        baseline, result: campaign tables (:func:`~drake_uav.campaigns.results.read_results`).
        alpha: family-wise false-alarm probability of the whole comparison.
        metrics: metric names to check (default: every metric of the baseline);
            the error rate is always checked.
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    names = [c[len(METRIC):] for c in metric_columns(baseline)]
    if metrics is not None:
        unknown = sorted(set(metrics) - set(names))
        if unknown:
            raise ValueError(f"metrics {unknown} are not in the baseline (it has {names})")
        names = list(metrics)
    missing = tuple(n for n in names if METRIC + n not in result.column_names)
    base_groups, result_groups = group_rows(baseline), group_rows(result)
    checks = []
    for point, base in base_groups.items():
        other = result_groups.get(point)
        if other is None:
            missing += (f"grid point {point}",)
            continue
        checks.append(_check(point, ERROR_RATE, "rate", [s != "ok" for s in base["status"]],
                             [s != "ok" for s in other["status"]]))
        for name in names:
            column = METRIC + name
            kind = _metric_kind(baseline, column)
            if column in other and kind != "other":
                checks.append(_check(point, name, kind, base[column], other[column]))
    checks = _holm([c for c in checks if c is not None], alpha)
    return Comparison(tuple(checks), alpha, missing)


class CampaignRegression(AssertionError):
    """A campaign result differs from its baseline beyond chance."""


def _table(value: Any) -> pa.Table:
    if isinstance(value, pa.Table):
        return value
    if hasattr(value, "table"):  # a CampaignRun
        return value.table
    from drake_uav.campaigns.results import read_results

    return read_results(value)


def assert_campaign_matches(baseline: Any, result: Any, *, alpha: float = 0.05,
                            metrics: Sequence[str] | None = None) -> Comparison:
    """pytest helper: raises :class:`CampaignRegression` (an AssertionError) listing the
    flagged checks when ``result`` differs from ``baseline`` (:func:`compare`).

    ``baseline`` and ``result``: a Parquet path, a table, or a
    :class:`~drake_uav.campaigns.runner.CampaignRun`. Returns the comparison.
    """
    comparison = compare(_table(baseline), _table(result), alpha=alpha, metrics=metrics)
    if not comparison.ok:
        raise CampaignRegression(comparison.message())
    return comparison


def comparison_json(comparison: Comparison) -> str:
    """The comparison as JSON text (for the command line)."""
    return json.dumps({"ok": comparison.ok, "alpha": comparison.alpha,
                       "missing": list(comparison.missing),
                       "checks": [dataclasses.asdict(c) for c in comparison.checks]},
                      indent=2)
