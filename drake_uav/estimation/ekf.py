"""Continuous-discrete extended Kalman filter core (Vaiopoulos 2017, sec. 5.4.2, Ortiz & Gutierrez
2009, sec. 4).

A filter is built from an :class:`EkfModel`: scalar-generic functions

    x_dot = f(x, u, w)        (process; ``w`` are continuous process-noise inputs at 0)
    y     = h(x, u)           (measurements)

that work for float, ``AutoDiffXd`` and ``symbolic.Expression``. There is no
hand-written Jacobian: :class:`CompiledFunction` traces each function once with
symbolic inputs and writes value and Jacobians (forward-mode differentiation of
the trace) as straight-line Python with shared subexpressions. They equal the
``AutoDiffXd`` Jacobians of the same function; the ``"autodiff"`` backend
computes those on every call instead.

Time update over a step ``dt``, input held (the mean of the previous and the
current sample): with ``A = F dt`` and ``phi1(A) = I + A/2 + A^2/6 + A^3/24``
(evaluated by Horner's rule),

    x- = x + dt phi1(A) f(x, u),    Phi = I + A phi1(A),
    P- = Phi (P + Qd/2) Phi^T + Qd/2,   Qd = G Qc G^T dt + (B dt) Sigma_u (B dt)^T

(exponential integration of the linearised model, Taylor series of ``exp(A)`` to
fourth order), ``Qc`` the power spectral density of ``w``, ``Sigma_u`` the
per-sample covariance of the noisy inputs (IMU, attitude), ``F = df/dx``,
``G = df/dw``, ``B = df/du``. One compiled call gives ``f`` and ``[F | B | G]``;
``Qd/2 = L L^T`` with the columns of ``[B | G]`` scaled.

Measurement update in Joseph form with the availability mask of Vaiopoulos 2017: the
channels with no new sample at this step, NaN samples, and the sensor groups
rejected by the innovation gate contribute nothing (one filter: the update runs
on the rows in use, the gain from one Cholesky solve; a batch: zero rows in
``C_k = D_k H_k`` and zero innovations). The gate tests each channel's
``nu_i^2 / S_ii`` against the chi-square(1) quantile and drops the whole group
of a failing channel. Input noise entering ``h`` (attitude in the GPS rows) is
added to ``R`` through ``dh/du``, with ``EkfNoise.measurement_input_std`` where
the model smooths that input. Each update reports its normalised innovation
squared (NIS) and degrees of freedom.

Everything works on one filter or, with a leading batch axis, on many
independent filters in lockstep (Monte-Carlo campaigns). :func:`run_filter`
runs the core over logged samples offline.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np
from scipy.linalg.lapack import dposv as _posv
from scipy.stats import chi2

from drake_uav.model.compiled import CompiledFunction

__all__ = [
    "EkfModel",
    "EkfNoise",
    "UpdateResult",
    "ExtendedKalmanFilter",
    "FilterRun",
    "FilterPass",
    "run_filter",
    "filter_pass",
    "wrap_angle",
    "chi2_bounds",
]


def wrap_angle(angle):
    """Angle(s) wrapped to [-pi, pi) [rad]."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def chi2_bounds(dof: float, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` bounds of the mean of ``runs`` chi-square(``dof``) samples."""
    tail = 0.5 * (1.0 - probability)
    total = dof * runs
    return float(chi2.ppf(tail, total) / runs), float(chi2.ppf(1.0 - tail, total) / runs)


def _diagonal(M: np.ndarray) -> np.ndarray:
    """Writable view of the diagonal(s) of a contiguous (n, n) or (B, n, n) array."""
    n = M.shape[-1]
    return M.reshape(*M.shape[:-2], n * n)[..., :: n + 1]


def _t(M: np.ndarray) -> np.ndarray:
    """Transpose of the last two axes."""
    return M.swapaxes(-1, -2)


def _symmetric(M: np.ndarray) -> np.ndarray:
    """``(M + M^T) / 2`` of (n, n) or (B, n, n) matrices (``M`` is overwritten). The
    transpose is copied first: adding a contiguous array is cheaper than a strided one."""
    M += _t(M).copy()
    M *= 0.5
    return M


def _index(indices: tuple[int, ...]) -> slice | list[int] | None:
    """A slice for consecutive indices (a view), else the list; None when empty."""
    if not indices:
        return None
    if list(indices) == list(range(indices[0], indices[-1] + 1)):
        return slice(indices[0], indices[-1] + 1)
    return list(indices)


# --------------------------------------------------------------------------------------
# Model description and noise.
# --------------------------------------------------------------------------------------


