"""Backward reachable tubes to near-hover attitude after motor failures (Argyropoulos 2020, 5.2).

The tube ``R(T)`` holds the states from which the vehicle, with its healthy motors, can
bring body z within ``theta_th`` of the vertical and the roll/pitch rates within
``omega_th`` at some time in ``[0, T]`` (eq. 5.2). It is the zero sub-level set of
``V(x, 0)``, the viscosity solution of the HJB equation with freezing (eq. 5.15)::

    dV/dt + min{0, min_f grad V . x_dot(x, f, r)} = 0,     V(x, T) = l(x)

solved on a grid with ``hj_reachability`` (JAX; Hamiltonian post-processor
``backwards_reachable_tube``). The state is the yaw-free attitude subsystem of
:mod:`drake_uav.model.tilt`: tilt coordinates ``s`` (2) and roll/pitch rates
``p, q``; the yaw rate ``r`` enters as a bounded disturbance that plays against
recovery, its band covering every yaw rate reachable within the horizon from
``|r(0)| <= yaw_rate_limit`` (docs/faults.md, "Reachable tubes", explains the
choice). Motor thrusts ``f`` in ``[0, f_max]`` with ``f_i = 0`` for failed motors act
through the allocation's torque rows.

The value function is cached on disk per failure set up to the frame's symmetry and
queried at run time by multilinear interpolation in numpy: loading a cached tube and
querying it never imports JAX.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from drake_uav.model.multirotor import (
    BODY_RATES,
    QUATERNION,
    STATE_SIZE,
    body_rate_derivative,
)
from drake_uav.model.tilt import down_in_body, tilt_coordinates, tilt_dynamics
from drake_uav.optimization.allocation import canonical_failed_motors
from drake_uav.optimization.frame_symmetry import (
    FrameSymmetry,
    canonical_failure_set,
    frame_symmetries,
)
from drake_uav.optimization.grid_interpolation import RegularGridValues
from drake_uav.vehicles.multirotor import MultirotorParams

__all__ = [
    "RecoveryTube",
    "TubeSettings",
    "backward_reachable_tube",
    "default_cache_dir",
    "recovery_tube",
    "solve_value_function",
    "target_value",
    "yaw_acceleration_bound",
    "yaw_rate_band",
]

CACHE_FORMAT = 1
"""Bumped whenever the computation changes, so older cache files are not reused."""

_ACCURACIES = ("low", "medium", "high", "very_high")
_RATE_TARGETS = ("disc", "square")


@dataclasses.dataclass(frozen=True)
class TubeSettings:
    """Target set, horizon, grid and solver accuracy of a recovery tube.

    The defaults are justified in docs/faults.md ("Reachable tubes"); :meth:`coarse`
    gives a grid that solves in seconds, for tests and quick looks.
    """

    theta_th: float = math.radians(20.0)
    """Half-angle [rad] of the cone around the vertical that body z must reach."""
    omega_th: float = 1.5
    """Roll/pitch rate bound [rad/s] of the target set."""
    rate_target: str = "disc"
    """``"disc"``: ``sqrt(p^2 + q^2) <= omega_th`` (frame-independent, default);
    ``"square"``: ``|p|, |q| <= omega_th`` (as printed in Argyropoulos 2020, sec. 5.2)."""
    horizon: float = 0.3
    """``T`` [s]: the target must be reached within this time."""
    tilt_limit: float = math.radians(90.0)
    """Tilt [rad] at the middle of the grid's edges (``tan(tilt_limit / 2)`` is the
    half-width in tilt coordinates; the corners reach further)."""
    rate_limit: float = 8.0
    """Half-width of the grid in ``p`` and ``q`` [rad/s]."""
    yaw_rate_limit: float = 2.0
    """Largest ``|r|`` [rad/s] at a query; the disturbance band adds what the yaw
    acceleration can add within the horizon. Faster-spinning states count as outside."""
    tilt_points: int = 25
    """Grid nodes along each tilt coordinate (odd, so that level is a node)."""
    rate_points: int = 25
    """Grid nodes along ``p`` and ``q`` (odd)."""
    accuracy: str = "medium"
    """``hj_reachability`` scheme: ``"low"`` (first order), ``"medium"`` (ENO2, RK2),
    ``"high"`` (WENO3, RK3), ``"very_high"`` (WENO5, RK3)."""

    def __post_init__(self):
        self.validate()

    @classmethod
    def coarse(cls, **overrides) -> TubeSettings:
        """A 13^4 grid (seconds to solve) with the default target and horizon."""
        return cls(**{**dict(tilt_points=13, rate_points=13), **overrides})

    @property
    def tilt_half_width(self) -> float:
        """Half-width of the grid in tilt coordinates, ``tan(tilt_limit / 2)``."""
        return math.tan(0.5 * self.tilt_limit)

    @property
    def lower(self) -> np.ndarray:
        """Grid's lower corner ``(s_x, s_y, p, q)``."""
        w, r = self.tilt_half_width, self.rate_limit
        return np.array([-w, -w, -r, -r])

    @property
    def upper(self) -> np.ndarray:
        """Grid's upper corner ``(s_x, s_y, p, q)``."""
        return -self.lower

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """Grid nodes per dimension."""
        return (self.tilt_points, self.tilt_points, self.rate_points, self.rate_points)

    def validate(self) -> None:
        """Raises ``ValueError`` naming the first invalid field."""
        for field in ("theta_th", "omega_th", "horizon", "tilt_limit", "rate_limit",
                      "yaw_rate_limit"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"TubeSettings.{field} must be positive and finite, "
                                 f"got {value!r}")
        if not self.tilt_limit < math.pi:
            raise ValueError(f"TubeSettings.tilt_limit must be below pi (the inverted "
                             f"attitude is outside the chart), got {self.tilt_limit}")
        if not self.theta_th < self.tilt_limit:
            raise ValueError(f"TubeSettings.theta_th ({self.theta_th}) must be below "
                             f"tilt_limit ({self.tilt_limit})")
        if not self.omega_th < self.rate_limit:
            raise ValueError(f"TubeSettings.omega_th ({self.omega_th}) must be below "
                             f"rate_limit ({self.rate_limit})")
        for field in ("tilt_points", "rate_points"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, int) or value < 5 \
                    or value % 2 == 0:
                raise ValueError(f"TubeSettings.{field} must be an odd integer >= 5, "
                                 f"got {value!r}")
        if self.accuracy not in _ACCURACIES:
            raise ValueError(f"TubeSettings.accuracy must be one of {_ACCURACIES}, "
                             f"got {self.accuracy!r}")
        if self.rate_target not in _RATE_TARGETS:
            raise ValueError(f"TubeSettings.rate_target must be one of {_RATE_TARGETS}, "
                             f"got {self.rate_target!r}")
        tilt_cell = 2.0 * self.tilt_half_width / (self.tilt_points - 1)
        if math.tan(0.5 * self.theta_th) < tilt_cell:
            raise ValueError(f"TubeSettings.tilt_points: the target cone (theta_th "
                             f"{math.degrees(self.theta_th):.3g} deg) is narrower than one grid "
                             f"cell; use more points or a smaller tilt_limit")
        if self.omega_th < 2.0 * self.rate_limit / (self.rate_points - 1):
            raise ValueError("TubeSettings.rate_points: the target rates (omega_th) span less "
                             "than one grid cell; use more points or a smaller rate_limit")


