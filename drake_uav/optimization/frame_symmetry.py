"""Symmetries of a multirotor frame: rotations and reflections of the motor ring.

A rotation or reflection ``M = diag(T, 1)`` of the body x-y plane is a symmetry when
it maps every rotor onto a rotor, keeps the inertia (``M J M^T = J``) and maps each
rotor's spin onto the image rotor's spin times ``det T`` (a mirror reverses the sense
of rotation: spin, angular velocity and torque are pseudo-vectors,
``omega -> det(M) M omega``). The rigid body with its motors is then equivariant:
a trajectory with motor ``i`` at thrust ``f_i`` maps onto a trajectory with motor
``perm[i]`` at ``f_i``, so the analysis of one failure set serves every set in its
orbit (e.g. the six single failures of the alternating hexacopter are one case).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = ["FrameSymmetry", "frame_symmetries", "canonical_failure_set"]

_ANGLE_TOL = 1e-9
"""Angles [rad] and relative inertia entries closer than this are equal."""


@dataclasses.dataclass(frozen=True)
class FrameSymmetry:
    """One symmetry: motor ``i`` goes to motor ``permutation[i]``; ``plane`` is ``T`` (2x2)."""

    permutation: tuple[int, ...]
    plane: tuple[tuple[float, float], tuple[float, float]]

    @property
    def matrix(self) -> np.ndarray:
        """``T`` (2, 2), orthogonal."""
        return np.array(self.plane)

    @property
    def orientation(self) -> int:
        """``det T``: +1 for a rotation, -1 for a reflection."""
        return 1 if np.linalg.det(self.matrix) > 0 else -1

    def apply(self, failed: Iterable[int]) -> tuple[int, ...]:
        """Image of a set of motors, sorted."""
        return tuple(sorted(self.permutation[i] for i in failed))


def _same_angle(a: float, b: float) -> bool:
    return abs(math.remainder(a - b, 2.0 * math.pi)) < _ANGLE_TOL


def _is_right_angle_multiple(angle: float) -> bool:
    return abs(math.remainder(angle, 0.5 * math.pi)) < _ANGLE_TOL


def frame_symmetries(params: MultirotorParams, square_rates: bool = False
                     ) -> list[FrameSymmetry]:
    """Every rotation/reflection of the body plane that maps the frame onto itself.

    Parameters
    ----------
    params : MultirotorParams
        Arm angles, spins and inertia of the frame (one arm length for all rotors).
    square_rates : bool
        Keep only the symmetries that also map the square ``|p|, |q| <= c`` onto
        itself (rotations by multiples of 90 degrees, mirrors along the axes and the
        diagonals), for an analysis whose target is that square.

    Returns
    -------
    list of FrameSymmetry
        Starting with the identity.
    """
    angles = params.arm_angles
    spins = params.spin_directions
    J = params.inertia_matrix
    n = params.num_motors
    found: dict[tuple[int, ...], FrameSymmetry] = {}
    for j in range(n):
        for orientation in (1, -1):
            if orientation == 1:  # rotation by phi: a -> a + phi
                phi = angles[j] - angles[0]
                if square_rates and not _is_right_angle_multiple(phi):
                    continue
                image = [a + phi for a in angles]
                T = ((math.cos(phi), -math.sin(phi)), (math.sin(phi), math.cos(phi)))
            else:  # mirror across the line at angle c/2: a -> c - a
                c = angles[j] + angles[0]
                if square_rates and not _is_right_angle_multiple(c):
                    continue
                image = [c - a for a in angles]
                T = ((math.cos(c), math.sin(c)), (math.sin(c), -math.cos(c)))
            perm = []
            for i, a in enumerate(image):
                k = [m for m in range(n) if _same_angle(angles[m], a)]
                if len(k) != 1 or spins[k[0]] != orientation * spins[i]:
                    break
                perm.append(k[0])
            else:
                M = np.eye(3)
                M[:2, :2] = T
                if np.allclose(M @ J @ M.T, J, rtol=0.0, atol=_ANGLE_TOL * np.abs(J).max()):
                    found.setdefault(tuple(perm), FrameSymmetry(tuple(perm), T))
    identity = tuple(range(n))
    return [found.pop(identity)] + list(found.values())


def canonical_failure_set(symmetries: list[FrameSymmetry], failed: tuple[int, ...]
                          ) -> tuple[tuple[int, ...], FrameSymmetry]:
    """Smallest image of ``failed`` under the symmetries, and the symmetry that maps onto it.

    Parameters
    ----------
    symmetries : list of FrameSymmetry
        From :func:`frame_symmetries`.
    failed : tuple of int
        A validated, sorted failure set.

    Returns
    -------
    (tuple of int, FrameSymmetry)
        The representative of the orbit (lexicographically smallest sorted image) and
        a symmetry ``sigma`` with ``sigma.apply(failed)`` equal to it.
    """
    return min(((s.apply(failed), s) for s in symmetries), key=lambda item: item[0])
