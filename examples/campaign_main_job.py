"""A regression campaign of the main job: does it find propeller slipstream drag, and does it
stay quiet on clean flights?

Flies 60 s identification flights (seeds 0..N-1) with and without the effect on a local
Dask cluster (one worker per core), writes one Parquet row per flight, the HTML summary
(rates with Wilson intervals, histograms), and compares the campaign with a baseline when
one is given. Run it again after an interruption: finished flights are not flown again.

Run: python examples/campaign_main_job.py [--seeds 0:10] [--baseline baseline.parquet]
     python examples/campaign_main_job.py --quick   (seed 0 only, 30 s flights, its own file)
"""

import argparse
from pathlib import Path

from drake_uav.campaigns import (
    Campaign,
    compare,
    parse_seeds,
    read_results,
    run_campaign,
)
from drake_uav.campaigns.summary import write_campaign_report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0:10", help="START:STOP (default 0:10)")
    parser.add_argument("--out", default="out/campaign_main_job.parquet", help="results file")
    parser.add_argument("--baseline", help="an earlier results file to compare with")
    parser.add_argument("--workers", type=int, default=None, help="default: one per core")
    parser.add_argument("--quick", action="store_true",
                        help="seed 0 only, 30 s flights, results in out/campaign_main_job_quick")
    args = parser.parse_args()
    duration = 60.0
    if args.quick:
        duration, args.seeds = 30.0, "0"
        if args.out == parser.get_default("out"):
            args.out = "out/campaign_main_job_quick.parquet"

    campaign = Campaign("main_job", seeds=parse_seeds(args.seeds),
                        grid={"effect": ["propwash_drag", "none"]},
                        fixed={"duration": duration, "turbulence": "light"})
    done = run_campaign(campaign, args.out, workers=args.workers)
    print(f"{done.path}: {done.table.num_rows} rows, {done.ran} flown now, "
          f"{done.resumed} from an earlier run, {done.errors} errors")

    for row in done.table.to_pylist():
        if row["status"] != "ok":
            print(f"  seed {row['seed']} ({row['param.effect']}): {row['error']}")
    rows = [r for r in done.table.to_pylist() if r["status"] == "ok"]
    with_effect = [r for r in rows if r["param.effect"] == "propwash_drag"]
    clean = [r for r in rows if r["param.effect"] == "none"]
    print(f"propwash drag detected in {sum(r['metric.detected'] for r in with_effect)}"
          f"/{len(with_effect)} flights; clean flights with a discovery: "
          f"{sum(r['metric.any_discovery'] for r in clean)}/{len(clean)}")

    baseline = read_results(args.baseline) if args.baseline else None
    if baseline is not None:
        print(compare(baseline, done.table).message())
    report = write_campaign_report(done.table, Path(args.out).with_suffix(""), baseline)
    print(f"report: {report / 'report.html'}")


if __name__ == "__main__":  # the Dask workers import this file: run only in the main process
    main()
