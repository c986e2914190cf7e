"""Closed-loop trajectory tracking: minimum-snap reference, NMPC, multirotor plant, loggers."""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.model.rotations import euler_to_quat, quat_multiply
from drake_uav.optimization.flatness import flat_reference, velocity_heading
from drake_uav.optimization.min_snap import minimum_snap
from drake_uav.optimization.nmpc import NmpcSettings, default_waypoints
from drake_uav.optimization.terminal_set import ReferenceTable, TerminalSet, terminal_set
from drake_uav.systems.multirotor import MultirotorPlant
from drake_uav.systems.nmpc_controller import NmpcController
from drake_uav.systems.state_sensor import StateNoise, add_noisy_state_sensor
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["TrackingRun", "tracking_reference", "gust_force", "fly_tracking",
           "build_terminal_set", "solve_time_stats", "StateNoise"]


def tracking_reference(params: MultirotorParams, waypoints=None, duration: float | None = None,
                       dt: float = 0.005) -> ReferenceTable:
    """Minimum-snap trajectory through ``waypoints`` (NED [m], equal segment times over
    ``duration`` [s]) with the velocity heading, sampled every ``dt`` [s] by flatness."""
    if waypoints is None:
        waypoints, default = default_waypoints()
        duration = duration or default
    waypoints = np.asarray(waypoints, dtype=float)
    traj = minimum_snap(waypoints, np.linspace(0.0, duration, len(waypoints)))
    t = np.arange(0.0, duration + dt / 2, dt)
    ref = flat_reference(traj, params, t, yaw=velocity_heading(traj))
    return ReferenceTable(ref.time, ref.state, ref.motor_thrusts)


def gust_force(duration: float, sigma: float, time_constant: float = 1.0,
               dt: float = 0.05, seed: int = 0) -> PiecewisePolynomial:
    """Horizontal gust force [N] (6-vector wrench, torques zero): first-order filtered
    white noise (the low-frequency shape of the Dryden spectrum) of standard
    deviation ``sigma`` [N] and correlation time ``time_constant`` [s], seeded."""
    rng = np.random.default_rng(seed)
    n = int(np.ceil(duration / dt)) + 2
    a = np.exp(-dt / time_constant)
    f = np.zeros((n, 6))
    f[0, :3] = sigma * rng.normal(size=3)
    for k in range(1, n):
        f[k, :3] = a * f[k - 1, :3] + sigma * np.sqrt(1 - a * a) * rng.normal(size=3)
    f[:, 2] *= 0.3  # vertical gusts are weaker
    return PiecewisePolynomial.FirstOrderHold(dt * np.arange(n), f.T)


@dataclasses.dataclass(frozen=True, eq=False)
class TrackingRun:
    """Logged closed-loop run."""

    time: np.ndarray
    state: np.ndarray
    """Plant state (N, 13)."""
    reference: np.ndarray
    """Reference state (N, 13)."""
    control_time: np.ndarray
    thrusts: np.ndarray
    """Commands at each control period (M, n) [N]."""
    status: np.ndarray
    solve_time: np.ndarray
    terminal_ratio: np.ndarray
    """``e_N^T P~ e_N / pi~^2`` of each solve (<= 1: terminal constraint met; inf: fallback)."""
    f_max: float

    @property
    def position_error(self) -> np.ndarray:
        return np.linalg.norm(self.state[:, :3] - self.reference[:, :3], axis=1)

    def rmse(self, after: float = 2.0) -> float:
        """Position RMSE [m] after ``after`` [s]."""
        e = self.position_error[self.time >= after]
        return float(np.sqrt(np.mean(e**2)))


