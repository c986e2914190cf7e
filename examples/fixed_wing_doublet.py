"""Trim the Aerosonde at 25 m/s, fly an elevator doublet and plot the response.

Run: python examples/fixed_wing_doublet.py [output.png]   (default out/fixed_wing_doublet.png)
     python examples/fixed_wing_doublet.py --quick   (10 s of flight instead of 30 s)
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.optimization.linearization import mode_analysis
from drake_uav.optimization.trim import trim
from drake_uav.systems.fixed_wing import FixedWingPlant
from drake_uav.vehicles.fixed_wing import aerosonde

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("output", nargs="?", default="out/fixed_wing_doublet.png", help="figure file")
parser.add_argument("--quick", action="store_true", help="10 s of flight instead of 30 s")
args = parser.parse_args()

params = aerosonde()
level = trim(params, airspeed=25.0)
print(mode_analysis(params, level).table())

# Elevator doublet: +3 deg for 1 s, -3 deg for 1 s, starting at t = 2 s.
times = [0.0, 2.0, 3.0, 4.0, 10.0 if args.quick else 30.0]
controls = np.tile(level.controls[:, None], (1, len(times)))
controls[0, 1] += np.radians(3.0)
controls[0, 2] -= np.radians(3.0)

builder = DiagramBuilder()
plant = builder.AddSystem(FixedWingPlant(params))
doublet = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, controls)))
builder.Connect(doublet.get_output_port(), plant.GetInputPort("controls"))
air_log = LogVectorOutput(plant.GetOutputPort("air_data"), builder, 0.02)
euler_log = LogVectorOutput(plant.GetOutputPort("euler"), builder, 0.02)
diagram = builder.Build()

simulator = Simulator(diagram)
plant.set_state(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), level.state)
simulator.AdvanceTo(times[-1])

context = simulator.get_context()
air = air_log.FindLog(context)
euler = euler_log.FindLog(context)
fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
axes[0].plot(air.sample_times(), air.data()[0])
axes[0].set_ylabel("Va [m/s]")
axes[1].plot(air.sample_times(), np.degrees(air.data()[1]), label="alpha")
axes[1].plot(euler.sample_times(), np.degrees(euler.data()[1]), label="pitch")
axes[1].set_ylabel("[deg]")
axes[1].legend()
axes[2].step(times, np.degrees(controls[0]), where="post")
axes[2].set_ylabel("elevator [deg]")
axes[2].set_xlabel("time [s]")
fig.suptitle("Aerosonde, elevator doublet at 25 m/s")
out = Path(args.output)
out.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(out, dpi=120)
print(f"figure written to {out}")