def target_value(s, rates, settings: TubeSettings):
    """``l(x)``: negative inside the near-hover target set, positive outside (dimensionless).

    ``max(tilt / theta_th, rate / omega_th) - 1`` with ``tilt = 2 atan |s|`` and ``rate``
    the disc or square norm of ``(p, q)``; each entry may be an array. The bounds printed
    as ``Omega_x <= Omega_th`` (Argyropoulos 2020, sec. 5.2) are read as
    ``|Omega_x| <= Omega_th``.
    """
    tilt = 2.0 * np.arctan(np.hypot(s[0], s[1]))
    if settings.rate_target == "disc":
        rate = np.hypot(rates[0], rates[1])
    else:
        rate = np.maximum(np.abs(rates[0]), np.abs(rates[1]))
    return np.maximum(tilt / settings.theta_th, rate / settings.omega_th) - 1.0


def _torque_columns(params: MultirotorParams, failed: tuple[int, ...]) -> np.ndarray:
    """Torque rows of ``A diag(h)`` (3, n), failed motors' columns zero [N m per N]."""
    health = np.ones(params.num_motors)
    health[list(failed)] = 0.0
    return params.effective_allocation(health)[1:4]


def yaw_acceleration_bound(params: MultirotorParams, failed: tuple[int, ...],
                           settings: TubeSettings) -> float:
    """Largest ``|r_dot|`` [rad/s^2] on the grid for any admissible thrusts.

    Yaw torque of the healthy motors of one spin sense at full thrust, plus the
    gyroscopic term ``(J_x - J_y) p q / J_z`` at the grid's largest rates.
    """
    yaw = _torque_columns(params, failed)[2]
    torque = params.f_max * max(yaw[yaw > 0].sum(), -yaw[yaw < 0].sum())
    Jx, Jy, Jz = params.inertia
    return (torque + abs(Jx - Jy) * settings.rate_limit ** 2) / Jz


