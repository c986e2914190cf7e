"""Multirotor parameters from frame geometry, and the catalog (quad X, quad +, hexa).

Frames follow the project convention: body FRD (x forward, y right, z down),
inertial NED, every rotor thrust along ``-z_b``. Motor ``i`` sits at
``r_i = l [cos a_i, sin a_i, 0]`` with the arm angle ``a_i`` measured in the
body x-y plane from ``+x_b`` towards ``+y_b`` (clockwise seen from above). A
rotor turning clockwise seen from above (``spin = +1``, angular velocity along
``+z_b``) drags the body the other way, so its yaw torque is ``-km f_i``.

The allocation matrix maps motor thrusts to ``[F, tau_x, tau_y, tau_z]``
(``F`` = total thrust along ``-z_b``) and is derived from ``tau_i = r_i x f_i``:

    column i = [1, -l sin a_i, l cos a_i, -spin_i km]

Argyropoulos 2020 (eq. 1.2-1.3) works in z-up frames. Rotating both of its frames by pi
about x maps its matrices onto these ones: the ``tau_y`` and ``tau_z`` rows change
sign, its arm azimuths ``psi_i`` (counter-clockwise from above) become
``a_i = -psi_i``, and its ``+k_m`` yaw entries are the clockwise rotors.

Argyropoulos 2020 gives no mass, inertia, arm length, ``km`` or ``f_max``; the
catalog values are assumptions for typical 450 mm (quad) and 550 mm (hexa)
frames (docs/multirotor.md).
"""

from __future__ import annotations

import dataclasses
import math
from functools import cached_property

import numpy as np
from scipy.optimize import lsq_linear

__all__ = [
    "MultirotorParams",
    "quadrotor_x",
    "quadrotor_plus",
    "hexacopter",
]