def fly_tracking(params: MultirotorParams, terminal: TerminalSet, duration: float, *,
                 settings: NmpcSettings | None = None, offset=(0.0, 0.0, 0.0),
                 attitude_offset: float = 0.0, gust_sigma: float = 0.0, seed: int = 0,
                 log_period: float = 0.025, sensor_noise: StateNoise | None = None
                 ) -> TrackingRun:
    """Simulates the closed loop for ``duration`` [s] from the reference start shifted by
    ``offset`` (NED [m]) and rolled by ``attitude_offset`` [rad], with an optional gust
    force of standard deviation ``gust_sigma`` [N] and an optional noisy state
    measurement ``sensor_noise`` between plant and controller (both seeded by ``seed``).
    ``params`` may carry a motor time constant (the controller's model does not). The
    logged state and the RMSE are the plant's true state."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultirotorPlant(params))
    ctrl = builder.AddSystem(NmpcController(params, terminal, settings))
    measured = plant.GetOutputPort("state")
    if sensor_noise is not None:
        measured = add_noisy_state_sensor(builder, sensor_noise, measured)
    builder.Connect(measured, ctrl.GetInputPort("state"))
    builder.Connect(ctrl.GetOutputPort("motor_thrusts"), plant.GetInputPort("motor_thrusts"))
    if gust_sigma > 0:
        gust = builder.AddSystem(TrajectorySource(gust_force(duration, gust_sigma, seed=seed)))
        builder.Connect(gust.get_output_port(), plant.GetInputPort("external_wrench"))
    ref_src = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(
        terminal.reference.time, terminal.reference.state.T)))
    logs = {}
    for name, port, period in (("state", plant.GetOutputPort("state"), log_period),
                               ("reference", ref_src.get_output_port(), log_period),
                               ("control", ctrl.GetOutputPort("all"), ctrl.mpc.settings.period)):
        logs[name] = builder.AddSystem(VectorLogSink(port.size(), period))
        builder.Connect(port, logs[name].get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    context = sim.get_mutable_context()
    if sensor_noise is not None:
        diagram.SetRandomContext(context, RandomGenerator(seed))
    _set_initial_state(plant.GetMyMutableContextFromRoot(context), terminal, offset,
                       attitude_offset)
    sim.AdvanceTo(duration)
    get = {k: v.FindLog(context) for k, v in logs.items()}
    n = params.num_motors
    c = get["control"].data().T
    return TrackingRun(time=get["state"].sample_times(), state=get["state"].data().T,
                       reference=get["reference"].data().T,
                       control_time=get["control"].sample_times(), thrusts=c[:, :n],
                       status=c[:, n], solve_time=c[:, n + 1],
                       terminal_ratio=c[:, n + 2], f_max=params.f_max)


def _set_initial_state(plant_context, terminal: TerminalSet, offset, attitude_offset) -> None:
    """The reference start shifted by ``offset`` [m] and rolled by ``attitude_offset`` [rad]."""
    x0 = terminal.reference.state[0].copy()
    x0[:3] += np.asarray(offset, dtype=float)
    x0[3:7] = quat_multiply(x0[3:7], euler_to_quat([attitude_offset, 0.0, 0.0]))
    xc = plant_context.get_continuous_state_vector().CopyToVector()
    xc[:13] = x0
    plant_context.SetContinuousState(xc)


def build_terminal_set(params: MultirotorParams, reference: ReferenceTable | None = None,
                       **kwargs) -> TerminalSet:
    """:func:`~drake_uav.optimization.terminal_set.terminal_set` along the default
    reference (or ``reference``) with the input weight ``R = I``."""
    reference = reference or tracking_reference(params)
    return terminal_set(reference, params, R=kwargs.pop("R", np.ones(params.num_motors)),
                        **kwargs)


def solve_time_stats(run: TrackingRun) -> dict:
    """Median, 95th percentile and max of the per-step solve times [s]."""
    s = run.solve_time[run.solve_time > 0]
    if len(s) == 0:
        return {"median": np.nan, "p95": np.nan, "max": np.nan}
    return {"median": float(np.median(s)), "p95": float(np.percentile(s, 95)),
            "max": float(s.max())}