def yaw_rate_band(params: MultirotorParams, failed: tuple[int, ...],
                  settings: TubeSettings) -> float:
    """Bound [rad/s] of ``|r|`` over the horizon from ``|r(0)| <= yaw_rate_limit``.

    ``yaw_rate_limit + T max|r_dot|`` (:func:`yaw_acceleration_bound`): the disturbance
    band of the tube, as tight as the failure set allows (the band's width is what makes
    the tube conservative).
    """
    return settings.yaw_rate_limit + settings.horizon * yaw_acceleration_bound(
        params, failed, settings)


def _check_principal_inertia(params: MultirotorParams) -> None:
    if params.inertia_products != (0.0, 0.0, 0.0):
        raise ValueError(f"MultirotorParams.inertia_products must be zero for a recovery "
                         f"tube (the yaw rate then enters the tilt dynamics affinely), got "
                         f"{params.inertia_products}")


def solve_value_function(params: MultirotorParams, failed_motors: Iterable[int],
                         settings: TubeSettings | None = None) -> np.ndarray:
    """``V(x, 0)`` on the settings' grid for this failure set, computed with hj_reachability.

    No caching and no symmetry: :func:`recovery_tube` is the entry point; this is the
    solver it calls (imports JAX).

    Parameters
    ----------
    params : MultirotorParams
        The vehicle (principal inertia).
    failed_motors : iterable of int
        0-based indices of totally failed motors.
    settings : TubeSettings, optional
        Defaults to ``TubeSettings()``.

    Returns
    -------
    numpy.ndarray
        Values ``(tilt_points, tilt_points, rate_points, rate_points)`` over
        ``(s_x, s_y, p, q)``, float64; ``<= 0`` inside the tube.

    Raises
    ------
    ValueError
        Invalid ``failed_motors`` or non-zero products of inertia.
    """
    import hj_reachability as hj
    import jax.numpy as jnp

    settings = settings or TubeSettings()
    failed = canonical_failed_motors(params, failed_motors)
    _check_principal_inertia(params)
    torque = _torque_columns(params, failed)
    n = params.num_motors
    upper = np.full(n, params.f_max)
    upper[list(failed)] = 0.0
    band = yaw_rate_band(params, failed, settings)

    def derivative(state, torque_value, yaw_rate):
        s, rates = (state[0], state[1]), (state[2], state[3], yaw_rate)
        d = tilt_dynamics(s, rates, torque_value, params)
        return jnp.stack([d[0], d[1], d[2], d[3]])

    zero_torque = (0.0, 0.0, 0.0)
    # d(p, q)/df: Euler's equation is affine in the torque, so column j is its response to
    # motor j's torque column (zero for failed motors).
    control_jacobian = np.zeros((4, n))
    for j in range(n):
        control_jacobian[2:, j] = body_rate_derivative((0.0, 0.0, 0.0), torque[:, j],
                                                       params)[:2]
    control_jacobian = jnp.asarray(control_jacobian)
    thrust_middle, thrust_spread = jnp.asarray(upper / 2.0), jnp.asarray(upper / 2.0)

    class _AttitudeRecovery(hj.ControlAndDisturbanceAffineDynamics):
        """Tilt and roll/pitch rates; thrusts minimise, the yaw rate maximises the value."""

        def open_loop_dynamics(self, state, time):
            return derivative(state, zero_torque, 0.0)

        def control_jacobian(self, state, time):
            return control_jacobian

        def disturbance_jacobian(self, state, time):
            # Affine in r with principal inertia: the slope is the difference at r = 1.
            return (derivative(state, zero_torque, 1.0)
                    - derivative(state, zero_torque, 0.0))[:, None]

        def partial_max_magnitudes(self, state, time, value, grad_value_box):
            # |x_dot_i| bound about the middle of the thrust box: the library's bound takes
            # |G| f_max around zero thrust, twice the spread of [0, f_max]; the
            # Lax-Friedrichs dissipation (and the time step) follow this bound.
            middle = self.open_loop_dynamics(state, time) + control_jacobian @ thrust_middle
            return (jnp.abs(middle) + jnp.abs(control_jacobian) @ thrust_spread
                    + jnp.abs(self.disturbance_jacobian(state, time)[:, 0])
                    * band)

    dynamics = _AttitudeRecovery(
        control_mode="min", disturbance_mode="max",
        control_space=hj.sets.Box(jnp.zeros(n), jnp.asarray(upper)),
        disturbance_space=hj.sets.Box(jnp.array([-band]), jnp.array([band])))
    grid = hj.Grid.from_lattice_parameters_and_boundary_conditions(
        hj.sets.Box(jnp.asarray(settings.lower), jnp.asarray(settings.upper)), settings.shape)
    states = grid.states
    target = jnp.asarray(target_value((states[..., 0], states[..., 1]),
                                      (states[..., 2], states[..., 3]), settings))
    return backward_reachable_tube(dynamics, grid, target, settings.horizon, settings.accuracy)


