"""Batch linear-in-the-parameters regression: OLS, TLS/GTLS, PCA-TLS and BCLS (Vaiopoulos 2017,
ch. 4).

The model is ``z = X theta + v`` (Vaiopoulos 2017, eq. 4.3-4.4): ``X`` is the ``N x n``
regressor matrix (one row per sample, usually a constant column first), ``z`` the ``N``
observations (an aerodynamic coefficient), ``theta`` the ``n`` parameters.

* :func:`ols` -- ordinary least squares (Vaiopoulos 2017, eq. 4.2): estimate, covariance
  ``s^2 (X^T X)^-1`` with ``s`` estimated from the residuals, Student-t ratios and
  significance (eq. 4.12-4.13), R^2 (eq. 4.25).
* :func:`tls` -- total least squares when the regressors are noisy too (Vaiopoulos 2017,
  eq. 4.3). With an error standard deviation per column (or a full error covariance
  ``W_T = C^T C``) it is generalised TLS: the augmented matrix ``[X | z]`` is normalised by
  ``C^-1`` and the parameter vector comes from the last right singular vector (eq. 4.54-4.61).
* :func:`pca_tls` -- TLS restricted to the singular directions that the data excite
  (Vaiopoulos 2017, sec. 4.3.6): direction ``j <= n`` is excited when
  ``s_j > (1 + S/n) sqrt(N - n)`` (eq. 4.68-4.70); the parameters are the weighted
  minimum-norm member of the remaining solution space (eq. 4.75-4.79) and the parameter
  combinations the data cannot fix are reported.
* :func:`bcls` -- bias-compensated least squares when the regressor noise is known in
  absolute terms but differs from sample to sample (noise of the air data carried through
  the coefficient isolation), with the long-run sandwich covariance of correlated residuals.

The errors-in-variables pieces (noise moments, bias compensation, sandwich covariance, the
SVD solution of TLS) are in :mod:`drake_uav.identification.statistics.errors_in_variables`.

All return one :class:`RegressionResult`. Data that do not support every parameter (rank
deficiency, ill conditioning, insufficient excitation) never crash and never give a silent huge
number: :func:`ols` and :func:`tls` emit :class:`InsufficientExcitationWarning` and return the
reduced (PCA-style) answer, with ``sigma = inf`` for the parameters that load on an
unidentifiable direction.

Covariance of TLS/GTLS. Vaiopoulos 2017, eq. 4.62 gives ``s^2 (X0^T X0)^-1`` with
``s^2 = [theta; -1]^T W_T [theta; -1]``; that is the Cramer-Rao bound of the
errors-in-variables model (see ``crlb.py``). The estimator's asymptotic covariance adds a
second term of order (regressor noise / regressor signal)^2 (Fuller 1987, Thm 2.3.2); the sum
is returned, so the reported sigma stays honest when the regressor noise is large. ``X0^T X0``
is estimated as ``X^T X`` minus the noise energy ``s_min^2`` along every retained singular
direction (as in Vaiopoulos 2017, eq. 4.63), and the error covariance is known up to a scale
factor estimated from the smallest singular value (``scale_from_data``), the TLS analogue of
the residual variance of OLS; the excitation threshold then reads ``(1 + S/n) s_min``, equal
to Vaiopoulos 2017, eq. 4.68 when the given error covariance is right.
"""

from __future__ import annotations

import inspect
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import stats

from drake_uav.identification.statistics.errors_in_variables import (
    PropagatedNoise,
    compensated_normal_equations,
    excitation_threshold,
    long_run_covariance,
    moment_scores,
    normalization_matrix,
    orthonormal_columns,
    restricted_inverse,
    sandwich_covariance,
    solve_normal_equations,
    tls_covariance,
    tls_solution,
    weight_matrix,
)

__all__ = [
    "f_survival",
    "regression_result",
    "IdentificationWarning",
    "InsufficientExcitationWarning",
    "RegressionResult",
    "bcls",
    "ols",
    "pca_tls",
    "r_factor",
    "tls",
    "unidentifiable_loading",
]

