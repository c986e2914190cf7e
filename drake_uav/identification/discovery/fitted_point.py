"""A force towards a fixed point that the data locate: the candidate points, the profile
of the joint fit over them and its local refinement.

The force ``F(t) = m u(t)``, ``u`` the unit vector from the aircraft's GPS position
``p(t)`` towards a NED point ``P`` (a tether's or a tow's anchor nobody surveyed), is linear
in ``m`` but not in ``P``. For a given ``P`` the joint fit over the force coefficients
(:mod:`~drake_uav.identification.discovery.vector_effects`) removes from their weighted,
bias-compensated training errors

    ``D(P) = (sum_k w_k t_k)^2 / sum_k w_k s_k``

(``t_k`` and ``s_k`` the compensated moments ``v' z`` and ``v' v`` of the force's column
``v`` on coefficient ``k`` per newton, with the coefficient's own columns eliminated;
``w_k`` its inverse residual variance): the profile of the fit over ``m``
(Frisch-Waugh-Lovell), the first pass of the joint test. ``P`` is the point of largest
``D`` over :func:`candidate_points`, refined by a simplex search (Nelder-Mead) on ``D``
from there (:class:`PointProfile`).

Under the null hypothesis (no such force) ``P`` is not identified: the largest ``D`` of
``G`` points is not one F-test's statistic. The effect is tested at the best candidate
point, its p-value multiplied by ``G`` (Bonferroni over the candidates: the chance that any
of them passes a level ``a / G`` is at most ``a``); the refined point is kept for the
estimate only, and its 3 coordinates count in the BIC.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import numpy as np

from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.segments import span_starts
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
from drake_uav.model.rotations import euler_to_rotmat

__all__ = ["NEAREST", "FARTHEST", "SPACING", "MAX_CANDIDATES", "KNOT_STEP", "PointFit",
           "PointProfile", "ProfileKernels", "candidate_points", "locate_point", "towards",
           "towards_gradient", "ned_to_body", "positions", "unit_vectors_towards"]

NEAREST = 50.0
"""[m]: the candidate points closest to the flight path lie this far from it."""
FARTHEST = 2.0
"""The farthest shell of candidate points lies this many times the path's extent from it;
beyond, the direction hardly changes over the flight (a force fixed in the NED frame)."""
SPACING = 1.0
"""Step of each shell's cubic lattice over the shell's inner distance from the path."""

MAX_CANDIDATES = 10000
"""The most candidate points searched (the Bonferroni factor)."""
KNOT_STEP = 10
"""Samples between two knots of :class:`PointProfile` (0.2 s at 50 Hz)."""

_PROFILE_ELEMENTS = 250_000
"""Points times knots of one evaluation of :class:`PointProfile` (its memory)."""
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))

_ATTITUDE = ("roll", "pitch", "yaw")
_POSITION = ("gps_pn", "gps_pe", "gps_pd")


def ned_to_body(samples: AeroSamples, v: np.ndarray) -> np.ndarray:
    """NED vectors in body axes at each sample's attitude.

    Parameters
    ----------
    samples : AeroSamples
        The samples (their ``roll``, ``pitch`` and ``yaw`` signals [rad]).
    v : numpy.ndarray of shape (..., N, 3)
        NED vectors, one per sample.

    Returns
    -------
    numpy.ndarray of shape (..., N, 3)
        The same vectors in body axes.
    """
    rotation = euler_to_rotmat(np.array([samples.signals[s] for s in _ATTITUDE]))
    return np.einsum("ijn,...ni->...nj", rotation, v)


def positions(samples: AeroSamples) -> np.ndarray:
    """The GPS positions of ``samples``.

    Parameters
    ----------
    samples : AeroSamples
        The samples (their GPS position signals).

    Returns
    -------
    numpy.ndarray of shape (N, 3)
        Positions [m, NED].
    """
    return np.column_stack([samples.signals[s] for s in _POSITION])


def unit_vectors_towards(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """NED components of the unit vectors from the positions ``path`` towards each point.

    Parameters
    ----------
    path : numpy.ndarray of shape (N, 3)
        Positions [m, NED].
    points : numpy.ndarray of shape (m, 3)
        Points [m, NED].

    Returns
    -------
    numpy.ndarray of shape (3, m, N)
        The unit vectors' components.
    """
    d = points.T[:, :, None] - path.T[:, None, :]
    return d / np.sqrt(np.maximum(np.sum(d * d, axis=0), 1e-18))


def _offsets(samples: AeroSamples, point) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (N, 3) NED from the GPS positions towards ``point`` and the distances
    (N,) [m]."""
    d = np.asarray(point, dtype=float) - positions(samples)
    r = np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    return d / r[:, None], r


