"""Fly a 60 s identification flight in moderate turbulence and look at the log.

Orthogonal multisines on elevator, aileron and rudder on top of the trim, the low-cost
sensor suite of Vaiopoulos 2017, Dryden gusts and a 4 m/s crosswind. The log holds
what the autopilot would record (measured) and the simulation truth.

Run: python examples/identification_flight.py [output.png]   (default out/identification_flight.png)
     python examples/identification_flight.py --quick   (a 20 s flight)
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from drake_uav.diagrams.identification_flight import fly

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("output", nargs="?", default="out/identification_flight.png",
                    help="figure file (the log goes next to it as .parquet)")
parser.add_argument("--quick", action="store_true", help="a 20 s flight instead of 60 s")
args = parser.parse_args()

log = fly("aerosonde", turbulence="moderate", steady_wind=(0.0, 4.0, 0.0),
          excitation="multisine", seed=7, duration=20.0 if args.quick else 60.0)
print(log)
for measured, true in (("imu_q", "q"), ("vane_alpha", "alpha"), ("pitot_airspeed", "airspeed")):
    error = log[measured] - log[true]
    print(f"{measured:15s} - {true:9s}: mean {error.mean():+.4f}, std {error.std():.4f} "
          f"[{log.unit(true)}]")

out = Path(args.output)
out.parent.mkdir(parents=True, exist_ok=True)
log.save(out.with_suffix(".parquet"))

t = log.time
fig, axes = plt.subplots(4, 1, sharex=True, figsize=(9, 9))
for surface in ("elevator", "aileron", "rudder"):
    axes[0].plot(t, np.degrees(log[f"cmd_{surface}"]), label=surface)
axes[0].set_ylabel("command [deg]")
axes[0].legend(ncol=3, loc="upper right")
axes[1].plot(t, np.degrees(log["vane_alpha"]), ".", ms=1, color="0.6", label="vane")
axes[1].plot(t, np.degrees(log["alpha"]), label="true")
axes[1].set_ylabel("alpha [deg]")
axes[1].legend(loc="upper right")
axes[2].plot(t, np.degrees(log["imu_p"]), ".", ms=1, color="0.6", label="gyro")
axes[2].plot(t, np.degrees(log["p"]), label="true")
axes[2].set_ylabel("roll rate [deg/s]")
axes[2].legend(loc="upper right")
for axis in ("u", "v", "w"):
    axes[3].plot(t, log[f"gust_{axis}"], label=f"gust {axis}")
axes[3].set_ylabel("gust, body [m/s]")
axes[3].set_xlabel("time [s]")
axes[3].legend(ncol=3, loc="upper right")
fig.suptitle("Aerosonde identification flight: multisines, moderate Dryden turbulence")
fig.tight_layout()
fig.savefig(out, dpi=120)
print(f"figure written to {out}, log to {out.with_suffix('.parquet')}")
