"""Cost and accuracy of the offline air-data estimation without vanes (estimate_air_data).

Flies a 300 s identification flight at 100 Hz per seed (light turbulence, default
sensors), keeps what a real log holds (measured channels without vanes, no noise
metadata) and times, best of ``--repeat`` runs (wall clock and CPU):

* ``estimate_air_data``: forward EKF + RTS smoother with the specific-force relation
  (the default), and the kinematic-only variant (``lift_relation=False``);
* its pieces: the forward pass alone (``filter_pass``) and the backward pass alone
  (``rts_smooth``);
* the peer: the library's forward EKF run (``run_filter``) on the same model and samples.

Real-time factor = flight duration / wall time; target >= 200x (a 300 s flight in
<= 1.5 s). MAE of alpha, beta [deg] and airspeed [m/s] against the simulation's truth
(after the first 5 s), for the smoothed estimate and for the forward filter alone, and
the mean normalised squared error of the smoothed alpha and beta (samples 2 s apart).

``--decimation`` sets the filter steps of ``estimate_air_data`` (default: its own);
``--quick`` flies one 30 s flight and times each piece once (the same figures, noisier).

Run: python benchmarks/bench_air_data_smoother.py [--seeds 0 1 2 3 4] [--repeat 3]
     [--decimation 3] [--quick]
"""

import argparse
import math

import numpy as np
from figures import figure
from timing import best_of

from drake_uav.diagrams import fly
from drake_uav.estimation import (
    ExtendedKalmanFilter,
    VanelessAirDataModel,
    estimate_air_data,
    filter_pass,
    rts_smooth,
    run_filter,
)
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.vehicles import aerosonde

DURATION = 300.0  # s
QUICK_DURATION = 30.0  # s
RTF_TARGET = 200.0
SETTLE = 5.0  # s


def measured_only(log: FlightLog) -> FlightLog:
    """The log as a real one: measured channels without vanes, no noise metadata."""
    names = [n for n in log.measured_names if not n.startswith("vane_")]
    meta = {k: v for k, v in log.metadata.items() if k != "sensor_noise_std"}
    return FlightLog(log.time, {n: log[n] for n in names}, {},
                     {n: log.unit(n) for n in names}, meta)


def errors(log: FlightLog, time_, airspeed, alpha, beta, keep) -> tuple[float, float, float]:
    """MAE of alpha, beta [deg] and airspeed [m/s]."""
    keep = keep & (time_ >= SETTLE)
    return (math.degrees(np.abs(alpha - log["alpha"])[keep].mean()),
            math.degrees(np.abs(beta - log["beta"])[keep].mean()),
            float(np.abs(airspeed - log["airspeed"])[keep].mean()))


def nees(log: FlightLog, estimate) -> tuple[float, float]:
    """Mean normalised squared error of alpha and beta on samples 2 s apart."""
    picks = np.flatnonzero(estimate.valid & (estimate.time >= SETTLE))[::200]
    return tuple(float(np.mean(((getattr(estimate, n) - log[n]) / getattr(
        estimate, f"{n}_std"))[picks] ** 2)) for n in ("alpha", "beta"))


def run_seed(seed: int, repeat: int, options: dict, duration: float) -> dict[str, float]:
    aircraft = aerosonde()
    truth = fly(aircraft, "light", duration=duration, seed=seed)
    log = measured_only(truth)
    estimate_air_data(log.slice(0.0, 2.0), aircraft)  # code generation, once
    out = {}
    for label, lift in (("lift", True), ("kinematic", False)):
        estimate, wall, cpu = best_of(repeat, lambda lift=lift: estimate_air_data(
            log, aircraft, lift_relation=lift, **options))
        a, b, v = errors(truth, estimate.time, estimate.airspeed, estimate.alpha,
                         estimate.beta, estimate.valid)
        na, nb = nees(truth, estimate)
        print(f"  seed {seed} estimate_air_data ({label:9s}): wall {wall:6.3f} s, CPU "
              f"{cpu:6.3f} s, {duration / wall:6.1f}x real time; MAE alpha {a:.3f} deg, "
              f"beta {b:.3f} deg, airspeed {v:.3f} m/s; NEES alpha {na:.2f}, beta {nb:.2f}")
        out.update({f"{label}_wall": wall, f"{label}_alpha": a, f"{label}_beta": b,
                    f"{label}_airspeed": v})
    model = VanelessAirDataModel(aircraft)
    data = model.log_data(log)
    ekf = ExtendedKalmanFilter(model, model.default_noise())
    args = (ekf, data.time, data.inputs, data.measurements, data.available)
    forward, wall_f, cpu_f = best_of(repeat, lambda: filter_pass(*args))
    _, wall_b, cpu_b = best_of(repeat, lambda: rts_smooth(forward))
    run, wall_r, cpu_r = best_of(repeat, lambda: run_filter(*args))
    air = air_data_from_velocity(*run.state[:, 0:3].T)
    a, b, v = errors(truth, data.time, *air, np.ones(len(data.time), bool))
    print(f"  seed {seed} pieces: filter_pass {wall_f:.3f} s (CPU {cpu_f:.3f}), rts_smooth "
          f"{wall_b:.3f} s (CPU {cpu_b:.3f}); peer run_filter (forward EKF alone) "
          f"{wall_r:.3f} s (CPU {cpu_r:.3f}), {duration / wall_r:.1f}x real time, MAE alpha "
          f"{a:.3f} deg, beta {b:.3f} deg, airspeed {v:.3f} m/s")
    out.update({"forward_wall": wall_f, "backward_wall": wall_b, "peer_wall": wall_r,
                "peer_alpha": a, "peer_beta": b})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--decimation", type=int, default=None)
    parser.add_argument("--quick", action="store_true",
                        help=f"one {QUICK_DURATION:g} s flight of the first seed, timed once")
    args = parser.parse_args()
    duration = DURATION
    if args.quick:
        duration, args.seeds, args.repeat = QUICK_DURATION, args.seeds[:1], 1
    options = {} if args.decimation is None else {"decimation": args.decimation}
    print(f"Air data without vanes: {duration:.0f} s flights at 100 Hz, light turbulence, "
          f"seeds {args.seeds}, best of {args.repeat}, options {options}")
    results = [run_seed(seed, args.repeat, options, duration) for seed in args.seeds]
    mean = {k: float(np.mean([r[k] for r in results])) for k in results[0]}
    rtf = duration / mean["lift_wall"]
    print(f"Mean over seeds: estimate_air_data {mean['lift_wall']:.3f} s ({rtf:.1f}x real "
          f"time, target {RTF_TARGET:.0f}x: {'met' if rtf >= RTF_TARGET else 'NOT met'}); "
          f"MAE alpha {mean['lift_alpha']:.3f} deg, beta {mean['lift_beta']:.3f} deg "
          f"(kinematic only: {mean['kinematic_alpha']:.3f} / {mean['kinematic_beta']:.3f} "
          f"deg; forward EKF alone: {mean['peer_alpha']:.3f} / {mean['peer_beta']:.3f} deg)")
    figure("air_data_smoother_rtf", rtf, "x")
    figure("air_data_smoother_s", mean["lift_wall"], "s", "lower")
    figure("air_data_forward_ekf_s", mean["peer_wall"], "s", "lower")
    figure("air_data_smoother_alpha_mae_deg", mean["lift_alpha"], "deg", "lower")
    figure("air_data_smoother_beta_mae_deg", mean["lift_beta"], "deg", "lower")


if __name__ == "__main__":
    main()
