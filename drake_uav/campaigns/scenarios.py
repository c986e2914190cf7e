"""Built-in scenarios: identification flight + main job, air-data EKF consistency, tracking NMPC.

Each is a function ``(seed, params) -> metrics`` registered by name
(:func:`~drake_uav.campaigns.registry.register_scenario`); the fault scenarios join
the same way when they land.

``main_job``: an identification flight (:func:`drake_uav.diagrams.fly`) with an
effect the aircraft's catalog model lacks put into the physics, then the main job
(:func:`drake_uav.identification.pipeline.identify`) on the log.

``air_data_ekf``: an identification flight in turbulence and a steady wind, then the
model-free (Vaiopoulos 2017, sec. 5.4.3) or model-based (sec. 5.4.5, without vanes)
air-data filter over the log; consistency as NEES and NIS (Bar-Shalom et al. 2001,
sec. 5.4).

``tracking_nmpc``: the hexacopter's tracking NMPC (Argyropoulos 2020, ch. 4) on the
bundled minimum-snap trajectory from a seeded initial offset, optionally in gusts.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from drake_uav.campaigns.registry import register_scenario
from drake_uav.diagrams import (
    build_terminal_set,
    fly,
    fly_tracking,
    solve_time_stats,
    tracking_reference,
)
from drake_uav.estimation import AirDataModel, ModelBasedAirDataModel
from drake_uav.estimation.ekf import ExtendedKalmanFilter, run_filter
from drake_uav.identification.pipeline import identify
from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.optimization.nmpc import NmpcSettings
from drake_uav.vehicles import hexacopter, quadrotor_x
from drake_uav.vehicles.loading import load_fixed_wing

__all__ = ["EFFECTS", "TRACKING_TIMING_METRICS", "effect_flight", "main_job", "air_data_ekf",
           "tracking_nmpc"]

EFFECTS: dict[str, tuple[Callable[[float], Callable] | None, str | None, str, str]] = {
    "propwash_drag": (lambda k: lambda c: (0.0, 0.1 * k * c.thrust_coefficient, 0, 0, 0, 0),
                      "thrust_propwash", "CD", "airspeed"),
    "stall_onset": (lambda k: lambda c: (-60.0 * k * c.alpha**3, 0, 0, 0, 0, 0),
                    "stall_onset", "CL", "alpha"),
    "elevator_roll": (lambda k: lambda c: (0, 0, 0, 0.02 * k * c.elevator, 0, 0),
                      "control_cross_coupling", "Cl", "p"),
    "none": (None, None, "CD", "airspeed"),
}
"""Effect put into the physics: name -> (disturbance of a strength k, the effect the main
job should name, the coefficient it acts on, the reconstructed output it moves). At
k = 1: propeller slipstream drag C_D += 0.1 T_c, stall onset C_L -= 60 alpha^3, an
elevator rolling moment C_l += 0.02 delta_e."""

_OUTPUTS = ("airspeed", "alpha", "beta", "p", "q", "r")


def effect_flight(scenario: str, seed: int, params: dict, effect: str, duration: float):
    """(log, aircraft, EFFECTS entry) of an identification flight with the effect of
    ``params`` (``effect``, ``strength``, ``aircraft``, ``turbulence``, ``duration``;
    ``effect`` and ``duration`` [s] are the scenario's defaults)."""
    effect = params.get("effect", effect)
    if effect not in EFFECTS:
        raise ValueError(f"{scenario}: effect {effect!r} unknown (known: {', '.join(EFFECTS)})")
    disturbance = EFFECTS[effect][0]
    aircraft = load_fixed_wing(params.get("aircraft", "aerosonde"))
    options = {} if disturbance is None else {
        "disturbance": disturbance(float(params.get("strength", 1.0)))}
    log = fly(aircraft, turbulence=params.get("turbulence", "light"), seed=seed,
              duration=float(params.get("duration", duration)), **options)
    return log, aircraft, EFFECTS[effect]


@register_scenario("main_job")
def main_job(seed: int, params: dict) -> dict:
    """Identification flight with an undeclared effect, then the main job.

    Parameters (defaults): ``aircraft`` ("aerosonde"), ``turbulence`` ("light"),
    ``duration`` [s] (60), ``effect`` (a key of :data:`EFFECTS`, "propwash_drag"),
    ``strength`` (1.0, scales the effect).

    Metrics: ``detected`` (the expected effect is among those found; absent for
    effect "none"), ``any_discovery``, ``false_discoveries`` (effects found other than
    the expected one), ``rms_before`` / ``rms_after`` (held-out equation-error RMS of
    the coefficient the effect acts on) and ``mae_before`` / ``mae_after``
    (reconstruction mean absolute error of the output it moves, SI units).
    """
    log, aircraft, (_, expected, coefficient, output) = effect_flight(
        "main_job", seed, params, "propwash_drag", 60.0)
    run = identify(log, aircraft, seed=seed)
    found = [f.name for f in run.discovery.found]
    before, after = run.discovery.rms_change()[coefficient]
    k = _OUTPUTS.index(output)
    metrics = {
        "any_discovery": bool(found),
        "false_discoveries": sum(name != expected for name in found),
        "rms_before": float(before),
        "rms_after": float(after),
        "mae_before": float(run.reconstruction_before.mae[k]),
        "mae_after": float(run.reconstruction_after.mae[k]),
    }
    if expected is not None:
        metrics["detected"] = expected in found
    return metrics


def _steady_wind(speed: float, seed: int) -> tuple[float, float, float]:
    """A horizontal wind of ``speed`` [m/s] from a heading drawn from ``seed``."""
    heading = np.random.default_rng([seed, 1000]).uniform(0.0, 2.0 * math.pi)
    return (speed * math.cos(heading), speed * math.sin(heading), 0.0)


@register_scenario("air_data_ekf")
def air_data_ekf(seed: int, params: dict) -> dict:
    """Air-data EKF over a turbulent identification flight: accuracy and consistency.

    Parameters (defaults): ``aircraft`` ("aerosonde"), ``turbulence`` ("light"),
    ``duration`` [s] (120), ``wind_speed`` [m/s] (5, heading drawn from the seed),
    ``filter`` ("model_free" or "model_based"; the model-based one runs without vanes),
    ``settle`` [s] (10: the start transient left out of the figures).

    Metrics: ``nees`` (time-average NEES over the 6 states; chi-square with 6 degrees
    of freedom per sample when consistent), ``nis_per_dof`` (time-average NIS divided by
    the channels used), ``mae_airspeed`` [m/s], ``mae_alpha_deg``, ``mae_beta_deg`` [deg],
    ``mae_wind`` [m/s] (mean absolute error of the three wind components), ``rejected``
    (updates rejected by the innovation gate).
    """
    aircraft = load_fixed_wing(params.get("aircraft", "aerosonde"))
    kind = params.get("filter", "model_free")
    if kind not in ("model_free", "model_based"):
        raise ValueError(f"air_data_ekf: filter {kind!r} unknown (model_free, model_based)")
    log = fly(aircraft, params.get("turbulence", "light"), seed=seed,
              steady_wind=_steady_wind(float(params.get("wind_speed", 5.0)), seed),
              duration=float(params.get("duration", 120.0)))
    model = AirDataModel(aircraft) if kind == "model_free" else ModelBasedAirDataModel(aircraft)
    ekf = ExtendedKalmanFilter(model, model.default_noise())
    data = model.log_data(log)
    available = np.array(data.available)
    if kind == "model_based":
        available[:, list(model.groups["vanes"])] = False
    run = run_filter(ekf, data.time, data.inputs, data.measurements, available,
                     truth=data.truth)
    keep = run.time > float(params.get("settle", 10.0))
    state, truth = run.state[keep], data.truth[keep]
    if kind == "model_free":  # air-relative velocity -> (Va, alpha, beta)
        state = np.column_stack([*air_data_from_velocity(*state[:, :3].T), state[:, 3:]])
        truth = np.column_stack([*air_data_from_velocity(*truth[:, :3].T), truth[:, 3:]])
    mae = np.abs(state - truth).mean(axis=0)
    used = keep & (run.dof > 0)
    return {
        "nees": float(np.nanmean(run.nees[keep])),
        "nis_per_dof": float(np.mean(run.nis[used] / run.dof[used])),
        "mae_airspeed": float(mae[0]),
        "mae_alpha_deg": math.degrees(mae[1]),
        "mae_beta_deg": math.degrees(mae[2]),
        "mae_wind": float(mae[3:].mean()),
        "rejected": int(np.sum(run.rejected)),
    }


@functools.lru_cache(maxsize=2)
def _tracking_setup(aircraft: str):
    """The multirotor and the terminal sets along the bundled trajectory (once per process)."""
    params = {"hexacopter": hexacopter, "quadrotor_x": quadrotor_x}[aircraft]()
    return params, build_terminal_set(params, tracking_reference(params))


TRACKING_TIMING_METRICS = ("solve_ms_median", "solve_ms_p95", "solve_ms_max")
"""Metrics of :func:`tracking_nmpc` measured on the clock: they differ between runs of the
same campaign, so leave them out of a bit-for-bit comparison
(``results_equal(a, b, exclude=NONDETERMINISTIC + TRACKING_TIMING_METRICS)``)."""


@register_scenario("tracking_nmpc")
def tracking_nmpc(seed: int, params: dict) -> dict:
    """The tracking NMPC flying the bundled minimum-snap trajectory from a seeded offset.

    Parameters (defaults): ``aircraft`` ("hexacopter" or "quadrotor_x"), ``mode`` ("rti"
    or "nlp"), ``offset`` [m] (0.5, horizontal, direction drawn from the seed),
    ``roll_offset_deg`` (10), ``gust_sigma`` [N] (0: none; a seeded gust force
    otherwise), ``duration`` [s] (the trajectory plus 2 s).

    Metrics: ``rmse_cm`` and ``max_error_cm`` (position error after 2 s), ``fallback_steps``
    (steps of the local-law fallback), ``bounds_respected`` (every thrust in
    [0, f_max]), ``terminal_ratio_max`` (largest V / level at the solves, <= 1 when the
    terminal constraint holds) and the clock figures of :data:`TRACKING_TIMING_METRICS`.
    """
    aircraft = params.get("aircraft", "hexacopter")
    if aircraft not in ("hexacopter", "quadrotor_x"):
        raise ValueError(f"tracking_nmpc: aircraft {aircraft!r} unknown "
                         "(hexacopter, quadrotor_x)")
    vehicle, terminal = _tracking_setup(aircraft)
    heading = np.random.default_rng([seed, 2000]).uniform(0.0, 2.0 * math.pi)
    offset = float(params.get("offset", 0.5))
    duration = float(params.get("duration", terminal.end_time + 2.0))
    run = fly_tracking(vehicle, terminal, duration,
                       settings=NmpcSettings(mode=params.get("mode", "rti")),
                       offset=(offset * math.cos(heading), offset * math.sin(heading), 0.0),
                       attitude_offset=math.radians(float(params.get("roll_offset_deg", 10.0))),
                       gust_sigma=float(params.get("gust_sigma", 0.0)), seed=seed)
    late = run.position_error[run.time >= 2.0]
    solved = run.terminal_ratio[run.status == 0]
    stats = solve_time_stats(run)
    return {
        "rmse_cm": 100.0 * run.rmse(2.0),
        "max_error_cm": 100.0 * float(late.max()),
        "fallback_steps": int(np.sum(run.status != 0)),
        "bounds_respected": bool(run.thrusts.min() >= 0.0
                                 and run.thrusts.max() <= vehicle.f_max),
        "terminal_ratio_max": float(solved.max()) if len(solved) else math.nan,
        **{name: 1e3 * stats[key] for name, key in zip(TRACKING_TIMING_METRICS,
                                                         ("median", "p95", "max"), strict=True)},
    }