def backward_reachable_tube(dynamics, grid, target, horizon: float, accuracy: str
                            ) -> np.ndarray:
    """``V(x, 0)`` of the HJB equation with freezing (eq. 5.15) for ``V(x, T) = target``.

    The set-up shared by the recovery tubes and their validation on the double
    integrator (tests/test_recovery_tube.py): ``hj_reachability``'s solver from
    ``t = 0`` back to ``-horizon`` with the Hamiltonian post-processor
    ``backwards_reachable_tube`` (``min{0, H}``) at the given accuracy.

    Parameters
    ----------
    dynamics : hj_reachability.Dynamics
        Control minimises, disturbance maximises the value.
    grid : hj_reachability.Grid
    target : array
        ``l(x)`` on the grid, ``<= 0`` on the target set.
    horizon : float
        ``T`` [s].
    accuracy : str
        One of ``"low"``, ``"medium"``, ``"high"``, ``"very_high"``.

    Returns
    -------
    numpy.ndarray
        ``V(x, 0)`` on the grid; ``<= 0`` inside the tube.
    """
    import hj_reachability as hj

    solver_settings = hj.SolverSettings.with_accuracy(
        accuracy, hamiltonian_postprocessor=hj.solver.backwards_reachable_tube)
    value = hj.step(solver_settings, dynamics, grid, 0.0, target, -horizon, progress_bar=False)
    return np.asarray(value, dtype=float)


