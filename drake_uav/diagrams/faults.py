"""Closed loop with motor failures: injector, supervisor, fault-tolerant NMPC, plant, ground.

:func:`fly_fault` wires :class:`~drake_uav.systems.faults.FaultInjector` ->
``MultirotorPlant.motor_health``, the plant state into
:class:`~drake_uav.systems.faults.FaultSupervisor` and
:class:`~drake_uav.systems.faults.FaultTolerantController`, and the state into
:class:`~drake_uav.systems.ground.Ground`, whose touchdown ends the simulation.
"""

from __future__ import annotations

import dataclasses
import time as _time
from collections.abc import Callable, Sequence

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.optimization.escape import FreeFallImpact, free_fall_impact
from drake_uav.optimization.fault_response import (
    REFERENCE_MARGIN,
    Category,
    FaultResponse,
    FaultResponseSettings,
    UnsafeDisc,
)
from drake_uav.optimization.terminal_set import ReferenceTable
from drake_uav.systems.faults import (
    FaultInjector,
    FaultSupervisor,
    FaultTolerantController,
    MotorFailure,
)
from drake_uav.systems.ground import Ground
from drake_uav.systems.multirotor import MultirotorPlant
from drake_uav.systems.state_sensor import StateNoise, add_noisy_state_sensor
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["Touchdown", "FaultRun", "fly_fault", "INTEGRATION_ACCURACY"]

INTEGRATION_ACCURACY = 1e-5
"""Relative accuracy of the error-controlled integrator (it also localises the touchdown)."""


@dataclasses.dataclass(frozen=True)
class Touchdown:
    """Where and how the vehicle met the ground."""

    time: float
    """[s]"""
    position: np.ndarray
    """NED [m] (down = 0)."""
    velocity: np.ndarray
    """NED [m/s]; ``velocity[2]`` is the vertical impact speed (positive down)."""

    @property
    def vertical_speed(self) -> float:
        """Downward speed at impact [m/s]."""
        return float(self.velocity[2])


@dataclasses.dataclass(frozen=True, eq=False)
class FaultRun:
    """Logged closed-loop run with a motor failure."""

    time: np.ndarray
    state: np.ndarray
    """Plant state (N, 13)."""
    reference: np.ndarray
    """Mission reference state (N, 13) (what the vehicle flew before the failure)."""
    health: np.ndarray
    """Motor health (N, n)."""
    control_time: np.ndarray
    thrusts: np.ndarray
    """Commands (M, n) [N]."""
    phase: np.ndarray
    """Controller phase (M,) (:class:`~drake_uav.optimization.fault_response.Phase`)."""
    status: np.ndarray
    """0 solved, 1 relaxed, 2 fallback (M,)."""
    solve_time: np.ndarray
    """Wall time of each control step [s] (M,)."""
    category: Category
    """Category given by the supervisor (NONE when no failure happened)."""
    switch_time: float
    """When the controller took the category's objective [s] (nan: never)."""
    fault_time: float
    """When the supervisor saw the failure [s] (nan: never)."""
    tube_value: float
    """Tube value at the fault state (<= 0 inside; nan when not evaluated)."""
    reference_tube_value: float
    """Largest tube value along the remaining reference (nan when not evaluated)."""
    failed_motors: tuple[int, ...]
    touchdown: Touchdown | None
    """None when the run ended in the air."""
    unsafe_disc: UnsafeDisc | None
    safe_point: np.ndarray
    f_max: float
    gravity: float
    real_time_factor: float
    """Simulated time over wall time."""

    def state_at(self, t: float) -> np.ndarray:
        """Logged state (13) nearest to ``t`` [s]."""
        return self.state[int(np.argmin(np.abs(self.time - t)))]

    @property
    def free_fall(self) -> FreeFallImpact | None:
        """Free-fall impact predicted from the state at the fault (eq. 5.17-5.18)."""
        if not np.isfinite(self.fault_time):
            return None
        x = self.state_at(self.fault_time)
        return free_fall_impact(x[:3], x[7:10], self.gravity)

    def position_rmse(self, start: float, end: float | None = None) -> float:
        """Position RMSE [m] against the mission reference between ``start`` and ``end`` [s]."""
        keep = self.time >= start
        if end is not None:
            keep &= self.time <= end
        e = np.linalg.norm(self.state[keep, :3] - self.reference[keep, :3], axis=1)
        return float(np.sqrt(np.mean(e**2))) if len(e) else np.nan


