"""Fixed-wing aircraft parameters and the catalog (Aerosonde, UnATRaP).

Aerodynamic derivatives are named ``<coefficient>_<signal>``, e.g. ``CL_alpha``,
``CD_alpha2`` or ``Cn_rudder``; :mod:`drake_uav.systems.aerodynamics` defines the
coefficients, the signals and the regressor each name stands for.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from drake_uav.systems.aerodynamics import validate_derivative_names

__all__ = [
    "ControlLimits",
    "Propulsion",
    "FixedWingParams",
    "aerosonde",
    "unatrap",
    "fixed_wing_catalog",
]

GRAVITY = 9.80665
"""Standard gravity [m/s^2]."""


@dataclasses.dataclass(frozen=True)
class ControlLimits:
    """Actuator limits. Surfaces in rad (symmetric), throttle as a 0..1 fraction."""

    elevator: float = math.radians(25.0)
    aileron: float = math.radians(25.0)
    rudder: float = math.radians(25.0)
    throttle_min: float = 0.0
    throttle_max: float = 1.0

    def lower(self) -> np.ndarray:
        """Lower bounds of ``[elevator, aileron, rudder, throttle]``."""
        return np.array([-self.elevator, -self.aileron, -self.rudder, self.throttle_min])

    def upper(self) -> np.ndarray:
        """Upper bounds of ``[elevator, aileron, rudder, throttle]``."""
        return np.array([self.elevator, self.aileron, self.rudder, self.throttle_max])


@dataclasses.dataclass(frozen=True)
class Propulsion:
    """Propeller model of Beard & McLain (2012), sec. 4.3.

    Thrust ``T = 0.5 rho S_prop C_prop ((k_motor dT)^2 - Va^2)`` [N] along body x,
    reaction torque ``-k_Tp (k_Omega dT)^2`` [N m] about body x.
    """

    S_prop: float = 0.2027
    """Propeller disc area [m^2]."""
    C_prop: float = 1.0
    """Propeller efficiency coefficient [-]."""
    k_motor: float = 80.0
    """Motor constant: exit air speed at full throttle [m/s]."""
    k_Tp: float = 0.0
    """Torque constant [N m s^2]."""
    k_Omega: float = 0.0
    """Propeller speed constant [rad/s]."""

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        for field in ("S_prop", "C_prop", "k_motor"):
            if not getattr(self, field) > 0:
                raise ValueError(f"FixedWingParams.propulsion.{field} must be positive")

    def thrust_torque(self, airspeed, throttle, rho: float) -> tuple:
        """Thrust [N] and reaction torque [N m] at ``airspeed`` [m/s], ``throttle`` [0..1]
        and air density ``rho`` [kg/m^3]; any Drake scalar type."""
        k = self.k_motor * throttle
        thrust = 0.5 * rho * self.S_prop * self.C_prop * (k * k - airspeed * airspeed)
        w = self.k_Omega * throttle
        return thrust, -self.k_Tp * w * w


@dataclasses.dataclass(frozen=True)
class FixedWingParams:
    """Rigid-body, geometric, propulsive and aerodynamic parameters of a fixed wing."""

    name: str
    mass: float
    """Mass [kg]."""
    Jx: float
    """Roll moment of inertia [kg m^2]."""
    Jy: float
    """Pitch moment of inertia [kg m^2]."""
    Jz: float
    """Yaw moment of inertia [kg m^2]."""
    Jxz: float
    """Product of inertia [kg m^2] (J = [[Jx, 0, -Jxz], [0, Jy, 0], [-Jxz, 0, Jz]])."""
    S: float
    """Wing area [m^2]."""
    b: float
    """Wingspan [m]."""
    c: float
    """Mean aerodynamic chord [m]."""
    derivatives: Mapping[str, float]
    """Aerodynamic derivatives by name (``CL_alpha`` ...), non-dimensional, per rad."""
    rho: float = 1.225
    """Air density [kg/m^3]."""
    gravity: float = GRAVITY
    """Gravitational acceleration [m/s^2]."""
    propulsion: Propulsion = dataclasses.field(default_factory=Propulsion)
    """Propulsion model: any object with ``validate()`` and ``thrust_torque(Va, dT, rho)``."""
    limits: ControlLimits = dataclasses.field(default_factory=ControlLimits)

    def __post_init__(self):
        object.__setattr__(self, "derivatives", MappingProxyType(dict(self.derivatives)))
        self.validate()

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        positive = ("mass", "Jx", "Jy", "Jz", "S", "b", "c", "rho", "gravity")
        for field in positive:
            value = getattr(self, field)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(
                    f"FixedWingParams.{field} must be positive and finite, got {value}")
        if not np.isfinite(self.Jxz):
            raise ValueError(f"FixedWingParams.Jxz must be finite, got {self.Jxz}")
        if np.any(np.linalg.eigvalsh(self.inertia) <= 0) or self.Jx * self.Jz <= self.Jxz**2:
            raise ValueError(
                "FixedWingParams.inertia (Jx, Jy, Jz, Jxz) is not positive definite: "
                f"Jx={self.Jx}, Jy={self.Jy}, Jz={self.Jz}, Jxz={self.Jxz}"
            )
        if not (self.Jx + self.Jy >= self.Jz and self.Jy + self.Jz >= self.Jx
                and self.Jx + self.Jz >= self.Jy):
            raise ValueError("FixedWingParams.inertia violates the triangle inequality")
        validate_derivative_names(self.derivatives, owner="FixedWingParams.derivatives")
        for name, value in self.derivatives.items():
            if not np.isfinite(value):
                raise ValueError(f"FixedWingParams.derivatives['{name}'] is not finite: {value}")
        self.propulsion.validate()
        lim = self.limits
        for field in ("elevator", "aileron", "rudder"):
            if not getattr(lim, field) > 0:
                raise ValueError(f"FixedWingParams.limits.{field} must be positive")
        if not 0.0 <= lim.throttle_min < lim.throttle_max:
            raise ValueError("FixedWingParams.limits throttle range must satisfy 0 <= min < max")

    @property
    def inertia(self) -> np.ndarray:
        """Inertia matrix [kg m^2] in body FRD axes."""
        return np.array(
            [[self.Jx, 0.0, -self.Jxz], [0.0, self.Jy, 0.0], [-self.Jxz, 0.0, self.Jz]]
        )

    def derivative(self, name: str) -> float:
        """Value of one derivative, zero when the model does not have the term."""
        return float(self.derivatives.get(name, 0.0))

    def with_derivatives(self, **updates: float) -> FixedWingParams:
        """A copy with some derivatives replaced or added (validated)."""
        merged = dict(self.derivatives)
        merged.update(updates)
        return dataclasses.replace(self, derivatives=merged)


def _aerosonde_derivatives(S: float, b: float, e: float, C_D_p: float, CL0: float,
                           CL_alpha: float) -> dict[str, float]:
    # Beard & McLain's drag polar C_D = C_D_p + (CL0 + CL_alpha alpha)^2 / (pi e AR)
    # is exactly quadratic in alpha: expand it into CD_0 + CD_alpha a + CD_alpha2 a^2.
    k = 1.0 / (math.pi * e * b**2 / S)
    return {
        "CL_0": CL0, "CL_alpha": CL_alpha, "CL_q": 0.0, "CL_elevator": -0.36,
        "CD_0": C_D_p + k * CL0**2, "CD_alpha": 2 * k * CL0 * CL_alpha,
        "CD_alpha2": k * CL_alpha**2, "CD_q": 0.0, "CD_elevator": 0.0,
        "Cm_0": -0.02338, "Cm_alpha": -0.38, "Cm_q": -3.6, "Cm_elevator": -0.5,
        "CY_0": 0.0, "CY_beta": -0.98, "CY_p": 0.0, "CY_r": 0.0,
        "CY_aileron": 0.0, "CY_rudder": -0.17,
        "Cl_0": 0.0, "Cl_beta": -0.12, "Cl_p": -0.26, "Cl_r": 0.14,
        "Cl_aileron": 0.08, "Cl_rudder": 0.105,
        "Cn_0": 0.0, "Cn_beta": 0.25, "Cn_p": 0.022, "Cn_r": -0.35,
        "Cn_aileron": 0.06, "Cn_rudder": -0.032,
    }


def aerosonde() -> FixedWingParams:
    """The Aerosonde of Beard & McLain, *Small Unmanned Aircraft* (2012), appendix E.

    Mass, inertia, geometry, propulsion and all derivatives as published there.
    The book's drag polar ``C_D_p + (C_L0 + C_Lalpha alpha)^2 / (pi e AR)`` (with
    C_D_p = 0.0437, e = 0.9) is written exactly as ``CD_0 + CD_alpha alpha +
    CD_alpha2 alpha^2``. The post-stall blending (M = 50, alpha0 = 0.4712) is not
    part of the linear-in-parameters model; it is available as the stall effect
    of the identification library. Air density 1.2682 kg/m^3 as in the book.
    """
    S, b = 0.55, 2.8956
    return FixedWingParams(
        name="aerosonde",
        mass=13.5,
        Jx=0.8244,
        Jy=1.135,
        Jz=1.759,
        Jxz=0.1204,
        S=S,
        b=b,
        c=0.18994,
        rho=1.2682,
        derivatives=_aerosonde_derivatives(S, b, e=0.9, C_D_p=0.0437, CL0=0.28, CL_alpha=3.45),
        propulsion=Propulsion(S_prop=0.2027, C_prop=1.0, k_motor=80.0, k_Tp=0.0, k_Omega=0.0),
    )


def unatrap() -> FixedWingParams:
    """UnATRaP of seed S0 (Vaiopoulos 2017): Table 8 geometry, Table 10 force derivatives.

    From the seed: operating mass 12.6 kg, chord 0.34 m, span 2.72 m, wing area
    0.92 m^2, and the C_L, C_D, C_Y derivatives identified from flight 2 (Table 10,
    as printed, including the doubtful C_D0 = C_Dalpha = 0.1268 and the positive
    C_Ybeta; C_DTc multiplies the thrust coefficient T / (qbar S)).

    Assumed (the seed does not give them):
    * inertia: the Aerosonde's scaled by mass and by span^2 (roll, yaw) or chord
      and span (pitch): Jx = 0.68, Jy = 1.78, Jz = 1.45, Jxz = 0.10 kg m^2;
    * moment derivatives: the Aerosonde's values (static and damping
      derivatives of a conventional tail-aft layout);
    * propulsion: 0.51 m (20 in) propeller with k_motor = 40 m/s, about 200 N
      static thrust, the order of a 32 cc / 3.8 HP engine;
    * air density 1.225 kg/m^3 (sea level).
    """
    m_ref, b_ref, c_ref = 13.5, 2.8956, 0.18994
    mass, b, c = 12.6, 2.72, 0.34
    roll_scale = (mass / m_ref) * (b / b_ref) ** 2
    pitch_scale = (mass / m_ref) * (b * c) / (b_ref * c_ref)
    moments = {
        key: value
        for key, value in aerosonde().derivatives.items()
        if key.startswith(("Cm_", "Cl_", "Cn_"))
    }
    forces = {
        "CL_0": 0.2933, "CL_alpha": 3.6070, "CL_q": 2.3550, "CL_elevator": 0.0711,
        "CD_0": 0.1268, "CD_alpha": 0.1268, "CD_alpha2": 1.9081, "CD_q": 0.2904,
        "CD_elevator": 0.0068, "CD_Tc": 0.0152,
        "CY_0": 0.00312, "CY_beta": 0.6696, "CY_p": 0.1055, "CY_r": 0.5134,
        "CY_aileron": 0.0032, "CY_rudder": -0.1257,
    }
    return FixedWingParams(
        name="unatrap",
        mass=mass,
        Jx=round(0.8244 * roll_scale, 2),
        Jy=round(1.135 * pitch_scale, 2),
        Jz=round(1.759 * roll_scale, 2),
        Jxz=round(0.1204 * roll_scale, 2),
        S=0.92,
        b=b,
        c=c,
        rho=1.225,
        derivatives={**forces, **moments},
        propulsion=Propulsion(S_prop=0.2027, C_prop=1.0, k_motor=40.0),
    )


def fixed_wing_catalog() -> dict[str, FixedWingParams]:
    """All catalog aircraft by name."""
    return {"aerosonde": aerosonde(), "unatrap": unatrap()}
