"""Air data from low-cost sensors: fly an identification flight in light turbulence, run the
model-free EKF (GPS, pitot, vanes) and the model-based EKF (no vanes) over the log, and plot
airspeed, angle of attack and sideslip against the truth with 3-sigma bands.

Run: python examples/air_data_ekf.py [output.png]   (default out/air_data_ekf.png)
     python examples/air_data_ekf.py --quick    (a 30 s flight)
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from drake_uav.diagrams.identification_flight import fly
from drake_uav.estimation import AirDataModel, ModelBasedAirDataModel
from drake_uav.estimation.ekf import ExtendedKalmanFilter, run_filter
from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.vehicles.fixed_wing import aerosonde

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("output", nargs="?", default="out/air_data_ekf.png", help="figure file")
parser.add_argument("--quick", action="store_true", help="a 30 s flight instead of 120 s")
args = parser.parse_args()

aircraft = aerosonde()
duration = 30.0 if args.quick else 120.0
log = fly(aircraft, "light", steady_wind=(4.0, -3.0, 0.0), seed=3, duration=duration)

# Model-free filter: state [u_r, v_r, w_r, W_N, W_E, W_D]; triplet and its sigma by sampling
# the posterior (a first-order map would do as well at these small uncertainties).
free = AirDataModel(aircraft)
data = free.log_data(log)
run_free = run_filter(ExtendedKalmanFilter(free, free.default_noise()), data.time, data.inputs,
                      data.measurements, data.available, store_covariance=True)
rng = np.random.default_rng(0)
draws = rng.standard_normal((64, 3))
chol = np.linalg.cholesky(run_free.covariance[:, :3, :3])
samples = run_free.state[:, None, :3] + np.einsum("kij,sj->ksi", chol, draws)
triplets = np.stack(air_data_from_velocity(*np.moveaxis(samples, -1, 0)), axis=-1)
free_estimate = np.stack(air_data_from_velocity(*run_free.state[:, :3].T), axis=-1)
free_sigma = triplets.std(axis=1)

# Model-based filter without vanes: state [Va, alpha, beta, W_N, W_E, W_D].
based = ModelBasedAirDataModel(aircraft)
data_mb = based.log_data(log)
no_vanes = data_mb.available.copy()
no_vanes[:, list(based.groups["vanes"])] = False
run_based = run_filter(ExtendedKalmanFilter(based, based.default_noise()), data_mb.time,
                       data_mb.inputs, data_mb.measurements, no_vanes)

truth = log.stack(["airspeed", "alpha", "beta"])
scale = (1.0, np.degrees(1.0), np.degrees(1.0))
labels = ("airspeed [m/s]", "angle of attack [deg]", "sideslip [deg]")
fig, axes = plt.subplots(3, 1, sharex=True, figsize=(10, 8))
for i, ax in enumerate(axes):
    for name, estimate, sigma, color in (
            ("model-free EKF", free_estimate[:, i], free_sigma[:, i], "tab:blue"),
            ("model-based EKF, no vanes", run_based.state[:, i], run_based.std[:, i],
             "tab:orange")):
        ax.plot(log.time, scale[i] * estimate, color=color, lw=0.8, label=name)
        ax.fill_between(log.time, scale[i] * (estimate - 3 * sigma),
                        scale[i] * (estimate + 3 * sigma), color=color, alpha=0.25)
        error = np.abs(estimate - truth[:, i])[log.time > 10.0].mean() * scale[i]
        print(f"{name:27s} {labels[i]:22s} mean absolute error {error:.3f}")
    ax.plot(log.time, scale[i] * truth[:, i], "k", lw=0.6, label="truth")
    ax.set_ylabel(labels[i])
axes[0].legend(loc="upper right", fontsize=8)
axes[-1].set_xlabel("time [s]")
axes[-1].set_xlim(duration / 2, duration / 2 + 20.0)
fig.suptitle("Air data from IMU, GPS, pitot and vanes (3-sigma bands)")
fig.tight_layout()
out = Path(args.output)
out.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(out, dpi=120)
print(f"figure written to {out}")
