"""What the campaign's drag-axis effects leave for the data to see.

For each effect of the discovery campaign that acts on C_D, the median over flights of its
unique share (:mod:`drake_uav.campaigns.drag_aliasing`: ``1 - R^2`` of its term on a set of
columns, along the flight's truth) against the catalog's C_D terms, against those with the
throttle terms of a thrust identified from the flight, and against the catalog's terms with
each other drag-axis effect; for the campaign's flight ("multisine") and for one that also
moves the throttle ("multisine_throttle"), 120 s, light and moderate turbulence.

    python benchmarks/bench_drag_aliasing.py [--seeds 0:5] [--quick]

``--quick`` flies one seed of 60 s per excitation and turbulence level.

A share near 0 means the baseline (or the other effect) already reproduces the effect:
its fit moves the baseline's coefficients, and no evidence rule can name it.
"""

from __future__ import annotations

import argparse

import numpy as np
from figures import figure

from drake_uav.campaigns import parse_seeds
from drake_uav.diagrams import fly
from drake_uav.testing.discovery_cases import EXCITATIONS, FLIGHT_DURATION
from drake_uav.testing.drag_aliasing import WITH_THRUST, drag_axis_shares
from drake_uav.vehicles.loading import load_fixed_wing


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0:5", help="seeds of the flights START:END")
    parser.add_argument("--quick", action="store_true", help="one seed, 60 s flights")
    args = parser.parse_args()
    seeds = parse_seeds(args.seeds)[:1] if args.quick else parse_seeds(args.seeds)
    duration = 60.0 if args.quick else FLIGHT_DURATION
    params = load_fixed_wing("aerosonde")
    for excitation in EXCITATIONS:
        shares = [drag_axis_shares(fly(params, turbulence, excitation=excitation, seed=seed,
                                       duration=duration), params)
                  for turbulence in ("light", "moderate") for seed in seeds]
        print(f"\n== {excitation}: median unique share over {len(shares)} flights "
              "(light and moderate turbulence) ==")
        for effect, against in shares[0].items():
            print(f"  {effect}")
            for name in against:
                median = float(np.median([s[effect][name] for s in shares]))
                print(f"    against {name:55s} {median:.2g}")
            figure(f"drag_aliasing_{effect}_{excitation}",
                   float(np.median([s[effect][WITH_THRUST] for s in shares])), "1", "higher")


if __name__ == "__main__":
    main()