def towards(samples: AeroSamples, point) -> np.ndarray:
    """Body-axis unit vectors towards the NED ``point``.

    Parameters
    ----------
    samples : AeroSamples
        The samples (GPS position and attitude).
    point : array_like of shape (3,)
        The point [m, NED].

    Returns
    -------
    numpy.ndarray of shape (N, 3)
        The unit vectors, body axes.
    """
    return ned_to_body(samples, _offsets(samples, point)[0])


def towards_gradient(samples: AeroSamples, point) -> np.ndarray:
    """Derivatives of :func:`towards` along each NED coordinate of ``point``.

    ``(I - u u') / r`` in body axes.

    Parameters
    ----------
    samples : AeroSamples
        The samples (GPS position and attitude).
    point : array_like of shape (3,)
        The point [m, NED].

    Returns
    -------
    numpy.ndarray of shape (N, 3, 3)
        [1/m]; the last axis is the NED coordinate of ``point``.
    """
    u, r = _offsets(samples, point)
    ned = (np.eye(3)[None] - u[:, :, None] * u[:, None, :]) / r[:, None, None]
    return np.stack([ned_to_body(samples, ned[:, :, j]) for j in range(3)], axis=-1)


def candidate_points(path: np.ndarray) -> np.ndarray:
    """The NED points around the flight ``path`` where a fixed point is searched.

    Shells of points between ``d`` and ``2 d`` from the path, ``d`` = :data:`NEAREST`,
    twice that, ... up to :data:`FARTHEST` times the path's extent (the last shell
    unbounded outside), each a cubic lattice of step :data:`SPACING` ``d`` over the path's
    box widened by ``2 d``. When they are more than :data:`MAX_CANDIDATES` (a long flight
    over a wide area), the innermost shells are left out until they are not. The direction
    to a point ``d`` from the path turns over the ``~2 d`` of the path nearest to it, so a
    step proportional to ``d`` resolves every shell alike.

    Parameters
    ----------
    path : numpy.ndarray of shape (N, 3)
        The flight's positions [m, NED].

    Returns
    -------
    numpy.ndarray of shape (G, 3)
        The candidate points [m, NED].
    """
    from scipy.spatial import cKDTree

    path = np.asarray(path, dtype=float)
    tree = cKDTree(path)
    low, high = path.min(axis=0), path.max(axis=0)
    extent = max(float(np.linalg.norm(high - low)), NEAREST)
    shells, d = [], NEAREST
    while True:
        last = d >= FARTHEST * extent
        step = SPACING * d
        axes = [np.arange(lo - 2.0 * d, hi + 2.0 * d + 0.5 * step, step)
                for lo, hi in zip(low, high, strict=True)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        distance = tree.query(grid)[0]
        shells.append(grid[(distance >= d) & (last | (distance < 2.0 * d))])
        if last:
            break
        d *= 2.0
    while len(shells) > 1 and sum(map(len, shells)) > MAX_CANDIDATES:
        shells.pop(0)
    return np.concatenate(shells)


@dataclasses.dataclass(frozen=True)
class PointFit:
    """Where the profile search put the point.

    Attributes
    ----------
    grid_point : (float, float, float)
        The best candidate point, NED [m]: the one the effect is tested at.
    point : (float, float, float)
        The refined point, NED [m]: the one the effect is estimated at.
    candidates : int
        Number of candidate points searched (the Bonferroni factor of the test).
    """

    grid_point: tuple[float, float, float]
    point: tuple[float, float, float]
    candidates: int


def locate_point(path: np.ndarray, profile: Callable[[np.ndarray], np.ndarray],
                 points: np.ndarray | None = None, chunk: int = 512) -> PointFit:
    """The point of a force towards a fixed point (module docstring).

    The largest ``profile`` over the candidate points, ``chunk`` at a time, refined by a
    simplex search from there.

    Parameters
    ----------
    path : numpy.ndarray of shape (N, 3)
        The flight's positions [m, NED].
    profile : callable
        ``profile(points (m, 3)) -> D (m,)``.
    points : numpy.ndarray of shape (G, 3), optional
        The candidate points (default :func:`candidate_points` of ``path``).
    chunk : int
        Points evaluated per call of ``profile``.

    Returns
    -------
    PointFit
        The best candidate and the refined point.
    """
    from scipy.optimize import minimize

    points = candidate_points(path) if points is None else points
    values = np.concatenate([profile(points[i:i + chunk])
                             for i in range(0, len(points), chunk)])
    best = int(np.argmax(values))
    start = points[best]
    nearest = float(np.min(np.linalg.norm(path - start, axis=1)))
    step = SPACING * NEAREST * 2.0 ** np.floor(np.log2(max(nearest, NEAREST) / NEAREST))
    scale = max(float(values[best]), 1e-300)
    refined = minimize(lambda x: -profile(x[None])[0] / scale, start, method="Nelder-Mead",
                       options={"initial_simplex": start + np.vstack([np.zeros(3),
                                                                      0.5 * step * np.eye(3)]),
                                "xatol": 0.01 * step, "fatol": 1e-4, "maxfev": 200})
    point = refined.x if -refined.fun >= 1.0 else start
    if np.min(np.linalg.norm(path - point, axis=1)) < 0.5 * NEAREST:
        point = start
    return PointFit(tuple(float(x) for x in start), tuple(float(x) for x in point),
                    len(points))


@dataclasses.dataclass(frozen=True)
class ProfileKernels:
    """One force coefficient's part of ``D(P)`` (:class:`PointProfile`).

    For the force's column ``v = sum_i a_i u_i``: ``v' X - E[dv' dX] = sum_i u_i' x_i``,
    ``v' z - E[dv' dz] = sum_i u_i' z_i`` and ``v' v - E[dv' dv] = sum_n u_n' V_n u_n``,
    the bias-compensated moments of the design ``[X | v]`` (Fuller 1987, eq. 2.2.4, as
    :class:`~drake_uav.identification.statistics.errors_in_variables.BlockMoments`
    computes them).

    Attributes
    ----------
    x : numpy.ndarray of shape (3, N, p)
        The kernels of ``v' X``.
    z : numpy.ndarray of shape (3, N)
        The kernels of ``v' z``.
    v : numpy.ndarray of shape (6, N)
        The entries xx, yy, zz, 2 xy, 2 xz, 2 yz of the symmetric ``V_n``.
    inverse : numpy.ndarray of shape (p, p)
        The design's own compensated normal matrix inverted.
    estimate : numpy.ndarray of shape (p,)
        The design's own estimate.
    weight : float
        The coefficient's weight in the joint fit [1/coefficient^2].
    """

    x: np.ndarray
    z: np.ndarray
    v: np.ndarray
    inverse: np.ndarray
    estimate: np.ndarray
    weight: float

    @classmethod
    def of(cls, a: np.ndarray, sensitivities: Mapping[str, np.ndarray], X: np.ndarray,
           z: np.ndarray, noise: PropagatedNoise, A: np.ndarray, b: np.ndarray,
           weight: float) -> ProfileKernels:
        """The kernels of one coefficient's design.

        Parameters
        ----------
        a : numpy.ndarray of shape (N, 3)
            The column factors: the change of the coefficient by a unit force along each NED
            axis.
        sensitivities : Mapping[str, numpy.ndarray]
            Noise source -> (N, 3) sensitivity of ``a``.
        X : numpy.ndarray of shape (N, p)
            The design's columns.
        z : numpy.ndarray of shape (N,)
            The measured coefficient.
        noise : PropagatedNoise
            The design's regressor noise.
        A : numpy.ndarray of shape (p, p)
            Its compensated normal matrix.
        b : numpy.ndarray of shape (p,)
            Its compensated right-hand side.
        weight : float
            The coefficient's weight in the joint fit.

        Returns
        -------
        ProfileKernels
            The kernels.
        """
        K_x = a.T[:, :, None] * X[None]
        k_z = a.T * z[None]
        K = a[:, :, None] * a[:, None, :]
        for source, da in sensitivities.items():
            variance = noise.variance[source]
            J_x, j_z = noise.regressors.get(source), noise.observation.get(source)
            if J_x is not None:
                K_x -= variance * da.T[:, :, None] * J_x[None]
            if j_z is not None:
                k_z -= variance * da.T * j_z[None]
            K -= variance * da[:, :, None] * da[:, None, :]
        scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
        inverse = np.linalg.pinv(A / np.outer(scale, scale)) / np.outer(scale, scale)
        return cls(K_x, k_z, np.stack([K[:, i, j] * (1.0 if i == j else 2.0)
                                       for i, j in _PAIRS]), inverse, inverse @ b, weight)


class PointProfile:
    """``D(P)`` of the module docstring over a flight path, against each round's designs.

    The force's column on coefficient ``k`` is ``v = sum_i a_i u_i``: ``a`` (N, 3) the
    change of ``k`` by a unit force along each NED axis, which depends on the air data,
    ``u`` the unit vector towards ``P``, which does not (GPS and attitude). So are the
    column's noise sensitivities, and the compensated moments of the design extended by
    ``v`` are linear and quadratic forms in ``u`` (:class:`ProfileKernels`). ``u`` turns
    slowly (at most the airspeed over the nearest candidate's distance, 0.5 rad/s): its
    components and their products are taken as straight lines between knots every
    :data:`KNOT_STEP` samples, so that the kernels are summed onto the knots once per round
    and each point costs a few products of the knots' length. The test itself is the
    exact one at the best candidate point. Calling the profile with points (m, 3) gives
    their ``D`` (m,) (:meth:`against` first).

    Parameters
    ----------
    path : numpy.ndarray of shape (N, 3)
        The flight's positions [m, NED].
    time : numpy.ndarray of shape (N,)
        Their times [s] (joined spans keep their gaps).
    """

    def __init__(self, path: np.ndarray, time: np.ndarray):
        self.path = np.asarray(path, dtype=float)
        self.candidates = candidate_points(self.path)
        n = len(time)
        starts = span_starts(time)[1:]
        knots = np.unique(np.concatenate([np.arange(0, n, KNOT_STEP), starts - 1, starts,
                                          [n - 1]]))
        self._before = np.clip(np.searchsorted(knots, np.arange(n), side="right"), 1,
                               len(knots) - 1) - 1
        a, b = knots[self._before], knots[self._before + 1]
        self._share = (time - time[a]) / np.maximum(time[b] - time[a], 1e-12)
        self.knots = self.path[knots]
        self._kernels: list[ProfileKernels] = []

    def _on_knots(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N, c) summed onto the knots (M, c), each sample shared between the
        two knots around it as a straight line between them would."""
        m = len(self.knots)
        return np.stack([np.bincount(self._before, (1.0 - self._share) * v, m)
                         + np.bincount(self._before + 1, self._share * v, m)
                         for v in values.T], axis=1)

    def against(self, kernels: Mapping[str, ProfileKernels]) -> PointProfile:
        """This profile against the round's force coefficients' ``kernels``.

        Parameters
        ----------
        kernels : Mapping[str, ProfileKernels]
            Coefficient -> its kernels.

        Returns
        -------
        PointProfile
            This profile, ready to evaluate.
        """
        self._kernels = []
        for k in kernels.values():
            n, p = k.x.shape[1:]
            x = self._on_knots(k.x.transpose(1, 0, 2).reshape(n, 3 * p))
            self._kernels.append(dataclasses.replace(
                k, x=x.reshape(-1, 3, p).transpose(1, 0, 2), z=self._on_knots(k.z.T).T,
                v=self._on_knots(k.v.T).T))
        return self

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """``D`` at each of ``points`` (m, 3) [m, NED]; 0 where the fit is not well posed."""
        u = unit_vectors_towards(self.knots, np.asarray(points, dtype=float))
        products = [u[i] * u[j] for i, j in _PAIRS]
        numerator = np.zeros(len(points))
        denominator = np.zeros(len(points))
        for k in self._kernels:
            A_vx = sum(u[i] @ k.x[i] for i in range(3))
            A_vv = sum(uu @ v for uu, v in zip(products, k.v, strict=True))
            numerator += k.weight * (sum(u[i] @ k.z[i] for i in range(3)) - A_vx @ k.estimate)
            denominator += k.weight * (A_vv - np.einsum("mp,pq,mq->m", A_vx, k.inverse, A_vx))
        return np.where(denominator > 0.0, numerator**2 / np.maximum(denominator, 1e-300),
                        0.0)

    def locate(self) -> PointFit:
        """:func:`locate_point` on this profile's candidates.

        Returns
        -------
        PointFit
            The best candidate and the refined point.
        """
        return locate_point(self.path, self, self.candidates,
                            chunk=max(1, _PROFILE_ELEMENTS // len(self.knots)))