#: A parameter whose unit vector has a squared projection above this on the unidentifiable
#: subspace (raw parameter coordinates) is reported as not identifiable (sigma = inf).
LOADING_TOL = 0.01

#: Relative singular-value floor of the column-equilibrated OLS regressor matrix below which a
#: direction is treated as unsupported (it carries < 1e-12 of the regressor energy).
OLS_RCOND = 1e-6

#: Error std used for a column declared exact (std 0) in batch TLS: this fraction of the column's
#: root-mean-square value (Vaiopoulos 2017, eq. 4.41 uses "a small positive number" for the
# constant column).
EXACT_COLUMN_REL = 1e-6


class IdentificationWarning(UserWarning):
    """Base class of the warnings of the identification package.

    Filter on it to silence or catch every warning of the package at once.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("error", IdentificationWarning)
    ...     try:
    ...         warnings.warn("too little excitation", InsufficientExcitationWarning)
    ...     except IdentificationWarning as caught:
    ...         print(type(caught).__name__)
    InsufficientExcitationWarning
    """


class InsufficientExcitationWarning(IdentificationWarning):
    """The data do not support every parameter (rank deficient, ill conditioned or under-excited).

    The estimator returned the reduced answer: it estimates what the data support and lists the
    parameter combinations it could not identify in ``RegressionResult.unidentifiable``.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> x = np.linspace(-1.0, 1.0, 50)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     fit = ols(np.column_stack([x, x]), 2.0 * x)     # two copies of one column
    >>> caught[0].category.__name__, fit.rank
    ('InsufficientExcitationWarning', 1)
    """


@dataclass(frozen=True, eq=False)
class RegressionResult:
    """Estimate and statistics of one linear regression, whatever the method.

    Returned by :func:`ols`, :func:`tls`, :func:`pca_tls` and :func:`bcls`.

    Attributes
    ----------
    method : str
        "OLS", "TLS", "GTLS", "PCA-TLS" (TLS/GTLS reduced to the excited directions) or
        "BCLS".
    names : tuple of str
        Parameter names, length n.
    estimate : numpy.ndarray of shape (n,)
        Parameter vector theta, units of z per unit of each regressor.
    covariance : numpy.ndarray of shape (n, n)
        Parameter covariance of the identifiable part (zero along ``unidentifiable``).
    sigma : numpy.ndarray of shape (n,)
        One-standard-deviation uncertainty of each parameter; inf when not identifiable.
    t_statistic : numpy.ndarray of shape (n,)
        theta / sigma, 0 where sigma is inf (Vaiopoulos 2017, eq. 4.12).
    significant : numpy.ndarray of bool, shape (n,)
        |t| above the two-sided Student-t quantile with ``dof`` degrees of freedom.
    identifiable : numpy.ndarray of bool, shape (n,)
        False for parameters loading on an unidentifiable direction.
    noise_std : float
        Estimated standard deviation of the equation error z - X theta (units of z).
    r_squared : float
        Coefficient of determination 1 - SSE/SST (equals Vaiopoulos 2017, eq. 4.25 for OLS
        with a constant column); nan when z is constant.
    residual : numpy.ndarray of shape (N,)
        z - X theta, with the measured regressors.
    dof : int
        Degrees of freedom N - rank.
    rank : int
        Number of parameter directions the data support (n when fully identifiable).
    singular_values : numpy.ndarray
        Of the column-equilibrated X (OLS) or of the normalised [X | z] (TLS).
    excitation_threshold : float
        Singular-value threshold used to count supported directions.
    condition_number : float
        Condition number of the column-equilibrated (normalised) regressor matrix, inf if
        singular.
    unidentifiable : numpy.ndarray of shape (n - rank, n)
        Orthonormal parameter-space directions the data do not fix.
    t_critical : float
        The Student-t quantile used for ``significant``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.linspace(-1.0, 1.0, 50)
    >>> fit = ols(np.column_stack([np.ones(50), x]), 1.0 + 3.0 * x, names=["c", "slope"])
    >>> fit.names, fit.rank, bool(fit.identifiable.all())
    (('c', 'slope'), 2, True)
    """

    method: str
    names: tuple[str, ...]
    estimate: np.ndarray
    covariance: np.ndarray
    sigma: np.ndarray
    t_statistic: np.ndarray
    significant: np.ndarray
    identifiable: np.ndarray
    noise_std: float
    r_squared: float
    residual: np.ndarray
    dof: int
    rank: int
    singular_values: np.ndarray
    excitation_threshold: float
    condition_number: float
    unidentifiable: np.ndarray
    t_critical: float

    def __getitem__(self, name: str) -> float:
        """Estimate of the parameter called ``name``."""
        return float(self.estimate[self.names.index(name)])

    def table(self) -> str:
        """Plain-text table of the estimate: name, estimate, +-1 sigma, t, significant.

        Returns
        -------
        str
            One header line and one line per parameter.
        """
        lines = [
            f"{self.method}: R^2 = {self.r_squared:.4f}, noise std = {self.noise_std:.4g}, "
            f"rank {self.rank}/{len(self.names)}, cond = {self.condition_number:.3g}",
            f"{'parameter':>12} {'estimate':>11} {'+-1 sigma':>11} {'t':>9}  significant",
        ]
        for i, name in enumerate(self.names):
            lines.append(
                f"{name:>12} {self.estimate[i]:11.5f} {self.sigma[i]:11.5f} "
                f"{self.t_statistic[i]:9.2f}  {'yes' if self.significant[i] else 'no'}"
            )
        for direction in self.unidentifiable:
            terms = " ".join(f"{c:+.3f}*{n}" for c, n in zip(direction, self.names, strict=True))
            lines.append(f"  not identifiable: {terms}")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- helpers


