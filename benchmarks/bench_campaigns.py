"""Benchmark: a main-job campaign on a 2-worker Dask LocalCluster vs the same runs in one process.

Each run is a 60 s identification flight with propeller slipstream drag put into the
physics, then the main job on its log (the built-in ``main_job`` scenario). The same
campaign runs twice, each time in a fresh Python process started the same way: every run
in that process one after the other (``workers=0``), then on a new LocalCluster of
``--workers`` worker processes (one thread each). Each wall time is that of the
``run_campaign`` call alone, so both include loading the scenario's modules in the calling
process and the first run's warm-up; the cluster's also includes starting the cluster and
its workers' own imports and warm-up. Both modes run numerical libraries on one thread (the
workers' Dask setting, and the command line's for the one-process run; a thread count set
in the environment wins in both). Prints both wall times, their ratio (target <= 0.6 with 2
workers on 2 cores), how much CPU other processes took meanwhile (on Linux; with other load
the ratio says little), and checks that both give the same rows bit for bit (outside the
wall-time column). ``--repeats N`` runs each mode N times, alternating, and keeps each
mode's best wall time. ``--quick`` runs 2 flights of 30 s in each mode (the same figures;
the ratio then mostly measures the cluster's start-up).

    python benchmarks/bench_campaigns.py [--flights 40] [--workers 2] [--duration 60]
                                         [--repeats 1] [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from figures import figure

from drake_uav.campaigns import Campaign, read_results, results_equal

ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Thread counts set to 1 (unless already set) for both modes: the LocalCluster's workers get
them from Dask, the ``drake-uav`` command sets ``OPENBLAS_NUM_THREADS`` the same way."""


def _campaign(flights: int, duration: float) -> Campaign:
    return Campaign("main_job", seeds=range(flights),
                    fixed={"duration": duration, "effect": "propwash_drag"})


def _cpu_seconds(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def _one_mode(args: argparse.Namespace) -> None:
    """Runs the campaign once in this process (``--workers`` 0: no Dask) and prints the
    wall time of ``run_campaign`` and the CPU time of this process and its children."""
    from drake_uav.campaigns import run_campaign

    campaign = _campaign(args.flights, args.duration)
    cpu = _cpu_seconds(resource.RUSAGE_SELF), _cpu_seconds(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = run_campaign(campaign, args.child, workers=args.workers, progress=True)
    wall = time.perf_counter() - start
    print(json.dumps({"wall": wall, "errors": done.errors,
                      "cpu_self": _cpu_seconds(resource.RUSAGE_SELF) - cpu[0],
                      "cpu_children": _cpu_seconds(resource.RUSAGE_CHILDREN) - cpu[1]}))


def _busy_cpu_seconds() -> float:
    """CPU seconds the whole machine has spent busy (Linux ``/proc/stat``; NaN elsewhere)."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    except OSError:
        return float("nan")
    user, nice, system, _idle, _iowait, irq, softirq = map(int, fields[:7])
    return (user + nice + system + irq + softirq) / os.sysconf("SC_CLK_TCK")


def _timed(args: argparse.Namespace, out: Path, workers: int) -> dict:
    """The figures of one mode, run in a fresh process."""
    env = dict(os.environ)
    for name in ONE_THREAD:
        env.setdefault(name, "1")
    command = [sys.executable, __file__, "--flights", str(args.flights), "--duration",
               str(args.duration), "--workers", str(workers), "--child", str(out)]
    busy = _busy_cpu_seconds()
    done = subprocess.run(command, env=env, stdout=subprocess.PIPE, text=True, check=True)
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    ours = figures["cpu_self"] + figures["cpu_children"]
    figures["others"] = max(_busy_cpu_seconds() - busy - ours, 0.0)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=40, help="runs (seeds 0..N-1)")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster workers")
    parser.add_argument("--duration", type=float, default=60.0, help="flight duration [s]")
    parser.add_argument("--repeats", type=int, default=1,
                        help="runs of each mode, alternating; each mode's best is kept")
    parser.add_argument("--quick", action="store_true", help="2 flights of 30 s, once")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.quick:
        args.flights, args.duration, args.repeats = 2, 30.0, 1
    if args.child is not None:
        _one_mode(args)
        return
    load = os.getloadavg()[0]
    modes = {"one process": 0, f"LocalCluster, {args.workers} workers": args.workers}
    timed: dict[str, list[dict]] = {label: [] for label in modes}
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(args.repeats):
            for k, (label, workers) in enumerate(modes.items()):
                out = Path(tmp) / f"mode{k}_{repeat}.parquet"
                timed[label].append({**_timed(args, out, workers), "table": read_results(out)})
    best = {label: min(runs, key=lambda t: t["wall"]) for label, runs in timed.items()}
    print(f"\n{args.flights} main-job runs ({args.duration:g} s flights), {os.cpu_count()} cores,"
          f" load average {load:.1f} before / {os.getloadavg()[0]:.1f} after")
    for label, t in best.items():
        runs = t["table"].column("wall_time_s").to_pylist()
        print(f"  {label:24s}: {t['wall']:8.1f} s  (a run: {sum(runs) / len(runs):.2f} s mean;"
              f" CPU {t['cpu_self']:.1f} s here + {t['cpu_children']:.1f} s in workers;"
              f" other processes {t['others']:.1f} CPU s)")
        if args.repeats > 1:
            print("  " + " " * 24 + "  every run: " + ", ".join(
                f"{r['wall']:.1f} s (others {r['others']:.1f})" for r in timed[label]))
    serial, parallel = (t["wall"] for t in best.values())
    print(f"  ratio                   : {parallel / serial:8.3f}  (target <= 0.6 with 2 "
          f"workers; other processes' CPU above 2 % of the wall time makes it say little)")
    tables = [r["table"] for runs in timed.values() for r in runs]
    print(f"  rows identical          : {all(results_equal(tables[0], t) for t in tables)};"
          f" errors {' / '.join(str(t['errors']) for t in best.values())}")
    detected = sum(tables[0].column("metric.detected").to_pylist())
    print(f"  propwash drag detected  : {detected}/{args.flights}")
    figure("campaign_cluster_to_one_process_wall", parallel / serial, "ratio", "lower")
    if args.quick and any(t["errors"] for t in best.values()):
        raise SystemExit("runs failed")


if __name__ == "__main__":
    main()
