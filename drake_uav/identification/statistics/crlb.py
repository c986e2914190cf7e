"""Cramer-Rao lower bounds of the linear-regression identification problems (Vaiopoulos 2017,
ch. 4).

Two problems, both ``z = X0 theta + e`` with Gaussian white errors:

* exact regressors (the OLS assumptions, Vaiopoulos 2017, eq. 4.2): the bound is
  ``sigma_z^2 (X^T X)^-1``, attained by OLS (:func:`crlb_ols`);
* errors in variables (Vaiopoulos 2017, eq. 4.30-4.31): the measured
  ``[X | z] = [X0 | X0 theta] + [dX | e]``, rows of the errors i.i.d. N(0, W_T), the true
  regressors ``X0`` unknown (one nuisance vector per row: the functional model). Eliminating
  the nuisance parameters from the Fisher information of row i,
  ``xi_i^T xi_i * (w^T W_T w)^-1`` with ``w = [theta; -1]`` spanning the null space of
  ``[I, theta]``, gives the bound ``s^2 (X0^T X0)^-1``, ``s^2 = [theta; -1]^T W_T [theta; -1]``
  (:func:`crlb_errors_in_variables`). This is Vaiopoulos 2017, eq. 4.62. GTLS approaches it
  when the regressor noise is small against the regressor signal; its asymptotic covariance
  has an extra term of that relative order
  (:func:`~drake_uav.identification.statistics.errors_in_variables.tls_covariance`).

:func:`sample_errors_in_variables` draws Monte-Carlo data sets from the second model (the first
is the special case of zero regressor noise), to compare estimators against the bounds.
"""

from __future__ import annotations

import numpy as np

__all__ = ["crlb_errors_in_variables", "crlb_ols", "sample_errors_in_variables"]


def _regressors(X) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[0] < X.shape[1]:
        raise ValueError(f"X must be (N, n) with N >= n, got shape {X.shape}")
    if not np.isfinite(X).all():
        raise ValueError("X contains NaN or inf")
    return X


def _inverse_gram(X: np.ndarray) -> np.ndarray:
    scale = np.linalg.norm(X, axis=0)
    if np.any(scale == 0.0):
        raise ValueError("X has an all-zero column: the bound is infinite for its parameter")
    r = np.linalg.qr(X / scale, mode="r")
    r_inv = np.linalg.inv(r)
    inv = r_inv @ r_inv.T / np.outer(scale, scale)
    return 0.5 * (inv + inv.T)


def crlb_ols(X, noise_std: float) -> np.ndarray:
    """Cramer-Rao bound (n, n) of theta for exact regressors X (N, n) and white noise on z.

    Parameters
    ----------
    X : array_like
        (N, n) exact regressors.
    noise_std : float
        Standard deviation of the observation noise (units of z).

    Returns
    -------
    ndarray
        (n, n) the bound on the covariance of any unbiased estimate of theta.

    Raises
    ------
    ValueError
        When ``X`` is not (N, n) with N >= n, holds NaN or inf or an all-zero column, or
        ``noise_std`` is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.column_stack([np.ones(100), np.linspace(-1.0, 1.0, 100)])
    >>> float(np.sqrt(crlb_ols(X, 0.1)[0, 0]))   # 0.1 / sqrt(100)
    0.01
    """
    if not noise_std > 0:
        raise ValueError(f"noise_std must be positive, got {noise_std}")
    return noise_std**2 * _inverse_gram(_regressors(X))


def crlb_errors_in_variables(X_true, theta, error_cov) -> np.ndarray:
    """Cramer-Rao bound (n, n) of theta with noisy regressors (functional EIV model).

    Parameters
    ----------
    X_true : array_like
        (N, n) true regressors.
    theta : array_like
        (n,) true parameters.
    error_cov : array_like
        (n+1, n+1) covariance W_T of one row of [dX | e], or its diagonal (n+1,) of
        variances; zero entries mark exact columns.

    Returns
    -------
    ndarray
        (n, n) the bound.

    Raises
    ------
    ValueError
        When the shapes do not match.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.column_stack([np.ones(100), np.linspace(-1.0, 1.0, 100)])
    >>> bound = crlb_errors_in_variables(X, [0.0, 2.0], [0.0, 0.05, 0.05])
    >>> bound.shape
    (2, 2)
    """
    X = _regressors(X_true)
    n = X.shape[1]
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (n,):
        raise ValueError(f"theta must have shape ({n},), got {theta.shape}")
    W = np.asarray(error_cov, dtype=float)
    if W.shape == (n + 1,):
        W = np.diag(W)
    if W.shape != (n + 1, n + 1):
        raise ValueError(f"error_cov must be (n+1,) or (n+1, n+1) with n = {n}, got {W.shape}")
    if np.any(np.linalg.eigvalsh(0.5 * (W + W.T)) < -1e-12 * max(np.abs(W).max(), 1e-300)):
        raise ValueError("error_cov must be positive semidefinite")
    w = np.append(theta, -1.0)
    s2 = float(w @ W @ w)
    if not s2 > 0:
        raise ValueError("the equation error [theta; -1]^T W_T [theta; -1] must be positive")
    return s2 * _inverse_gram(X)


def sample_errors_in_variables(
    X_true, theta, error_std, rng, runs: int | None = None, *, antithetic: bool = False
):
    """Draw measured data sets [X | z] = [X0 | X0 theta] + independent Gaussian column errors.

    Parameters
    ----------
    X_true : array_like
        (N, n) true regressors.
    theta : array_like
        (n,) true parameters.
    error_std : array_like
        (n+1,) error standard deviation of each column of [X | z] (0 = exact).
    rng : numpy.random.Generator
        The only source of randomness.
    runs : int, optional
        Number of data sets; None draws one.
    antithetic : bool
        Draw the runs in pairs with opposite errors (run i + runs/2 has the negated
        errors of run i; ``runs`` must be even). Every run keeps the error distribution;
        the Monte-Carlo mean of an estimator is then free of the sampling noise that is
        odd in the errors, so it shows the estimator's own bias.

    Returns
    -------
    tuple
        (X, z): shapes (N, n) and (N,), or (runs, N, n) and (runs, N) when ``runs`` is
        given.

    Raises
    ------
    ValueError
        For a bad ``error_std`` or an odd number of antithetic runs.

    Examples
    --------
    >>> import numpy as np
    >>> X0 = np.column_stack([np.ones(50), np.linspace(-1.0, 1.0, 50)])
    >>> X, z = sample_errors_in_variables(X0, [0.0, 2.0], [0.0, 0.1, 0.1],
    ...                                   np.random.default_rng(0), runs=4)
    >>> X.shape, z.shape
    ((4, 50, 2), (4, 50))
    """
    X = _regressors(X_true)
    N, n = X.shape
    c = np.asarray(error_std, dtype=float)
    if c.shape != (n + 1,) or np.any(c < 0) or not np.isfinite(c).all():
        raise ValueError(f"error_std must be (n+1,) = ({n + 1},) finite and >= 0")
    y = X @ np.asarray(theta, dtype=float)
    if antithetic:
        if runs is None or runs % 2:
            raise ValueError(f"antithetic sampling needs an even number of runs, got {runs}")
        half = rng.standard_normal((runs // 2, N, n + 1))
        noise = np.concatenate([half, -half])
    else:
        noise = rng.standard_normal((N, n + 1) if runs is None else (runs, N, n + 1))
    noise *= c
    return X + noise[..., :n], y + noise[..., n]