class EkfModel:
    """Process and measurement model of a filter (subclass and fill in).

    Attributes (tuples of names): ``state_names``, ``input_names``,
    ``noise_names`` (process-noise inputs ``w`` of :meth:`dynamics`) and
    ``measurement_names``. ``groups`` maps a sensor name to the measurement
    indices it delivers together (gated together). ``angle_inputs``,
    ``angle_states`` and ``angle_measurements`` are indices whose differences
    wrap at +-pi. Inputs are samples of continuous signals (held at the mean
    of the two samples around a step) except ``held_inputs`` (commands held
    over the step; their current value is the one in effect during the step
    that ends at the sample). ``smoothed_inputs`` are replaced by
    :meth:`smooth_inputs` before the filter uses them (the offline runs and the
    LeafSystems both do).
    """

    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()
    noise_names: tuple[str, ...] = ()
    measurement_names: tuple[str, ...] = ()
    groups: Mapping[str, tuple[int, ...]] = {}
    angle_inputs: tuple[int, ...] = ()
    angle_states: tuple[int, ...] = ()
    angle_measurements: tuple[int, ...] = ()
    held_inputs: tuple[int, ...] = ()
    smoothed_inputs: tuple[int, ...] = ()

    def dynamics(self, x, u, w):
        """State derivative (scalar-generic)."""
        raise NotImplementedError

    def measurement(self, x, u):
        """Predicted measurements (scalar-generic)."""
        raise NotImplementedError

    def initial_state(self, u: np.ndarray, y: np.ndarray, available: np.ndarray) -> np.ndarray:
        """First state estimate from the first input and measurement samples."""
        raise NotImplementedError

    def smooth_inputs(self, previous: np.ndarray, u: np.ndarray, dt) -> np.ndarray:
        """Input vector the filter uses at a sample (``(n_inputs,)`` or ``(B, n_inputs)``):
        the sample ``u`` with its ``smoothed_inputs`` entries smoothed from ``previous``
        (the vector used ``dt`` [s] earlier). Only called when ``smoothed_inputs`` is
        not empty."""
        raise NotImplementedError

    @property
    def sizes(self) -> tuple[int, int, int, int]:
        """(states, inputs, noise inputs, measurements)."""
        return (len(self.state_names), len(self.input_names), len(self.noise_names),
                len(self.measurement_names))


@dataclasses.dataclass(frozen=True)
class EkfNoise:
    """Noise and initial-uncertainty description of a filter (all by name, SI units).

    Attributes:
        process_psd: power spectral density of each process-noise input ``w``
            [(unit of w)^2 s].
        input_std: standard deviation of each noisy input sample (inputs not
            named are exact) [unit of the input].
        measurement_std: standard deviation of each measurement [its unit].
        initial_std: standard deviation of each initial state [its unit].
        measurement_input_std: standard deviation of a noisy input where it
            enters the measurements, when it differs from ``input_std`` (an
            input smoothed over a short time: its sample-to-sample noise, seen
            by ``h``, is smaller than the samples', while its low-frequency
            noise, which drives the prediction, is that of the samples)
            [unit of the input].
    """

    process_psd: Mapping[str, float]
    input_std: Mapping[str, float]
    measurement_std: Mapping[str, float]
    initial_std: Mapping[str, float]
    measurement_input_std: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def validate(self, model: EkfModel | None = None) -> EkfNoise:
        """Raises ``ValueError`` naming the field; checks names against ``model``."""
        checks = (("process_psd", "noise_names", True), ("input_std", "input_names", False),
                  ("measurement_std", "measurement_names", True),
                  ("initial_std", "state_names", True),
                  ("measurement_input_std", "input_names", False))
        for field, attribute, complete in checks:
            values = getattr(self, field)
            for key, value in values.items():
                if not (math.isfinite(value) and value >= 0):
                    raise ValueError(f"EkfNoise.{field}['{key}'] must be finite and >= 0, "
                                     f"got {value}")
            if model is None:
                continue
            names = getattr(model, attribute)
            unknown = sorted(set(values) - set(names))
            if unknown:
                raise ValueError(f"EkfNoise.{field}: unknown names {unknown} "
                                 f"(model has {names})")
            missing = [n for n in names if n not in values]
            if complete and missing:
                raise ValueError(f"EkfNoise.{field}: missing {missing}")
        for name in self.measurement_input_std:
            if not self.input_std.get(name, 0.0) > 0:
                raise ValueError(f"EkfNoise.measurement_input_std['{name}']: the input has no "
                                 "noise in input_std")
        if model is not None:
            for field, names in (("measurement_std", model.measurement_names),
                                 ("initial_std", model.state_names)):
                for name in names:
                    if not getattr(self, field)[name] > 0:
                        raise ValueError(f"EkfNoise.{field}['{name}'] must be positive")
        return self

    def replace(self, **fields: Mapping[str, float]) -> EkfNoise:
        """A copy with some entries of the given fields replaced."""
        return dataclasses.replace(self, **{k: {**getattr(self, k), **v}
                                            for k, v in fields.items()})