def f_survival(f_stat, dfn, dfd):
    """P(F > f_stat) of the F distribution with (dfn, dfd) degrees of freedom.

    Parameters
    ----------
    f_stat : float or array_like
        The F statistic(s).
    dfn : float or array_like
        Numerator degrees of freedom.
    dfd : float or array_like
        Denominator degrees of freedom.

    Returns
    -------
    float or numpy.ndarray
        The survival probability, elementwise (a float for scalars).
    """
    from scipy.special import fdtrc

    return fdtrc(dfn, dfd, f_stat)


def _as_data(X, z) -> tuple[np.ndarray, np.ndarray]:
    X = np.asarray(X, dtype=float)
    z = np.asarray(z, dtype=float)
    if X.ndim != 2:
        raise ValueError(f"X must be a 2-D regressor matrix (N, n), got shape {X.shape}")
    if z.shape != (X.shape[0],):
        raise ValueError(f"z must have shape ({X.shape[0]},) to match X, got {z.shape}")
    if X.shape[0] <= X.shape[1]:
        raise ValueError(f"need more samples than parameters: X has shape {X.shape}")
    if not np.isfinite(X).all():
        raise ValueError("X contains NaN or inf")
    if not np.isfinite(z).all():
        raise ValueError("z contains NaN or inf")
    return X, z


def _names(names, n: int) -> tuple[str, ...]:
    if names is None:
        return tuple(f"theta{i}" for i in range(n))
    names = tuple(str(s) for s in names)
    if len(names) != n:
        raise ValueError(f"names has {len(names)} entries for {n} parameters")
    return names


