"""Linear models about a trim and the classical modes of a fixed wing.

The nonlinear model is :class:`~drake_uav.model.fixed_wing.FixedWingModel`,
written with Euler angles instead of the quaternion (12 states), and
differentiated exactly with AutoDiffXd. The decoupled models follow Beard &
McLain ch. 5 and Ortiz & Gutierrez 2009, sec. 3:

* longitudinal: states ``[u, w, q, theta, h]``, inputs ``[elevator, throttle]``;
* lateral: states ``[v, p, r, phi, psi]``, inputs ``[aileron, rudder]``.

Modes come from the 4x4 cores ``[u, w, q, theta]`` and ``[v, p, r, phi]`` (the
heading and altitude integrators only add zero eigenvalues).

Exact Jacobians rather than the printed small-perturbation models: Ortiz &
Gutierrez 2009, eq. 31 and 33-35 carry sign errors (docs/references.md), and
the Jacobians stay right for any aircraft the model describes. Units: SI and
rad; eigenvalues in 1/s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff

from drake_uav.model.fixed_wing import CONTROL_NAMES, FixedWingModel
from drake_uav.model.rotations import euler_rates, euler_to_quat, quat_to_euler
from drake_uav.optimization.trim import TrimResult
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = [
    "EULER_STATE_NAMES",
    "LinearModel",
    "Mode",
    "ModeAnalysis",
    "linearize_euler",
    "decoupled_models",
    "mode_analysis",
]

EULER_STATE_NAMES = ("pN", "pE", "pD", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
"""Names of the 12-state Euler-angle model."""

_LON_STATES = ("u", "w", "q", "theta", "h")
_LAT_STATES = ("v", "p", "r", "phi", "psi")


@dataclasses.dataclass(frozen=True)
class LinearModel:
    """``d(dx)/dt = A dx + B du`` about ``(x0, u0)``, with named states and inputs."""

    A: np.ndarray
    B: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    x0: np.ndarray
    u0: np.ndarray

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of A [1/s]."""
        return np.linalg.eigvals(self.A)


@dataclasses.dataclass(frozen=True)
class Mode:
    """One dynamic mode: eigenvalue, natural frequency [rad/s], damping ratio,
    and time constant [s] (``inf`` for a marginal mode, negative if unstable)."""

    name: str
    eigenvalue: complex
    natural_frequency: float
    damping: float
    time_constant: float

    @classmethod
    def from_eigenvalue(cls, name: str, lam: complex) -> Mode:
        wn = abs(lam)
        damping = -lam.real / wn if wn > 0 else 0.0
        tau = -1.0 / lam.real if lam.real != 0 else np.inf
        return cls(name, complex(lam), float(wn), float(damping), float(tau))


@dataclasses.dataclass(frozen=True)
class ModeAnalysis:
    """The five classical modes of a conventional aircraft."""

    short_period: Mode
    phugoid: Mode
    roll: Mode
    spiral: Mode
    dutch_roll: Mode

    def table(self) -> str:
        """A text table of the modes."""
        rows = ["mode          eigenvalue               wn [rad/s]  zeta     tau [s]"]
        for mode in (self.short_period, self.phugoid, self.roll, self.spiral, self.dutch_roll):
            lam = mode.eigenvalue
            rows.append(
                f"{mode.name:<12}  {lam.real:+9.4f} {lam.imag:+9.4f}j   "
                f"{mode.natural_frequency:9.4f}  {mode.damping:+7.4f}  {mode.time_constant:9.3f}"
            )
        return "\n".join(rows)


def _euler_derivative(model: FixedWingModel, x12, u):
    """12-state Euler-angle derivative built on the quaternion model."""
    quat = euler_to_quat(x12[3:6])
    x13 = np.array([*x12[0:3], *quat, *x12[6:12]], dtype=x12.dtype)
    xdot13 = model.evaluate(x13, u).state_derivative
    return np.array([*xdot13[0:3], *euler_rates(x12[3:6], x12[9:12]), *xdot13[7:13]])


def linearize_euler(params: FixedWingParams, trim_point: TrimResult) -> LinearModel:
    """Full 12-state Jacobian linearisation about a trim (exact, by AutoDiffXd)."""
    model = FixedWingModel(params)
    s = trim_point.state
    x0 = np.array([*s[0:3], *quat_to_euler(s[3:7]), *s[7:13]])
    u0 = np.asarray(trim_point.controls, dtype=float)
    z_ad = InitializeAutoDiff(np.concatenate([x0, u0]))[:, 0]
    z_ad = np.array(z_ad, dtype=AutoDiffXd)
    f_ad = _euler_derivative(model, z_ad[:12], z_ad[12:])
    jac = ExtractGradient(f_ad)
    return LinearModel(jac[:, :12], jac[:, 12:], EULER_STATE_NAMES, CONTROL_NAMES, x0, u0)


def _select(full: LinearModel, states: tuple[str, ...], inputs: tuple[str, ...]) -> LinearModel:
    names = list(EULER_STATE_NAMES)
    # Altitude h = -pD: flip the sign of its row and column.
    index = [names.index("pD" if s == "h" else s) for s in states]
    sign = np.array([-1.0 if s == "h" else 1.0 for s in states])
    jdx = [CONTROL_NAMES.index(i) for i in inputs]
    A = full.A[np.ix_(index, index)] * np.outer(sign, sign)
    B = full.B[np.ix_(index, jdx)] * sign[:, None]
    return LinearModel(A, B, states, inputs, full.x0[index] * sign, full.u0[jdx])


def decoupled_models(params: FixedWingParams, trim_point: TrimResult) -> tuple:
    """``(longitudinal, lateral)`` LinearModels about a wings-level trim."""
    full = linearize_euler(params, trim_point)
    return (_select(full, _LON_STATES, ("elevator", "throttle")),
            _select(full, _LAT_STATES, ("aileron", "rudder")))


def mode_analysis(params: FixedWingParams, trim_point: TrimResult) -> ModeAnalysis:
    """Short period, phugoid, roll, spiral and dutch roll of a wings-level trim.

    Longitudinal: the complex pair of larger modulus is the short period, the
    other the phugoid. Lateral: the complex pair is the dutch roll, the real
    root of larger modulus the roll subsidence, the other the spiral. Raises
    ``ValueError`` when the roots do not have that conventional pattern.
    """
    lon, lat = decoupled_models(params, trim_point)
    lon_eigs = np.linalg.eigvals(lon.A[:4, :4])
    lat_eigs = np.linalg.eigvals(lat.A[:4, :4])
    lon_pairs = sorted((lam for lam in lon_eigs if lam.imag > 0), key=abs)
    if len(lon_pairs) != 2:
        raise ValueError(f"longitudinal roots are not two oscillatory pairs: {lon_eigs}")
    lat_pair = [lam for lam in lat_eigs if lam.imag > 0]
    lat_real = sorted((lam for lam in lat_eigs if abs(lam.imag) < 1e-12), key=abs)
    if len(lat_pair) != 1 or len(lat_real) != 2:
        raise ValueError(f"lateral roots are not one pair and two real roots: {lat_eigs}")
    return ModeAnalysis(
        short_period=Mode.from_eigenvalue("short period", lon_pairs[1]),
        phugoid=Mode.from_eigenvalue("phugoid", lon_pairs[0]),
        roll=Mode.from_eigenvalue("roll", lat_real[1]),
        spiral=Mode.from_eigenvalue("spiral", lat_real[0]),
        dutch_roll=Mode.from_eigenvalue("dutch roll", lat_pair[0]),
    )
