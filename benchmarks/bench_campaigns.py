"""Benchmark: a main-job campaign on a 2-worker Dask LocalCluster vs the same runs in one process.

Each run is a 60 s identification flight with propeller slipstream drag put into the
physics, then the main job on its log (the built-in ``main_job`` scenario). The same
campaign runs twice: every run in this process one after the other (``workers=0``), then on
a new LocalCluster of ``--workers`` worker processes (one thread each); the wall time of the
cluster run includes starting the cluster and the workers' first imports. Prints both wall
times, their ratio (target <= 0.6 with 2 workers on 2 cores) and checks that both give the
same rows bit for bit (outside the wall-time column).

    python benchmarks/bench_campaigns.py [--flights 40] [--workers 2] [--duration 60]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from drake_uav.campaigns import Campaign, results_equal, run_campaign


def _timed(campaign: Campaign, out: Path, workers: int) -> tuple[float, object]:
    start = time.perf_counter()
    done = run_campaign(campaign, out, workers=workers, progress=True)
    return time.perf_counter() - start, done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=40, help="runs (seeds 0..N-1)")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster workers")
    parser.add_argument("--duration", type=float, default=60.0, help="flight duration [s]")
    args = parser.parse_args()
    campaign = Campaign("main_job", seeds=range(args.flights),
                        fixed={"duration": args.duration, "effect": "propwash_drag"})
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        serial, one = _timed(campaign, Path(tmp) / "serial.parquet", 0)
        parallel, many = _timed(campaign, Path(tmp) / "parallel.parquet", args.workers)
    print(f"\n{args.flights} main-job runs ({args.duration:g} s flights), {os.cpu_count()} cores,"
          f" load average {load:.1f} before / {os.getloadavg()[0]:.1f} after (with other load "
          f"on the machine the ratio says little)")
    for label, total, done in (("one process", serial, one),
                               (f"LocalCluster, {args.workers} workers", parallel, many)):
        runs = done.table.column("wall_time_s").to_pylist()
        print(f"  {label:24s}: {total:8.1f} s  (a run: {sum(runs) / len(runs):.1f} s mean)")
    print(f"  ratio                   : {parallel / serial:8.2f}  (target <= 0.6 with 2 "
          f"workers)")
    print(f"  rows identical          : {results_equal(one.table, many.table)}; "
          f"errors {one.errors} / {many.errors}")
    detected = sum(one.table.column("metric.detected").to_pylist())
    print(f"  propwash drag detected  : {detected}/{args.flights}")


if __name__ == "__main__":
    main()