def r_factor(A: np.ndarray, chunk: int = 512) -> np.ndarray:
    """Upper-triangular R with R^T R = A^T A, by QR of row blocks then of the stacked R's.

    Block (tall-skinny) QR is as stable as one QR of A and faster for long flight records:
    LAPACK on a few hundred rows stays in cache and single-threaded, while a multi-threaded
    BLAS can spend far longer synchronising its threads on one tall factorisation than
    computing it.

    Parameters
    ----------
    A : numpy.ndarray of shape (N, n)
        The matrix.
    chunk : int
        Rows per block.

    Returns
    -------
    numpy.ndarray of shape (min(N, n), n)
        R.
    """
    if A.shape[0] <= chunk:
        return np.linalg.qr(A, mode="r")
    blocks = [np.linalg.qr(A[i : i + chunk], mode="r") for i in range(0, A.shape[0], chunk)]
    return np.linalg.qr(np.vstack(blocks), mode="r")


def unidentifiable_loading(directions: np.ndarray, n: int) -> np.ndarray:
    """Squared projection of each parameter axis on the unidentifiable subspace.

    Parameters
    ----------
    directions : numpy.ndarray of shape (m, n)
        Orthonormal unidentifiable directions (rows); may be empty.
    n : int
        Number of parameters.

    Returns
    -------
    numpy.ndarray of shape (n,)
        In [0, 1]: 0 for a parameter the data fix, 1 for one they do not touch.
    """
    if directions.size == 0:
        return np.zeros(n)
    return np.sum(directions**2, axis=0)


# ----------------------------------------------------------------------------- OLS


def ols(X, z, names=None, *, confidence: float = 0.95, rcond: float = OLS_RCOND):
    """Ordinary least squares with statistics (Vaiopoulos 2017, eq. 4.2, A.10).

    Parameters
    ----------
    X : array_like
        (N, n) regressors, assumed exact.
    z : array_like
        (N,) observations.
    names : sequence of str, optional
        Parameter names (default theta0..).
    confidence : float
        Two-sided level of the significance test (0.95 -> |t| > ~1.96).
    rcond : float
        Directions of the column-equilibrated X with singular value below
        ``rcond * s_max`` are unsupported: they trigger an
        :class:`InsufficientExcitationWarning` and the minimum-norm answer.

    Returns
    -------
    RegressionResult
        Method "OLS".

    Raises
    ------
    ValueError
        When the shapes of ``X`` and ``z`` do not match.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> X = np.column_stack([np.ones(200), rng.normal(size=200)])
    >>> fit = ols(X, X @ [0.5, 2.0] + 0.01 * rng.normal(size=200), names=["c", "slope"])
    >>> np.round(fit.estimate, 2).tolist()
    [0.5, 2.0]
    """
    X, z = _as_data(X, z)
    N, n = X.shape
    names = _names(names, n)
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0.0] = 1.0
    # QR of the augmented, equilibrated matrix: R[:n,:n] is R of X/scale, R[:n, n] = Q^T z.
    R = r_factor(np.column_stack([X / scale, z]))
    u, s, vt = np.linalg.svd(R[:n, :n])
    rank = int(np.sum(s > rcond * s[0])) if s[0] > 0 else 0
    qtz = u[:, :rank].T @ R[:n, n]
    theta = (vt[:rank].T @ (qtz / s[:rank])) / scale
    directions = orthonormal_columns((vt[rank:] / scale).T).T
    if rank < n:
        warnings.warn(
            f"OLS: regressors support only {rank} of {n} parameter directions "
            f"(equilibrated condition number {s[0] / max(s[-1], 1e-300):.3g}); "
            "returning the minimum-norm estimate",
            InsufficientExcitationWarning,
            stacklevel=2,
        )
        theta = theta - directions.T @ (directions @ theta)
    residual = z - X @ theta
    dof = N - rank
    noise_var = float(residual @ residual) / dof
    info_equilibrated = R[:n, :n].T @ R[:n, :n]
    cov_unit = restricted_inverse(info_equilibrated, directions, scale)
    return regression_result(
        method="OLS",
        names=names,
        theta=theta,
        covariance=noise_var * cov_unit,
        noise_std=np.sqrt(noise_var),
        residual=residual,
        z=z,
        dof=dof,
        rank=rank,
        singular_values=s,
        threshold=rcond * s[0],
        condition=s[0] / s[-1] if s[-1] > 0 else np.inf,
        directions=directions,
        confidence=confidence,
    )


