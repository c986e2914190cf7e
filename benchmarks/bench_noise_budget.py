"""Which sensor limits each measured coefficient, on the discovery campaign's flights.

For each sensor suite and turbulence level, the median over flights of each sensor group's
share of every coefficient's error per sample (:mod:`drake_uav.campaigns.noise_budget`:
the coefficients isolated with that group logged and every other channel true), of the
error with every sensor logged, and, beside it, the standard deviation of the coefficient
along the flight's truth (what an effect's size is a share of). Flights: the campaign's,
120 s.

    python benchmarks/bench_noise_budget.py [--seeds 500:502] [--suites default research]
        [--turbulence light moderate] [--quick]

``--quick`` flies one 60 s flight (the first seed) per suite and turbulence level.

The default seeds are tuning seeds, never those of the campaign's acceptance cells.
"""

from __future__ import annotations

import argparse

import numpy as np
from figures import figure

from drake_uav.campaigns import parse_seeds
from drake_uav.diagrams import fly
from drake_uav.model.coefficients import COEFFICIENTS
from drake_uav.testing.discovery_cases import (
    FLIGHT_DURATION,
    SUITES,
    aero_condition,
    true_coefficients,
)
from drake_uav.testing.noise_budget import ALL, SENSOR_GROUPS, noise_budget
from drake_uav.vehicles.loading import load_fixed_wing


def _true_spread(flight, params) -> dict[str, float]:
    """Standard deviation of each catalog coefficient along the flight's truth."""
    values = true_coefficients(flight, aero_condition(flight, params))
    return {c: float(np.std(values[c])) for c in COEFFICIENTS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="500:502", help="flight seeds START:END")
    parser.add_argument("--suites", nargs="+", default=list(SUITES), choices=list(SUITES))
    parser.add_argument("--turbulence", nargs="+", default=["light"],
                        choices=["light", "moderate"])
    parser.add_argument("--quick", action="store_true", help="one 60 s flight per cell")
    args = parser.parse_args()
    seeds = parse_seeds(args.seeds)[:1] if args.quick else parse_seeds(args.seeds)
    duration = 60.0 if args.quick else FLIGHT_DURATION
    params = load_fixed_wing("aerosonde")
    for suite in args.suites:
        for turbulence in args.turbulence:
            budgets, spreads = [], []
            for seed in seeds:
                flight = fly(params, turbulence, seed=seed, duration=duration,
                             sensors=SUITES[suite](params.rho))
                budgets.append(noise_budget(flight, params))
                spreads.append(_true_spread(flight, params))
            print(f"\n== {suite} sensors, {turbulence} turbulence: median RMS error per "
                  f"sample over {len(seeds)} flights ==")
            rows = [*SENSOR_GROUPS, ALL]
            print(f"  {'':18s}" + "".join(f"{c:>9s}" for c in COEFFICIENTS))
            for row in rows:
                print(f"  {row:18s}" + "".join(
                    f"{np.median([b[row][c] for b in budgets]):9.5f}" for c in COEFFICIENTS))
            print(f"  {'truth std':18s}" + "".join(
                f"{np.median([s[c] for s in spreads]):9.5f}" for c in COEFFICIENTS))
            for c in ("CL", "CD"):
                figure(f"noise_budget_{suite}_{turbulence}_{c}",
                       float(np.median([b[ALL][c] for b in budgets])), "1", "lower")


if __name__ == "__main__":
    main()
