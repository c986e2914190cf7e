"""Differential flatness of the multirotor (Argyropoulos 2020, sec. 2.2).

The flat outputs are the NED position and the yaw angle. From the position
derivatives up to snap and the yaw up to its second derivative, the reference
attitude, body rates, thrust, torques and motor thrusts follow exactly (NED /
FRD, thrust along ``-z_b``)::

    z_b = (g e_3 - a) / |g e_3 - a|,   F = m |g e_3 - a|                  (eq. 2.6-2.7)
    x_b = (y_c x z_b) / |y_c x z_b|,   y_c = [-sin psi, cos psi, 0],  y_b = z_b x x_b
    omega = [-y_b . dz_b, x_b . dz_b, y_b . dx_b],  d omega/dt from the second derivatives

(the thrust points along ``a - g``, where eq. 2.6-2.8 print ``a + g``, and the
torques use ``J domega/dt``, where eq. 2.11 prints ``J omega``:
docs/references.md), so ``psi`` is exactly the 3-2-1 Euler yaw of the
reference. Units: m, s, rad, N, N m. The thrust and
torques are then the wrench for which the plant's own dynamics function
(:func:`drake_uav.model.multirotor.multirotor_dynamics`) reproduces the
reference accelerations; the motor thrusts come from the allocation.

:func:`velocity_heading` builds the yaw reference of Argyropoulos 2020 (eq. 2.8-2.9): the body
x axis follows the velocity projected on the rotor plane, with the yaw rate
penalised, the angle kept continuous across +-pi (no wrap jumps, as in its
fig. 2.3), median and Gaussian smoothing, and zero rate at both ends.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.trajectories import PiecewisePolynomial
from scipy.interpolate import BSpline, make_interp_spline
from scipy.ndimage import gaussian_filter1d, median_filter

from drake_uav.model.multirotor import BODY_RATES, VELOCITY, multirotor_dynamics
from drake_uav.model.rotations import rotmat_to_quat
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "FlatAttitude",
    "attitude_from_flat_outputs",
    "FlatReference",
    "flat_reference",
    "reference_from_flat_outputs",
    "YawProfile",
    "velocity_heading",
]


def _dot(a, b):
    return np.einsum("ni,ni->n", a, b)


def _normalized_derivatives(u, du, ddu=None):
    """Unit vector ``u/|u|`` and its first (and second) time derivatives, row-wise."""
    norm = np.linalg.norm(u, axis=1)
    e = u / norm[:, None]
    rate = _dot(e, du)
    de = (du - rate[:, None] * e) / norm[:, None]
    if ddu is None:
        return e, de, None
    along = _dot(e, ddu)
    dde = (ddu - along[:, None] * e - 2.0 * rate[:, None] * de
           - _dot(de, du)[:, None] * e) / norm[:, None]
    return e, de, dde


@dataclasses.dataclass(frozen=True, eq=False)
class FlatAttitude:
    """Attitude part of the flat map, one row per sample."""

    rotation: np.ndarray
    """Body FRD -> NED rotation matrices (N, 3, 3)."""
    body_rates: np.ndarray
    """omega (N, 3) [rad/s]."""
    body_acceleration: np.ndarray
    """d omega / dt (N, 3) [rad/s^2]."""
    thrust_per_mass: np.ndarray
    """F / m (N,) [m/s^2]."""


def attitude_from_flat_outputs(acceleration, jerk, snap, yaw, yaw_rate, yaw_acceleration,
                               gravity: float) -> FlatAttitude:
    """Reference rotation, body rates and their derivative from flat-output derivatives.

    ``acceleration``, ``jerk``, ``snap``: (N, 3) NED [m/s^2, m/s^3, m/s^4];
    ``yaw``, ``yaw_rate``, ``yaw_acceleration``: (N,) [rad, rad/s, rad/s^2].
    Raises ``ValueError`` where the thrust vanishes (free fall) or the body z
    axis is horizontal, where the attitude is not defined by these outputs.
    """
    a, j, s = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (acceleration, jerk, snap))
    psi, dpsi, ddpsi = (np.atleast_1d(np.asarray(v, dtype=float))
                        for v in (yaw, yaw_rate, yaw_acceleration))
    thrust = -a
    thrust[:, 2] += gravity
    norm = np.linalg.norm(thrust, axis=1)
    if np.any(norm < 1e-6 * gravity):
        raise ValueError("the reference has zero thrust (free fall): attitude undefined at "
                         f"sample {int(np.argmin(norm))}")
    z, dz, ddz = _normalized_derivatives(thrust, -j, -s)
    c, sn = np.cos(psi), np.sin(psi)
    zero = np.zeros_like(psi)
    xc = np.column_stack([c, sn, zero])
    yc = np.column_stack([-sn, c, zero])
    dyc = -dpsi[:, None] * xc
    ddyc = -ddpsi[:, None] * xc - (dpsi**2)[:, None] * yc
    u = np.cross(yc, z)
    if np.any(np.linalg.norm(u, axis=1) < 1e-6):
        raise ValueError("the body z axis is horizontal and along the yaw direction: "
                         "yaw does not define the attitude there")
    du = np.cross(dyc, z) + np.cross(yc, dz)
    ddu = np.cross(ddyc, z) + 2.0 * np.cross(dyc, dz) + np.cross(yc, ddz)
    x, dx, ddx = _normalized_derivatives(u, du, ddu)
    y = np.cross(z, x)
    dy = np.cross(dz, x) + np.cross(z, dx)
    omega = np.column_stack([-_dot(y, dz), _dot(x, dz), _dot(y, dx)])
    omega_dot = np.column_stack([
        -(_dot(dy, dz) + _dot(y, ddz)),
        _dot(dx, dz) + _dot(x, ddz),
        _dot(dy, dx) + _dot(y, ddx),
    ])
    return FlatAttitude(rotation=np.stack([x, y, z], axis=2), body_rates=omega,
                        body_acceleration=omega_dot, thrust_per_mass=norm)


@dataclasses.dataclass(frozen=True, eq=False)
class FlatReference:
    """Reference state and input along a trajectory, one row per sample time."""

    time: np.ndarray
    """Sample times (N,) [s]."""
    state: np.ndarray
    """Plant state (N, 13): p NED [m], q (w, x, y, z), v NED [m/s], omega FRD [rad/s]."""
    body_acceleration: np.ndarray
    """d omega / dt (N, 3) [rad/s^2]."""
    wrench: np.ndarray
    """``[F, tau_x, tau_y, tau_z]`` (N, 4) [N, N m]."""
    motor_thrusts: np.ndarray
    """Per-motor thrusts (N, n) [N] from the allocation (failed motors 0)."""
    yaw: np.ndarray
    """Reference yaw (N,) [rad], continuous (not wrapped)."""
    dynamics_residual: float
    """Max |acceleration mismatch| of the plant dynamics at (state, wrench) [SI]."""
    allocation_residual: float
    """Max |A diag(h) f - wrench| [N, N m]; > 0 when the motors cannot produce the wrench."""

    def within_limits(self, tolerance: float = 1e-6) -> bool:
        """True when the motor thrusts (in [0, f_max]) reproduce the wrench."""
        return self.allocation_residual <= tolerance

    def state_trajectory(self) -> PiecewisePolynomial:
        """Cubic spline of the state (13 x 1), e.g. for a ``TrajectorySource``."""
        return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(self.time, self.state.T)

    def motor_thrust_trajectory(self) -> PiecewisePolynomial:
        """Cubic spline of the motor thrusts (n x 1) [N]."""
        return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            self.time, self.motor_thrusts.T)

    def wrench_trajectory(self) -> PiecewisePolynomial:
        """Cubic spline of ``[F, tau]`` (4 x 1) [N, N m]."""
        return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(self.time, self.wrench.T)


def reference_from_flat_outputs(time, position, velocity, acceleration, jerk, snap, yaw,
                                yaw_rate, yaw_acceleration, params: MultirotorParams,
                                health=None) -> FlatReference:
    """Reference state and input from sampled flat outputs and their derivatives.

    Position-like arrays are (N, 3) NED [m, m/s, ...]; yaw arrays (N,) [rad,
    rad/s, rad/s^2]. ``health`` (n,) in [0, 1] distributes the wrench over the
    remaining motors. Rotor drag across the body axes breaks the flat map and is
    rejected.
    """
    if params.rotor_drag[0] != 0.0 or params.rotor_drag[1] != 0.0:
        raise ValueError("MultirotorParams.rotor_drag x and y must be 0 for the flat map "
                         f"(thrust is along z_b only), got {params.rotor_drag}")
    time = np.atleast_1d(np.asarray(time, dtype=float))
    att = attitude_from_flat_outputs(acceleration, jerk, snap, yaw, yaw_rate,
                                     yaw_acceleration, params.gravity)
    N = len(time)
    quats = np.empty((N, 4))
    for k in range(N):
        q = rotmat_to_quat(att.rotation[k])
        if k > 0 and q @ quats[k - 1] < 0:
            q = -q
        quats[k] = q
    state = np.column_stack([np.asarray(position, float), quats, np.asarray(velocity, float),
                             att.body_rates])
    target = np.column_stack([np.asarray(acceleration, float), att.body_acceleration])
    wrench = np.empty((N, 4))
    residual = 0.0
    accel_rows = np.r_[VELOCITY, BODY_RATES]
    unit = np.eye(4)
    # The plant dynamics are affine in the wrench: evaluate the drift and the four input
    # columns, then solve for the wrench that gives the reference accelerations.
    for k in range(N):
        drift = multirotor_dynamics(state[k], np.zeros(4), params)[accel_rows]
        B = np.column_stack([multirotor_dynamics(state[k], unit[i], params)[accel_rows] - drift
                             for i in range(4)])
        wrench[k] = np.linalg.lstsq(B, target[k] - drift, rcond=None)[0]
        residual = max(residual, float(np.abs(B @ wrench[k] + drift - target[k]).max()))
    thrusts = params.thrusts_for_wrench(wrench, health)
    produced = thrusts @ params.effective_allocation(health).T
    return FlatReference(
        time=time, state=state, body_acceleration=att.body_acceleration, wrench=wrench,
        motor_thrusts=thrusts, yaw=np.asarray(yaw, float) * np.ones(N),
        dynamics_residual=residual,
        allocation_residual=float(np.abs(produced - wrench).max()),
    )


def _yaw_derivatives(yaw, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not hasattr(yaw, "value"):
        return np.full(len(times), float(yaw)), np.zeros(len(times)), np.zeros(len(times))
    return tuple(np.reshape(yaw.value(times, d), len(times)) for d in range(3))


def flat_reference(trajectory, params: MultirotorParams, times, *, yaw=0.0,
                   health=None) -> FlatReference:
    """Reference state and input along a position ``trajectory`` at ``times`` [s].

    ``trajectory`` provides ``value(t, derivative)`` -> (N, 3) NED (e.g. a
    :class:`~drake_uav.optimization.min_snap.PolynomialTrajectory`); ``yaw`` is a
    constant [rad] or anything with ``value(t, derivative)`` (a
    :class:`YawProfile` from :func:`velocity_heading`, or a 1-D trajectory).
    """
    t = np.atleast_1d(np.asarray(times, dtype=float))
    d = [trajectory.value(t, k) for k in range(5)]
    psi, dpsi, ddpsi = _yaw_derivatives(yaw, t)
    return reference_from_flat_outputs(t, *d, psi, dpsi, ddpsi, params, health)


@dataclasses.dataclass(frozen=True, eq=False)
class YawProfile:
    """Smooth yaw reference ``psi(t)`` [rad]; constant with zero rate outside its span."""

    spline: BSpline

    def value(self, t, derivative: int = 0) -> np.ndarray:
        """``d^derivative psi / dt^derivative`` at ``t`` (same shape as ``t``)."""
        t = np.asarray(t, dtype=float)
        lo, hi = self.spline.t[0], self.spline.t[-1]
        out = self.spline(np.clip(t, lo, hi), nu=derivative)
        if derivative > 0:
            out = np.where((t < lo) | (t > hi), 0.0, out)
        return out


def _heading_step(psi_prev, target, z, dz, dt, weight, max_step):
    """One step of eq. 2.9: argmin over psi of omega_z(psi)^2 + weight (psi - target)^2.

    ``omega_z = a + b (psi - psi_prev) / dt`` is linear in the yaw rate (the
    flat map at ``psi_prev``), so the minimiser is explicit. ``target`` is
    unwrapped next to ``psi_prev`` first: no 2 pi jumps. The change is limited
    to ``max_step`` [rad].
    """
    c, s = math.cos(psi_prev), math.sin(psi_prev)
    xc, yc = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    u = np.cross(yc, z)
    mu = np.linalg.norm(u)
    y = np.cross(z, u / mu)
    a = y @ np.cross(yc, dz) / mu
    b = -(y @ np.cross(xc, z)) / mu
    error = math.remainder(target - psi_prev, 2.0 * math.pi)
    delta = (weight * error - a * b / dt) / (b * b / dt**2 + weight)
    return psi_prev + min(max(delta, -max_step), max_step)


def velocity_heading(trajectory, *, sample_time: float = 0.02, time_constant: float = 1.0,
                     max_yaw_rate: float = 1.0, median_window: float = 0.3,
                     smoothing: float = 0.3, min_speed: float = 0.2,
                     gravity: float = 9.80665, initial_yaw: float | None = None) -> YawProfile:
    """Yaw that points the body x axis along the velocity (Argyropoulos 2020, eq. 2.8-2.9,
    fig. 2.3).

    On a grid of ``sample_time`` [s] the target heading is that of the velocity
    projected on the plane normal to the thrust axis; where that speed is below
    ``min_speed`` [m/s] the yaw is held. Each step solves eq. 2.9 with the
    weight ``k = 1 / (time_constant * sample_time)`` [1/s^2], so the yaw lags
    the heading by about ``time_constant`` [s] whatever the grid, and turns no
    faster than ``max_yaw_rate`` [rad/s] (before smoothing). The result is
    median filtered (``median_window`` [s]), Gaussian smoothed (standard
    deviation ``smoothing`` [s]) and fitted by a quintic spline with zero rate
    and acceleration at both ends. ``initial_yaw`` defaults to the first valid
    heading.
    """
    for name, value in (("sample_time", sample_time), ("time_constant", time_constant),
                        ("max_yaw_rate", max_yaw_rate), ("min_speed", min_speed)):
        if not value > 0:
            raise ValueError(f"{name} must be positive, got {value}")
    t0, t1 = trajectory.start_time(), trajectory.end_time()
    n = max(int(round((t1 - t0) / sample_time)), 7) + 1
    t = np.linspace(t0, t1, n)
    dt = t[1] - t[0]
    v, a, j = (trajectory.value(t, k) for k in (1, 2, 3))
    thrust = -a
    thrust[:, 2] += gravity
    z, dz, _ = _normalized_derivatives(thrust, -j)
    vp = v - _dot(v, z)[:, None] * z
    valid = np.linalg.norm(vp, axis=1) >= min_speed
    heading = np.arctan2(vp[:, 1], vp[:, 0])
    if initial_yaw is None:
        initial_yaw = float(heading[np.argmax(valid)]) if np.any(valid) else 0.0
    weight = 1.0 / (time_constant * dt)
    psi = np.empty(n)
    psi[0] = initial_yaw
    for k in range(1, n):
        target = heading[k] if valid[k] else psi[k - 1]
        psi[k] = _heading_step(psi[k - 1], target, z[k], dz[k], dt, weight, max_yaw_rate * dt)
    window = max(int(round(median_window / dt)) | 1, 1)
    psi = median_filter(psi, size=window, mode="nearest")
    if smoothing > 0:
        psi = gaussian_filter1d(psi, smoothing / dt, mode="nearest")
    flat_end = [(1, 0.0), (2, 0.0)]
    return YawProfile(make_interp_spline(t, psi, k=5, bc_type=(flat_end, flat_end)))