def regression_result(
    *,
    method,
    names,
    theta,
    covariance,
    noise_std,
    residual,
    z,
    dof,
    rank,
    singular_values,
    threshold,
    condition,
    directions,
    confidence,
):
    """The common :class:`RegressionResult` (significance, R^2, identifiability) of an estimate.

    Keyword-only, one parameter per field of the result the estimators compute: each
    estimator fills them from its own decomposition, so no smaller grouping is shared by
    all of them.

    Parameters
    ----------
    method : str
        Name of the estimator.
    names : sequence of str
        Parameter names.
    theta : numpy.ndarray of shape (n,)
        The estimate.
    covariance : numpy.ndarray of shape (n, n)
        Its covariance.
    noise_std : float
        Equation-error std (units of z).
    residual : numpy.ndarray of shape (N,)
        z - X theta.
    z : numpy.ndarray of shape (N,)
        The observation (for R^2).
    dof : int
        Degrees of freedom.
    rank : int
        Number of supported parameter directions.
    singular_values : array_like
        Singular values of the (normalised) design.
    threshold : float
        Excitation threshold on them.
    condition : float
        Condition number of the design.
    directions : numpy.ndarray of shape (n - rank, n)
        Unidentifiable directions.
    confidence : float
        Two-sided confidence level of the significance test, in (0, 1).

    Returns
    -------
    RegressionResult
        The result.
    """
    n = theta.size
    identifiable = unidentifiable_loading(directions, n) <= LOADING_TOL
    sigma = np.where(identifiable, np.sqrt(np.clip(np.diag(covariance), 0.0, None)), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.isfinite(sigma) & (sigma > 0), theta / sigma, 0.0)
    t_crit = float(stats.t.ppf(0.5 + 0.5 * confidence, max(dof, 1)))
    zc = z - z.mean()
    sst = float(zc @ zc)
    r2 = 1.0 - float(residual @ residual) / sst if sst > 0 else float("nan")
    return RegressionResult(
        method=method,
        names=names,
        estimate=theta,
        covariance=covariance,
        sigma=sigma,
        t_statistic=t,
        significant=(np.abs(t) > t_crit) & identifiable,
        identifiable=identifiable,
        noise_std=float(noise_std),
        r_squared=r2,
        residual=residual,
        dof=int(dof),
        rank=int(rank),
        singular_values=np.asarray(singular_values, dtype=float),
        excitation_threshold=float(threshold),
        condition_number=float(condition),
        unidentifiable=directions,
        t_critical=t_crit,
    )


# ----------------------------------------------------------------------------- TLS