@dataclasses.dataclass(frozen=True)
class MultirotorParams:
    """Rigid-body, frame-geometry and motor parameters of a multirotor."""

    name: str
    mass: float
    """Mass [kg]."""
    inertia: tuple[float, float, float]
    """Principal moments ``(Jx, Jy, Jz)`` about body FRD axes [kg m^2]."""
    arm_length: float
    """Distance from the centre of gravity to each rotor axis, ``l`` [m]."""
    arm_angles: tuple[float, ...]
    """Azimuth of each arm from ``+x_b`` towards ``+y_b`` [rad], one per motor."""
    spin_directions: tuple[int, ...]
    """``+1`` for a rotor turning clockwise seen from above, ``-1`` counter-clockwise."""
    km: float
    """Rotor drag torque per unit thrust [m] (N m per N)."""
    f_max: float
    """Maximum thrust of one motor [N]; commands are saturated to ``[0, f_max]``."""
    inertia_products: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """``(Jxy, Jxz, Jyz)`` [kg m^2], with ``J = [[Jx, -Jxy, -Jxz], [-Jxy, Jy, -Jyz], ...]``."""
    motor_time_constant: float = 0.0
    """First-order motor lag [s]; 0 means the thrust follows the command instantly."""
    rotor_drag: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Linear drag coefficients on the body FRD velocity [N s/m]; zero = no rotor drag."""
    gravity: float = 9.80665
    """Gravitational acceleration [m/s^2]."""

    def __post_init__(self):
        object.__setattr__(self, "inertia", tuple(float(v) for v in self.inertia))
        object.__setattr__(self, "arm_angles", tuple(float(v) for v in self.arm_angles))
        object.__setattr__(self, "spin_directions", tuple(int(v) for v in self.spin_directions))
        object.__setattr__(
            self, "inertia_products", tuple(float(v) for v in self.inertia_products)
        )
        object.__setattr__(self, "rotor_drag", tuple(float(v) for v in self.rotor_drag))
        self.validate()

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        for field in ("mass", "arm_length", "f_max", "gravity"):
            value = getattr(self, field)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"MultirotorParams.{field} must be positive and finite, "
                                 f"got {value}")
        for field in ("km", "motor_time_constant"):
            value = getattr(self, field)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"MultirotorParams.{field} must be >= 0 and finite, got {value}")
        for field in ("inertia", "inertia_products", "rotor_drag"):
            values = getattr(self, field)
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise ValueError(f"MultirotorParams.{field} must be 3 finite numbers, "
                                 f"got {values}")
        if any(d < 0 for d in self.rotor_drag):
            raise ValueError(f"MultirotorParams.rotor_drag must be >= 0, got {self.rotor_drag}")
        J1, J2, J3 = np.linalg.eigvalsh(self.inertia_matrix)
        if J1 <= 0:
            raise ValueError(f"MultirotorParams.inertia is not positive definite: "
                             f"{self.inertia_matrix.tolist()}")
        if J1 + J2 < J3 * (1.0 - 1e-9):
            raise ValueError("MultirotorParams.inertia violates the triangle inequality "
                             f"(principal moments {J1:.4g}, {J2:.4g}, {J3:.4g})")
        n = len(self.arm_angles)
        if n < 1 or not all(math.isfinite(a) for a in self.arm_angles):
            raise ValueError(f"MultirotorParams.arm_angles must be finite, one per motor, "
                             f"got {self.arm_angles}")
        if len(self.spin_directions) != n:
            raise ValueError(f"MultirotorParams.spin_directions needs {n} entries "
                             f"(one per arm), got {len(self.spin_directions)}")
        if any(s not in (-1, 1) for s in self.spin_directions):
            raise ValueError(f"MultirotorParams.spin_directions entries must be +1 or -1, "
                             f"got {self.spin_directions}")

    @property
    def num_motors(self) -> int:
        """Number of motors ``n``."""
        return len(self.arm_angles)

    @property
    def weight(self) -> float:
        """``m g`` [N]."""
        return self.mass * self.gravity

    @cached_property
    def inertia_matrix(self) -> np.ndarray:
        """Inertia matrix ``J`` about the centre of gravity in body FRD axes [kg m^2]."""
        Jx, Jy, Jz = self.inertia
        Jxy, Jxz, Jyz = self.inertia_products
        return np.array([[Jx, -Jxy, -Jxz], [-Jxy, Jy, -Jyz], [-Jxz, -Jyz, Jz]])

    @cached_property
    def inertia_inverse(self) -> np.ndarray:
        """``J^-1`` [1/(kg m^2)]."""
        return np.linalg.inv(self.inertia_matrix)

    @cached_property
    def motor_positions(self) -> np.ndarray:
        """Rotor positions ``r_i`` (n, 3) in body FRD [m]."""
        a = np.asarray(self.arm_angles)
        l = self.arm_length
        return np.column_stack([l * np.cos(a), l * np.sin(a), np.zeros_like(a)])

    @cached_property
    def allocation_matrix(self) -> np.ndarray:
        """Allocation ``A`` (4, n): ``[F, tau_x, tau_y, tau_z] = A f`` with ``F`` along ``-z_b``.

        Each column is ``[1, (r_i x (-e_z))_x, (r_i x (-e_z))_y, -spin_i km]``.
        """
        r = self.motor_positions
        thrust_dir = np.array([0.0, 0.0, -1.0])
        torques = np.cross(r, thrust_dir)
        yaw = -self.km * np.asarray(self.spin_directions, dtype=float)
        A = np.vstack([np.ones(self.num_motors), torques[:, 0], torques[:, 1], yaw])
        A.setflags(write=False)
        return A

    def effective_allocation(self, health=None) -> np.ndarray:
        """``A diag(h)``: column ``i`` scaled by the health ``h_i`` in [0, 1] (0 = failed)."""
        if health is None:
            return self.allocation_matrix
        h = np.asarray(health, dtype=float)
        if h.shape != (self.num_motors,) or np.any((h < 0) | (h > 1)) or not np.all(
            np.isfinite(h)
        ):
            raise ValueError(f"health must be {self.num_motors} values in [0, 1], got {health}")
        return self.allocation_matrix * h

    def thrusts_for_wrench(self, wrench, health=None, yaw_weight: float = 1.0) -> np.ndarray:
        """Motor thrusts [N] producing ``wrench = [F, tau_x, tau_y, tau_z]``.

        Minimum-norm solution of ``A diag(h) f = wrench``; failed motors get 0.
        When it leaves ``[0, f_max]``, the bounded least-squares solution is
        returned instead (it then matches the wrench only as closely as the
        limits allow), with the yaw-torque row weighted by ``yaw_weight`` (below 1:
        the yaw torque gives way before the thrust and the roll/pitch torques, as
        after a motor failure, where the yaw is left free). ``wrench`` may be (4,)
        or (N, 4).
        """
        A = self.effective_allocation(health)
        active = np.any(A != 0.0, axis=0)
        A = A[:, active]
        w = np.asarray(wrench, dtype=float)
        targets = np.atleast_2d(w)
        f = targets @ np.linalg.pinv(A).T
        outside = np.any((f < -1e-9) | (f > self.f_max + 1e-9), axis=1)
        rows = np.array([1.0, 1.0, 1.0, yaw_weight])[:, None]
        for k in np.flatnonzero(outside):
            f[k] = lsq_linear(rows * A, rows[:, 0] * targets[k], bounds=(0.0, self.f_max)).x
        thrusts = np.zeros((len(targets), self.num_motors))
        thrusts[:, active] = np.clip(f, 0.0, self.f_max)
        return thrusts if w.ndim == 2 else thrusts[0]


def _from_seed_azimuths(name: str, seed_azimuths_deg, seed_yaw_signs, **values):
    """Builds params from the z-up arm azimuths [deg] (counter-clockwise seen from above) and
    yaw-entry signs of Argyropoulos 2020, eq. 1.2-1.3."""
    return MultirotorParams(
        name=name,
        arm_angles=tuple(-math.radians(a) for a in seed_azimuths_deg),
        spin_directions=tuple(seed_yaw_signs),
        **values,
    )


_QUAD_450 = dict(mass=1.2, inertia=(0.011, 0.011, 0.021), arm_length=0.225, km=0.016, f_max=6.5)
"""Assumed 450 mm quadrotor: mass [kg], inertia [kg m^2], arm [m], km [m], f_max [N]."""


def quadrotor_plus(**overrides) -> MultirotorParams:
    """Quadrotor in "+" layout, motors numbered as in Argyropoulos 2020, eq. 1.2.

    Motor 0 front, 1 left, 2 back, 3 right; 0 and 2 turn clockwise seen from
    above. Assumed 450 mm frame: m = 1.2 kg, l = 0.225 m, J = diag(0.011, 0.011,
    0.021) kg m^2, km = 0.016 m, f_max = 6.5 N (thrust/weight 2.2).
    """
    values = {**_QUAD_450, **overrides}
    return _from_seed_azimuths("quadrotor_plus", [0, 90, 180, 270], [1, -1, 1, -1], **values)


def quadrotor_x(**overrides) -> MultirotorParams:
    """Quadrotor in "X" layout: the "+" frame turned by 45 degrees, same numbering.

    Motor 0 front-left, 1 back-left, 2 back-right, 3 front-right (counter-
    clockwise seen from above); 0 and 2 turn clockwise. Same assumed mass,
    inertia, ``km`` and ``f_max`` as :func:`quadrotor_plus`.
    """
    values = {**_QUAD_450, **overrides}
    return _from_seed_azimuths("quadrotor_x", [45, 135, 225, 315], [1, -1, 1, -1], **values)


def hexacopter(**overrides) -> MultirotorParams:
    """Hexarotor of Argyropoulos 2020, eq. 1.3: arms every 60 degrees starting at 30 degrees.

    Motor 0 front-left, then counter-clockwise seen from above (1 left, 2 back-
    left, 3 back-right, 4 right, 5 front-right); even motors turn clockwise.
    Assumed 550 mm frame: m = 2.0 kg, l = 0.275 m, J = diag(0.022, 0.022, 0.040)
    kg m^2, km = 0.016 m, f_max = 7.0 N (thrust/weight 2.1).
    """
    values = {**dict(mass=2.0, inertia=(0.022, 0.022, 0.040), arm_length=0.275, km=0.016,
                     f_max=7.0), **overrides}
    return _from_seed_azimuths(
        "hexacopter", [30, 90, 150, 210, 270, 330], [1, -1, 1, -1, 1, -1], **values
    )
