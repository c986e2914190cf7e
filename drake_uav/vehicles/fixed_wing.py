"""Fixed-wing aircraft parameters and the catalog (Aerosonde, UnATRaP).

Aerodynamic derivatives are named ``<coefficient>_<signal>``, e.g. ``CL_alpha``,
``CD_alpha2`` or ``Cn_rudder``; :mod:`drake_uav.model.coefficients` defines the
coefficients, the signals and the regressor each name stands for. Units: SI
(kg, m, m^2, kg m^2, kg/m^3), angles in rad; derivatives are non-dimensional,
per rad or per unit of their normalised signal. Every dataclass validates its
fields and raises ``ValueError`` naming the first invalid one.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from drake_uav.model.coefficients import validate_derivative_names
from drake_uav.model.propeller import propeller_thrust, propeller_torque
from drake_uav.model.scalar import ssqrt

__all__ = [
    "ControlLimits",
    "Propulsion",
    "MotorPropeller",
    "FixedWingParams",
    "aerosonde",
    "aerosonde_mavsim",
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

    def deflections(self) -> dict[str, float]:
        """Full deflection of each surface [rad], as the log readers take it (a servo's
        full throw is the surface's limit)."""
        return {"elevator": self.elevator, "aileron": self.aileron, "rudder": self.rudder}

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
class MotorPropeller:
    """Electric motor driving a fixed-pitch propeller: McLain's propulsion model, as used by
    the simulator accompanying Beard & McLain (repository randybeard/mavsim_public).

    The battery voltage ``V_in = V_max dT`` drives a DC motor (back-emf constant ``KV``,
    torque constant ``KQ``, resistance ``R_motor``, no-load current ``i0``). The propeller
    speed ``Omega`` [rad/s] balances motor and propeller torque, the positive root of

        a Omega^2 + b Omega + c = 0,  a = rho D^5 C_Q0 / (2 pi)^2,
        b = rho D^4 C_Q1 Va / (2 pi) + KQ KV / R_motor,
        c = rho D^3 C_Q2 Va^2 - KQ V_in / R_motor + KQ i0.

    With the advance ratio ``J = 2 pi Va / (Omega D)`` and the polynomial fits
    ``C_T(J) = C_T0 + C_T1 J + C_T2 J^2`` and ``C_Q(J)`` alike, thrust is
    ``T = rho (Omega / 2 pi)^2 D^4 C_T(J)`` [N] along body x and the propeller torque
    ``Q = rho (Omega / 2 pi)^2 D^5 C_Q(J)`` [N m]; the airframe feels ``-Q`` about body x.
    The defaults are that simulator's Aerosonde: 20 in propeller, 145 rpm/V motor, 12 cells.
    """

    diameter: float = 20 * 0.0254
    """Propeller diameter D [m]."""
    KV: float = 60.0 / (2 * math.pi * 145.0)
    """Motor back-emf constant [V s/rad] (60 / (2 pi KV_rpm) for KV_rpm in rpm/V)."""
    KQ: float = 60.0 / (2 * math.pi * 145.0)
    """Motor torque constant [N m/A] (equal to ``KV`` in SI units for an ideal motor)."""
    R_motor: float = 0.042
    """Motor winding resistance [ohm]."""
    i0: float = 1.5
    """No-load (zero-torque) current [A]."""
    V_max: float = 3.7 * 12
    """Battery voltage at full throttle [V]."""
    C_T0: float = 0.09357
    """Thrust coefficient at J = 0 [-]."""
    C_T1: float = -0.06044
    """Thrust coefficient slope in J [-]."""
    C_T2: float = -0.1079
    """Thrust coefficient curvature in J [-]."""
    C_Q0: float = 0.005230
    """Torque coefficient at J = 0 [-]."""
    C_Q1: float = 0.004970
    """Torque coefficient slope in J [-]."""
    C_Q2: float = -0.01664
    """Torque coefficient curvature in J [-]."""

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        for field in ("diameter", "KV", "KQ", "R_motor", "V_max", "C_T0"):
            value = getattr(self, field)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(
                    f"FixedWingParams.propulsion.{field} must be positive and finite, got {value}")
        for field in ("i0", "C_Q0"):
            value = getattr(self, field)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(
                    f"FixedWingParams.propulsion.{field} must be non-negative and finite, "
                    f"got {value}")
        for field in ("C_T1", "C_T2", "C_Q1", "C_Q2"):
            value = getattr(self, field)
            if not np.isfinite(value):
                raise ValueError(f"FixedWingParams.propulsion.{field} must be finite, got {value}")

    def propeller_speed(self, airspeed, throttle, rho: float):
        """Propeller speed Omega [rad/s] at ``airspeed`` [m/s], ``throttle`` [0..1] and
        air density ``rho`` [kg/m^3]; any Drake scalar type."""
        D = self.diameter
        two_pi = 2.0 * math.pi
        a = rho * D**5 * self.C_Q0 / two_pi**2
        b = rho * D**4 * self.C_Q1 * airspeed / two_pi + self.KQ * self.KV / self.R_motor
        c = (rho * D**3 * self.C_Q2 * airspeed * airspeed
             - self.KQ * self.V_max * throttle / self.R_motor + self.KQ * self.i0)
        # (-b + sqrt(b^2 - 4ac)) / (2a) written without cancellation (b > 0), valid for a = 0.
        return -2.0 * c / (b + ssqrt(b * b - 4.0 * a * c))

    def thrust_torque(self, airspeed, throttle, rho: float) -> tuple:
        """Thrust [N] and reaction torque on the airframe [N m] at ``airspeed`` [m/s],
        ``throttle`` [0..1] and air density ``rho`` [kg/m^3]; any Drake scalar type."""
        omega = self.propeller_speed(airspeed, throttle, rho)
        D = self.diameter
        n_d = omega * D / (2.0 * math.pi)  # revolutions per second times D [m/s]
        thrust = propeller_thrust(rho, n_d, airspeed, D, (self.C_T0, self.C_T1, self.C_T2))
        torque = propeller_torque(rho, n_d, airspeed, D, (self.C_Q0, self.C_Q1, self.C_Q2))
        return thrust, -torque


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
    propulsion: Propulsion | MotorPropeller = dataclasses.field(default_factory=Propulsion)
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


def _drag_polar(S: float, b: float, e: float, C_D_p: float, CL0: float,
                CL_alpha: float) -> dict[str, float]:
    # Beard & McLain's drag polar C_D = C_D_p + (CL0 + CL_alpha alpha)^2 / (pi e AR)
    # is exactly quadratic in alpha: expand it into CD_0 + CD_alpha a + CD_alpha2 a^2.
    k = 1.0 / (math.pi * e * b**2 / S)
    return {"CD_0": C_D_p + k * CL0**2, "CD_alpha": 2 * k * CL0 * CL_alpha,
            "CD_alpha2": k * CL_alpha**2}


def _aerosonde_derivatives(S: float, b: float, e: float, C_D_p: float, CL0: float,
                           CL_alpha: float) -> dict[str, float]:
    return {
        "CL_0": CL0, "CL_alpha": CL_alpha, "CL_q": 0.0, "CL_elevator": -0.36,
        **_drag_polar(S, b, e, C_D_p, CL0, CL_alpha), "CD_q": 0.0, "CD_elevator": 0.0,
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


def aerosonde_mavsim() -> FixedWingParams:
    """The Aerosonde of Beard & McLain's simulator ``mavsim_python`` (2nd-edition set).

    Source: repository randybeard/mavsim_public, file
    ``mavsim_python/parameters/aerosonde_parameters.py`` (mass, inertia, geometry,
    derivatives, motor and propeller), whose published trim and linear models
    (``mavsim_python/design_projects/model_coef.py``) this set reproduces.

    Differences from :func:`aerosonde` (the 2012 book's appendix E):

    * mass 11 kg (13.5), gravity 9.81 m/s^2 as in the simulator;
    * new longitudinal derivatives: C_L0 = 0.23, C_Lalpha = 5.61, C_Lq = 7.95,
      C_Ldelta_e = +0.13, C_m0 = 0.0135, C_malpha = -2.74, C_mq = -38.21,
      C_mdelta_e = -0.99, C_Ddelta_e = 0.0135; the drag polar
      ``C_D_p + (C_L0 + C_Lalpha alpha)^2 / (pi e AR)`` with C_D_p = 0 and e = 0.9
      (the file's C_D_0 = 0.043 and C_D_alpha = 0.03 are not used by that polar),
      written exactly as ``CD_0 + CD_alpha alpha + CD_alpha2 alpha^2``;
    * new lateral derivatives (C_lbeta = -0.13, C_nbeta = 0.073, C_lp = -0.51, ...);
      with these the spiral mode is unstable;
    * propulsion: :class:`MotorPropeller`, a 20 in propeller on a 145 rpm/V motor
      with a 12-cell battery, instead of the book's k_motor model.

    Same convention for the controls: positive elevator gives a nose-down moment,
    throttle in 0..1 scales the battery voltage. The simulator's sigmoid blending
    to a flat-plate lift past stall (M = 50, alpha0 = 0.47 rad) is not part of the
    linear-in-parameters model: it changes C_L by 4e-10 at the 25 m/s trim
    (alpha = 0.05 rad) and by less than 2e-7 below alpha = 0.15 rad.
    """
    S, b = 0.55, 2.8956
    CL0, CL_alpha = 0.23, 5.61
    derivatives = {
        "CL_0": CL0, "CL_alpha": CL_alpha, "CL_q": 7.95, "CL_elevator": 0.13,
        **_drag_polar(S, b, e=0.9, C_D_p=0.0, CL0=CL0, CL_alpha=CL_alpha),
        "CD_q": 0.0, "CD_elevator": 0.0135,
        "Cm_0": 0.0135, "Cm_alpha": -2.74, "Cm_q": -38.21, "Cm_elevator": -0.99,
        "CY_0": 0.0, "CY_beta": -0.98, "CY_p": 0.0, "CY_r": 0.0,
        "CY_aileron": 0.075, "CY_rudder": 0.19,
        "Cl_0": 0.0, "Cl_beta": -0.13, "Cl_p": -0.51, "Cl_r": 0.25,
        "Cl_aileron": 0.17, "Cl_rudder": 0.0024,
        "Cn_0": 0.0, "Cn_beta": 0.073, "Cn_p": 0.069, "Cn_r": -0.095,
        "Cn_aileron": -0.011, "Cn_rudder": -0.069,
    }
    kv = 60.0 / (2 * math.pi * 145.0)  # 145 rpm/V in V s/rad
    # Inertia, geometry and air density are the book's (aerosonde()).
    return dataclasses.replace(
        aerosonde(),
        name="aerosonde_mavsim",
        mass=11.0,
        gravity=9.81,
        derivatives=derivatives,
        propulsion=MotorPropeller(
            diameter=20 * 0.0254, KV=kv, KQ=kv, R_motor=0.042, i0=1.5, V_max=3.7 * 12,
            C_T0=0.09357, C_T1=-0.06044, C_T2=-0.1079,
            C_Q0=0.005230, C_Q1=0.004970, C_Q2=-0.01664,
        ),
    )


def unatrap() -> FixedWingParams:
    """UnATRaP of Vaiopoulos 2017: Table 8 geometry, Table 10 force derivatives.

    From the thesis: operating mass 12.6 kg, chord 0.34 m, span 2.72 m, wing area
    0.92 m^2, and the C_L, C_D, C_Y derivatives identified from flight 2 (Table 10,
    as printed, including the doubtful C_D0 = C_Dalpha = 0.1268 and the positive
    C_Ybeta; C_DTc multiplies the thrust coefficient T / (qbar S)).

    Assumed (the thesis does not give them):
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
    return {"aerosonde": aerosonde(), "aerosonde_mavsim": aerosonde_mavsim(),
            "unatrap": unatrap()}
