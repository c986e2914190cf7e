"""Acceptance of the tracking NMPC on the bundled 6-waypoint trajectory (docs/nmpc.md).

Each run flies the whole trajectory; they are marked slow.
"""

import numpy as np
import pytest

from drake_uav.diagrams.tracking import (
    StateNoise,
    build_terminal_set,
    fly_tracking,
    solve_time_stats,
    tracking_reference,
)
from drake_uav.optimization.nmpc import NmpcSettings
from drake_uav.systems.nmpc_controller import STATUS_FALLBACK_INFEASIBLE, STATUS_SOLVED
from drake_uav.vehicles.multirotor import hexacopter

pytestmark = pytest.mark.slow
OFFSET = (0.3, 0.4, 0.0)  # 0.5 m


@pytest.fixture(scope="module")
def params():
    return hexacopter()


@pytest.fixture(scope="module")
def tset(params):
    return build_terminal_set(params, tracking_reference(params))


def _summary(name, run):
    s = solve_time_stats(run)
    print(f"\n{name}: RMSE after 2 s {100 * run.rmse(2.0):.3f} cm, max error after 2 s "
          f"{100 * run.position_error[run.time >= 2].max():.3f} cm, fallback steps "
          f"{int((run.status != STATUS_SOLVED).sum())}/{len(run.status)}, solve time median "
          f"{1e3 * s['median']:.1f} ms p95 {1e3 * s['p95']:.1f} ms max {1e3 * s['max']:.1f} ms, "
          f"thrust range {run.thrusts.min():.3f}..{run.thrusts.max():.3f} N")


@pytest.mark.parametrize("mode", ["rti", "nlp"])
def test_offset_start_tracks_within_5_cm(params, tset, mode):
    run = fly_tracking(params, tset, tset.end_time + 2.0, settings=NmpcSettings(mode=mode),
                       offset=OFFSET, attitude_offset=np.radians(10.0))
    _summary(f"{mode}, 0.5 m / 10 deg offset", run)
    assert run.rmse(2.0) < 0.05
    assert np.all(run.status == STATUS_SOLVED)
    assert np.all(run.terminal_ratio <= 1.0 + 1e-3)
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


def test_wind_gusts_keep_the_loop_stable(params, tset):
    run = fly_tracking(params, tset, tset.end_time + 2.0, offset=OFFSET,
                       attitude_offset=np.radians(10.0), gust_sigma=1.0, seed=3)
    _summary("rti, gusts sigma 1 N", run)
    assert run.rmse(2.0) < 0.25
    assert run.position_error[-40:].max() < 0.5
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


@pytest.mark.parametrize("mode", ["rti", "nlp"])
def test_sensor_noise_keeps_tracking_within_5_cm(params, tset, mode):
    run = fly_tracking(params, tset, tset.end_time + 2.0, settings=NmpcSettings(mode=mode),
                       offset=OFFSET, attitude_offset=np.radians(10.0),
                       sensor_noise=StateNoise(), seed=7)
    _summary(f"{mode}, 0.5 m / 10 deg offset, state noise {StateNoise()}", run)
    assert run.rmse(2.0) < 0.05
    assert np.all(run.status == STATUS_SOLVED)
    assert np.all(run.terminal_ratio <= 1.0 + 1e-3)
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


def test_recursive_feasibility_over_30_s(params, tset):
    run = fly_tracking(params, tset, 30.0)
    _summary("rti, nominal 30 s", run)
    assert np.all(run.status == STATUS_SOLVED)
    assert np.all(run.terminal_ratio <= 1.0 + 1e-3)


def test_10_m_offset_falls_back_and_recovers(params, tset):
    run = fly_tracking(params, tset, 30.0, offset=(6.0, 8.0, 0.0))
    _summary("rti, 10 m offset", run)
    assert np.any(run.status[:40] == STATUS_FALLBACK_INFEASIBLE)
    assert np.all(np.isfinite(run.state))
    assert run.position_error[-1] < 0.05
    assert np.all(run.status[-40:] == STATUS_SOLVED)
