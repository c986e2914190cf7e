"""Scenario ``realistic_logs``: the main job on one flight in three files.

An identification flight with an effect the catalog model lacks is written as an
autopilot would log it (:mod:`drake_uav.io.realistic_ardupilot`,
:mod:`drake_uav.io.realistic_px4`: ground segment, take-off, late GPS fix, PWM 0
before arming, a reversed servo, +-400 us throws, a 50 Hz IMU, 1 Hz optional
topics, a truncated tail, no vanes) and as a vane-equipped CSV of its measured
channels. The main job runs on each file exactly as ``drake-uav identify FILE``
does with no option (:func:`identify_file`); the scenario reports what each found
and how well the air data were estimated without vanes.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np

from drake_uav.campaigns.registry import register_scenario
from drake_uav.campaigns.scenarios import effect_flight
from drake_uav.estimation.air_data_estimate import estimate_air_data
from drake_uav.identification.pipeline import IdentificationRun, identify
from drake_uav.io import read_log
from drake_uav.io.realistic_ardupilot import write_ardupilot_log
from drake_uav.io.realistic_px4 import write_px4_log

__all__ = ["identify_file", "realistic_logs"]

FORMATS = ("bin", "ulg", "csv")


def identify_file(path: Path, params, seed: int = 0) -> IdentificationRun:
    """The main job on a log file with the command line's defaults (reader warnings
    silenced: the scenario's logs raise them on purpose)."""
    options = {}
    if path.suffix in (".bin", ".ulg"):
        options["deflections"] = params.limits.deflections()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_log(path, **options)
        return identify(log, params, source=str(path), seed=seed)


def _flow_angle_error(log_path: Path, flight, flight_start: float, run, params) -> dict:
    """MAE [deg] of the estimated alpha and beta against the truth over the used spans."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_log(log_path)
    error = {"alpha": [], "beta": []}
    for start, end in run.data.spans:
        part = log.slice(start, end)
        estimate = estimate_air_data(part, params, segments=[[part.time[0], part.time[-1]]])
        ok = estimate.valid
        t = part.time[ok] - flight_start
        for name in error:
            truth = np.interp(t, flight.time, flight[name])
            error[name].append(getattr(estimate, name)[ok] - truth)
    return {f"{name}_mae_deg": float(np.degrees(np.mean(np.abs(np.concatenate(e)))))
            for name, e in error.items()}


@register_scenario("realistic_logs")
def realistic_logs(seed: int, params: dict) -> dict:
    """One flight as .bin, .ulg and vane CSV; the main job on each.

    Parameters (defaults): ``aircraft`` ("aerosonde"), ``turbulence`` ("light"),
    ``duration`` [s] (180), ``effect`` (a key of
    :data:`~drake_uav.campaigns.scenarios.EFFECTS`, "elevator_roll"), ``strength`` (1.0).

    Metrics per format F in bin, ulg, csv: ``found_F`` (the effects found, comma
    separated), ``exact_F`` (exactly the expected effect, nothing else; for effect
    "none": nothing found); ``same_as_csv_bin`` / ``same_as_csv_ulg`` (the same list as
    the vane CSV); ``alpha_mae_deg`` / ``beta_mae_deg`` (the estimate from the .bin
    against the truth over the spans the job used).
    """
    flight, aircraft, (_, expected, _, _) = effect_flight("realistic_logs", seed, params,
                                                          "elevator_roll", 180.0)
    metrics: dict = {}
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        written = write_ardupilot_log(flight, folder / "flight.bin", seed=seed,
                                      aircraft=aircraft)
        write_px4_log(flight, folder / "flight.ulg", seed=seed, aircraft=aircraft)
        flight.select(flight.measured_names).save(folder / "flight.csv")
        runs = {kind: identify_file(folder / f"flight.{kind}", aircraft, seed)
                for kind in FORMATS}
        metrics.update(_flow_angle_error(written.path, flight, written.phases.flight_s,
                                         runs["bin"], aircraft))
    want = [] if expected is None else [expected]
    for kind, run in runs.items():
        found = [f.name for f in run.discovery.found]
        metrics[f"found_{kind}"] = ",".join(found)
        metrics[f"exact_{kind}"] = found == want
    for kind in ("bin", "ulg"):
        metrics[f"same_as_csv_{kind}"] = metrics[f"found_{kind}"] == metrics["found_csv"]
    return metrics
