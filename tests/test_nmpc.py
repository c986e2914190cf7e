"""Tracking NMPC (Argyropoulos 2020, ch. 3-4): the OCP, its modes and the controller."""

import numpy as np
import pytest

from drake_uav.diagrams.tracking import build_terminal_set, fly_tracking, tracking_reference
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.multirotor import motor_wrench, multirotor_dynamics
from drake_uav.optimization.nmpc import NmpcSettings, TrackingNmpc, _dynamics, _rk4_batch, rk4_step
from drake_uav.systems.nmpc_controller import STATUS_FALLBACK_INFEASIBLE, STATUS_SOLVED
from drake_uav.vehicles.multirotor import hexacopter

SHORT = np.array([[0, 0, -1], [1.5, 0.5, -1.5], [2.5, 2.0, -2.0]], dtype=float)


@pytest.fixture(scope="module")
def params():
    return hexacopter()


@pytest.fixture(scope="module")
def tset(params):
    return build_terminal_set(params, tracking_reference(params, SHORT, 4.0), samples=64,
                              refine=2)


def test_rk4_jacobians_are_exact(params):
    rng = np.random.default_rng(0)
    X = np.tile([0, 0, -1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0.0], (3, 1)) + 0.1 * rng.normal(
        size=(3, 13))
    U = 3.0 + rng.normal(size=(3, 6))
    Xn, Ax, Bu = _rk4_batch(_dynamics(params), X, U, 0.025)
    ref = CompiledFunction(lambda x, u: rk4_step(x, u, 0.025, params), [13, 6],
                           wrt={0: None, 1: None})
    for b in range(3):
        value, (Jx, Ju) = ref.autodiff_jacobians(X[b], U[b])
        np.testing.assert_allclose(Xn[b], value, atol=1e-12)
        np.testing.assert_allclose(Ax[b], Jx, atol=1e-10)
        np.testing.assert_allclose(Bu[b], Ju, atol=1e-10)
    f = multirotor_dynamics(X[0], motor_wrench(U[0], params), params)
    np.testing.assert_allclose((Xn[0] - X[0]) / 0.025, f, atol=0.5)


@pytest.mark.parametrize("mode, solver", [
    ("rti", "sqp"), ("nlp", "sqp"),
    pytest.param("nlp", "snopt", marks=pytest.mark.slow),
    pytest.param("nlp", "ipopt", marks=pytest.mark.slow),
])
def test_one_step_respects_bounds_and_the_terminal_set(params, tset, mode, solver):
    # SNOPT and IPOPT start cold here (no shifted solution): give them room
    mpc = TrackingNmpc(params, tset, NmpcSettings(mode=mode, nlp_solver=solver,
                                                  max_iterations=500))
    x, _ = tset.reference.at(0.0)
    x = x.copy()
    x[0] += 0.05
    result = mpc.solve(0.0, x)
    assert result.status == "solved", result.solver_status
    assert result.solve_time > 0
    assert np.all(result.inputs >= -1e-6) and np.all(result.inputs <= params.f_max + 1e-6)
    assert result.terminal_ratio <= 1.0 + 1e-4
    np.testing.assert_allclose(result.states[0], x, atol=1e-6)


@pytest.mark.parametrize("mode", ["rti", "nlp"])
def test_closed_loop_tracks_from_an_offset(params, tset, mode):
    run = fly_tracking(params, tset, 3.0, settings=NmpcSettings(mode=mode),
                       offset=(0.3, 0.4, 0.0), attitude_offset=np.radians(10.0))
    assert run.rmse(2.0) < 0.05
    assert np.all(run.status == STATUS_SOLVED)
    assert np.all(run.terminal_ratio <= 1.0 + 1e-3)
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


def test_far_offset_falls_back_without_raising(params, tset):
    run = fly_tracking(params, tset, 1.0, offset=(6.0, 8.0, 0.0))
    assert np.any(run.status == STATUS_FALLBACK_INFEASIBLE)
    assert run.position_error[-1] < 8.0  # closing in on the reference
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max
    assert np.all(np.isfinite(run.state))


@pytest.mark.parametrize("field, settings", [
    ("horizon", NmpcSettings(horizon=1.01)),
    ("state_weight", NmpcSettings(state_weight=(1.0,) * 11 + (-1.0,))),
    ("input_weight", NmpcSettings(input_weight=0.0)),
    ("mode", NmpcSettings(mode="fast")),
    ("nlp_solver", NmpcSettings(nlp_solver="newton")),
    ("qp_solver", NmpcSettings(qp_solver="osqp")),
])
def test_bad_settings_name_the_field(params, tset, field, settings):
    with pytest.raises(ValueError, match=field):
        TrackingNmpc(params, tset, settings)


def test_local_law_fallback_when_relaxing_is_off(params, tset):
    run = fly_tracking(params, tset, 0.2, settings=NmpcSettings(relax_terminal=False),
                       offset=(6.0, 8.0, 0.0))
    assert np.all(run.status[1:] == STATUS_FALLBACK_INFEASIBLE)
    assert np.all(np.isinf(run.terminal_ratio[1:]))
    assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


