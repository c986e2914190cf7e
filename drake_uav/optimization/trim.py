"""Trim of the fixed-wing model: wings-level, climbing/descending and coordinated turns.

The trim is a MathematicalProgram over body velocity, attitude, body rates and
controls, with the equations of motion of :class:`FixedWingModel` as nonlinear
equality constraints (evaluated with AutoDiffXd). The program is square (12
unknowns, 12 equations); its solution is polished by Newton steps on the same
equations so the residual reaches machine precision.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.math import cos, sin
from pydrake.solvers import MathematicalProgram, SnoptSolver, Solve

from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.rotations import euler_to_quat
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["TrimResult", "TrimError", "trim"]

_UNKNOWNS = ("u", "v", "w", "roll", "pitch", "p", "q", "r",
             "elevator", "aileron", "rudder", "throttle")


class TrimError(RuntimeError):
    """No trim exists for the request within the control limits."""


@dataclasses.dataclass(frozen=True)
class TrimResult:
    """A steady flight condition."""

    state: np.ndarray
    """Plant state (13) with position (0, 0, -altitude) and zero yaw."""
    controls: np.ndarray
    """[elevator, aileron, rudder (rad), throttle (0..1)]."""
    airspeed: float
    """[m/s]."""
    alpha: float
    """Angle of attack [rad]."""
    beta: float
    """Sideslip [rad] (zero: coordinated)."""
    flight_path_angle: float
    """[rad], positive climbing."""
    turn_rate: float
    """Yaw rate [rad/s], positive turning right."""
    residual: float
    """Norm of the trim equations at the solution (accelerations [m/s^2, rad/s^2])."""


def _equations(model: FixedWingModel, z, airspeed: float, gamma: float, turn_rate: float,
               altitude: float) -> np.ndarray:
    u, v, w, roll, pitch, p, q, r = z[:8]
    controls = z[8:12]
    state = np.array([0.0, 0.0, -altitude, *euler_to_quat([roll, pitch, 0.0 * roll]),
                      u, v, w, p, q, r], dtype=z.dtype)
    xdot = model.evaluate(state, controls).state_derivative
    climb_rate = u * sin(pitch) - v * sin(roll) * cos(pitch) - w * cos(roll) * cos(pitch)
    return np.array([
        *xdot[7:13],
        u * u + v * v + w * w - airspeed**2,
        climb_rate - airspeed * np.sin(gamma),
        p + turn_rate * sin(pitch),
        q - turn_rate * sin(roll) * cos(pitch),
        r - turn_rate * cos(roll) * cos(pitch),
        v,
    ])


def trim(params: FixedWingParams, airspeed: float, flight_path_angle: float = 0.0,
         turn_rate: float = 0.0, altitude: float = 100.0, tolerance: float = 1e-10) -> TrimResult:
    """Trims the aircraft at ``airspeed`` [m/s], ``flight_path_angle`` [rad] and
    ``turn_rate`` [rad/s] with zero sideslip and no wind.

    Raises ``TrimError`` when no solution exists within the control limits (the
    message names the violated limit or the solver status) and ``ValueError``
    for a non-positive airspeed.
    """
    if not airspeed > 0:
        raise ValueError(f"trim: airspeed must be positive, got {airspeed}")
    model = FixedWingModel(params)
    limits = params.limits
    prog = MathematicalProgram()
    z = prog.NewContinuousVariables(len(_UNKNOWNS), "z")
    lower = np.full(12, -np.inf)
    upper = np.full(12, np.inf)
    lower[3:5], upper[3:5] = -1.4, 1.4
    lower[8:12], upper[8:12] = limits.lower(), limits.upper()
    prog.AddBoundingBoxConstraint(lower, upper, z)

    def constraint(zz):
        return _equations(model, zz, airspeed, flight_path_angle, turn_rate, altitude)

    prog.AddConstraint(constraint, np.zeros(12), np.zeros(12), z, description="trim equations")
    prog.AddQuadraticCost(1e-3 * np.eye(4), np.zeros(4), z[8:12])
    guess = np.array([airspeed, 0, 0.05 * airspeed, 0, 0.05, 0, 0, 0, 0, 0, 0, 0.5])
    solver = SnoptSolver() if SnoptSolver().available() else None
    result = solver.Solve(prog, guess) if solver else Solve(prog, guess)
    z_opt = result.GetSolution(z)
    z_opt = _polish(constraint, z_opt, tolerance)
    residual = float(np.linalg.norm(constraint(z_opt)))
    if not result.is_success() and residual > tolerance:
        raise TrimError(
            f"no trim at airspeed {airspeed} m/s, flight path {flight_path_angle} rad, "
            f"turn rate {turn_rate} rad/s: solver status {result.get_solution_result()}, "
            f"equation residual {residual:.2e}{_limit_report(z_opt, lower, upper)}"
        )
    violated = _limit_report(z_opt, lower, upper)
    if violated or residual > tolerance:
        raise TrimError(
            f"no trim at airspeed {airspeed} m/s within the limits: residual {residual:.2e}"
            f"{violated}"
        )
    u, v, w, roll, pitch, p, q, r = z_opt[:8]
    state = np.array([0.0, 0.0, -altitude, *euler_to_quat([roll, pitch, 0.0]), u, v, w, p, q, r])
    evaluation = model.evaluate(state, z_opt[8:12])
    _, alpha, beta = evaluation.air_data
    return TrimResult(
        state=state, controls=z_opt[8:12].copy(), airspeed=airspeed, alpha=float(alpha),
        beta=float(beta), flight_path_angle=flight_path_angle, turn_rate=turn_rate,
        residual=residual,
    )


def _polish(constraint, z: np.ndarray, tolerance: float, max_steps: int = 20) -> np.ndarray:
    """Newton iterations on the square trim equations, Jacobian by AutoDiffXd."""
    for _ in range(max_steps):
        z_ad = InitializeAutoDiff(z)[:, 0]
        g_ad = constraint(np.array(z_ad, dtype=AutoDiffXd))
        g = ExtractValue(g_ad)[:, 0]
        if np.linalg.norm(g) < 1e-3 * tolerance:
            break
        J = ExtractGradient(g_ad)
        step, *_ = np.linalg.lstsq(J, -g, rcond=None)
        z = z + step
    return z


def _limit_report(z: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> str:
    bad = [
        f"{_UNKNOWNS[i]}={z[i]:.4g} outside [{lower[i]:.4g}, {upper[i]:.4g}]"
        for i in range(len(z))
        if z[i] < lower[i] - 1e-9 or z[i] > upper[i] + 1e-9
    ]
    return "; " + ", ".join(bad) if bad else ""