def _touchdown(ground: Ground, context) -> np.ndarray:
    """The ``touchdown`` output (8) of ``ground`` in the diagram ``context``."""
    return ground.GetOutputPort("touchdown").Eval(ground.GetMyContextFromRoot(context))


def _check_failures(failures, duration: float, num_motors: int) -> tuple[MotorFailure, ...]:
    failures = tuple(failures)
    for k, f in enumerate(failures):
        f.validate(num_motors, f"failures[{k}]")
        if not f.time < duration:
            raise ValueError(f"failures[{k}].time = {f.time} s is outside the flight "
                             f"[0, {duration}) s")
    return failures


def fly_fault(params: MultirotorParams, reference: ReferenceTable,
              failures: Sequence[MotorFailure], duration: float, *,
              tube_for: Callable | None = None, unsafe_disc: UnsafeDisc | None = None,
              safe_point=(0.0, 0.0), settings: FaultResponseSettings | None = None,
              category: Category | None = None, margin: float = REFERENCE_MARGIN,
              sensor_noise: StateNoise | None = None, seed: int = 0,
              external_wrench: PiecewisePolynomial | None = None,
              log_period: float = 0.025, end_after_mission: float | None = None) -> FaultRun:
    """Flies ``reference`` from its first state with the motor ``failures`` for up to
    ``duration`` [s] (less when the vehicle touches the ground).

    Parameters
    ----------
    params : MultirotorParams
        The vehicle (plant and controller model).
    reference : ReferenceTable
        The mission.
    failures : sequence of MotorFailure
        When and which motors fail (total or partial).
    duration : float
        Longest simulated time [s].
    tube_for : callable, optional
        ``tube_for(failed_motors) -> value function`` of the recovery tube (see
        :class:`~drake_uav.systems.faults.FaultSupervisor`); required unless closure
        fails or ``category`` is given.
    unsafe_disc : UnsafeDisc, optional
        Area category II avoids.
    safe_point : (north, east)
        Landing point of category III [m].
    settings : FaultResponseSettings, optional
    category : Category, optional
        Forces the category (the tube's figures are still logged when a tube is given).
    margin : float
        Category-III margin on the tube value (``REFERENCE_MARGIN``).
    sensor_noise : StateNoise, optional
        Noisy state measurement between the plant and the supervisor and controller
        (seeded by ``seed``); the ground and the logs see the true state.
    seed : int
        Seed of the measurement noise.
    external_wrench : PiecewisePolynomial, optional
        Disturbance on the plant's ``external_wrench`` (6: force NED [N], torque FRD
        [N m]) over time, e.g. an upset just before a failure.
    log_period : float
        Logging period [s].
    end_after_mission : float, optional
        With a value [s], a run still tracking the mission that long after its end (no
        failure yet, or category IV) stops there instead of hovering until ``duration``;
        a landing or an escape flies on. Campaigns use it: a landing may need minutes, a
        tracked mission does not.

    Raises
    ------
    ValueError
        A failure with an unknown motor, a health outside [0, 1], a time outside the
        flight, or a disc with a negative radius.
    """
    if not duration > 0:
        raise ValueError(f"duration must be positive, got {duration}")
    if end_after_mission is not None and not end_after_mission >= 0:
        raise ValueError(f"end_after_mission must be >= 0 s, got {end_after_mission}")
    n = params.num_motors
    failures = _check_failures(failures, duration, n)
    if unsafe_disc is not None and not isinstance(unsafe_disc, UnsafeDisc):
        unsafe_disc = UnsafeDisc(*unsafe_disc)
    response = FaultResponse(params, reference, settings, unsafe_disc, safe_point, tube_for)
    period = response.settings.nmpc.period
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultirotorPlant(params))
    injector = builder.AddSystem(FaultInjector(n, failures))
    supervisor = builder.AddSystem(FaultSupervisor(params, reference, tube_for, period,
                                                   margin, category))
    controller = builder.AddSystem(FaultTolerantController(response))
    ground = builder.AddSystem(Ground())
    state = plant.GetOutputPort("state")
    measured = state if sensor_noise is None else add_noisy_state_sensor(
        builder, sensor_noise, state)
    health = injector.GetOutputPort("motor_health")
    builder.Connect(health, plant.GetInputPort("motor_health"))
    for system in (supervisor, controller):
        builder.Connect(measured, system.GetInputPort("state"))
        builder.Connect(health, system.GetInputPort("motor_health"))
    builder.Connect(supervisor.GetOutputPort("category"), controller.GetInputPort("category"))
    builder.Connect(controller.GetOutputPort("motor_thrusts"),
                    plant.GetInputPort("motor_thrusts"))
    builder.Connect(state, ground.GetInputPort("state"))
    if external_wrench is not None:
        disturbance = builder.AddSystem(TrajectorySource(external_wrench))
        builder.Connect(disturbance.get_output_port(), plant.GetInputPort("external_wrench"))
    ref_src = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(
        reference.time, reference.state.T)))
    logs = {}
    for name, port, p in (("state", state, log_period),
                          ("reference", ref_src.get_output_port(), log_period),
                          ("health", health, log_period),
                          ("control", controller.GetOutputPort("all"), period)):
        logs[name] = builder.AddSystem(VectorLogSink(port.size(), p))
        builder.Connect(port, logs[name].get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    context = sim.get_mutable_context()
    context.SetAccuracy(INTEGRATION_ACCURACY)
    if sensor_noise is not None:
        diagram.SetRandomContext(context, RandomGenerator(seed))
    plant_context = plant.GetMyMutableContextFromRoot(context)
    xc = plant_context.get_continuous_state_vector().CopyToVector()
    xc[:13] = reference.state[0]
    plant_context.SetContinuousState(xc)
    start = _time.perf_counter()
    stop = duration if end_after_mission is None else min(
        duration, reference.end_time + end_after_mission)
    sim.AdvanceTo(stop)
    if stop < duration and _touchdown(ground, context)[0] == 0:
        category = supervisor.GetOutputPort("category").Eval(
            supervisor.GetMyContextFromRoot(context))[0]
        if int(category) not in (Category.NONE, Category.IV):  # a landing flies on
            sim.AdvanceTo(duration)
    wall = _time.perf_counter() - start
    get = {k: v.FindLog(context) for k, v in logs.items()}
    c = get["control"].data().T
    sup = supervisor.GetOutputPort("all").Eval(supervisor.GetMyContextFromRoot(context))
    td = _touchdown(ground, context)
    touchdown = Touchdown(float(td[1]), td[2:5].copy(), td[5:8].copy()) if td[0] > 0 \
        else None
    failed = tuple(int(i) for i in np.flatnonzero(injector.health_at(duration) < 0.5)) \
        if int(sup[0]) else ()
    return FaultRun(
        time=get["state"].sample_times(), state=get["state"].data().T,
        reference=get["reference"].data().T, health=get["health"].data().T,
        control_time=get["control"].sample_times(), thrusts=c[:, :n], phase=c[:, n],
        status=c[:, n + 1], solve_time=c[:, n + 2], category=Category(int(sup[0])),
        switch_time=float(sup[1]), fault_time=float(sup[2]), tube_value=float(sup[3]),
        reference_tube_value=float(sup[4]), failed_motors=failed, touchdown=touchdown,
        unsafe_disc=unsafe_disc, safe_point=np.asarray(safe_point, dtype=float),
        f_max=params.f_max, gravity=params.gravity,
        real_time_factor=float(context.get_time() / max(wall, 1e-9)))