def test_controller_never_raises_on_a_bad_state(params, tset):
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from drake_uav.systems.nmpc_controller import STATUS_FALLBACK_FAILED, NmpcController

    builder = DiagramBuilder()
    ctrl = builder.AddSystem(NmpcController(params, tset))
    src = builder.AddSystem(ConstantVectorSource(np.full(13, np.nan)))
    builder.Connect(src.get_output_port(), ctrl.GetInputPort("state"))
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.03)
    sub = ctrl.GetMyContextFromRoot(simulator.get_context())
    assert ctrl.GetOutputPort("status").Eval(sub)[0] == STATUS_FALLBACK_FAILED
    u = ctrl.GetOutputPort("motor_thrusts").Eval(sub)
    assert np.all(np.isfinite(u)) and u.min() >= 0.0 and u.max() <= params.f_max


def test_tracking_plots_are_written(params, tset, tmp_path):
    from drake_uav.reporting.tracking_figures import write_tracking_plots

    run = fly_tracking(params, tset, 0.5)
    files = write_tracking_plots(run, tmp_path / "plots")
    assert [f.name for f in files] == ["path_3d.png", "position_error.png", "thrusts.png",
                                       "solve_times.png"]
    assert all(f.stat().st_size > 5000 for f in files)


def test_riccati_qps_are_the_clarabel_qps(params, tset):
    from pydrake.solvers import ClarabelSolver, SolverOptions

    fast = TrackingNmpc(params, tset)
    exact = TrackingNmpc(params, tset, NmpcSettings(qp_solver="clarabel"))
    exact._options = SolverOptions()
    for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio"):
        exact._options.SetOption(ClarabelSolver.id(), name, 1e-10)
    rng = np.random.default_rng(1)
    x, _ = tset.reference.at(0.0)
    x = x.copy()
    x[:3] += (0.3, 0.4, 0.0)
    names = set()
    for k in range(16):  # from the prediction of each step, jolted in velocity and rates
        measured = x.copy()
        if k >= 4:
            measured[7:13] += np.concatenate([0.3 * rng.normal(size=3), 0.6 * rng.normal(size=3)])
        a, b = fast.solve(0.025 * k, measured), exact.solve(0.025 * k, measured)
        assert a.status == b.status == "solved"
        names.add(a.solver_status)
        # the interior-point iterate stops ~1e-5 N short of the optimum on an active cone
        np.testing.assert_allclose(a.inputs, b.inputs, atol=1e-4)
        assert a.terminal_ratio <= 1.0 + 1e-6
        assert a.inputs.min() >= 0.0 and a.inputs.max() <= params.f_max
        x = a.states[1]
    assert "Riccati, cone active" in names
    assert "Riccati, cone active, bounds active" in names


def test_sensor_noise_is_seeded_and_tracked_through(params, tset):
    from drake_uav.diagrams.tracking import StateNoise

    runs = [fly_tracking(params, tset, 3.0, offset=(0.3, 0.4, 0.0),
                         attitude_offset=np.radians(10.0), sensor_noise=StateNoise(), seed=s)
            for s in (4, 4, 5)]
    np.testing.assert_array_equal(runs[0].thrusts, runs[1].thrusts)
    assert not np.array_equal(runs[0].thrusts, runs[2].thrusts)
    for run in runs[::2]:
        assert run.rmse(2.0) < 0.05
        assert np.all(run.status == STATUS_SOLVED)
        assert np.all(run.terminal_ratio <= 1.0 + 1e-3)
        assert run.thrusts.min() >= 0.0 and run.thrusts.max() <= params.f_max


@pytest.mark.parametrize("field", ["position", "attitude", "velocity", "rates", "period"])
def test_bad_sensor_noise_names_the_field(field):
    from drake_uav.systems.state_sensor import NoisyStateSensor, StateNoise

    with pytest.raises(ValueError, match=field):
        NoisyStateSensor(StateNoise(**{field: -1.0}))


@pytest.mark.parametrize("period, shift", [(0.025, 1.0), (0.0125, 0.5)])
def test_warm_start_moves_by_one_control_period(params, period, shift):
    """Solved every ``period`` with 25 ms intervals, the previous solution is shifted by
    ``period / interval`` nodes (linear between nodes) before the next step."""
    reference = tracking_reference(params, SHORT, 4.0)
    mpc = TrackingNmpc(params, None, NmpcSettings(period=period), reference=reference)
    nodes = np.arange(mpc.N + 1, dtype=float)
    X = np.tile(reference.state[0], (mpc.N + 1, 1))
    X[:, 0] = 0.1 * nodes  # north position ramps by 0.1 m per node
    U = np.tile(np.arange(6, dtype=float), (mpc.N, 1)) + nodes[:-1, None]
    mpc._guess, mpc._x = (X, U), X[0]
    Xg, Ug = mpc._initial_guess()
    np.testing.assert_allclose(Xg[1:-1, 0], 0.1 * (nodes[1:-1] + shift))
    np.testing.assert_allclose(Ug[:-1, 0], nodes[:-2] + shift)
