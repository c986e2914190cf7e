"""Campaign: the main job on realistic autopilot logs against the vane CSV of the same flight.

Each seed flies one identification flight with an effect the catalog model lacks,
writes it as an ArduPlane .bin and a PX4 .ulg (ground segment, take-off, late GPS,
PWM 0 before arming, reversed servo, +-400 us throws, 50 Hz IMU, 10 Hz pitot, 1 Hz
optional topics, truncated tail, no vanes) and as a vane-equipped CSV, and runs the
main job on each file as `drake-uav identify FILE` does with no option (the
``realistic_logs`` scenario). Prints, per format, the exact-detection rate (the
injected effect and nothing else) with its 95 % Wilson interval, how often each
extra effect appeared, the agreement with the CSV, and the alpha/beta error of the
vaneless estimate against the truth.

    python benchmarks/bench_realistic_logs.py [--seeds 0:5] [--effect elevator_roll]
        [--duration 180] [--workers 2] [--quick]

``--quick`` runs one seed of 90 s in this process.
"""

from __future__ import annotations

import argparse
import collections
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from figures import figure

from drake_uav.campaigns import Campaign, parse_seeds, read_results, run_campaign, wilson_interval
from drake_uav.testing.realistic_logs import FORMATS


def _rate(flags) -> str:
    k, n = int(np.sum(flags)), len(flags)
    low, high = wilson_interval(k, n)
    return f"{k}/{n} ({low:.2f}-{high:.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0:5", help="seed range START:END")
    parser.add_argument("--effect", default="elevator_roll", help="a main_job EFFECTS key")
    parser.add_argument("--duration", type=float, default=180.0, help="flight time [s]")
    parser.add_argument("--workers", type=int, default=2, help="0: in this process")
    parser.add_argument("--quick", action="store_true", help="one 90 s flight in this process")
    args = parser.parse_args()
    if args.quick:
        args.seeds, args.duration, args.workers = str(parse_seeds(args.seeds)[0]), 90.0, 0
    campaign = Campaign("realistic_logs", seeds=parse_seeds(args.seeds),
                        fixed={"effect": args.effect, "duration": args.duration})
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "realistic.parquet"
        run_campaign(campaign, out, workers=args.workers, progress=True)
        rows = [{k.removeprefix("metric."): v for k, v in row.items()}
                for row in read_results(out).to_pylist()]
    wall = time.perf_counter() - start
    ok = [r for r in rows if r["status"] == "ok"]
    print(f"{len(ok)} of {len(rows)} runs finished, effect {args.effect}, {args.duration:g} s "
          f"flights, {wall:.0f} s wall on {args.workers or 1} worker(s), load "
          f"{os.getloadavg()[0]:.1f}")
    for row in rows:
        if row["status"] != "ok":
            print(f"  seed {row['seed']}: {row['status']} {row.get('error', '')}")
    if args.quick and len(ok) < len(rows):
        raise SystemExit(f"{len(rows) - len(ok)} run(s) failed")
    for kind in FORMATS:
        named = collections.Counter(name for r in ok for name in str(r[f"found_{kind}"]).split(",")
                                    if name)
        print(f"  {kind:4s} exact detection {_rate([r[f'exact_{kind}'] for r in ok])}; "
              "effects named: " + ", ".join(f"{n} x{c}" for n, c in named.most_common()))
        figure(f"realistic_exact_detection_{kind}",
               float(np.mean([r[f"exact_{kind}"] for r in ok])), "1", "higher")
    for kind in ("bin", "ulg"):
        print(f"  {kind} same findings as the vane CSV: "
              f"{_rate([r[f'same_as_csv_{kind}'] for r in ok])}")
    for name in ("alpha", "beta"):
        mae = np.array([r[f"{name}_mae_deg"] for r in ok], float)
        print(f"  {name} MAE of the vaneless estimate: mean {mae.mean():.2f} deg, max "
              f"{mae.max():.2f} deg (target <= 0.5), per seed "
              + " ".join(f"{v:.2f}" for v in mae))
        figure(f"realistic_{name}_mae_max", float(mae.max()), "deg", "lower")

if __name__ == "__main__":
    main()
