"""Waypoints -> minimum-snap trajectory -> hexacopter reference (Argyropoulos 2020 fig. 2.2).

Plans one mission twice, with equal segment times and with the times found by
the constrained gradient descent (same total time), then derives the hexacopter
reference motor thrusts from the optimal trajectory by differential flatness.

    python examples/minimum_snap_hexacopter.py [figure.png]   (out/minimum_snap_hexacopter.png)
    python examples/minimum_snap_hexacopter.py --quick   (the reference at 10 Hz instead of 50 Hz)
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drake_uav.optimization.flatness import flat_reference, velocity_heading  # noqa: E402
from drake_uav.optimization.min_snap import minimum_snap, optimize_segment_times  # noqa: E402
from drake_uav.vehicles.multirotor import hexacopter  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("output", nargs="?", default="out/minimum_snap_hexacopter.png",
                    help="figure file")
parser.add_argument("--quick", action="store_true", help="the reference at 10 Hz, not 50 Hz")
args = parser.parse_args()

# NED waypoints [m] (negative down = up): take off, uneven legs, come back.
waypoints = np.array([[0, 0, 0], [0, 0, -3], [2, 1, -4], [10, 3, -5], [11, 9, -5],
                      [4, 10, -4], [0, 0, -2]], dtype=float)
equal_times = np.linspace(0.0, 24.0, len(waypoints))

equal = minimum_snap(waypoints, equal_times)
optimal = optimize_segment_times(waypoints, equal_times)
print(f"snap cost: equal times {optimal.initial_cost:.3f}, optimal times {optimal.cost:.3f} "
      f"({optimal.iterations} iterations)")
print("optimal segment times [s]:", np.round(np.diff(optimal.times), 2))

vehicle = hexacopter()
t = np.linspace(0.0, 24.0, 241 if args.quick else 1201)
reference = flat_reference(optimal.trajectory, vehicle, t, yaw=velocity_heading(optimal.trajectory))
print(f"motor thrust range {reference.motor_thrusts.min():.2f}.."
      f"{reference.motor_thrusts.max():.2f} N (f_max {vehicle.f_max} N)")

fig, ax = plt.subplots(2, 2, figsize=(11, 8))
for traj, label in ((equal, "equal times"), (optimal.trajectory, "optimal times")):
    p = traj.position(t)
    ax[0, 0].plot(p[:, 1], p[:, 0], label=label)
    ax[0, 1].plot(t, np.linalg.norm(traj.velocity(t), axis=1), label=label)
    ax[1, 0].plot(t, np.linalg.norm(traj.value(t, 4), axis=1), label=label)
ax[0, 0].plot(waypoints[:, 1], waypoints[:, 0], "ko", label="waypoints")
ax[0, 0].set(xlabel="east [m]", ylabel="north [m]", title="path (top view)", aspect="equal")
ax[0, 1].set(xlabel="t [s]", ylabel="speed [m/s]", title="speed")
ax[1, 0].set(xlabel="t [s]", ylabel="|snap| [m/s^4]", title="snap (the minimised quantity)")
ax[1, 1].plot(t, reference.motor_thrusts)
ax[1, 1].axhline(vehicle.f_max, color="k", ls="--", lw=0.8)
ax[1, 1].set(xlabel="t [s]", ylabel="thrust [N]", title="hexacopter motor thrusts (optimal)")
for a in ax.flat[:3]:
    a.legend()
fig.tight_layout()

out = Path(args.output)
out.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(out, dpi=120)
print(f"figure saved to {out}")
