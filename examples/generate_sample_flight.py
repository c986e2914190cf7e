"""Regenerate the sample flight bundled with drake_uav (drake_uav/data/sample_flight.parquet).

An Aerosonde identification flight (orthogonal multisines, light Dryden turbulence,
the sensor suite of Vaiopoulos 2017, Table 7) with one effect its catalog model does not
have: propeller slipstream drag, C_D += 0.1 T_c (Vaiopoulos 2017 found such a C_D_Tc term in
its flight data). Only the measured channels are kept, at the 100 Hz at which the autopilot
issues its commands (a log thinned after the flight loses the commands in between, and the
main job would see them late); the metadata records how the flight was made.

Run: python examples/generate_sample_flight.py [out.parquet]   (default out/sample_flight.parquet)
     python examples/generate_sample_flight.py --bundle   (replaces the bundled file)
     python examples/generate_sample_flight.py --quick    (a 30 s flight, never bundled)
"""

import argparse
from pathlib import Path

import drake_uav
from drake_uav.diagrams import fly

PROPWASH_DRAG = 0.1
"""C_D per unit thrust coefficient added by the slipstream."""

BUNDLED = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("output", nargs="?", default="out/sample_flight.parquet",
                    help="where to write the flight (default: %(default)s)")
parser.add_argument("--bundle", action="store_true",
                    help=f"write the package's bundled sample instead ({BUNDLED})")
parser.add_argument("--quick", action="store_true",
                    help="a 30 s flight (a try of the script; not with --bundle)")
args = parser.parse_args()
if args.quick and args.bundle:
    parser.error("--quick writes a 30 s flight, not the bundled sample: drop one of them")

log = fly("aerosonde", turbulence="light", seed=2026, duration=30.0 if args.quick else 150.0,
          disturbance=lambda c: (0.0, PROPWASH_DRAG * c.thrust_coefficient, 0, 0, 0, 0))
sample = log.select(log.measured_names)
sample.metadata.update(
    injected_effect=f"C_D += {PROPWASH_DRAG} T_c (propwash drag)",
    generator=f"examples/generate_sample_flight.py, drake_uav {drake_uav.__version__}")
out = BUNDLED if args.bundle else Path(args.output)
out.parent.mkdir(parents=True, exist_ok=True)
print(f"sample flight written to {sample.save(out)} ({len(sample)} samples)")