def _tls(X, z, error_std, error_cov, names, snr_min, weights, confidence, scale_from_data, warn):
    """:func:`tls` (its parameters, and ``warn``: warn when a direction is not excited);
    :func:`pca_tls` calls it without the warning."""
    X, z = _as_data(X, z)
    N, n = X.shape
    names = _names(names, n)
    if snr_min < 0:
        raise ValueError(f"snr_min must be >= 0, got {snr_min}")
    Wm = weight_matrix(weights)
    if Wm is not None and Wm.shape != (n, n):
        raise ValueError(f"weights must be ({n},) or ({n}, {n}), got {np.shape(weights)}")
    D = np.column_stack([X, z])
    if error_std is not None:
        c = np.asarray(error_std, dtype=float).copy()
        if c.shape == (n + 1,) and np.isfinite(c).all() and (c >= 0).all():
            rms = np.sqrt(np.mean(D**2, axis=0))
            exact = c == 0.0
            c[exact] = EXACT_COLUMN_REL * np.where(rms[exact] > 0, rms[exact], 1.0)
        error_std = c
    method = "TLS" if error_std is None and error_cov is None else "GTLS"
    C = normalization_matrix(error_std, error_cov, n + 1)
    C_inv = np.linalg.inv(C)
    R = r_factor(D @ C_inv)
    _, s, vt = np.linalg.svd(R)
    # R[:n, :n] is the R factor of the normalised regressors X C_xx^-1 (C is upper triangular)
    Rx = R[:n, :n] / np.maximum(np.linalg.norm(R[:n, :n], axis=0), 1e-300)
    sx = np.linalg.svd(Rx, compute_uv=False)
    V = vt.T
    noise_energy = s[-1] ** 2
    scale = noise_energy / (N - n) if scale_from_data else 1.0
    threshold = excitation_threshold(N, n, snr_min, scale)
    floor = (n + 1) * np.finfo(float).eps * s[0]
    k = int(np.sum(s[:n] > max(threshold, floor)))
    theta, k, directions = tls_solution(s, V, C_inv, k, Wm)
    if k < n:
        method = "PCA-TLS"
        if warn:
            warnings.warn(
                f"TLS: only {k} of {n} parameter directions are excited above the threshold "
                f"(S/n = {snr_min}); returning the PCA-TLS estimate",
                InsufficientExcitationWarning,
                stacklevel=3,
            )
    covariance, s2 = tls_covariance(s, V, C, theta, k, directions, N, scale)
    return regression_result(
        method=method,
        names=names,
        theta=theta,
        covariance=covariance,
        noise_std=np.sqrt(s2),
        residual=z - X @ theta,
        z=z,
        dof=N - k,
        rank=k,
        singular_values=s,
        threshold=threshold,
        condition=sx[0] / sx[-1] if sx[-1] > 0 else np.inf,
        directions=directions,
        confidence=confidence,
    )


def tls(
    X,
    z,
    error_std=None,
    *,
    error_cov=None,
    names=None,
    snr_min: float = 1.0,
    weights=None,
    confidence: float = 0.95,
    scale_from_data: bool = True,
):
    """Total least squares / generalised TLS via SVD (Vaiopoulos 2017, eq. 4.3, A.13).

    The nine parameters are the estimator's published inputs (the data, the error model,
    the excitation test and the minimum-norm weights); keyword-only past ``error_std``.

    Parameters
    ----------
    X : array_like
        (N, n) measured regressors.
    z : array_like
        (N,) measured observations.
    error_std : array_like, optional
        (n+1,) error standard deviations of the columns of [X | z] (units of each
        column); 0 marks an exact column (the constant), replaced by 1e-6 of its rms.
    error_cov : array_like, optional
        (n+1, n+1) full error covariance W_T instead of ``error_std``. Neither: plain TLS
        (C = I).
    names : sequence of str, optional
        Parameter names.
    snr_min : float
        S/n of the excitation test (Vaiopoulos 2017, eq. 4.68, typically 1..10).
    weights : array_like, optional
        W of the minimum-norm choice if some direction is not excited (Vaiopoulos 2017,
        eq. 4.76).
    confidence : float
        Level of the significance test.
    scale_from_data : bool
        Estimate the error-variance scale from the smallest singular value (C known up
        to a factor); False trusts C exactly.

    Returns
    -------
    RegressionResult
        Method "TLS"/"GTLS"; if a direction is not excited, warns
        (:class:`InsufficientExcitationWarning`) and returns the PCA-TLS answer.

    Raises
    ------
    ValueError
        When the shapes do not match or an error standard deviation is negative.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> x = rng.normal(size=500)
    >>> X = np.column_stack([np.ones(500), x + 0.05 * rng.normal(size=500)])
    >>> fit = tls(X, 2.0 * x + 0.05 * rng.normal(size=500), error_std=[0.0, 0.05, 0.05])
    >>> round(float(fit.estimate[1]), 1)
    2.0
    """
    return _tls(
        X, z, error_std, error_cov, names, snr_min, weights, confidence, scale_from_data, True
    )


