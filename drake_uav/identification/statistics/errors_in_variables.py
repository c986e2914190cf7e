"""Errors-in-variables core: regressor noise, bias compensation and parameter covariance.

The model ``z = X0 theta + e`` is measured as ``[X | z] = [X0 | z0] + [dX | dz]``: the
regressors are noisy too (air data, rates). Least squares on the measured ``X`` then
attenuates ``theta`` (Vaiopoulos 2017, Table 5). Every estimator of the package that
corrects for this (batch TLS/GTLS/PCA-TLS and BCLS in :mod:`.regression`, the recursive
PCA-GTLS in :mod:`.recursive`, the flight-log fits of :mod:`.discovery`) is built from the
three pieces below (Fuller, *Measurement Error Models*, 1987, sec. 2.2-2.3).

1. **Noise of the regressors.** Either one error covariance ``W_T = C^T C`` per row of
   ``[X | z]``, known up to a scale factor (:func:`normalization_matrix`, Vaiopoulos 2017,
   eq. 4.38-4.40), or the noise of independent sources (sensor channels) carried to every
   column and to the observation by per-sample sensitivities, with known variances
   (:class:`PropagatedNoise`). Both give the expected noise moments
   ``E[dD^T dD]`` of the augmented data ``D = [X | z]``.
2. **Bias compensation.** The normal equations of the true regressors are the measured
   ones minus the noise moments: ``(X^T X - E[dX^T dX]) theta = X^T z - E[dX^T dz]``
   (:func:`compensated_normal_equations`). With ``W_T`` known only up to a scale the
   scale is the smallest singular value of the normalised ``D`` and the estimate its
   last right singular vector (TLS/GTLS, :func:`tls_solution`, Vaiopoulos 2017, eq.
   4.54-4.61); the compensated Gram matrix is then :func:`compensated_gram` (eq. 4.63).
3. **Covariance.** The estimate solves ``sum_t psi_t(theta) = 0``; its covariance is the
   sandwich ``A^-1 S A^-1`` (:func:`sandwich_covariance`) with ``A`` the compensated
   normal matrix and ``S`` the covariance of the summed scores ``psi_t``: for white
   Gaussian errors ``s^2 A + N (s^2 S_uu - S_uv S_uv^T)`` (Fuller 1987, Thm 2.3.2;
   :func:`white_noise_covariance`, the TLS covariance of Vaiopoulos 2017, eq. 4.62 plus
   its second-order term), for correlated residuals (smoothed flight data) the long-run
   Newey-West covariance of the scores (:func:`long_run_covariance`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from drake_uav.identification.statistics.residuals import long_run_covariance

__all__ = [
    "BlockMoments",
    "PropagatedNoise",
    "compensated_gram",
    "compensated_normal_equations",
    "excitation_threshold",
    "is_well_posed",
    "long_run_covariance",
    "moment_scores",
    "noise_error_energy",
    "normalization_matrix",
    "orthonormal_columns",
    "restricted_inverse",
    "sandwich_covariance",
    "solve_normal_equations",
    "tls_covariance",
    "tls_solution",
    "weight_matrix",
    "white_noise_covariance",
]


# ----------------------------------------------------------------------------- noise models


def normalization_matrix(error_std=None, error_cov=None, n_cols: int = 0) -> np.ndarray:
    """Upper-triangular error std matrix C with C^T C = W_T (Vaiopoulos 2017, eq. 4.38-4.40).

    TLS and GTLS normalise the augmented data ``[X | z]`` by ``C^-1`` so that its noise is
    isotropic. Entries must be positive here; the batch :func:`~.regression.tls` replaces
    zero stds of exact columns before calling this.

    Parameters
    ----------
    error_std : array_like of shape (n_cols,), optional
        Noise std of each column, in the column's unit; gives C = diag(error_std).
    error_cov : array_like of shape (n_cols, n_cols), optional
        Noise covariance of one row (symmetric positive definite); gives its Cholesky factor.
    n_cols : int
        Number of columns of ``[X | z]``.

    Returns
    -------
    numpy.ndarray of shape (n_cols, n_cols)
        C; the identity (plain TLS) when neither ``error_std`` nor ``error_cov`` is given.

    Raises
    ------
    ValueError
        If both are given, a shape is wrong, ``error_cov`` is not symmetric positive
        definite or an ``error_std`` entry is not finite and positive.
    """
    if error_std is not None and error_cov is not None:
        raise ValueError("give error_std or error_cov, not both")
    if error_cov is not None:
        W = np.asarray(error_cov, dtype=float)
        if W.shape != (n_cols, n_cols):
            raise ValueError(f"error_cov must have shape ({n_cols}, {n_cols}), got {W.shape}")
        if not np.allclose(W, W.T):
            raise ValueError("error_cov must be symmetric")
        try:
            return np.linalg.cholesky(W).T
        except np.linalg.LinAlgError:
            raise ValueError(
                "error_cov must be positive definite (use error_std with 0 for exact columns)"
            ) from None
    if error_std is None:
        return np.eye(n_cols)
    c = np.asarray(error_std, dtype=float)
    if c.shape != (n_cols,):
        raise ValueError(f"error_std must have shape ({n_cols},), got {c.shape}")
    if not (np.isfinite(c).all() and (c > 0).all()):
        raise ValueError("error_std entries must be finite and positive")
    return np.diag(c)


@dataclasses.dataclass(frozen=True)
class PropagatedNoise:
    """Noise of independent sources carried to the regressors and the observation.

    Source ``s`` (e.g. the airspeed sensor) has white noise of variance ``variance[s]``;
    ``regressors[s]`` (N, n) holds d x_t / d s and ``observation[s]`` (N,) d z_t / d s at
    every sample (a source missing there does not enter the observation). To first
    order the noise of row t is ``sum_s J_(s,t) n_(s,t)``, so its moments are
    ``sum_s var_s J_s^T J_s``: sample-dependent, which no single row covariance ``W_T``
    describes.

    Attributes
    ----------
    columns : int
        Number of regressor columns n.
    regressors : Mapping[str, numpy.ndarray]
        Source name -> (N, n) sensitivities of the regressors to that source.
    observation : Mapping[str, numpy.ndarray]
        Source name -> (N,) sensitivity of the observation to that source.
    variance : Mapping[str, float]
        Source name -> noise variance, in the source's unit squared.

    Examples
    --------
    >>> import numpy as np
    >>> noise = PropagatedNoise(1, {"pitot": np.ones((4, 1))}, {}, {"pitot": 0.25})
    >>> C_xx, c_xz = noise.moments()
    >>> float(C_xx[0, 0]), float(c_xz[0])
    (1.0, 0.0)
    """

    columns: int
    """Number of regressor columns n."""
    regressors: Mapping[str, np.ndarray]
    observation: Mapping[str, np.ndarray]
    variance: Mapping[str, float]

    def moments(self, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """Expected noise moments ``(dX^T dX, dX^T dz)`` summed over some rows.

        Parameters
        ----------
        rows : array_like or slice, optional
            A boolean mask, indices or a slice of the samples; None: all samples.

        Returns
        -------
        C_xx : numpy.ndarray of shape (n, n)
            Expected ``dX^T dX``.
        c_xz : numpy.ndarray of shape (n,)
            Expected ``dX^T dz``.
        """
        C_xx, c_xz = np.zeros((self.columns, self.columns)), np.zeros(self.columns)
        for source, J in self.regressors.items():
            Jr = J if rows is None else J[rows]
            var = self.variance[source]
            C_xx += var * (Jr.T @ Jr)
            jz = self.observation.get(source)
            if jz is not None:
                c_xz += var * (Jr.T @ (jz if rows is None else jz[rows]))
        return C_xx, c_xz

    def extended(self, regressors: Mapping[str, np.ndarray], n_new: int) -> PropagatedNoise:
        """The noise of the design with ``n_new`` columns appended.

        A source the present columns do not depend on joins when ``variance`` knows it.

        Parameters
        ----------
        regressors : Mapping[str, numpy.ndarray]
            Source name -> (N, n_new) sensitivities of the added columns (a source missing:
            the columns do not depend on it).
        n_new : int
            Number of added columns.

        Returns
        -------
        PropagatedNoise
            The noise of the n + n_new columns, with the same observation and variances.
        """
        new = {}
        for source in (*self.regressors, *(s for s in regressors if s not in self.regressors
                                           and s in self.variance)):
            J, added = self.regressors.get(source), regressors.get(source)
            rows = (J if added is None else added).shape[0]
            new[source] = np.column_stack(
                [np.zeros((rows, self.columns)) if J is None else J,
                 np.zeros((rows, n_new)) if added is None else added])
        return PropagatedNoise(self.columns + n_new, new, self.observation, self.variance)


# ----------------------------------------------------------------------------- moment form


def compensated_normal_equations(X, z, noise: PropagatedNoise, rows=None):
    """Bias-compensated normal equations ``(X^T X - E[dX^T dX], X^T z - E[dX^T dz])``.

    Fuller 1987, eq. 2.2.4, with sample-dependent noise moments: their solution is
    the estimate that least squares would give on the noise-free regressors.

    Parameters
    ----------
    X : numpy.ndarray of shape (N, n)
        Measured regressors.
    z : numpy.ndarray of shape (N,)
        Measured observation.
    noise : PropagatedNoise
        Noise of the regressors and the observation.
    rows : array_like or slice, optional
        The samples summed over (mask, indices or slice); None: all.

    Returns
    -------
    A : numpy.ndarray of shape (n, n)
        Compensated normal matrix.
    b : numpy.ndarray of shape (n,)
        Compensated right-hand side.
    """
    X = X if rows is None else X[rows]
    z = z if rows is None else z[rows]
    C_xx, c_xz = noise.moments(rows)
    return X.T @ X - C_xx, X.T @ z - c_xz


@dataclasses.dataclass(frozen=True)
class BlockMoments:
    """Measured and expected-noise moments of a design, summed over contiguous row blocks.

    Blocked K-fold cross-validation fits on every block but one and predicts the one left
    out. With the sums per block, the normal equations of every training set are the
    totals minus one block, so the K fits need one pass over the data, not K; a design
    extended by a few columns needs only the products of the new columns
    (:meth:`extended`).

    Attributes
    ----------
    edges : tuple of int
        Block boundaries: block k holds rows ``edges[k]:edges[k + 1]``.
    xx : numpy.ndarray of shape (K, n, n)
        ``X_k^T X_k``.
    xz : numpy.ndarray of shape (K, n)
        ``X_k^T z_k``.
    noise_xx : numpy.ndarray of shape (K, n, n)
        Expected ``dX_k^T dX_k`` (:meth:`PropagatedNoise.moments` on block k).
    noise_xz : numpy.ndarray of shape (K, n)
        Expected ``dX_k^T dz_k``.
    """

    edges: tuple[int, ...]
    """Block boundaries: block k holds rows ``edges[k]:edges[k + 1]``."""
    xx: np.ndarray
    """(K, n, n) ``X_k^T X_k``."""
    xz: np.ndarray
    """(K, n) ``X_k^T z_k``."""
    noise_xx: np.ndarray
    """(K, n, n) expected ``dX_k^T dX_k`` (:meth:`PropagatedNoise.moments` on block k)."""
    noise_xz: np.ndarray
    """(K, n) expected ``dX_k^T dz_k``."""

    @classmethod
    def of(cls, X: np.ndarray, z: np.ndarray, noise: PropagatedNoise,
           edges) -> BlockMoments:
        """The block sums of the design ``(X, z)`` with regressor noise ``noise``.

        Parameters
        ----------
        X : numpy.ndarray of shape (N, n)
            Regressors.
        z : numpy.ndarray of shape (N,)
            Observation.
        noise : PropagatedNoise
            Noise of the regressors and the observation.
        edges : sequence of int
            Block boundaries, from 0 to N.

        Returns
        -------
        BlockMoments
            The per-block sums.
        """
        edges = tuple(int(e) for e in edges)
        blocks = [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]
        xx = np.stack([X[b].T @ X[b] for b in blocks])
        xz = np.stack([X[b].T @ z[b] for b in blocks])
        noise_moments = [noise.moments(b) for b in blocks]
        return cls(edges, xx, xz, np.stack([m[0] for m in noise_moments]),
                   np.stack([m[1] for m in noise_moments]))

    def extended(self, X: np.ndarray, z: np.ndarray, noise: PropagatedNoise,
                 X_new: np.ndarray, J_new: Mapping[str, np.ndarray]) -> BlockMoments:
        """The block sums of ``[X | X_new]``, with the noise of :meth:`PropagatedNoise.extended`.

        Only the new rows of the moments are computed. ``X_new`` (N, m, q) and ``J_new``
        values of the same shape are m alternative extensions at once (the candidates of a
        search): every array of the result then has a leading axis m.

        Parameters
        ----------
        X : numpy.ndarray of shape (N, p)
            The regressors these sums were built from.
        z : numpy.ndarray of shape (N,)
            The observation these sums were built from.
        noise : PropagatedNoise
            The noise these sums were built from.
        X_new : numpy.ndarray of shape (N, q) or (N, m, q)
            The added columns.
        J_new : Mapping[str, numpy.ndarray]
            Source name -> sensitivities of the added columns, shaped as ``X_new`` (a source
            missing: the columns do not depend on it; a source joins when
            ``noise.variance`` knows it).

        Returns
        -------
        BlockMoments
            The sums of the extended design (with a leading axis m for a batch).
        """
        batch = X_new.ndim == 3
        if not batch:
            X_new, J_new = X_new[:, None, :], {s: J[:, None, :] for s, J in J_new.items()}
        m, q = X_new.shape[1:]
        p = X.shape[1]
        xx = np.zeros((m, len(self.edges) - 1, p + q, p + q))
        noise_xx = np.zeros_like(xx)
        xx[..., :p, :p], noise_xx[..., :p, :p] = self.xx, self.noise_xx
        xz = np.zeros(xx.shape[:-1])
        noise_xz = np.zeros_like(xz)
        xz[..., :p], noise_xz[..., :p] = self.xz, self.noise_xz
        sources = [(noise.variance[s], added, noise.regressors.get(s), noise.observation.get(s))
                   for s, added in J_new.items() if s in noise.variance]
        for k, (a, b) in enumerate(zip(self.edges[:-1], self.edges[1:], strict=True)):
            _add_new_rows(xx[:, k], xz[:, k], 1.0, X_new[a:b], X[a:b], z[a:b])
            for var, added, J, jz in sources:
                _add_new_rows(noise_xx[:, k], noise_xz[:, k], var, added[a:b],
                              None if J is None else J[a:b], None if jz is None else jz[a:b])
        for moments in (xx, noise_xx):
            moments[..., :p, p:] = np.swapaxes(moments[..., p:, :p], -1, -2)
        if batch:
            return BlockMoments(self.edges, xx, xz, noise_xx, noise_xz)
        return BlockMoments(self.edges, xx[0], xz[0], noise_xx[0], noise_xz[0])

    def total(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The compensated normal equations and the noise moments over all rows.

        Returns
        -------
        A, b : numpy.ndarray
            Compensated normal equations, (n, n) and (n,) (with the leading axis of a batch).
        C_xx, c_xz : numpy.ndarray
            Expected noise moments, (n, n) and (n,).
        """
        C_xx, c_xz = self.noise_xx.sum(axis=-3), self.noise_xz.sum(axis=-2)
        return self.xx.sum(axis=-3) - C_xx, self.xz.sum(axis=-2) - c_xz, C_xx, c_xz

    def held_in_least_squares(self) -> tuple[np.ndarray, np.ndarray]:
        """The plain normal equations without block k, for every k.

        Least squares, no noise compensation.

        Returns
        -------
        A : numpy.ndarray of shape (K, n, n)
            ``X^T X`` without block k (with the leading axis of a batch).
        b : numpy.ndarray of shape (K, n)
            ``X^T z`` without block k.
        """
        return (self.xx.sum(axis=-3)[..., None, :, :] - self.xx,
                self.xz.sum(axis=-2)[..., None, :] - self.xz)

    def held_in(self) -> tuple[np.ndarray, np.ndarray]:
        """The compensated normal equations without block k, for every k.

        Returns
        -------
        A : numpy.ndarray of shape (K, n, n)
            Compensated normal matrix without block k (with the leading axis of a batch).
        b : numpy.ndarray of shape (K, n)
            Compensated right-hand side without block k.
        """
        A, b, _, _ = self.total()
        return (A[..., None, :, :] - (self.xx - self.noise_xx),
                b[..., None, :] - (self.xz - self.noise_xz))


