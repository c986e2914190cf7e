"""Motor failures, the pieces: escape geometry, plans, classification logic, injector,
supervisor, ground, bad input (Argyropoulos 2020, sec. 5.3)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from drake_uav.diagrams.fault_scenarios import fault_vehicle, scenario, scenario_reference
from drake_uav.diagrams.faults import fly_fault
from drake_uav.model.rotations import quat_to_rotmat
from drake_uav.optimization.escape import (
    altitude_hold_thrust,
    escape_attitude,
    free_fall_impact,
)
from drake_uav.optimization.fault_plans import LandingSettings, plan_reference
from drake_uav.optimization.fault_response import Category, UnsafeDisc, classify_fault
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.optimization.nmpc import NmpcSettings
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.systems.faults import FaultInjector, FaultSupervisor, MotorFailure
from drake_uav.systems.ground import Ground
from drake_uav.systems.multirotor import MultirotorPlant

G = 9.80665


@pytest.fixture(scope="module")
def params():
    return fault_vehicle()


def test_fault_vehicle_has_thrust_to_weight_about_three(params):
    ratio = params.num_motors * params.f_max / params.weight
    print(f"fault vehicle thrust/weight {ratio:.3f}")
    assert params.f_max == 10.0 and params.mass == 2.0
    assert 3.0 < ratio < 3.1


def test_free_fall_impact_matches_the_closed_form():
    impact = free_fall_impact([1.0, 2.0, -10.0], [3.0, -1.0, -2.0], G)
    t = (2.0 + np.sqrt(4.0 + 2 * G * 10.0)) / G  # eq. 5.17, climbing at 2 m/s
    print(f"fall time {impact.time:.4f} s, point {impact.point}, speed {impact.vertical_speed:.3f}")
    assert impact.time == pytest.approx(t, rel=1e-12)
    np.testing.assert_allclose(impact.point, [1.0 + 3.0 * t, 2.0 - t], rtol=1e-12)
    assert impact.vertical_speed == pytest.approx(G * t - 2.0, rel=1e-12)
    # a 10 m drop from rest hits at 14.0 m/s (the source's -14 m/s)
    assert free_fall_impact([0, 0, -10.0], [0, 0, 0], G).vertical_speed == pytest.approx(
        14.0047, abs=1e-4)


def test_escape_attitude_tilts_the_thrust_away_from_the_disc():
    for position in ([4.0, 1.0, -8.0], [12.0, -3.0, -5.0], [10.0, 5.0, -2.0]):
        q, phi = escape_attitude(position, (10.0, 0.0), 19.6, 39.2)
        thrust = -quat_to_rotmat(q)[:, 2]
        outward = np.array(position[:2]) - [10.0, 0.0]
        outward /= np.linalg.norm(outward)
        assert phi == pytest.approx(np.pi / 3)  # cos phi = F_z / F_max = 1/2
        np.testing.assert_allclose(thrust[:2], np.sin(phi) * outward, atol=1e-12)
        assert thrust[2] == pytest.approx(-0.5)  # up
    _, phi = escape_attitude([0, 0, -1.0], (5.0, 0.0), 50.0, 40.0)
    assert phi == 0.0  # cannot hold the altitude: all the thrust up


def test_altitude_hold_pushes_back_towards_the_target():
    weight = 2.0 * G
    assert altitude_hold_thrust(8.0, 0.0, 8.0, 2.0, G, (1.0, 2.0)) == pytest.approx(weight)
    assert altitude_hold_thrust(7.0, 0.0, 8.0, 2.0, G, (1.0, 2.0)) > weight  # too low
    assert altitude_hold_thrust(8.0, 1.0, 8.0, 2.0, G, (1.0, 2.0)) < weight  # climbing
    assert altitude_hold_thrust(30.0, 5.0, 8.0, 2.0, G, (1.0, 2.0)) == 0.0


def test_minimum_snap_starts_from_the_given_velocity_and_acceleration():
    v0, a0 = [2.0, -1.0, 0.5], [0.3, 0.2, -0.4]
    traj = minimum_snap([[0, 0, -8.0], [3, 1, -4.0], [6, 0, 0.2]], [0, 3, 7],
                        initial_derivatives=[v0, a0])
    np.testing.assert_allclose(traj.value(0.0, 1), v0, atol=1e-9)
    np.testing.assert_allclose(traj.value(0.0, 2), a0, atol=1e-9)
    np.testing.assert_allclose(traj.value(0.0, 3), 0.0, atol=1e-8)
    np.testing.assert_allclose(traj.value(7.0, 1), 0.0, atol=1e-8)
    np.testing.assert_allclose(traj.value(3.0), [3, 1, -4.0], atol=1e-9)
    with pytest.raises(ValueError, match="initial_derivatives"):
        minimum_snap([[0, 0, 0], [1, 1, 1]], [0, 1], initial_derivatives=np.zeros((5, 3)))


def test_plan_lands_below_the_ground_slowly(params):
    x = np.zeros(13)
    x[:3], x[3], x[7:10] = [2.0, 1.0, -6.0], 1.0, [1.5, 0.0, 0.0]
    s = LandingSettings()
    ref = plan_reference(params, x, np.zeros(3), [[0.0, 0.0, s.touchdown_depth]], [9.0],
                         np.ones(6), s)
    np.testing.assert_allclose(ref.state[0, 7:10], x[7:10], atol=1e-9)
    np.testing.assert_allclose(ref.state[-1, :3], [0, 0, s.touchdown_depth], atol=1e-9)
    crossing = np.argmax(ref.state[:, 2] >= 0.0)
    print(f"reference crosses the ground at {ref.state[crossing, 9]:.3f} m/s")
    assert 0.0 < ref.state[crossing, 9] < 1.0


def test_classification_order():
    p = fault_vehicle()
    x = np.zeros(13)
    x[3] = 1.0
    ref = np.tile(x, (5, 1))

    def inside(_):
        return -1.0

    def outside(_):
        return 1.0

    def reference_leaves(state):
        return 0.5 if state is not x and state[0] > 0 else -1.0

    assert classify_fault(p, (3, 4), x, ref, None).category == Category.I  # no tube needed
    # the alternating triple keeps closure but hovers only spinning up: land (no tube)
    assert classify_fault(p, (0, 2, 4), x, ref, None).category == Category.II
    assert classify_fault(p, (0, 3), x, ref, outside).category == Category.II
    assert classify_fault(p, (0, 3), x, ref, inside).category == Category.IV
    later = ref.copy()
    later[3, 0] = 5.0
    result = classify_fault(p, (0, 3), x, later, reference_leaves, margin=0.2)
    assert result.category == Category.III and result.reference_value == 0.5
    assert classify_fault(p, (0, 3), x, later, reference_leaves, margin=0.6).category == \
        Category.IV
    with pytest.raises(ValueError, match="tube"):
        classify_fault(p, (0, 3), x, ref, None)


def test_injector_schedule_total_and_partial():
    inj = FaultInjector(6, [MotorFailure(2.0, (1,), 0.4), MotorFailure(5.0, (1, 3))])
    np.testing.assert_array_equal(inj.health_at(1.9), np.ones(6))
    np.testing.assert_array_equal(inj.health_at(2.0), [1, 0.4, 1, 1, 1, 1])
    np.testing.assert_array_equal(inj.health_at(6.0), [1, 0, 1, 0, 1, 1])
    context = inj.CreateDefaultContext()
    context.SetTime(3.0)
    np.testing.assert_array_equal(inj.GetOutputPort("motor_health").Eval(context),
                                  [1, 0.4, 1, 1, 1, 1])


@pytest.mark.parametrize("failure, field", [
    (MotorFailure(1.0, (6,)), "failures\\[0\\].motors: unknown motor index 6"),
    (MotorFailure(1.0, (-1,)), "failures\\[0\\].motors"),
    (MotorFailure(1.0, (2,), 1.5), "failures\\[0\\].health"),
    (MotorFailure(1.0, (2,), -0.1), "failures\\[0\\].health"),
    (MotorFailure(-1.0, (2,)), "failures\\[0\\].time"),
])
def test_bad_failures_name_the_field(failure, field):
    with pytest.raises(ValueError, match=field):
        FaultInjector(6, [failure])


def test_fault_time_outside_the_flight_and_bad_disc_are_refused(params):
    sc = scenario("IVa")
    ref = scenario_reference(sc, params, dt=0.05)
    with pytest.raises(ValueError, match="failures\\[0\\].time = 30.0 s is outside the flight"):
        fly_fault(params, ref, [MotorFailure(30.0, (2,))], 20.0)
    with pytest.raises(ValueError, match="unsafe_disc.radius"):
        UnsafeDisc((10.0, 0.0), -1.0)
    with pytest.raises(ValueError, match="unsafe_disc.radius"):
        fly_fault(params, ref, [MotorFailure(3.0, (2,))], 20.0,
                  unsafe_disc=((10.0, 0.0), -6.0))
    with pytest.raises(ValueError, match="unknown fault scenario 'V'"):
        scenario("V")


def test_supervisor_classifies_once_at_the_first_period_after_the_failure(params):
    ref = scenario_reference(scenario("IVa"), params, dt=0.05)
    calls = []

    def tube_for(failed):
        calls.append(failed)
        return lambda x: -1.0

    builder = DiagramBuilder()
    state = builder.AddSystem(ConstantVectorSource(ref.state[0]))
    inj = builder.AddSystem(FaultInjector(6, [MotorFailure(0.51, (2,))]))
    sup = builder.AddSystem(FaultSupervisor(params, ref, tube_for, period=0.025))
    builder.Connect(state.get_output_port(), sup.GetInputPort("state"))
    builder.Connect(inj.GetOutputPort("motor_health"), sup.GetInputPort("motor_health"))
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(0.5)
    ctx = sup.GetMyContextFromRoot(sim.get_context())
    assert sup.GetOutputPort("category").Eval(ctx)[0] == 0
    assert np.isnan(sup.GetOutputPort("switch_time").Eval(ctx)[0])
    sim.AdvanceTo(1.0)
    ctx = sup.GetMyContextFromRoot(sim.get_context())
    assert sup.GetOutputPort("category").Eval(ctx)[0] == Category.IV
    assert sup.GetOutputPort("switch_time").Eval(ctx)[0] == pytest.approx(0.525)
    assert calls == [(2,)]


def test_ground_ends_the_simulation_at_touchdown(params):
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultirotorPlant(params))
    zero = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
    ground = builder.AddSystem(Ground())
    builder.Connect(zero.get_output_port(), plant.GetInputPort("motor_thrusts"))
    builder.Connect(plant.GetOutputPort("state"), ground.GetInputPort("state"))
    diagram = builder.Build()
    sim = Simulator(diagram)
    context = sim.get_mutable_context()
    context.SetAccuracy(1e-8)
    x0 = np.zeros(13)
    x0[2], x0[3], x0[7], x0[9] = -5.0, 1.0, 2.0, -1.0  # 5 m up, climbing at 1 m/s
    plant.GetMyMutableContextFromRoot(context).SetContinuousState(x0)
    status = sim.AdvanceTo(10.0)
    expected = free_fall_impact(x0[:3], x0[7:10], params.gravity)
    td = ground.GetOutputPort("touchdown").Eval(ground.GetMyContextFromRoot(context))
    print(f"touchdown at {td[1]:.5f} s (free fall {expected.time:.5f} s), speed {td[7]:.4f}")
    assert status.reason() == status.ReturnReason.kReachedTerminationCondition
    assert td[0] == 1.0
    assert td[1] == pytest.approx(expected.time, abs=1e-5)
    assert context.get_time() == pytest.approx(td[1])
    np.testing.assert_allclose(td[2:4], expected.point, atol=1e-4)
    assert abs(td[4]) < 1e-6
    assert td[7] == pytest.approx(expected.vertical_speed, abs=1e-4)


def _hover_reference(params, seconds):
    """A hover 2 m up for ``seconds`` [s] (thrusts shared equally)."""
    t = np.arange(0.0, seconds + 1e-9, 0.05)
    state = np.tile(np.r_[0.0, 0.0, -2.0, 1.0, np.zeros(9)], (len(t), 1))
    thrusts = np.full((len(t), params.num_motors), params.weight / params.num_motors)
    return ReferenceTable(t, state, thrusts)


def test_a_tracked_mission_ends_after_it_and_a_falling_vehicle_flies_on(params):
    ref = _hover_reference(params, 1.0)
    tracked = fly_fault(params, ref, (), 30.0, end_after_mission=0.5)
    print(f"tracked: ends at {tracked.time[-1]:.3f} s")
    assert tracked.time[-1] == pytest.approx(1.5, abs=0.03)
    assert tracked.touchdown is None
    # motors 3 and 4 (no closure) at 0.5 s: category I, the run flies on
    falling = fly_fault(params, ref, [MotorFailure(0.5, (3, 4))], 2.5, end_after_mission=0.5)
    print(f"falling: category {falling.category.name}, ends at {falling.time[-1]:.3f} s")
    assert falling.category == Category.I
    assert falling.time[-1] == pytest.approx(2.5, abs=0.03)
    with pytest.raises(ValueError, match="end_after_mission"):
        fly_fault(params, ref, (), 30.0, end_after_mission=-1.0)


def test_semidefinite_state_weight_is_accepted_and_negative_refused():
    NmpcSettings(state_weight=(1.0,) * 5 + (0.0,) + (1.0,) * 6).validate()
    with pytest.raises(ValueError, match="state_weight"):
        NmpcSettings(state_weight=(1.0,) * 11 + (-1.0,)).validate()


def test_nmpc_terminal_region_of_a_value_function(params):
    """A terminal region ``north <= 0.2 m`` against a reference 1 m north: the Riccati path
    puts the end state on the plane and agrees with Clarabel."""
    from drake_uav.optimization.nmpc import SublevelTerminal, TrackingNmpc
    from drake_uav.optimization.terminal_set import ReferenceTable

    hover = np.zeros(13)
    hover[2], hover[3] = -5.0, 1.0
    target = hover.copy()
    target[0] = 1.0
    u = np.full(6, params.weight / 6)
    ref = ReferenceTable([0.0, 2.0], [target, target], [u, u])
    region = SublevelTerminal(lambda x: x[0] - 0.2)
    ends = {}
    for qp in ("riccati", "clarabel"):
        mpc = TrackingNmpc(params, None, NmpcSettings(qp_solver=qp), reference=ref,
                           bounds=(np.inf,) * 12, terminal_region=region)
        result = mpc.solve(0.0, hover)
        print(qp, result.status, result.solver_status, f"x_N north {result.states[-1, 0]:.6f}")
        assert result.status == "solved"
        assert abs(result.terminal_ratio) < 1e-5  # on the plane
        ends[qp] = result.states[-1]
    assert "region active" in TrackingNmpc(
        params, None, reference=ref, bounds=(np.inf,) * 12,
        terminal_region=region).solve(0.0, hover).solver_status
    np.testing.assert_allclose(ends["riccati"], ends["clarabel"], atol=1e-4)


def test_nmpc_bounds_and_reference_are_checked(params):
    from drake_uav.optimization.nmpc import TrackingNmpc

    ref = scenario_reference(scenario("IVa"), params, dt=0.05)
    with pytest.raises(ValueError, match="reference is required"):
        TrackingNmpc(params, None)
    with pytest.raises(ValueError, match="bounds must be ErrorBounds or 12"):
        TrackingNmpc(params, None, reference=ref, bounds=(1.0,) * 12)  # position bounded
    with pytest.raises(ValueError, match="health"):
        TrackingNmpc(params, None, reference=ref, health=[1, 1, 2, 1, 1, 1])
    x = ref.state[0].copy()
    x[12] = 1.5  # spinning at 1.5 rad/s; the box wants 1.3 rad/s from the next node on
    result = TrackingNmpc(params, None, reference=ref,
                          bounds=(np.inf,) * 9 + (6.0, 6.0, 1.3)).solve(0.0, x)
    later = np.abs(result.states[1:, 12])
    print(result.status, result.solver_status, later.max())
    assert result.status == "solved" and later.max() <= 1.3 + 1e-5
    assert not result.solver_status.startswith("Riccati")  # a box row active: Clarabel


def test_a_tube_that_fails_classifies_as_II_and_the_loop_goes_on(params):
    """The documented fallback: a tube that cannot be read gives category II (escape or
    land), never an exception inside the simulation."""
    def broken(failed):
        raise OSError("cache folder not readable")

    sc = scenario("IVa")
    run = fly_fault(params, scenario_reference(sc, params, dt=0.01), sc.failures(), 6.0,
                    tube_for=broken)
    print(run.category.name, np.unique(run.phase), np.isnan(run.tube_value))
    assert run.category == Category.II and np.isnan(run.tube_value)
    assert np.all(np.isfinite(run.thrusts)) and np.all(run.thrusts[:, 2][run.control_time > 4.0]
                                                        == 0.0)


def test_the_healthy_motors_carry_the_wrench_and_give_up_the_yaw_first(params):
    """Motors 2 and 4 failed: hover is exact on the opposite pair 0 and 3 (zero yaw torque,
    the input reference after the failure); 24 N is beyond the 20 N of zero yaw torque, and
    with the yaw row weighed 0.1 the thrust and the roll/pitch torques are kept, the yaw
    torque given up."""
    health = np.ones(6)
    health[[2, 4]] = 0.0
    hover = params.thrusts_for_wrench([params.weight, 0.0, 0.0, 0.0], health)
    np.testing.assert_allclose(hover, [params.weight / 2, 0, 0, params.weight / 2, 0, 0],
                               atol=1e-9)
    free_yaw = params.allocation_matrix @ params.thrusts_for_wrench(
        [24.0, 0.0, 0.0, 0.0], health, yaw_weight=0.1)
    equal = params.allocation_matrix @ params.thrusts_for_wrench([24.0, 0.0, 0.0, 0.0],
                                                                 health)
    print(f"24 N asked: yaw row 0.1 gives {free_yaw.round(4)}, 1 gives {equal.round(4)}")
    assert abs(free_yaw[0] - 24.0) < 1e-3 and np.abs(free_yaw[1:3]).max() < 1e-3
    assert np.abs(equal[1:3]).max() > 1e-2  # equal weights trade roll/pitch for yaw