@dataclasses.dataclass
class UpdateResult:
    """Outcome of a measurement update (leading batch axis when the inputs had one)."""

    x: np.ndarray
    """Posterior state."""
    P: np.ndarray
    """Posterior covariance."""
    nis: np.ndarray
    """Normalised innovation squared of the used channels (NaN when none)."""
    dof: np.ndarray
    """Number of used channels (degrees of freedom of ``nis``)."""
    used: np.ndarray
    """Channels that entered the update (bool)."""
    rejected: np.ndarray
    """Groups rejected by the innovation gate (bool, one per group)."""
    innovation: np.ndarray | None
    """``y - h(x-)`` where a sample was available (NaN elsewhere)."""
    innovation_var: np.ndarray | None
    """Innovation variance ``S_ii`` where a sample was available (NaN elsewhere)."""


# --------------------------------------------------------------------------------------
# The filter.
# --------------------------------------------------------------------------------------


class ExtendedKalmanFilter:
    """Continuous-discrete EKF on an :class:`EkfModel` (see the module docstring).

    :meth:`predict` and :meth:`update` take one filter (state ``(n,)``) or a
    batch of independent filters (``(B, n)``, e.g. one per flight of a
    Monte-Carlo campaign) with the same arithmetic.

    Args:
        model: process and measurement model.
        noise: noise description (validated against ``model``).
        gate_probability: a group is rejected when the normalised innovation
            squared ``nu_i^2 / S_ii`` of any of its channels exceeds the
            chi-square(1) quantile at this probability (``1.0`` disables gating).
        backend: ``"compiled"`` (default) or ``"autodiff"`` Jacobians.
    """

    def __init__(self, model: EkfModel, noise: EkfNoise, gate_probability: float = 0.9999,
                 backend: str = "compiled"):
        noise.validate(model)
        if not 0.0 < gate_probability <= 1.0:
            raise ValueError(f"gate_probability must be in (0, 1], got {gate_probability}")
        if backend not in ("compiled", "autodiff"):
            raise ValueError(f"backend must be 'compiled' or 'autodiff', got {backend!r}")
        self.model, self.noise, self.backend = model, noise, backend
        nx, nu, nw, ny = model.sizes
        self.n_states, self.n_inputs, self.n_measurements = nx, nu, ny
        noisy = tuple(n for n in model.input_names if noise.input_std.get(n, 0.0) > 0)
        input_std = np.array([noise.input_std[n] for n in noisy])
        self._input_var = input_std**2
        # Noise of the inputs where they enter h (smaller for smoothed inputs).
        self._h_input_std = np.array([noise.measurement_input_std.get(n, noise.input_std[n])
                                      for n in noisy])
        # Scale of the columns of [B | G] in Qd / 2 = L L^T: sqrt(1/2) [sigma_u dt, sqrt(Qc dt)].
        self._input_std, self._qc_std = input_std, np.sqrt(
            [noise.process_psd[n] for n in model.noise_names])
        self._column_scale_dt, self._column_scale_value = None, None
        self._r = np.array([noise.measurement_std[n] for n in model.measurement_names]) ** 2
        self.initial_covariance = np.diag(
            [noise.initial_std[n] ** 2 for n in model.state_names])
        noisy_index = tuple(model.input_names.index(n) for n in noisy)
        self.dynamics = CompiledFunction(model.dynamics, (nx, nu, nw),
                                         {0: None, 1: noisy_index, 2: None}, "dynamics")
        self.measurement = CompiledFunction(model.measurement, (nx, nu), {0: None, 1: noisy_index},
                                            "measurement")
        self.group_names = tuple(model.groups)
        self._membership = np.zeros((ny, len(self.group_names)))
        for g, name in enumerate(self.group_names):
            self._membership[list(model.groups[name]), g] = 1.0
        if not np.array_equal(self._membership.sum(axis=1), np.ones(ny)):
            raise ValueError(f"{type(model).__name__}.groups must cover every measurement once")
        self._group_of = self._membership.argmax(axis=1)
        self.gate_probability = gate_probability
        self._gate = chi2.ppf(gate_probability, 1) if gate_probability < 1 else np.inf
        self._angle_inputs = _index(model.angle_inputs)
        self._held = _index(model.held_inputs)
        self._angle_y = _index(model.angle_measurements)
        self._w0 = np.zeros(nw)
        self._eye = np.eye(nx)
        self._eye_half, self._eye_sixth = 0.5 * self._eye, self._eye / 6.0
        self._patterns: dict[bytes, tuple] = {}
        # Measurement rows through which input noise enters (attitude in the GPS rows).
        self._input_rows = self.measurement.jacobian_structure[:, nx:].any(axis=1)
        self._nan = np.full(ny, np.nan)
        self._none_rejected = np.zeros(len(self.group_names), bool)
        self._none_rejected.flags.writeable = False

    # -------------------------------------------------------------- pieces
    def _value_and_jacobian(self, function: CompiledFunction, *args):
        """Value and Jacobian ``[d/dx | d/du (noisy) | d/dw]`` for one sample (1-D args)
        or a batch (2-D args)."""
        if self.backend == "compiled":
            if args[0].ndim == 1:
                return function.value_and_jacobian(*args)
            return function.batch_value_and_jacobian(*args)
        samples = [args] if args[0].ndim == 1 else [[a[b] for a in args]
                                                    for b in range(len(args[0]))]
        results = [function.autodiff_jacobians(*sample) for sample in samples]
        value = np.array([r[0] for r in results])
        J = np.array([np.concatenate(r[1], axis=1) for r in results])
        return (value[0], J[0]) if args[0].ndim == 1 else (value, J)

    def midpoint_input(self, u_previous: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Input held over a step: the mean of two samples (angles wrapped); held inputs
        (commands) take their current value."""
        delta = np.subtract(u, u_previous)
        if self._angle_inputs is not None:
            angles = delta[..., self._angle_inputs]
            angles += math.pi  # wrap_angle in place
            angles %= 2.0 * math.pi
            angles -= math.pi
            if not isinstance(self._angle_inputs, slice):  # a copy, not a view
                delta[..., self._angle_inputs] = angles
        if self._held is not None:
            delta[..., self._held] *= 2.0
        delta *= 0.5
        delta += u_previous
        return delta

    def _noise_scale(self, dt):
        """Column scale of ``[B | G]``: ``sqrt(1/2) [sigma_u dt, sqrt(Qc dt)]``."""
        if not isinstance(dt, np.ndarray):
            return math.sqrt(0.5) * np.concatenate(
                [self._input_std * dt, self._qc_std * math.sqrt(dt)])
        return math.sqrt(0.5) * np.concatenate(
            [self._input_std * dt, np.broadcast_to(self._qc_std * np.sqrt(dt),
                                                   dt.shape[:-1] + self._qc_std.shape)],
            axis=-1)

    def _column_scale(self, dt: float) -> np.ndarray:
        """Scale of the columns of ``[F | B | G]`` giving ``[A | L]`` for one step ``dt`` [s]:
        ``dt`` on F, :meth:`_noise_scale` on ``[B | G]``; one row per state (the same shape
        as the Jacobian), cached: the step rarely changes."""
        if dt != self._column_scale_dt:
            self._column_scale_dt = dt
            row = np.concatenate([np.full(self.n_states, dt), self._noise_scale(dt)])
            self._column_scale_value = np.tile(row, (self.n_states, 1))
        return self._column_scale_value

    def _transition(self, A: np.ndarray, dot) -> tuple[np.ndarray, np.ndarray]:
        """``phi1(A) = I + A/2 + A^2/6 + A^3/24`` (Horner) and ``Phi = I + A phi1(A)``."""
        phi1 = A * (1.0 / 24.0)
        phi1 += self._eye_sixth
        phi1 = dot(A, phi1)
        phi1 += self._eye_half
        phi1 = dot(A, phi1)
        phi1 += self._eye
        Phi = dot(A, phi1)
        Phi += self._eye
        return phi1, Phi

    def predict(self, x: np.ndarray, P: np.ndarray, u: np.ndarray, dt) -> tuple:
        """Time update over ``dt`` [s] (scalar, or one per filter of a batch) with ``u`` held."""
        if x.ndim == 1:
            return self._predict_one(x, P, u, dt)
        return self._predict_batch(x, P, u, dt)

    def predict_transition(self, x: np.ndarray, P: np.ndarray, u: np.ndarray,
                           dt: float) -> tuple:
        """:meth:`predict` of one filter that also returns the transition matrix ``Phi``
        of the step: ``(x-, P-, Phi)``, what a Rauch-Tung-Striebel smoother needs."""
        return self._predict_one(x, P, u, dt, transition=True)

    def _predict_one(self, x: np.ndarray, P: np.ndarray, u, dt: float,
                     transition: bool = False) -> tuple:
        """:meth:`predict` of one filter (and ``Phi`` with ``transition``).

        Small matrices: ``ndarray.dot`` (a fraction of matmul's call cost) on contiguous
        operands of equal shape (numpy's broadcasting and strided loops cost more than
        the arithmetic at this size).
        """
        f, J = self._value_and_jacobian(self.dynamics, x, u, self._w0)
        J = J * self._column_scale(dt)  # [A | L] = [F dt | [B | G] noise scale]
        nx = self.n_states
        A, L = J[:, :nx].copy(), J[:, nx:].copy()
        phi1, Phi = self._transition(A, np.ndarray.dot)
        x_new = x + dt * phi1.dot(f)
        half = L.dot(L.T)
        P_new = Phi.dot(P + half).dot(Phi.T)
        P_new += half
        if transition:
            return x_new, _symmetric(P_new), Phi
        return x_new, _symmetric(P_new)

    def _predict_batch(self, x: np.ndarray, P: np.ndarray, u: np.ndarray, dt) -> tuple:
        """:meth:`predict` of a batch of filters."""
        w0 = np.broadcast_to(self._w0, (len(x), len(self._w0)))
        dt = np.broadcast_to(np.asarray(dt, float), (len(x),))[:, None, None]
        f, J = self._value_and_jacobian(self.dynamics, x, u, w0)
        nx = self.n_states
        A = J[..., :nx] * dt
        phi1, Phi = self._transition(A, np.matmul)
        x_new = x + dt[..., 0] * (phi1 @ f[..., None])[..., 0]
        L = J[..., nx:] * self._noise_scale(dt)
        half = L @ _t(L)
        P_new = Phi @ (P + half) @ _t(Phi)
        P_new += half
        return x_new, _symmetric(P_new)

    def update(self, x: np.ndarray, P: np.ndarray, u: np.ndarray, y: np.ndarray,
               available: np.ndarray | None = None, diagnostics: bool = True) -> UpdateResult:
        """Measurement update (Joseph form) with the channels flagged in ``available``.

        ``available`` (bool, default all) is the D matrix of Vaiopoulos 2017; NaN samples
        are never used. Batched inputs (leading axis) give batched results. Without
        ``diagnostics`` (one filter) the result's ``innovation`` and
        ``innovation_var`` are None.
        """
        yhat, J = self._value_and_jacobian(self.measurement, x, u)
        nu = y - yhat
        if self._angle_y is not None:
            nu[..., self._angle_y] = wrap_angle(nu[..., self._angle_y])
        mask = np.isfinite(nu)
        if available is not None:
            mask &= available
        if x.ndim == 1:
            return self._update_one(x, P, J, nu, mask, diagnostics)
        return self._update_batch(x, P, J, nu, mask)

    def _rows(self, mask: np.ndarray) -> tuple:
        """(used channels, unused channels, their sensor-noise covariance, whether any of
        them depends on a noisy input) of an availability pattern (cached: a flight
        repeats few patterns)."""
        key = mask.tobytes()
        rows = self._patterns.get(key)
        if rows is None:
            used = mask.nonzero()[0]
            rows = self._patterns[key] = (used, (~mask).nonzero()[0], np.diag(self._r[used]),
                                          bool(self._input_rows[used].any()))
        return rows

    def _update_one(self, x, P, J, nu, mask, diagnostics: bool) -> UpdateResult:
        """Update of one filter on the rows of the channels in use."""
        used, unused, R_sensor, input_noise = self._rows(mask)
        rejected = self._none_rejected
        innovation = innovation_var = None
        if diagnostics:
            innovation = nu.copy()
            innovation[unused] = np.nan
            innovation_var = self._nan.copy()
        if not used.size:
            return UpdateResult(x, P, np.nan, 0, mask, rejected, innovation, innovation_var)
        nx = self.n_states
        if unused.size:
            J, nu = J.take(used, axis=0), nu.take(used)
        H = J[:, :nx].copy()
        if input_noise:
            D = J[:, nx:] * self._h_input_std
            R = D.dot(D.T)
            R += R_sensor
        else:
            R = R_sensor
        PHt = P.dot(H.T)
        S = H.dot(PHt)
        S += R
        S_diag = S.diagonal()
        if diagnostics:
            innovation_var[used] = S_diag
        gate = self._gate
        if any(v * v > gate * d for v, d in zip(nu.tolist(), S_diag.tolist(), strict=True)):
            bad = nu * nu > gate * S_diag
            rejected = np.zeros(len(self.group_names), bool)
            rejected[self._group_of[used[bad]]] = True
            keep = ~rejected[self._group_of[used]]
            mask[used[~keep]] = False
            used, H, PHt, nu = used[keep], H[keep], PHt[:, keep], nu[keep]
            if not used.size:
                return UpdateResult(x, P, np.nan, 0, mask, rejected, innovation,
                                    innovation_var)
            kept = keep.nonzero()[0]
            S, R = S.take(kept, 0).take(kept, 1), R.take(kept, 0).take(kept, 1)
        # S [K^T | z] = [H P | nu] (Cholesky): gain K and NIS nu^T z.
        _, solution, info = _posv(S, np.concatenate((PHt.T, nu[:, None]), axis=1))
        if info:
            raise np.linalg.LinAlgError("EKF update: innovation covariance not positive "
                                        "definite")
        Kt = solution[:, :nx]
        K = Kt.T
        A = self._eye - K.dot(H)
        P_new = A.dot(P).dot(A.T)
        P_new += K.dot(R).dot(Kt)
        return UpdateResult(x + K.dot(nu), _symmetric(P_new), nu.dot(solution[:, nx]),
                            len(used), mask, rejected, innovation, innovation_var)

    def _update_batch(self, x, P, J, nu, mask) -> UpdateResult:
        """Update of a batch of filters: unused channels get zero rows (the D matrix of
        Vaiopoulos 2017)."""
        nx = self.n_states
        H = J[..., :nx]
        D = J[..., nx:] * self._h_input_std
        Ht = _t(H)
        PHt = P @ Ht
        R = D @ _t(D)
        _diagonal(R)[...] += self._r
        S = H @ PHt + R
        S_diag = _diagonal(S).copy()
        innovation = np.where(mask, nu, np.nan)
        innovation_var = np.where(mask, S_diag, np.nan)
        bad = mask & (nu * nu > self._gate * S_diag)
        if bad.any():
            rejected = bad @ self._membership > 0
            mask &= rejected @ self._membership.T == 0
        else:
            rejected = np.zeros(mask.shape[:-1] + (len(self.group_names),), bool)
        # Unused channels: zero rows of C = D_k H and zero innovation (no gain), unit S.
        m = mask.astype(float)
        nu = np.where(mask, nu, 0.0)
        if not mask.all():
            outer = m[..., :, None] * m[..., None, :]
            PHt = PHt * m[..., None, :]
            H = H * m[..., :, None]
            S = S * outer
            _diagonal(S)[...] += 1.0 - m
            R = R * outer
        solution = np.linalg.solve(S, np.concatenate([_t(PHt), nu[..., None]], axis=-1))
        K = _t(solution[..., :nx])
        nis = np.einsum("bi,bi->b", nu, solution[..., nx])
        dof = mask.sum(axis=-1)
        A = self._eye - K @ H
        P_new = A @ P @ _t(A) + K @ R @ _t(K)
        nis = np.where(dof > 0, nis, np.nan)
        return UpdateResult(x + (K @ nu[..., None])[..., 0], 0.5 * (P_new + _t(P_new)), nis,
                            dof, mask, rejected, innovation, innovation_var)


# --------------------------------------------------------------------------------------
# Offline runs.
# --------------------------------------------------------------------------------------


@dataclasses.dataclass
class FilterRun:
    """Result of :func:`run_filter`: arrays over N samples (leading B axis for a batch)."""

    time: np.ndarray
    """Sample times [s] (N)."""
    state: np.ndarray
    """Posterior state (N, n)."""
    std: np.ndarray
    """Posterior standard deviations (N, n)."""
    nis: np.ndarray
    """NIS of each update (N; NaN when nothing was used)."""
    dof: np.ndarray
    """Channels used in each update (N)."""
    nees: np.ndarray | None
    """Normalised estimation error squared against ``truth`` (N), if given."""
    innovation: np.ndarray
    """Innovations (N, m); NaN where the channel had no sample."""
    innovation_var: np.ndarray
    """Innovation variances (N, m); NaN where the channel had no sample."""
    used: np.ndarray
    """Channels that entered each update (N, m) bool."""
    rejected: np.ndarray
    """Updates rejected by the innovation gate, per group (G)."""
    nan_measurements: np.ndarray
    """NaN measurement samples skipped, per channel (m)."""
    nan_inputs: np.ndarray
    """NaN input samples replaced by the previous input, per input (n_inputs)."""
    covariance: np.ndarray | None
    """Posterior covariance (N, n, n) when requested."""
    state_names: tuple[str, ...]
    measurement_names: tuple[str, ...]
    group_names: tuple[str, ...]

    def rejected_by_group(self) -> dict[str, int]:
        """Gate rejections per group (summed over a batch)."""
        total = np.asarray(self.rejected).reshape(-1, len(self.group_names)).sum(axis=0)
        return {g: int(n) for g, n in zip(self.group_names, total, strict=True)}


@dataclasses.dataclass
class _Samples:
    """Logged samples checked for :func:`run_filter`, always with a leading batch axis."""

    time: np.ndarray
    inputs: np.ndarray
    """(B, N, n_inputs), NaN entries replaced and smoothed inputs smoothed."""
    measurements: np.ndarray
    available: np.ndarray
    """(B, N, n_measurements): a new, finite sample."""
    nan_measurements: np.ndarray
    nan_inputs: np.ndarray
    single: bool
    """The arrays had no batch axis."""


def _samples(ekf: ExtendedKalmanFilter, time, inputs, measurements, available) -> _Samples:
    """Checks the shapes, counts the NaN samples and prepares the inputs."""
    time = np.asarray(time, float)
    U = np.array(inputs, float)
    Y = np.asarray(measurements, float)
    single = U.ndim == 2
    if single:
        U, Y = U[None], Y[None]
    batch, n = U.shape[0], time.size
    if U.shape != (batch, n, ekf.n_inputs) or Y.shape != (batch, n, ekf.n_measurements):
        raise ValueError(f"run_filter: inputs {U.shape} / measurements {Y.shape} do not match "
                         f"({batch}, {n}, {ekf.n_inputs}) / ({batch}, {n}, {ekf.n_measurements})")
    finite = np.isfinite(Y)
    avail = finite if available is None else np.asarray(available, bool).reshape(Y.shape)
    nan_measurements = (avail & ~finite).sum(axis=1)
    bad_u = ~np.isfinite(U)
    if bad_u[:, 0].any():
        raise ValueError("run_filter: the first input sample must be finite")
    _prepare_inputs(ekf.model, time, U, bad_u)
    return _Samples(time, U, Y, avail & finite, nan_measurements, bad_u.sum(axis=1), single)


def _prepare_inputs(model: EkfModel, time: np.ndarray, U: np.ndarray, bad: np.ndarray) -> None:
    """Replaces NaN inputs by the previous value used and smooths the model's
    ``smoothed_inputs``, sample by sample as the LeafSystems do (``U`` in place)."""
    batch, n = U.shape[:2]
    if not model.smoothed_inputs:
        for k in np.flatnonzero(bad.any(axis=(0, 2))):
            U[:, k] = np.where(bad[:, k], U[:, k - 1], U[:, k])
        return
    for k in range(1, n):
        row = np.where(bad[:, k], U[:, k - 1], U[:, k])
        if batch == 1:
            U[0, k] = model.smooth_inputs(U[0, k - 1], row[0], time[k] - time[k - 1])
        else:
            U[:, k] = model.smooth_inputs(U[:, k - 1], row, time[k] - time[k - 1])


def _start(ekf: ExtendedKalmanFilter, samples: _Samples, x0, P0) -> tuple:
    """Initial states (B, n) and covariances (B, n, n)."""
    U, Y, avail = samples.inputs, samples.measurements, samples.available
    batch = len(U)
    if x0 is None:
        X = np.array([ekf.model.initial_state(U[b, 0], Y[b, 0], avail[b, 0])
                      for b in range(batch)])
        if not np.all(np.isfinite(X)):
            raise ValueError("run_filter: the first samples do not determine the initial state "
                             "(missing sensors at the first sample); give x0")
    else:
        X = np.broadcast_to(np.asarray(x0, float), (batch, ekf.n_states)).copy()
    P = np.broadcast_to(ekf.initial_covariance if P0 is None else np.asarray(P0, float),
                        (batch, ekf.n_states, ekf.n_states)).copy()
    return X, P


class _History:
    """The per-sample results of :func:`run_filter` as they are filled in."""

    def __init__(self, ekf: ExtendedKalmanFilter, batch: int, n: int, truth,
                 store_covariance: bool):
        nx, ny = ekf.n_states, ekf.n_measurements
        self.truth = None if truth is None else np.asarray(truth, float).reshape(batch, n, nx)
        self.states, self.stds = np.empty((batch, n, nx)), np.empty((batch, n, nx))
        self.covariances = np.empty((batch, n, nx, nx)) if store_covariance else None
        self.nees = None if self.truth is None else np.empty((batch, n))
        self.nis, self.dof = np.full((batch, n), np.nan), np.zeros((batch, n), int)
        self.innovation = np.full((batch, n, ny), np.nan)
        self.innovation_var = np.full((batch, n, ny), np.nan)
        self.used = np.zeros((batch, n, ny), bool)
        self.rejected = np.zeros((batch, len(ekf.group_names)), int)
        self._angle_states = list(ekf.model.angle_states)

    def update(self, k: int, result: UpdateResult) -> None:
        """Keeps the diagnostics of the update at sample ``k``."""
        self.nis[:, k], self.dof[:, k], self.used[:, k] = result.nis, result.dof, result.used
        self.innovation[:, k] = result.innovation
        self.innovation_var[:, k] = result.innovation_var
        self.rejected += result.rejected

    def posterior(self, k: int, X: np.ndarray, P: np.ndarray) -> None:
        """Keeps the posterior at sample ``k`` and its NEES against the truth."""
        self.states[:, k] = X
        self.stds[:, k] = np.sqrt(_diagonal(P))
        if self.covariances is not None:
            self.covariances[:, k] = P
        if self.truth is not None:
            error = X - self.truth[:, k]
            if self._angle_states:
                error[:, self._angle_states] = wrap_angle(error[:, self._angle_states])
            self.nees[:, k] = np.einsum("bi,bi->b", error,
                                        np.linalg.solve(P, error[..., None])[..., 0])

    def run(self, ekf: ExtendedKalmanFilter, samples: _Samples) -> FilterRun:
        """The :class:`FilterRun` (without the batch axis for a single flight)."""
        model = ekf.model
        out = FilterRun(samples.time, self.states, self.stds, self.nis, self.dof, self.nees,
                        self.innovation, self.innovation_var, self.used, self.rejected,
                        samples.nan_measurements, samples.nan_inputs, self.covariances,
                        tuple(model.state_names), tuple(model.measurement_names),
                        ekf.group_names)
        if samples.single:
            for f in dataclasses.fields(FilterRun):
                value = getattr(out, f.name)
                if isinstance(value, np.ndarray) and f.name != "time":
                    setattr(out, f.name, value[0])
        return out


def run_filter(ekf: ExtendedKalmanFilter, time, inputs, measurements, available=None, *,
               x0: np.ndarray | None = None, P0: np.ndarray | None = None, truth=None,
               store_covariance: bool = False) -> FilterRun:
    """Runs ``ekf`` over logged samples: the core of the LeafSystems, offline.

    Arrays may carry a leading batch axis B (several flights on the same time
    base, filtered in lockstep); the results then carry it too.

    Args:
        time: sample times [s] (N), strictly increasing.
        inputs: ([B,] N, n_inputs); a NaN entry is replaced by the previous
            value of that input and counted. The model's ``smoothed_inputs`` are
            smoothed here, sample by sample, as in the LeafSystems.
        measurements: ([B,] N, n_measurements); NaN samples are skipped and
            counted (where ``available`` flagged a sample).
        available: same shape, bool, True where a new sample exists (multi-rate
            sensors); default: every finite entry.
        x0, P0: initial state(s) and covariance(s); default: the model's
            ``initial_state`` from the first samples and the noise's initial_std.
        truth: ([B,] N, n) true states for the NEES.
        store_covariance: also return the full covariance history.
    """
    samples = _samples(ekf, time, inputs, measurements, available)
    time, U, Y, avail = samples.time, samples.inputs, samples.measurements, samples.available
    batch, n = U.shape[:2]
    X, P = _start(ekf, samples, x0, P0)
    history = _History(ekf, batch, n, truth, store_covariance)
    # A single flight runs as one filter (the cheaper per-sample path).
    cut = (lambda a: a[0]) if batch == 1 else (lambda a: a)
    X, P = cut(X), cut(P)
    for k in range(n):
        if k:
            X, P = ekf.predict(X, P, ekf.midpoint_input(cut(U[:, k - 1]), cut(U[:, k])),
                               time[k] - time[k - 1])
        if avail[:, k].any():
            result = ekf.update(X, P, cut(U[:, k]), cut(Y[:, k]), cut(avail[:, k]))
            X, P = result.x, result.P
            history.update(k, result)
        history.posterior(k, X, P)
    return history.run(ekf, samples)


@dataclasses.dataclass
class FilterPass:
    """Forward pass of one filter over N samples, kept for a smoother
    (:func:`filter_pass`)."""

    time: np.ndarray
    """Sample times [s] (N)."""
    prior_state: np.ndarray
    """State after the time update to each sample (N, n); the initial state at 0."""
    prior_covariance: np.ndarray
    """Its covariance (N, n, n)."""
    state: np.ndarray
    """Posterior state (N, n)."""
    covariance: np.ndarray
    """Posterior covariance (N, n, n)."""
    transition: np.ndarray
    """Transition matrix ``Phi`` of the step ending at each sample (N, n, n); identity
    at 0."""
    inputs: np.ndarray
    """The inputs the filter used (N, n_inputs): NaN entries replaced, smoothed inputs
    smoothed."""
    rejected: np.ndarray
    """Updates rejected by the innovation gate, per group (G)."""


def filter_pass(ekf: ExtendedKalmanFilter, time, inputs, measurements, available=None, *,
                x0: np.ndarray | None = None, P0: np.ndarray | None = None) -> FilterPass:
    """Runs ``ekf`` over the samples of one flight (arguments as in :func:`run_filter`,
    no batch axis) and keeps the prior, the posterior and the transition matrix of every
    step: the forward pass of a Rauch-Tung-Striebel smoother.

    The steps are rounded to 1 ns: a log's time stamps carry floating-point noise that
    would defeat the cache of the step-dependent noise scale.
    """
    samples = _samples(ekf, time, inputs, measurements, available)
    if not samples.single:
        raise ValueError("filter_pass: one flight only (inputs of shape (N, n_inputs))")
    X, P0s = _start(ekf, samples, x0, P0)
    x, P = X[0], P0s[0]
    U, Y, avail = samples.inputs[0], samples.measurements[0], samples.available[0]
    n, nx = len(samples.time), ekf.n_states
    prior_x, post_x = np.empty((n, nx)), np.empty((n, nx))
    prior_P, post_P, Phi = (np.empty((n, nx, nx)) for _ in range(3))
    Phi[0] = ekf._eye
    rejected = np.zeros(len(ekf.group_names), int)
    steps = np.round(np.diff(samples.time), 9).tolist()
    updated = avail.any(axis=1).tolist()
    for k in range(n):
        if k:
            x, P, Phi[k] = ekf.predict_transition(x, P, ekf.midpoint_input(U[k - 1], U[k]),
                                                  steps[k - 1])
        prior_x[k], prior_P[k] = x, P
        if updated[k]:
            result = ekf.update(x, P, U[k], Y[k], avail[k], diagnostics=False)
            x, P = result.x, result.P
            rejected += result.rejected
        post_x[k], post_P[k] = x, P
    return FilterPass(samples.time, prior_x, prior_P, post_x, post_P, Phi, U, rejected)
