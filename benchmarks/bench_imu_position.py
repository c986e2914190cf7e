"""An IMU away from the centre of gravity: the main job without and with its position.

Flights of the discovery campaign (Aerosonde, 120 s, the default multisine) with the IMU
20 cm ahead of the centre of gravity, 5 cm left and 10 cm below
(:mod:`drake_uav.campaigns.imu_offset`); the job on the measured channels alone, once
without the IMU position and once with it (as the autopilot's ``INS_POS<n>_*`` or
``EKF2_IMU_POS_*`` give it). Prints, per sensor suite and turbulence level, the flights
with any finding and with an air-data time skew applied, and the findings' names.

    python benchmarks/bench_imu_position.py [--seeds 200:220] [--workers 2] [--quick]

``--quick`` runs one flight (the first seed, default sensors, light turbulence) on one worker.
"""

from __future__ import annotations

import argparse
import collections
import multiprocessing

from figures import figure

from drake_uav.campaigns import parse_seeds
from drake_uav.testing.imu_offset import imu_offset_run


def _run(job: tuple[int, str, str]) -> tuple[tuple[str, str], dict]:
    seed, turbulence, suite = job
    return (suite, turbulence), imu_offset_run(seed, turbulence, suite)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="200:220", help="seeds of the flights START:END")
    parser.add_argument("--turbulence", default="light,moderate")
    parser.add_argument("--suites", default="default")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--quick", action="store_true",
                        help="one flight: first seed, default sensors, light turbulence")
    args = parser.parse_args()
    if args.quick:
        args.seeds = str(parse_seeds(args.seeds)[0])
        args.turbulence, args.suites, args.workers = "light", "default", 1
    jobs = [(seed, turbulence, suite) for suite in args.suites.split(",")
            for turbulence in args.turbulence.split(",") for seed in parse_seeds(args.seeds)]
    cells = collections.defaultdict(list)
    with multiprocessing.get_context("spawn").Pool(args.workers, maxtasksperchild=1) as pool:
        for cell, result in pool.imap_unordered(_run, jobs):
            cells[cell].append(result)
    for (suite, turbulence), results in sorted(cells.items()):
        n = len(results)
        print(f"\n== {suite} sensors, {turbulence} turbulence, {n} flights ==")
        for key in ("without", "with"):
            found = [r[f"found_{key}"] for r in results if r[f"found_{key}"]]
            skewed = [r[f"skew_{key}"] for r in results if r[f"skew_{key}"]]
            names = collections.Counter(x for f in found for x in f.split(","))
            print(f"  {key:7s} the IMU position: {len(found)}/{n} flights with a finding, "
                  f"{len(skewed)}/{n} with an air-data skew applied"
                  + (f" ({min(skewed) * 1e3:.0f} to {max(skewed) * 1e3:.0f} ms)" if skewed
                     else "")
                  + (f"; {dict(names.most_common())}" if names else ""))
            figure(f"imu_position_{key}_{suite}_{turbulence}_flights_with_a_finding",
                   len(found) / n, "1", "lower")


if __name__ == "__main__":
    main()