@dataclasses.dataclass(frozen=True, eq=False)
class RecoveryTube:
    """A recovery tube: ``V(x, 0)`` of one failure set, queried on full 13-states.

    Built by :func:`recovery_tube`. The stored values belong to the *canonical*
    failure set of the orbit; ``symmetry`` maps a query state of the requested set
    onto it (tilt and rates rotated or mirrored, the yaw rate's sign flipped by a
    mirror).
    """

    params: MultirotorParams
    failed_motors: tuple[int, ...]
    """The failure set asked for (sorted)."""
    canonical_failed_motors: tuple[int, ...]
    """The set whose value function is stored (same orbit under the frame's symmetry)."""
    symmetry: FrameSymmetry
    settings: TubeSettings
    values: RegularGridValues
    """``V(x, 0)`` on the grid ``(s_x, s_y, p, q)`` of the canonical set."""
    yaw_rate_band: float
    """Bound [rad/s] of the yaw-rate disturbance the tube was solved with."""

    @property
    def yaw_rate_limit(self) -> float:
        """``|r|`` [rad/s] up to which a query is answered from the grid."""
        return self.settings.yaw_rate_limit

    def reduced_state(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reduced coordinates of states (N, 13) in the canonical set's frame.

        Returns ``(s_x, s_y, p, q)`` (N, 4), ``|r|`` (N,) and a mask (N,) of inverted
        attitudes (outside the tilt chart; their coordinates are set to zero).
        """
        gx, gy, gz = down_in_body(state[:, QUATERNION].T)
        inverted = gz <= -1.0 + 1e-12
        sx, sy = tilt_coordinates((gx, gy, np.where(inverted, 0.0, gz)))
        s = np.where(inverted[:, None], 0.0, np.column_stack([sx, sy]))
        rates = state[:, BODY_RATES]
        T = self.symmetry.matrix
        reduced = np.column_stack([s @ T.T, self.symmetry.orientation * rates[:, :2] @ T.T])
        return reduced, np.abs(rates[:, 2]), inverted

    def value(self, state: np.ndarray) -> np.ndarray | float:
        """``V(x, 0)`` of a 13-state (float) or of a batch (N, 13) (array (N,)); ``<= 0`` inside.

        States beyond the grid, spinning faster than :attr:`yaw_rate_limit` or inverted
        are outside: their value is ``max(V, 0)`` at the nearest grid point plus the
        excess (in grid cells, or relative to the yaw-rate band), or ``inf`` if inverted.

        Raises
        ------
        ValueError
            ``state`` is not (13,) or (N, 13), or holds non-finite entries.
        """
        x = np.asarray(state, dtype=float)
        if x.shape[-1:] != (STATE_SIZE,) or x.ndim not in (1, 2):
            raise ValueError(f"state must be ({STATE_SIZE},) or (N, {STATE_SIZE}), got "
                             f"{x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError("state holds non-finite entries")
        if x.ndim == 1:
            return self._value_of_one(x)
        reduced, yaw_rate, inverted = self.reduced_state(x)
        v = self.values(reduced)
        # Round-off of a state on the grid's edge is not "beyond" it.
        beyond = np.maximum(self.values.outside_distance(reduced) - 1e-9, 0.0)
        excess = beyond + np.maximum(yaw_rate - self.yaw_rate_limit, 0.0) \
            / self.yaw_rate_band
        v = np.where(excess > 0.0, np.maximum(v, 0.0) + excess, v)
        v[inverted] = np.inf
        return v

    def _value_of_one(self, x: np.ndarray) -> float:
        """:meth:`value` of one state with float arithmetic (a few microseconds)."""
        down = down_in_body(x[QUATERNION].tolist())
        if down[2] <= -1.0 + 1e-12:
            return math.inf
        sx, sy = tilt_coordinates(down)
        p, q, r = x[BODY_RATES].tolist()
        (a, b), (c, d) = self.symmetry.plane
        o = self.symmetry.orientation
        v, beyond = self.values.at((a * sx + b * sy, c * sx + d * sy,
                                    o * (a * p + b * q), o * (c * p + d * q)))
        beyond = max(beyond - 1e-9, 0.0)
        excess = beyond + max(abs(r) - self.yaw_rate_limit, 0.0) / self.yaw_rate_band
        return max(v, 0.0) + excess if excess > 0.0 else v

    def contains(self, state: np.ndarray) -> bool | np.ndarray:
        """Whether a 13-state (bool) or each of a batch (N, 13) (array) lies in the tube."""
        v = self.value(state)
        return bool(v <= 0.0) if np.ndim(v) == 0 else v <= 0.0


def default_cache_dir() -> Path:
    """``$DRAKE_UAV_CACHE/tubes`` if set, else ``$XDG_CACHE_HOME`` (or ``~/.cache``)
    ``/drake_uav/tubes``."""
    root = os.environ.get("DRAKE_UAV_CACHE")
    if root:
        return Path(root) / "tubes"
    xdg = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(xdg) / "drake_uav" / "tubes"


def _cache_key(params: MultirotorParams, canonical: tuple[int, ...],
               settings: TubeSettings) -> str:
    """Content hash of everything the value function depends on (not the vehicle's name)."""
    vehicle = dataclasses.asdict(params)
    del vehicle["name"]
    content = json.dumps({"format": CACHE_FORMAT, "vehicle": vehicle,
                          "failed_motors": list(canonical),
                          "settings": dataclasses.asdict(settings)},
                         sort_keys=True)
    return hashlib.sha256(content.encode()).hexdigest()


def _load(path: Path, key: str) -> np.ndarray | None:
    """Cached values, or None if missing or written for another key (hash collision or
    a damaged file)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            return np.array(data["values"], dtype=float)
    except (OSError, KeyError, ValueError):
        return None


def _store(path: Path, key: str, values: np.ndarray) -> None:
    """Writes atomically (temporary file then rename), so concurrent readers see
    either nothing or the whole file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz.tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, key=np.array(key), values=values)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def recovery_tube(params: MultirotorParams, failed_motors: Iterable[int],
                  settings: TubeSettings | None = None,
                  cache_dir: str | os.PathLike | None = None) -> RecoveryTube:
    """The backward reachable tube to near-hover attitude for one failure set.

    Solved once per orbit of failure sets under the frame's symmetry
    (:func:`~drake_uav.optimization.frame_symmetry.frame_symmetries`) and cached on disk
    under a content hash of the vehicle's parameters, the canonical failure set and the
    settings; a cached tube loads without JAX.

    Parameters
    ----------
    params : MultirotorParams
        The vehicle (principal inertia).
    failed_motors : iterable of int
        0-based indices of totally failed motors (empty: the healthy vehicle).
    settings : TubeSettings, optional
        Target, horizon and grid; defaults to ``TubeSettings()``.
    cache_dir : path, optional
        Folder of the cache; defaults to :func:`default_cache_dir`.

    Returns
    -------
    RecoveryTube

    Raises
    ------
    ValueError
        Invalid ``failed_motors`` or non-zero products of inertia.
    """
    settings = settings or TubeSettings()
    failed = canonical_failed_motors(params, failed_motors)
    _check_principal_inertia(params)
    symmetries = frame_symmetries(params, square_rates=settings.rate_target == "square")
    canonical, symmetry = canonical_failure_set(symmetries, failed)
    key = _cache_key(params, canonical, settings)
    path = Path(cache_dir if cache_dir is not None else default_cache_dir()) / f"{key[:32]}.npz"
    values = _load(path, key)
    if values is None:
        values = solve_value_function(params, canonical, settings)
        _store(path, key, values)
    return RecoveryTube(params=params, failed_motors=failed, canonical_failed_motors=canonical,
                        symmetry=symmetry, settings=settings,
                        values=RegularGridValues(values, settings.lower, settings.upper),
                        yaw_rate_band=yaw_rate_band(params, failed, settings))
