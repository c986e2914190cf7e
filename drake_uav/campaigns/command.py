"""``drake-uav campaign run|compare|report``: the command-line face of the campaigns.

:func:`add_campaign_parser` adds the ``campaign`` command to the ``drake-uav``
parser; each sub-command is a thin layer over :func:`run_campaign`,
:func:`compare` and :func:`write_campaign_report`. Every argument, the scenario and the
outputs are checked before any run (:func:`check_scenario`, :func:`check_results_target`,
:func:`~drake_uav.reporting.output.check_output_folder`).
"""

from __future__ import annotations

import argparse
import json
import math
import re

from drake_uav.arguments import MAX_SEED, integer, real
from drake_uav.campaigns.registry import BUILT_IN, check_scenario
from drake_uav.reporting.output import check_output_folder

__all__ = ["add_campaign_parser"]

MAX_RUNS_PER_POINT = 1_000_000
"""Most seeds a campaign runs per grid point (a typing error such as 0:4000000000 is refused
before the seeds are listed)."""


def _value(text: str):
    """A command-line value: JSON if it parses (numbers, true/false, lists), else text."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _pairs(items: list[str] | None, what: str) -> dict[str, str]:
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise ValueError(f"{what}: expected NAME=VALUE, got {item!r}")
        out[name.strip()] = value
    return out


def _seeds(text: str) -> tuple[int, ...]:
    """``--seeds`` -> the seeds, each in 0 .. 2**32 - 1, at most :data:`MAX_RUNS_PER_POINT`."""
    from drake_uav.campaigns.definition import parse_seeds

    start, sep, stop = text.partition(":")
    if sep and all(v.strip().lstrip("-").isdigit() for v in (start, stop)) and (
            int(stop) - int(start) > MAX_RUNS_PER_POINT):
        raise ValueError(f"--seeds {text}: more than {MAX_RUNS_PER_POINT} seeds")
    try:
        seeds = parse_seeds(text)
    except ValueError as err:
        raise ValueError(f"--{err}") from None
    if not seeds:
        raise ValueError(f"--seeds {text}: no seeds (START:STOP needs START < STOP)")
    if not all(0 <= s <= MAX_SEED for s in seeds):
        raise ValueError(f"--seeds {text}: seeds must be integers 0 .. {MAX_SEED}")
    return seeds


def _distribution(name: str, spec: str) -> list:
    """``--dist NAME=KIND:A:B`` -> ``[KIND, A, B]``, the bounds checked (finite numbers, low
    below high, a standard deviation >= 0)."""
    kind, *values = [_value(v) for v in spec.split(":")]
    if kind == "choice":
        return [kind, *values]
    numbers = [v for v in values if isinstance(v, int | float) and not isinstance(v, bool)
               and math.isfinite(v)]
    shown = f"--dist {name}={spec}"
    if kind not in ("uniform", "loguniform", "normal") or len(numbers) != 2 or len(values) != 2:
        raise ValueError(f"{shown}: expected uniform:LOW:HIGH, loguniform:LOW:HIGH, "
                         "normal:MEAN:STD (finite numbers) or choice:[V1, V2, ...]")
    if kind == "normal" and numbers[1] < 0:
        raise ValueError(f"{shown}: the standard deviation must be >= 0")
    if kind != "normal" and not numbers[0] < numbers[1]:
        raise ValueError(f"{shown}: LOW must be below HIGH")
    return [kind, *values]


_SCHEDULER = re.compile(r"^[a-z][a-z0-9+.-]*://\S+$|^[^\s:/]+:\d+$")
"""A Dask scheduler address: ``tcp://host:8786``, ``tls://...`` or ``host:8786``."""


def _campaign(args: argparse.Namespace):
    from drake_uav.campaigns.definition import Campaign

    grid = {k: [_value(v) for v in values.split(",")]
            for k, values in _pairs(args.grid, "--grid").items()}
    dists = {k: _distribution(k, spec) for k, spec in _pairs(args.dist, "--dist").items()}
    fixed = {k: _value(v) for k, v in _pairs(args.param, "--param").items()}
    try:
        return Campaign(args.scenario, _seeds(args.seeds), grid=grid, distributions=dists,
                        fixed=fixed)
    except TypeError as err:  # a value of the wrong kind (e.g. a distribution's bound)
        raise ValueError(f"campaign: {err}") from None