def pca_tls(X, z, error_std=None, **options):
    """PCA-TLS: GTLS restricted to the excited singular directions (Vaiopoulos 2017, sec.
    4.3.6, A.14).

    Estimates only what the data support, without a warning: ``result.rank`` directions
    are kept, ``result.unidentifiable`` lists the parameter combinations left at their
    weighted minimum norm and ``result.identifiable`` / ``result.sigma`` (inf) mark the
    parameters involved.

    Parameters
    ----------
    X, z, error_std
        As :func:`tls`.
    **options
        The keyword options of :func:`tls`.

    Returns
    -------
    RegressionResult
        Method "PCA-TLS" when rank < n, otherwise "TLS"/"GTLS".

    Raises
    ------
    ValueError
        As :func:`tls`.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.linspace(-1.0, 1.0, 100)
    >>> fit = pca_tls(np.column_stack([x, x]), 2.0 * x)    # two copies of one column
    >>> fit.rank
    1
    """
    arguments = inspect.signature(tls).bind(X, z, error_std, **options)
    arguments.apply_defaults()
    return _tls(**arguments.arguments, warn=False)


pca_tls.__signature__ = inspect.signature(tls)


# ----------------------------------------------------------------------------- BCLS


def bcls(X, z, noise: PropagatedNoise, *, names=None, confidence: float = 0.95,
         scores_covariance=None) -> RegressionResult:
    """Bias-compensated least squares with a sandwich covariance (method "BCLS").

    Parameters
    ----------
    X : array_like
        (N, n) measured regressors.
    z : array_like
        (N,) measured observations.
    noise : PropagatedNoise
        The regressor and observation noise propagated from its sources
        (:class:`~.errors_in_variables.PropagatedNoise`), with known variances.
    names : sequence of str, optional
        Parameter names.
    confidence : float
        Level of the significance test.
    scores_covariance : array_like, optional
        (n, n) covariance ``S`` of the summed moment scores; default: their long-run
        (Newey-West) covariance estimated here.

    Returns
    -------
    RegressionResult
        The root of the compensated normal equations
        (:func:`~.errors_in_variables.compensated_normal_equations`) with covariance
        ``A^-1 S A^-1``. The residual of smoothed flight data is correlated over several
        samples (the smoothing window, turbulence), so ``S`` is the long-run covariance,
        not the white-residual one, which would understate sigma.

    Raises
    ------
    ValueError
        When the shapes of ``X``, ``z`` and ``noise`` do not match.

    Examples
    --------
    >>> import numpy as np
    >>> from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise
    >>> rng = np.random.default_rng(2)
    >>> x = rng.normal(size=1000)
    >>> X = np.column_stack([np.ones(1000), x + 0.3 * rng.normal(size=1000)])
    >>> noise = PropagatedNoise(2, {"x": np.tile([0.0, 1.0], (1000, 1))}, {}, {"x": 0.09})
    >>> fit = bcls(X, 1.5 * x, noise)
    >>> round(float(fit.estimate[1]), 1)
    1.5
    """
    X, z = _as_data(X, z)
    n, p = X.shape
    A, b = compensated_normal_equations(X, z, noise)
    theta = solve_normal_equations(A, b)
    residual = z - X @ theta
    if scores_covariance is None:
        scores_covariance = long_run_covariance(moment_scores(X, z, theta, noise))
    covariance = sandwich_covariance(np.linalg.pinv(A), scores_covariance)
    s = np.linalg.svd(r_factor(X / np.maximum(np.linalg.norm(X, axis=0), 1e-300)),
                      compute_uv=False)
    return regression_result(
        method="BCLS", names=_names(names, p), theta=theta, covariance=covariance,
        noise_std=np.sqrt(float(residual @ residual) / max(n - p, 1)), residual=residual,
        z=z, dof=n - p, rank=p, singular_values=s, threshold=0.0,
        condition=s[0] / max(s[-1], 1e-300), directions=np.zeros((0, p)),
        confidence=confidence)
