"""Hexacopter tracking a minimum-snap trajectory with the NMPC of Argyropoulos 2020, ch. 4.

Builds the time-varying terminal sets along the bundled 6-waypoint trajectory,
flies it from a 0.5 m / 10 deg offset with the real-time-iteration NMPC, prints
the tracking RMSE and solve times and writes the plots.

    python examples/nmpc_tracking.py [out_folder] [rti|nlp]   (default out/nmpc_tracking rti)
    python examples/nmpc_tracking.py --quick   (a coarser terminal level, the first 3 s)
"""

import argparse

import numpy as np

from drake_uav.diagrams.tracking import (
    build_terminal_set,
    fly_tracking,
    solve_time_stats,
    tracking_reference,
)
from drake_uav.optimization.nmpc import NmpcSettings
from drake_uav.reporting.tracking_figures import write_tracking_plots
from drake_uav.vehicles.multirotor import hexacopter

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("out", nargs="?", default="out/nmpc_tracking", help="folder of the plots")
parser.add_argument("mode", nargs="?", default="rti", choices=("rti", "nlp"))
parser.add_argument("--quick", action="store_true",
                    help="a coarser terminal level; fly the first 3 s only")
args = parser.parse_args()
params = hexacopter()
# --quick: fewer boundary directions and shrink points for the terminal level.
coarse = {"samples": 32, "shrink_interval": 1.0} if args.quick else {}
terminal = build_terminal_set(params, tracking_reference(params), **coarse)
print(f"terminal level pi~ in [{terminal.pi_shrunk.min():.3g}, {terminal.pi_shrunk.max():.3g}]"
      f" (LP level before the shrink: {terminal.pi.min():.3g})")
duration = 3.0 if args.quick else terminal.end_time + 2.0
run = fly_tracking(params, terminal, duration, settings=NmpcSettings(mode=args.mode),
                   offset=(0.3, 0.4, 0.0), attitude_offset=np.radians(10.0))
stats = solve_time_stats(run)
print(f"RMSE after 2 s: {100 * run.rmse(2.0):.2f} cm; solve time median "
      f"{1e3 * stats['median']:.1f} ms, p95 {1e3 * stats['p95']:.1f} ms")
for path in write_tracking_plots(run, args.out):
    print(path)