def _add_new_rows(xx: np.ndarray, xz: np.ndarray, weight: float, new: np.ndarray,
                  old: np.ndarray | None, z: np.ndarray | None) -> None:
    """Adds ``weight`` times the products of the new columns ``new`` (n, m, q) with the
    old ones ``old`` (n, p), with themselves and with ``z`` (n,) to the rows ``p:`` of the
    (m, p + q, p + q) ``xx`` and the entries ``p:`` of the (m, p + q) ``xz`` (None: zero)."""
    n, m, q = new.shape
    p = xx.shape[-1] - q
    flat = new.reshape(n, m * q)
    if old is not None:
        xx[:, p:, :p] += weight * (flat.T @ old).reshape(m, q, p)
    xx[:, p:, p:] += weight * np.matmul(new.transpose(1, 2, 0), new.transpose(1, 0, 2))
    if z is not None:
        xz[:, p:] += weight * (flat.T @ z).reshape(m, q)


def solve_normal_equations(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` with A equilibrated to a unit diagonal (least squares if A is singular).

    Equilibration keeps coefficients of very different scales (per radian and per
    throttle) from losing digits.

    Parameters
    ----------
    A : numpy.ndarray of shape (n, n) or (K, n, n)
        Normal matrix, or a stack of them solved together.
    b : numpy.ndarray of shape (n,) or (K, n)
        Right-hand side(s).

    Returns
    -------
    numpy.ndarray of shape (n,) or (K, n)
        The solution(s).
    """
    scale = np.sqrt(np.maximum(np.diagonal(A, axis1=-2, axis2=-1), 1e-300))
    try:
        equilibrated = A / (scale[..., :, None] * scale[..., None, :])
        return np.linalg.solve(equilibrated, (b / scale)[..., None])[..., 0] / scale
    except np.linalg.LinAlgError:
        if A.ndim > 2:
            return np.stack([solve_normal_equations(a, c) for a, c in zip(A, b, strict=True)])
        return np.linalg.lstsq(A, b, rcond=None)[0]


def is_well_posed(A: np.ndarray, tolerance: float = 1e-8):
    """Whether the compensated normal matrix ``A`` is safely positive definite.

    Removing the noise moments can make a nearly collinear design indefinite: its
    columns are then not separable from the regressor noise.

    Parameters
    ----------
    A : array_like of shape (n, n) or (..., n, n)
        Compensated normal matrix, or a stack of them.
    tolerance : float
        Smallest eigenvalue of the unit-diagonal ``A`` accepted.

    Returns
    -------
    bool or numpy.ndarray of bool
        The answer, one per matrix of a stack.
    """
    A = np.asarray(A, dtype=float)
    diagonal = np.diagonal(A, axis1=-2, axis2=-1)
    scale = np.sqrt(np.maximum(diagonal, 1e-300))
    equilibrated = A / (scale[..., :, None] * scale[..., None, :])
    finite = np.isfinite(equilibrated).all(axis=(-2, -1))
    smallest = np.linalg.eigvalsh(np.where(finite[..., None, None], equilibrated, 0.0))[..., 0]
    posed = finite & (diagonal.min(axis=-1) > 0) & (smallest > tolerance)
    return bool(posed) if A.ndim == 2 else posed


def moment_scores(X, z, theta, noise: PropagatedNoise) -> np.ndarray:
    """Per-sample terms of the compensated normal equations at ``theta``.

    ``x_t (z_t - x_t^T theta)`` plus the sample's expected regressor-noise part
    ``sum_s var_s J_(s,t) (J_(s,t)^T theta - dz_t/ds)``; they sum to zero at the estimate,
    and their long-run covariance gives the sandwich covariance.

    Parameters
    ----------
    X : numpy.ndarray of shape (N, n)
        Regressors.
    z : numpy.ndarray of shape (N,)
        Observation.
    theta : numpy.ndarray of shape (n,)
        Parameters.
    noise : PropagatedNoise
        Noise of the regressors and the observation.

    Returns
    -------
    numpy.ndarray of shape (N, n)
        The scores ``psi_t``.
    """
    psi = X * (z - X @ theta)[:, None]
    for source, J in noise.regressors.items():
        jz = noise.observation.get(source, 0.0)
        psi += noise.variance[source] * J * (J @ theta - jz)[:, None]
    return psi


def noise_error_energy(theta, C_xx, c_xz):
    """Expected regressor-noise part of the observed squared error ``|z - X theta|^2``.

    ``theta^T C_xx theta - 2 theta^T c_xz``, with the noise moments of
    :meth:`PropagatedNoise.moments`: what the regressor noise adds to the observed error
    of a fit.

    Parameters
    ----------
    theta : array_like of shape (n,) or (m, n)
        Parameters, or m fits.
    C_xx : numpy.ndarray of shape (n, n) or (m, n, n)
        Expected ``dX^T dX``.
    c_xz : numpy.ndarray of shape (n,) or (m, n)
        Expected ``dX^T dz``.

    Returns
    -------
    float or numpy.ndarray of shape (m,)
        The energy, in the observation's unit squared.
    """
    theta = np.asarray(theta)
    if theta.ndim == 1:
        return float(theta @ C_xx @ theta - 2.0 * theta @ c_xz)
    return (np.einsum("...i,...ij,...j->...", theta, C_xx, theta)
            - 2.0 * np.einsum("...i,...i->...", theta, c_xz))


# ----------------------------------------------------------------------------- covariance


def sandwich_covariance(A_inv: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``A^-1 S A^-1`` (symmetrised): the covariance of the root of ``sum_t psi_t = 0``.

    Parameters
    ----------
    A_inv : numpy.ndarray of shape (n, n)
        Inverse of ``A``, minus the Jacobian of the summed scores.
    S : numpy.ndarray of shape (n, n)
        Covariance of the summed scores.

    Returns
    -------
    numpy.ndarray of shape (n, n)
        The parameter covariance.
    """
    covariance = A_inv @ S @ A_inv
    return 0.5 * (covariance + covariance.T)


def white_noise_covariance(A_inv, s2: float, noise_xx, noise_xv, n_rows: float) -> np.ndarray:
    """Sandwich covariance for white Gaussian row errors (Fuller 1987, Thm 2.3.2).

    The summed scores have covariance ``s^2 A + N (s^2 S_uu - S_uv S_uv^T)``.
    ``A^-1 A A^-1 = A^-1`` is written out: ``s^2 A^-1`` (Vaiopoulos 2017, eq. 4.62) plus
    the term of order (regressor noise / regressor signal)^2.

    Parameters
    ----------
    A_inv : numpy.ndarray of shape (n, n)
        Inverse of the compensated normal matrix.
    s2 : float
        Equation-error variance s^2.
    noise_xx : numpy.ndarray of shape (n, n)
        ``S_uu``, the regressor-noise covariance of one row.
    noise_xv : numpy.ndarray of shape (n,)
        ``S_uv``, its covariance with the equation error.
    n_rows : float
        Number of rows N.

    Returns
    -------
    numpy.ndarray of shape (n, n)
        The parameter covariance.
    """
    second = n_rows * A_inv @ (s2 * noise_xx - np.outer(noise_xv, noise_xv)) @ A_inv
    covariance = s2 * A_inv + second
    return 0.5 * (covariance + covariance.T)


def restricted_inverse(info_eq: np.ndarray, null_dirs: np.ndarray, scale: np.ndarray):
    """Inverse of an information matrix on the complement of unidentifiable directions.

    Parameters
    ----------
    info_eq : numpy.ndarray of shape (n, n)
        Information matrix in equilibrated coordinates (theta_eq = scale * theta).
    null_dirs : numpy.ndarray of shape (m, n)
        Orthonormal raw unidentifiable directions (rows); may be empty.
    scale : numpy.ndarray of shape (n,)
        The equilibration scale.

    Returns
    -------
    numpy.ndarray of shape (n, n)
        The raw covariance factor ``B (B^T I B)^-1 B^T``, B an orthonormal raw basis of
        the complement of ``null_dirs`` (zero along them).
    """
    n = info_eq.shape[0]
    if null_dirs.shape[0] == 0:
        inv_eq = np.linalg.inv(info_eq)
        inv_eq = 0.5 * (inv_eq + inv_eq.T)
        return inv_eq / np.outer(scale, scale)
    m = null_dirs.shape[0]
    q, _ = np.linalg.qr(np.column_stack([null_dirs.T, np.eye(n)]))
    basis = q[:, m:n]  # raw orthonormal complement
    basis_eq = basis * scale[:, None]
    reduced = basis_eq.T @ info_eq @ basis_eq
    cov = basis @ np.linalg.inv(reduced) @ basis.T
    return 0.5 * (cov + cov.T)


def orthonormal_columns(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis (columns) of the range of ``A``.

    Parameters
    ----------
    A : numpy.ndarray of shape (n, m)
        Any matrix.

    Returns
    -------
    numpy.ndarray of shape (n, r)
        r = rank of ``A`` columns; empty if ``A`` has no columns or is zero.
    """
    if A.shape[1] == 0:
        return A
    u, s, _ = np.linalg.svd(A, full_matrices=False)
    return u[:, s > s[0] * 1e-12] if s[0] > 0 else u[:, :0]


# ----------------------------------------------------------------------------- SVD form (TLS)


def excitation_threshold(n_rows: float, n_params: int, snr_min: float, scale: float = 1.0):
    """Singular-value threshold of sufficient excitation (Vaiopoulos 2017, eq. 4.68-4.69).

    ``(1 + S/n) * sqrt(scale * (n_rows - n_params))`` in normalised units: the noise
    energy of a normalised direction is ``scale * (n_rows - n_params)`` (Vaiopoulos 2017,
    eq. 4.67). A direction whose singular value is below it is not excited.

    Parameters
    ----------
    n_rows : float
        Number of rows; may be an effective (forgetting-weighted) row count.
    n_params : int
        Number of parameters.
    snr_min : float
        Smallest signal-to-noise ratio S/n accepted.
    scale : float
        Error-variance scale, 1 when the error covariance is exact.

    Returns
    -------
    float
        The threshold, in the units of the normalised singular values.
    """
    return (1.0 + snr_min) * np.sqrt(scale * max(n_rows - n_params, 0.0))


def weight_matrix(weights) -> np.ndarray | None:
    """The weight matrix W of the minimum-norm choice.

    Parameters
    ----------
    weights : array_like of shape (n, n) or (n,), optional
        A matrix, or its diagonal; None: the identity.

    Returns
    -------
    numpy.ndarray of shape (n, n) or None
        W, or None for the identity.
    """
    if weights is None:
        return None
    w = np.asarray(weights, dtype=float)
    return np.diag(w) if w.ndim == 1 else w


def _null_basis(g: np.ndarray, g_norm: float) -> np.ndarray:
    """Orthonormal basis (m, m-1) of {mu : g^T mu = 0}, from a Householder reflector of g."""
    if g.size == 2:
        return np.array([[-g[1]], [g[0]]]) / g_norm
    v = g.copy()
    v[0] += math.copysign(g_norm, g[0])
    H = np.eye(g.size) - (2.0 / float(v @ v)) * np.outer(v, v)
    return H[:, 1:]


def tls_solution(s, V, C_inv, k: int, weights=None, *, with_directions: bool = True):
    """Weighted minimum-norm TLS solution from the SVD of the normalised augmented matrix.

    With k < n the data excite only k directions, and the estimate is the one of
    least ``||W theta||`` among those that fit (Vaiopoulos 2017, eq. 4.75-4.79).

    Parameters
    ----------
    s : numpy.ndarray of shape (n+1,)
        Singular values in decreasing order.
    V : numpy.ndarray of shape (n+1, n+1)
        Right singular vectors, as columns.
    C_inv : numpy.ndarray of shape (n+1, n+1)
        Inverse error std matrix.
    k : int
        Number of excited directions (<= n); k = n is plain TLS/GTLS (Vaiopoulos 2017,
        eq. 4.61).
    weights : array_like of shape (n, n) or (n,), optional
        W or its diagonal for min ||W theta|| (Vaiopoulos 2017, eq. 4.76); None: identity.
    with_directions : bool
        Also return the unidentifiable directions (else None, faster).

    Returns
    -------
    theta : numpy.ndarray of shape (n,)
        The estimate.
    k_used : int
        The number of directions actually kept (lowered if the kept subspace cannot
        represent ``[theta; -1]``, the non-generic TLS case).
    directions : numpy.ndarray of shape (n - k_used, n) or None
        Orthonormal parameter-space directions (rows) the data do not determine.
    """
    n = V.shape[0] - 1
    Wm = weight_matrix(weights)
    while k >= 0:
        G = C_inv @ V[:, k:]  # solution space of [theta; -1] (Vaiopoulos 2017, eq. 4.75)
        G_theta, g = G[:n], G[n]
        g_norm = math.sqrt(float(g @ g))
        if g_norm > 1e-12 * math.sqrt(float(np.vdot(G, G))):
            if G.shape[1] == 1:
                return -G_theta[:, 0] / g[0], k, np.zeros((0, n))
            # min ||W G_theta mu|| subject to g^T mu = -1 (Vaiopoulos 2017, eq. 4.76-4.79
            # without the big number): mu = mu_p + N nu, mu_p = -g / |g|^2, N an orthonormal
            # basis of {mu : g^T mu = 0}.
            N = _null_basis(g, g_norm)
            mu_p = -g / g_norm**2
            A = G_theta if Wm is None else Wm @ G_theta
            AN = A @ N
            b = A @ mu_p
            if AN.shape[1] == 1:
                a2 = float(AN[:, 0] @ AN[:, 0])
                nu = np.array([-float(AN[:, 0] @ b) / a2 if a2 > 0.0 else 0.0])
            else:
                nu = np.linalg.lstsq(AN, -b, rcond=None)[0]
            theta = G_theta @ (mu_p + N @ nu)
            directions = orthonormal_columns(G_theta @ N).T if with_directions else None
            return theta, k, directions
        k -= 1
    return np.zeros(n), 0, np.eye(n)


def compensated_gram(s, V, C, k: int) -> np.ndarray:
    """``[X0 | z0]^T [X0 | z0]`` estimated from the SVD of the normalised augmented matrix.

    The measured Gram matrix minus the noise energy ``s_min^2`` along every one of the ``k``
    retained singular directions (Vaiopoulos 2017, eq. 4.63): the SVD form of the bias
    compensation, with the noise scale estimated by the smallest singular value.

    Parameters
    ----------
    s : numpy.ndarray of shape (n+1,)
        Singular values in decreasing order.
    V : numpy.ndarray of shape (n+1, n+1)
        Right singular vectors, as columns.
    C : numpy.ndarray of shape (n+1, n+1)
        Error std matrix.
    k : int
        Number of retained directions.

    Returns
    -------
    numpy.ndarray of shape (n+1, n+1)
        The compensated Gram matrix.
    """
    energy = np.clip(s[:k] ** 2 - s[-1] ** 2, 0.0, None)
    CV = C.T @ V[:, :k]
    return (CV * energy) @ CV.T


def tls_covariance(s, V, C, theta, k: int, directions, n_rows: float, scale: float):
    """Asymptotic covariance of the (PCA-)TLS estimate.

    Vaiopoulos 2017, eq. 4.62-4.63, 4.80; Fuller 1987, Thm 2.3.2.

    Parameters
    ----------
    s : numpy.ndarray of shape (n+1,)
        Singular values of the normalised augmented matrix.
    V : numpy.ndarray of shape (n+1, n+1)
        Its right singular vectors, as columns.
    C : numpy.ndarray of shape (n+1, n+1)
        Error std matrix, W_T = C^T C.
    theta : numpy.ndarray of shape (n,)
        The estimate.
    k : int
        Number of kept directions.
    directions : numpy.ndarray of shape (m, n)
        Unidentifiable parameter directions (rows); the covariance is zero along them.
    n_rows : float
        (Effective) number of rows.
    scale : float
        Error-variance scale factor (1 if C is exact).

    Returns
    -------
    covariance : numpy.ndarray of shape (n, n)
        The parameter covariance.
    s2 : float
        Equation-error variance ``scale [theta; -1]^T W_T [theta; -1]``.
    """
    n = theta.size
    W_T = C.T @ C
    w = np.append(theta, -1.0)
    s2 = scale * float(w @ W_T @ w)
    Mxx = compensated_gram(s, V, C, k)[:n, :n]
    d = np.sqrt(np.clip(np.diag(Mxx), 0.0, None))
    d[d == 0.0] = 1.0
    A_inv = restricted_inverse(Mxx / np.outer(d, d), directions, d)
    S_uu = scale * W_T[:n, :n]
    S_uv = scale * (W_T[:n, n] - W_T[:n, :n] @ theta)
    return white_noise_covariance(A_inv, s2, S_uu, S_uv, n_rows), s2