def _cmd_run(args: argparse.Namespace) -> int:
    from drake_uav.campaigns.results import check_results_target

    campaign = _campaign(args)
    if args.scheduler is not None and not _SCHEDULER.match(args.scheduler):
        raise ValueError(f"--scheduler {args.scheduler}: expected an address such as "
                         "tcp://host:8786")
    check_scenario(campaign.scenario)
    check_results_target(args.out)
    if args.report:
        check_output_folder(args.report, what="--report")
    from drake_uav.campaigns.runner import run_campaign

    done = run_campaign(campaign, args.out, workers=args.workers, scheduler=args.scheduler,
                        progress=not args.quiet)
    print(f"{done.path}: {done.table.num_rows} rows ({done.ran} run now, {done.resumed} "
          f"resumed, {done.errors} errors)")
    if args.report:
        from drake_uav.campaigns.summary import write_campaign_report

        print(f"report: {write_campaign_report(done.table, args.report) / 'report.html'}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from drake_uav.campaigns.results import read_results

    if args.report:
        check_output_folder(args.report, what="--report", inputs=[args.baseline, args.result])
    baseline, result = read_results(args.baseline), read_results(args.result)
    from drake_uav.campaigns.regression import compare, comparison_json

    metrics = args.metrics.split(",") if args.metrics else None
    comparison = compare(baseline, result, alpha=args.alpha, metrics=metrics)
    print(comparison_json(comparison) if args.json else comparison.message())
    if args.report:
        from drake_uav.campaigns.summary import write_campaign_report

        out = write_campaign_report(result, args.report, baseline, alpha=args.alpha)
        print(f"report: {out / 'report.html'}")
    return 0 if comparison.ok else 1


def _cmd_report(args: argparse.Namespace) -> int:
    from drake_uav.campaigns.results import read_results

    inputs = [args.result, *([args.baseline] if args.baseline else [])]
    check_output_folder(args.out, inputs=inputs)
    baseline = read_results(args.baseline) if args.baseline else None
    result = read_results(args.result)
    from drake_uav.campaigns.summary import write_campaign_report

    out = write_campaign_report(result, args.out, baseline, alpha=args.alpha)
    print(f"report: {out / 'report.html'}")
    return 0


def _run_parser(sub) -> None:
    run = sub.add_parser(
        "run", help="run a campaign and write its rows to Parquet",
        description="Run SCENARIO once per seed and grid point on a Dask cluster (a local one "
                    "with one worker per core by default) and stream one row per run to OUT. "
                    "Run it again with the same arguments to resume an interrupted campaign.")
    run.add_argument("scenario", help=f"built-in scenario ({', '.join(BUILT_IN)}) or "
                                      "package.module:function (seed, params) -> metrics")
    run.add_argument("--seeds", default="0:40", help="START:STOP or a comma list (default 0:40)")
    run.add_argument("--grid", action="append", metavar="NAME=V1,V2",
                     help="a grid parameter and its values (repeatable)")
    run.add_argument("--dist", action="append", metavar="NAME=KIND:A:B",
                     help="a parameter drawn per run: uniform:LOW:HIGH, loguniform:LOW:HIGH, "
                          "normal:MEAN:STD, choice:[V1,V2,...] (repeatable)")
    run.add_argument("--param", action="append", metavar="NAME=VALUE",
                     help="a fixed parameter (repeatable), e.g. duration=60")
    run.add_argument("--out", default="campaign.parquet",
                     help="results file (Parquet): new, or the results of the same campaign "
                          "(resumed); any other file is refused, never overwritten")
    run.add_argument("--workers", type=integer(at_least=0, at_most=1024), default=None,
                     help="local Dask workers (default: one per core; 0: in this process)")
    run.add_argument("--scheduler", metavar="ADDRESS",
                     help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    run.add_argument("--report", metavar="DIR", help="also write the HTML summary to DIR "
                                                     "(new, empty or an earlier report)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(handler=_cmd_run)


_ALPHA = real(above=0.0, below=1.0)
"""A false-alarm probability."""


def add_campaign_parser(sub) -> None:
    """Adds ``campaign run|compare|report`` to the ``drake-uav`` sub-parsers ``sub``."""
    campaign = sub.add_parser(
        "campaign", help="Monte-Carlo campaigns: run, compare with a baseline, report",
        description="Monte-Carlo campaigns of closed-loop scenarios on Dask, their results in "
                    "Parquet, and regression checks against a stored baseline.")
    commands = campaign.add_subparsers(dest="campaign_command", metavar="<run|compare|report>",
                                       required=True)
    _run_parser(commands)
    comp = commands.add_parser(
        "compare", help="check a campaign against a baseline (exit code 1 on a regression)",
        description="Compare every rate (Boschloo's exact test) and distribution (two-sample "
                    "Kolmogorov-Smirnov) of RESULT with BASELINE, grid point by grid point, at "
                    "a family-wise false-alarm probability ALPHA (Holm-Bonferroni).")
    comp.add_argument("baseline", help="baseline results (Parquet)")
    comp.add_argument("result", help="results to check (Parquet)")
    comp.add_argument("--alpha", type=_ALPHA, default=0.05,
                      help="family-wise false-alarm probability (default 0.05)")
    comp.add_argument("--metrics", help="comma list of the metrics to check (default: all)")
    comp.add_argument("--json", action="store_true", help="print the checks as JSON")
    comp.add_argument("--report", metavar="DIR", help="also write the HTML summary to DIR "
                                                      "(new, empty or an earlier report)")
    comp.set_defaults(handler=_cmd_compare)
    rep = commands.add_parser("report", help="HTML summary of a campaign",
                              description="Write an HTML summary: rates with Wilson intervals, "
                                          "histograms, errors (and the comparison with a "
                                          "baseline when given).")
    rep.add_argument("result", help="results (Parquet)")
    rep.add_argument("--baseline", help="baseline results to compare with")
    rep.add_argument("--alpha", type=_ALPHA, default=0.05, help="family-wise alpha (default 0.05)")
    rep.add_argument("--out", default="campaign_report",
                     help="report folder: new, empty or an earlier report (replaced)")
    rep.set_defaults(handler=_cmd_report)
