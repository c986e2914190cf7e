"""Does flying the proposed manoeuvre resolve a near tie? Simulated flights of the campaign.

For each effect and seed, :func:`drake_uav.testing.manoeuvre_cases.fly_next` flies a
``discovery`` campaign flight (the three-axis multisine under the airspeed hold), runs the
main job, designs the manoeuvre that separates its near ties
(:func:`drake_uav.diagrams.manoeuvre_design.propose_manoeuvre`), flies it on the same
aircraft with the same effect and runs the job again. It prints, per effect, the flights
whose report held a near tie, and among them the share the manoeuvre resolved (the
injected effect named alone, with no near tie) with its 95 % Wilson interval (target
>= 80 %), the inputs the design moved (and how often it turned) and the predicted
separation (median expected F-statistic, the smaller way round, the share of the gain the
rival would reach and the column correlation, flown against designed). Then, per aliased
pair (the injected effect and one rival it was tied with on the campaign flight), the
share of those flights whose next flight told the two apart (it named the injected
effect or a near tie of it, did not name the rival and did not tie the two), with the
share the design predicted separated.

    python benchmarks/bench_manoeuvre.py [--effects tow_force,propwash_drag]
        [--seeds 0:10] [--suite research] [--size 0.2] [--turbulence light]
        [--propulsion data] [--quick]

``--propulsion catalog`` runs both jobs with the thrust known (the catalog's propulsion,
which the simulated aircraft has: what a logged motor speed or a declared propeller
gives); ``data``, the job's default, identifies it from a throttle that moves on its own.
``--quick``: one propwash-drag seed on 60 s flights with the thrust known.
"""

from __future__ import annotations

import argparse
import collections
import time
import warnings

import numpy as np

from drake_uav.campaigns import parse_seeds, wilson_interval
from drake_uav.testing.discovery_cases import FLIGHT_DURATION
from drake_uav.testing.manoeuvre_cases import fly_next

TARGET = 0.8
"""Share of the tied flights the proposed manoeuvre must resolve."""


def _rate(flags) -> str:
    k, n = int(np.sum(flags)), len(flags)
    low, high = wilson_interval(k, n) if n else (float("nan"), float("nan"))
    return f"{k}/{n} ({low:.2f}-{high:.2f})"


def _predicted(rows: list[dict]) -> str:
    pairs = [p for r in rows for p in r["predicted"]]
    if not pairs:
        return "no pair designed for"
    f = {k: np.median([min(p["expected_f"]["first_true"][k], p["expected_f"]["second_true"][k])
                       for p in pairs]) for k in ("flown", "designed")}
    c = {k: np.median([p["correlation"][k] for p in pairs]) for k in ("flown", "designed")}
    share = {k: np.median([max(p["rival_share"]["first_true"][k],
                               p["rival_share"]["second_true"][k]) for p in pairs])
             for k in ("flown", "designed")}
    return (f"{len(pairs)} pairs, {sum(p['resolves'] for p in pairs)} predicted separated: "
            f"rival's share of the gain (median) {share['flown']:.0%} flown -> "
            f"{share['designed']:.0%} designed; expected F {f['flown']:.1f} -> "
            f"{f['designed']:.1f}; correlation {c['flown']:.3f} -> {c['designed']:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effects", default="tow_force,propwash_drag")
    parser.add_argument("--seeds", default="0:10", help="START:END")
    parser.add_argument("--suite", default="research")
    parser.add_argument("--size", type=float, default=0.2)
    parser.add_argument("--turbulence", default="light")
    parser.add_argument("--duration", type=float, default=FLIGHT_DURATION)
    parser.add_argument("--propulsion", default="data", choices=("data", "catalog"),
                        help="the job's thrust: identified from the data, or known "
                             "(catalog: as with a logged motor speed)")
    parser.add_argument("--quick", action="store_true",
                        help="one propwash-drag seed, 60 s, thrust known")
    args = parser.parse_args()
    if args.quick:
        args.effects, args.seeds, args.duration = "propwash_drag", "0:1", 60.0
        args.propulsion = "catalog"
    warnings.simplefilter("ignore")  # the thrust/C_X confounding note of every flight
    start = time.perf_counter()
    for effect in args.effects.split(","):
        rows = []
        for seed in parse_seeds(args.seeds):
            row = fly_next(seed, effect, suite=args.suite, size=args.size,
                           turbulence=args.turbulence, duration=args.duration,
                           propulsion=args.propulsion)
            rows.append(row)
            print(f"  {effect} seed {seed}: first {row['found_first'] or '-'}"
                  f"{' (tied)' if row['tied_first'] else ''}; inputs {row['selected'] or '-'};"
                  f" next {row['found_next'] or '-'}{' (tied)' if row['tied_next'] else ''}",
                  flush=True)
        tied = [r for r in rows if r["resolved"] is not None]
        selected = collections.Counter(r["selected"] + (" in a turn" if r["turn"] else "")
                                       for r in tied)
        print(f"{effect} ({args.suite}, {args.turbulence}, size {args.size:.0%}, thrust "
              f"{args.propulsion}): "
              f"{len(tied)} of {len(rows)} flights with a near tie between named effects; "
              f"resolved by the next flight {_rate([r['resolved'] for r in tied])} "
              f"(target >= {TARGET:.0%}); exact on the first flight "
              f"{_rate([r['found_first'] == r['expected'] and not r['tied_first'] for r in rows])}"
              f"; inputs: " + ", ".join(f"{k} x{n}" for k, n in selected.most_common())
              + f"; {_predicted(tied)}")
        _print_pairs(rows)
    print(f"{time.perf_counter() - start:.0f} s wall")


def _print_pairs(rows: list[dict]) -> None:
    """Per aliased pair: how often the next flight told them apart, and the prediction."""
    outcomes = collections.defaultdict(list)
    predicted = collections.defaultdict(list)
    for r in rows:
        for rival, apart in r["pairs"].items():
            outcomes[rival].append(apart)
            predicted[rival] += [p["resolves"] for p in r["predicted"]
                                 if {p["first"], p["second"]} == {r["expected"], rival}]
    for rival, flags in sorted(outcomes.items()):
        guess = predicted[rival]
        print(f"    {rows[0]['expected']} against {rival}: told apart by the next flight "
              f"{_rate(flags)} (target >= {TARGET:.0%}); predicted separated on "
              f"{sum(guess)} of {len(guess)} designed for")


if __name__ == "__main__":
    main()
