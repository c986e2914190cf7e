"""Speed of the motor-failure pieces (Argyropoulos 2020, ch. 5-6).

* classification at run time: :meth:`FaultSupervisor.classify` (closure LP, tube value
  at the fault state and along the remaining reference every 0.1 s) for a category-I
  and a category-IV failure, against one tube query (its floor, measured in the same
  run);
* each scenario's real-time factor: simulated time over the wall time of
  ``fly_fault`` (plant, supervisor, fault-tolerant NMPC at 80 Hz, ground), next to the
  same mission flown as long without a failure (the nominal NMPC alone, the peer).

Tubes come from the disk cache (a cold cache computes them first; that time is the
tube benchmark's, not this one's). ``--quick`` uses the coarse tubes and flies one
scenario for its first 5 s (seconds); the default flies all seven to their end.

Run: python benchmarks/bench_faults.py [--quick]
"""

import argparse
import functools
import time

import numpy as np
from figures import figure

from drake_uav.diagrams.fault_scenarios import (
    SCENARIOS,
    fault_vehicle,
    fly_scenario,
    scenario_reference,
    scenario_tubes,
)
from drake_uav.diagrams.faults import fly_fault
from drake_uav.optimization.reachability import TubeSettings
from drake_uav.systems.faults import FaultSupervisor


def _best(f, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def classification(params, tubes, repeats: int) -> None:
    for name in ("I", "IVa"):
        sc = SCENARIOS[name]
        ref = scenario_reference(sc, params)
        sup = FaultSupervisor(params, ref, tubes)
        health = np.ones(params.num_motors)
        health[list(sc.failed_motors)] = 0.0
        x = ref.at(sc.fault_time)[0]
        sup.classify(sc.fault_time, x, health)  # loads the tube
        wall = _best(functools.partial(sup.classify, sc.fault_time, x, health), repeats)
        query = _best(functools.partial(tubes(sc.failed_motors), x), 20 * repeats)
        print(f"classification {name} ({sc.expected.name}): {1e3 * wall:.2f} ms; one tube "
              f"query {1e6 * query:.1f} us (ratio {wall / query:.0f})")
        figure(f"fault_classification_{name}", 1e3 * wall, "ms", "lower")


def real_time_factors(params, tubes, names, duration: float | None) -> None:
    for name in names:
        sc = SCENARIOS[name]
        ref = scenario_reference(sc, params)
        start = time.perf_counter()
        run = fly_scenario(sc, params, tube_for=tubes, duration=duration)
        fault_wall = time.perf_counter() - start
        flown = run.time[-1]
        start = time.perf_counter()
        fly_fault(params, ref, (), flown)
        peer = flown / (time.perf_counter() - start)
        rtf = flown / fault_wall
        print(f"{name:5s} category {run.category.name:3s} {flown:6.2f} s simulated: real-time "
              f"factor {rtf:5.2f} (no failure, same mission and time: {peer:5.2f}; ratio "
              f"{rtf / peer:.2f})", flush=True)
        figure(f"fault_rtf_{name}", rtf, "x", "higher")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="coarse tubes, two scenarios, seconds")
    args = parser.parse_args(argv)
    params = fault_vehicle()
    tubes = scenario_tubes(params, TubeSettings.coarse() if args.quick else None)
    classification(params, tubes, 3 if args.quick else 20)
    names = ("IIa",) if args.quick else tuple(SCENARIOS)
    real_time_factors(params, tubes, names, 5.0 if args.quick else None)


if __name__ == "__main__":
    main()
