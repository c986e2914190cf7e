"""Recursive (on-line) identification: RLS and recursive TLS with forgetting (Vaiopoulos 2017,
sec. 4.2.3-4.4).

* :class:`RecursiveOLS` -- recursive least squares (Vaiopoulos 2017, eq. 4.22-4.24) with a
  constant forgetting factor (CFF) or the variable forgetting factor (VFF) of
  :class:`VariableForgetting`.
* :class:`RecursiveTLS` -- recursive PCA-GTLS (Vaiopoulos 2017, Algorithms 1-2): the normalised
  augmented matrix is tracked through its singular values and right singular vectors, updated
  by one small SVD per sample (Vaiopoulos 2017, eq. 4.81-4.87); the estimate and its covariance
  are those of the batch (PCA-)TLS, from the shared core
  :mod:`~drake_uav.identification.statistics.errors_in_variables`.

Conventions:

* The forgetting factor ``lambda`` weighs past *squared* residuals by ``lambda`` per sample for
  both estimators (Vaiopoulos 2017, eq. 4.20). The recursive SVD therefore scales the tracked
  rows by ``sqrt(lambda)``; Vaiopoulos 2017, eq. 4.86 scales rows by lambda, i.e. its TLS
  lambda equals our lambda^0.5. :func:`forgetting_time` is Vaiopoulos 2017, eq. 4.93 for this
  weight.
* VFF law: the robust VFF-RLS of Paleologu, Benesty and Ciochina (IEEE Signal Processing
  Letters 15, 2008; Vaiopoulos 2017, ref. [73]) as restated by Vaiopoulos 2017, eq.
  4.107-4.115; see :func:`vff_forgetting`. For TLS the a-priori error uses the measured
  regressors (the TLS-corrected ones of Vaiopoulos 2017, eq. 4.116-4.118 give the same error up
  to a constant factor) and ``q`` is the leverage of the new normalised row in the retained
  singular directions.
* Initialisation (Vaiopoulos 2017, eq. 4.4): diffuse (theta0, P = p0 I); hybrid from a batch
  estimate and its covariance (equivalent to prepending the rows of Vaiopoulos 2017, eq.
  4.123-4.124, resp. 4.125 for TLS); or :meth:`RecursiveOLS.from_batch` with a batch result
  (unidentifiable directions stay diffuse).
* Excitation monitor: ``excitation()`` returns the singular values of the information gathered
  so far in normalised units, the threshold (1 + S/n) sqrt(N_eff - n) of Vaiopoulos 2017, eq.
  4.68 with the forgetting-weighted row count N_eff, and per-parameter identifiability flags.

The whole estimator state lives in one flat float vector (``state``), so a Drake system can keep
it in its discrete state and results are reproducible from it alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from drake_uav.identification.statistics.errors_in_variables import (
    excitation_threshold,
    normalization_matrix,
    tls_covariance,
    tls_solution,
    weight_matrix,
)
from drake_uav.identification.statistics.regression import LOADING_TOL, unidentifiable_loading

_EPS = float(np.finfo(float).eps)

__all__ = [
    "ExcitationStatus",
    "RecursiveHistory",
    "RecursiveOLS",
    "RecursiveTLS",
    "VariableForgetting",
    "forgetting_time",
    "reconvergence_time",
    "vff_forgetting",
]


def forgetting_time(forgetting: float, sample_rate: float, fraction: float = 0.05) -> float:
    """Time [s] after which a sample's weight lambda^(t f_s) falls to ``fraction``
    (Vaiopoulos 2017, eq. 4.93).

    Parameters
    ----------
    forgetting : float
        The forgetting factor lambda in (0, 1).
    sample_rate : float
        [Hz].
    fraction : float
        The weight left.

    Returns
    -------
    float
        [s].

    Raises
    ------
    ValueError
        When ``forgetting`` or ``fraction`` is outside (0, 1) or ``sample_rate`` is not
        positive.

    Examples
    --------
    >>> round(forgetting_time(0.999, 50.0), 1)   # ln(0.05) / (50 ln(0.999))
    59.9
    """
    if not 0.0 < forgetting < 1.0:
        raise ValueError(f"forgetting must be in (0, 1), got {forgetting}")
    if not sample_rate > 0:
        raise ValueError(f"sample_rate must be positive, got {sample_rate}")
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must be in (0, 1), got {fraction}")
    return math.log(fraction) / (sample_rate * math.log(forgetting))


def vff_forgetting(
    sigma_nu: float,
    sigma_eps: float,
    sigma_q: float,
    *,
    gamma: float,
    lambda_max: float,
    varsigma: float,
) -> float:
    """Variable forgetting factor of Vaiopoulos 2017, eq. 4.114-4.115 (Paleologu et al. 2008).

    No model change is declared while sigma_nu <= gamma sigma_eps (lambda_max); otherwise
    min(sigma_q sigma_eps / (varsigma + |sigma_nu - sigma_eps|), lambda_max).

    Parameters
    ----------
    sigma_nu : float
        Short-window std of the a-priori error (units of z).
    sigma_eps : float
        Long-window std of the a-priori error, the noise level (units of z).
    sigma_q : float
        Short-window rms of q = x P x^T.
    gamma : float
        Dead band of the change detection.
    lambda_max : float
        Forgetting factor without a detected change.
    varsigma : float
        Small constant against division by zero (units of z).

    Returns
    -------
    float
        The forgetting factor lambda.
    """
    if sigma_nu <= gamma * sigma_eps:
        return lambda_max
    return min(sigma_q * sigma_eps / (varsigma + abs(sigma_nu - sigma_eps)), lambda_max)


@dataclass(frozen=True)
class VariableForgetting:
    """Settings of the VFF law (Vaiopoulos 2017, eq. 4.109-4.115).

    Vaiopoulos 2017 gives ranges only; how the defaults were chosen is in
    ``docs/identification.md``.

    Attributes
    ----------
    k_e : float
        Short window, lambda_e = 1 - 1/(k_e n) for sigma_nu and sigma_q (k_e >= 2).
    k_eps : float
        Long window, lambda_eps = 1 - 1/(k_eps n) for sigma_eps (k_eps > k_e).
    gamma : float
        Dead band, no change declared while sigma_nu <= gamma sigma_eps (1 < gamma <= 2).
    varsigma : float
        Small constant against division by zero (units of z).
    lambda_max : float
        Forgetting factor without a detected change (1 keeps all data).
    lambda_min : float
        Lower bound on lambda (a safeguard added here; 0 disables it).

    Examples
    --------
    >>> import numpy as np
    >>> rls = RecursiveOLS(1, VariableForgetting(lambda_min=0.9))
    >>> history = rls.run(np.ones((20, 1)), np.full(20, 3.0))
    >>> round(float(rls.theta[0]), 6), history.forgetting.shape
    (3.0, (20,))
    """

    k_e: float = 2.0
    k_eps: float = 20.0
    gamma: float = 2.0
    varsigma: float = 1e-8
    lambda_max: float = 1.0
    lambda_min: float = 0.0

    def validate(self) -> None:
        """Check the settings.

        Raises
        ------
        ValueError
            Naming the first invalid field and its allowed range.
        """
        if not self.k_e >= 2.0:
            raise ValueError(f"k_e must be >= 2, got {self.k_e}")
        if not self.k_eps > self.k_e:
            raise ValueError(f"k_eps must be > k_e, got {self.k_eps}")
        if not 1.0 < self.gamma <= 2.0:
            raise ValueError(f"gamma must be in (1, 2], got {self.gamma}")
        if not self.varsigma > 0:
            raise ValueError(f"varsigma must be positive, got {self.varsigma}")
        if not 0.0 < self.lambda_max <= 1.0:
            raise ValueError(f"lambda_max must be in (0, 1], got {self.lambda_max}")
        if not 0.0 <= self.lambda_min < self.lambda_max:
            raise ValueError(f"lambda_min must be in [0, lambda_max), got {self.lambda_min}")


@dataclass(frozen=True, eq=False)
class ExcitationStatus:
    """On-line excitation monitor output.

    Attributes
    ----------
    singular_values : numpy.ndarray of shape (n,)
        Singular values of the information gathered so far (normalised units, largest first).
    threshold : float
        Excitation threshold (1 + S/n) sqrt(N_eff - n) (Vaiopoulos 2017, eq. 4.68).
    excited : numpy.ndarray of bool, shape (n,)
        True for singular directions above the threshold.
    identifiable : numpy.ndarray of bool, shape (n,)
        True for parameters that do not load on an un-excited direction.
    unidentifiable : numpy.ndarray of shape (n - rank, n)
        Orthonormal parameter-space directions not excited.
    """

    singular_values: np.ndarray
    threshold: float
    excited: np.ndarray
    identifiable: np.ndarray
    unidentifiable: np.ndarray

    @property
    def rank(self) -> int:
        """Number of excited directions."""
        return int(np.sum(self.excited))


@dataclass(frozen=True, eq=False)
class RecursiveHistory:
    """Time histories from :meth:`RecursiveOLS.run` / :meth:`RecursiveTLS.run`.

    Attributes
    ----------
    estimate : numpy.ndarray of shape (N, n)
        Estimate after each sample.
    forgetting : numpy.ndarray of shape (N,)
        Forgetting factor lambda used at each sample.
    """

    estimate: np.ndarray
    forgetting: np.ndarray


def reconvergence_time(time, estimates, truth, t_change: float, band) -> float:
    """Time [s] from ``t_change`` until the estimates stay inside ``band`` of the truth.

    Parameters
    ----------
    time : array_like
        (N,) sample times [s].
    estimates : array_like
        (N, n) the estimates over time.
    truth : array_like
        (N, n) or (n,) true parameters.
    t_change : float
        Time of the parameter change [s].
    band : array_like or float
        (n,) or scalar absolute tolerance.

    Returns
    -------
    float
        The delay [s], or inf if the estimates are outside the band at the last sample.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(10.0)
    >>> reconvergence_time(t, np.where(t < 4, 1.0, 0.0)[:, None], [0.0], 2.0, 0.1)
    2.0
    """
    time = np.asarray(time, dtype=float)
    err = np.abs(np.asarray(estimates, dtype=float) - np.asarray(truth, dtype=float))
    outside = np.any(err > np.asarray(band, dtype=float), axis=1) & (time >= t_change)
    if outside[-1]:
        return math.inf
    idx = np.flatnonzero(outside)
    if idx.size == 0:
        return 0.0
    return float(time[idx[-1] + 1] - t_change)


def _loadings_status(s, threshold, excited, directions, n) -> ExcitationStatus:
    identifiable = unidentifiable_loading(directions, n) <= LOADING_TOL
    return ExcitationStatus(
        singular_values=s,
        threshold=float(threshold),
        excited=excited,
        identifiable=identifiable,
        unidentifiable=directions,
    )


class _Recursive:
    """State vector, forgetting and the common loop of the recursive estimators."""

    # offsets of the trailing scalars, relative to self._scalar0
    _NEFF, _LAM, _SNU2, _SQ2, _SEPS2 = range(5)

    def __init__(self, n_params: int, forgetting, n_head: int, n_extra: int = 0):
        if n_params < 1:
            raise ValueError(f"n_params must be >= 1, got {n_params}")
        self.n = int(n_params)
        if isinstance(forgetting, VariableForgetting):
            forgetting.validate()
            self._vff = forgetting
            lam0 = forgetting.lambda_max
            self._le = 1.0 - 1.0 / (forgetting.k_e * self.n)
            self._leps = 1.0 - 1.0 / (forgetting.k_eps * self.n)
        else:
            lam0 = float(forgetting)
            if not 0.0 < lam0 <= 1.0:
                raise ValueError(f"forgetting must be in (0, 1] or VariableForgetting, got {lam0}")
            self._vff = None
        self._lam_const = lam0
        self._scalar0 = n_head
        self.state = np.zeros(n_head + 5 + n_extra)
        self.theta = self.state[: self.n]
        self._scalars = self.state[n_head : n_head + 5 + n_extra]
        self._scalars[self._LAM] = lam0

    @property
    def state_size(self) -> int:
        """Length of the flat state vector."""
        return self.state.size

    def set_state(self, state) -> None:
        """Overwrite the estimator state with a vector from :attr:`state` (no reallocation).

        Parameters
        ----------
        state : array_like of shape (state_size,)
            A state vector of an estimator of the same settings.
        """
        np.copyto(self.state, state)

    @property
    def estimate(self) -> np.ndarray:
        """Current parameter estimate (copy), (n,)."""
        return self.theta.copy()

    @property
    def forgetting_factor(self) -> float:
        """Forgetting factor used at the last update."""
        return float(self._scalars[self._LAM])

    @property
    def effective_samples(self) -> float:
        """Forgetting-weighted number of data rows N_eff = sum lambda^k."""
        return float(self._scalars[self._NEFF])

    def _forgetting(self, nu: float, q: float) -> float:
        cfg = self._vff
        if cfg is None:
            return self._lam_const
        sc = self._scalars
        nu2 = nu * nu
        if sc[self._SEPS2] == 0.0 and sc[self._SNU2] == 0.0:
            s_nu2 = s_eps2 = nu2
            s_q2 = q * q
        else:
            le, leps = self._le, self._leps
            s_nu2 = le * sc[self._SNU2] + (1.0 - le) * nu2
            s_q2 = le * sc[self._SQ2] + (1.0 - le) * q * q
            s_eps2 = leps * sc[self._SEPS2] + (1.0 - leps) * nu2
        sc[self._SNU2] = s_nu2
        sc[self._SQ2] = s_q2
        sc[self._SEPS2] = s_eps2
        lam = vff_forgetting(
            math.sqrt(s_nu2),
            math.sqrt(s_eps2),
            math.sqrt(s_q2),
            gamma=cfg.gamma,
            lambda_max=cfg.lambda_max,
            varsigma=cfg.varsigma,
        )
        return max(lam, cfg.lambda_min)

    def run(self, X, z) -> RecursiveHistory:
        """Process the rows of ``X`` and ``z`` in order.

        Parameters
        ----------
        X : array_like of shape (N, n)
            Regressor rows.
        z : array_like of shape (N,)
            Observations.

        Returns
        -------
        RecursiveHistory
            The estimate and forgetting factor after each row.

        Raises
        ------
        ValueError
            When the shapes do not match the number of parameters.
        """
        X = np.ascontiguousarray(X, dtype=float)
        z = np.asarray(z, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n or z.shape != (X.shape[0],):
            raise ValueError(f"X must be (N, {self.n}) and z (N,), got {X.shape}, {z.shape}")
        est = np.empty_like(X)
        lam = np.empty(X.shape[0])
        for i in range(X.shape[0]):
            self.update(X[i], float(z[i]))
            est[i] = self.theta
            lam[i] = self._scalars[self._LAM]
        return RecursiveHistory(estimate=est, forgetting=lam)


def _check_vector(name: str, value, n: int) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (n,) or not np.isfinite(v).all():
        raise ValueError(f"{name} must be a finite vector of length {n}, got shape {v.shape}")
    return v


def _check_covariance(name: str, value, n: int) -> np.ndarray:
    P = np.asarray(value, dtype=float)
    if P.shape != (n, n) or not np.isfinite(P).all():
        raise ValueError(f"{name} must be a finite ({n}, {n}) matrix, got shape {P.shape}")
    if not np.allclose(P, P.T, rtol=1e-10, atol=0.0):
        raise ValueError(f"{name} must be symmetric")
    if np.linalg.eigvalsh(P)[0] <= 0.0:
        raise ValueError(f"{name} must be positive definite")
    return 0.5 * (P + P.T)


class RecursiveOLS(_Recursive):
    """Recursive least squares with constant or variable forgetting (Vaiopoulos 2017, eq.
    4.22-4.24, 4.98-4.115).

    Parameters
    ----------
    n_params : int
        Number of parameters n.
    forgetting : float or VariableForgetting
        Constant lambda in (0, 1] or a :class:`VariableForgetting`.
    theta0 : array_like, optional
        Initial estimate (n,), default zeros.
    covariance0 : array_like, optional
        Prior covariance of theta0 (n, n) (hybrid start, Vaiopoulos 2017, eq.
        4.122-4.124); None starts diffuse with P = p0 I.
    noise_std0 : float, optional
        Observation-noise std [units of z] assumed until the data give one; with
        ``covariance0`` it converts it to P = covariance0 / noise_std0^2.
    p0 : float
        Diffuse initial P (per unit regressor^2).
    max_covariance_trace : float
        If trace(P) exceeds this, the sample is not forgotten (lambda = 1), which bounds
        the covariance wind-up of un-excited directions.

    Examples
    --------
    >>> import numpy as np
    >>> rls = RecursiveOLS(2)
    >>> for x in np.linspace(-1.0, 1.0, 50):
    ...     rls.update([1.0, x], 0.5 + 2.0 * x)
    >>> np.round(rls.theta, 3).tolist()
    [0.5, 2.0]
    """

    _J = 5  # weighted residual sum of squares, after the common scalars

    def __init__(
        self,
        n_params: int,
        forgetting: float | VariableForgetting = 1.0,
        *,
        theta0=None,
        covariance0=None,
        noise_std0: float = 1.0,
        p0: float = 1e6,
        max_covariance_trace: float = 1e9,
    ):
        n = int(n_params)
        super().__init__(n, forgetting, n_head=n + n * n, n_extra=1)
        if not noise_std0 > 0:
            raise ValueError(f"noise_std0 must be positive, got {noise_std0}")
        if not p0 > 0:
            raise ValueError(f"p0 must be positive, got {p0}")
        if not max_covariance_trace > 0:
            raise ValueError(f"max_covariance_trace must be positive, got {max_covariance_trace}")
        self.noise_std0 = float(noise_std0)
        self._max_trace = float(max_covariance_trace)
        self.P = self.state[n : n + n * n].reshape(n, n)
        if theta0 is not None:
            self.theta[:] = _check_vector("theta0", theta0, n)
        if covariance0 is None:
            self.P[:] = p0 * np.eye(n)
        else:
            self.P[:] = _check_covariance("covariance0", covariance0, n) / noise_std0**2
            # the n prior rows absorb the n degrees of freedom (Vaiopoulos 2017, eq. 4.123)
            self._scalars[self._NEFF] = n
        self._Px = np.empty(n)
        self._k = np.empty(n)
        self._tmp = np.empty(n)
        self._KP = np.empty((n, n))

    @classmethod
    def from_batch(cls, result, forgetting=1.0, *, p0: float = 1e6, **kwargs) -> RecursiveOLS:
        """Continue a batch :class:`RegressionResult` on-line.

        Hybrid start, Vaiopoulos 2017, eq. 4.4.

        The estimate, P = covariance / noise_std^2, the residual sum of squares and the row count
        are taken over, so with forgetting 1 the recursion continues the batch OLS exactly.
        Unidentifiable directions of the batch result get a diffuse P (``p0``).

        Parameters
        ----------
        result : RegressionResult
            The batch fit.
        forgetting : float or VariableForgetting
            Constant lambda in (0, 1] or a :class:`VariableForgetting`.
        p0 : float
            Diffuse P along the unidentifiable directions (per unit regressor^2).
        **kwargs
            Further arguments of :class:`RecursiveOLS`.

        Returns
        -------
        RecursiveOLS
            The estimator, in the state of the batch fit.
        """
        cov = np.array(result.covariance, dtype=float)
        cov += p0 * result.noise_std**2 * (result.unidentifiable.T @ result.unidentifiable)
        est = cls(
            len(result.names),
            forgetting,
            theta0=result.estimate,
            covariance0=cov,
            noise_std0=result.noise_std,
            p0=p0,
            **kwargs,
        )
        est._scalars[cls._J] = result.noise_std**2 * result.dof
        est._scalars[cls._NEFF] = result.dof + est.n
        return est

    def update(self, x, z: float) -> None:
        """One RLS step with one regressor row and its observation.

        Vaiopoulos 2017, eq. 4.98-4.101.

        Parameters
        ----------
        x : array_like of shape (n,)
            Regressor row.
        z : float
            Observation.
        """
        P, theta, Px, k = self.P, self.theta, self._Px, self._k
        np.dot(P, x, out=Px)
        q = float(np.dot(x, Px))
        nu = z - float(np.dot(x, theta))
        lam = self._forgetting(nu, q)
        if lam < 1.0 and P.trace() > self._max_trace:
            lam = 1.0
        denom = lam + q
        np.multiply(Px, 1.0 / denom, out=k)
        np.multiply(k, nu, out=self._tmp)
        theta += self._tmp
        KP = self._KP
        np.outer(k, Px, out=KP)
        P -= KP
        np.add(P, P.T, out=KP)
        np.multiply(KP, 0.5 / lam, out=P)
        sc = self._scalars
        sc[self._J] = lam * sc[self._J] + nu * nu * lam / denom  # nu * a-posteriori error
        sc[self._NEFF] = lam * sc[self._NEFF] + 1.0
        sc[self._LAM] = lam

    @property
    def noise_std(self) -> float:
        """Observation-noise std estimated from the weighted residuals (noise_std0 before)."""
        dof = self._scalars[self._NEFF] - self.n
        if dof < 1.0:
            return self.noise_std0
        return math.sqrt(max(self._scalars[self._J], 0.0) / dof)

    def covariance(self) -> np.ndarray:
        """Parameter covariance sigma^2 P.

        Returns
        -------
        numpy.ndarray of shape (n, n)
            In the units of theta squared.
        """
        return self.noise_std**2 * self.P.copy()

    def sigma(self) -> np.ndarray:
        """One-sigma parameter uncertainties.

        Returns
        -------
        numpy.ndarray of shape (n,)
            In the units of theta.
        """
        return self.noise_std * np.sqrt(np.clip(np.diag(self.P), 0.0, None))

    def excitation(self, regressor_std, snr_min: float = 1.0) -> ExcitationStatus:
        """Excitation of the regressors seen so far against their noise level.

        The information P^-1, normalised by the regressor noise std, has singular values
        compared with (1 + S/n) sqrt(N_eff - n).

        Parameters
        ----------
        regressor_std : array_like of shape (n,)
            Noise std of each regressor (use a small value for an exact column).
        snr_min : float
            S/n of the excitation test.

        Returns
        -------
        ExcitationStatus
            Singular values, threshold and identifiable parameters.

        Raises
        ------
        ValueError
            When an entry of ``regressor_std`` is not positive.
        """
        c = _check_vector("regressor_std", regressor_std, self.n)
        if not (c > 0).all():
            raise ValueError("regressor_std entries must be positive")
        mu, U = np.linalg.eigh(c[:, None] * self.P * c[None, :])
        order = np.argsort(mu)  # smallest covariance = largest singular value first
        mu, U = np.clip(mu[order], 1e-300, None), U[:, order]
        s = 1.0 / np.sqrt(mu)
        thr = excitation_threshold(self.effective_samples, self.n, snr_min)
        excited = s > thr
        raw = (U[:, ~excited] / c[:, None]).T
        if raw.shape[0]:
            u, sv, _ = np.linalg.svd(raw.T, full_matrices=False)
            raw = u[:, sv > sv[0] * 1e-12].T
        return _loadings_status(s, thr, excited, raw, self.n)


class RecursiveTLS(_Recursive):
    """Recursive PCA-GTLS by recursive SVD (Vaiopoulos 2017, Algorithms 1-2), with CFF or VFF.

    The nine constructor parameters are those of :func:`~.regression.tls` (the error
    model, the excitation test, the minimum-norm weights) plus the forgetting and the
    prior, keyword-only past ``error_std``.

    Parameters
    ----------
    n_params : int
        Number of parameters n.
    error_std : array_like, optional
        (n+1,) positive error stds of the columns of [x | z] (Vaiopoulos 2017, eq. 4.40;
        give a small value such as 1e-6 for an exact column like the constant), or
    error_cov : array_like, optional
        (n+1, n+1) error covariance W_T instead.
    forgetting : float or VariableForgetting
        Constant lambda in (0, 1] or a :class:`VariableForgetting`.
    snr_min : float
        S/n of the excitation test (Vaiopoulos 2017, eq. 4.68).
    weights : array_like, optional
        W of the minimum-norm choice under insufficient excitation (Vaiopoulos 2017,
        eq. 4.76).
    scale_from_data : bool
        Estimate the error-variance scale from the smallest singular value.
    theta0 : array_like, optional
        Initial estimate, kept until more than n rows arrived (unless a prior is given).
    covariance0 : array_like, optional
        Prior covariance of theta0; adds the prior rows of Vaiopoulos 2017, eq. 4.125,
        scaled sqrt(c0) covariance0^-1/2 with c0 = [theta0; -1]^T W_T [theta0; -1] so
        that the prior alone carries exactly covariance0.

    Raises
    ------
    ValueError
        Without ``error_std`` or ``error_cov``.

    Examples
    --------
    >>> import numpy as np
    >>> rtls = RecursiveTLS(2, error_std=[1e-6, 0.01, 0.01])
    >>> for x in np.linspace(-1.0, 1.0, 50):
    ...     rtls.update([1.0, x], 0.5 + 2.0 * x)
    >>> np.round(rtls.theta, 3).tolist(), rtls.rank
    ([0.5, 2.0], 2)
    """

    _RANK = 5  # number of excited directions, after the common scalars

    def __init__(
        self,
        n_params: int,
        error_std=None,
        *,
        error_cov=None,
        forgetting: float | VariableForgetting = 1.0,
        snr_min: float = 1.0,
        weights=None,
        scale_from_data: bool = True,
        theta0=None,
        covariance0=None,
    ):
        n = int(n_params)
        n1 = n + 1
        super().__init__(n, forgetting, n_head=n + n1 + n1 * n1, n_extra=1)
        if error_std is None and error_cov is None:
            raise ValueError("error_std or error_cov is required (use ones for plain TLS)")
        if not snr_min >= 0:
            raise ValueError(f"snr_min must be >= 0, got {snr_min}")
        self.C = normalization_matrix(error_std, error_cov, n1)
        self.C_inv = np.linalg.inv(self.C)
        self.snr_min = float(snr_min)
        self.weights = weight_matrix(weights)
        if self.weights is not None and self.weights.shape != (n, n):
            raise ValueError(f"weights must be ({n},) or ({n}, {n}), got {self.weights.shape}")
        self.scale_from_data = bool(scale_from_data)
        self.s = self.state[n : n + n1]
        self.V = self.state[n + n1 : n + n1 + n1 * n1].reshape(n1, n1)
        self.V[:] = np.eye(n1)
        self._has_prior = covariance0 is not None
        if theta0 is not None:
            self.theta[:] = _check_vector("theta0", theta0, n)
        if self._has_prior:
            cov0 = _check_covariance("covariance0", covariance0, n)
            w = np.append(self.theta, -1.0)
            c0 = float(w @ self.C.T @ self.C @ w)
            evals, evecs = np.linalg.eigh(cov0)
            A = math.sqrt(c0) * (evecs / np.sqrt(evals)) @ evecs.T  # sqrt(c0) cov0^-1/2
            rows = np.column_stack([A, A @ self.theta]) @ self.C_inv
            _, s, vt = np.linalg.svd(rows, full_matrices=True)
            self.s[:n] = s
            self.V[:] = vt.T
            self._scalars[self._RANK] = n
        self._d = np.empty(n1)
        self._ds = np.empty(n1)
        self._pi = np.empty(n1)
        self._Vtmp = np.empty((n1, n1))
        self._v = np.empty(n1)
        self._lev = np.empty(n)
        self._M0 = np.zeros((n1 + 1, n1))
        self._M0_diag = self._M0.reshape(-1)[: n1 * n1 : n1 + 1]  # writable view of the diagonal

    @property
    def rank(self) -> int:
        """Number of excited directions at the last update."""
        return int(self._scalars[self._RANK])

    def _scale(self) -> float:
        dof = self._scalars[self._NEFF] - self.n
        if not self.scale_from_data or dof <= 0.0:
            return 1.0
        return float(self.s[self.n] ** 2 / dof)

    def _threshold(self) -> float:
        """Excitation threshold of Vaiopoulos 2017, eq. 4.68, floored at the SVD's
        numerical resolution."""
        dof = float(self._scalars[self._NEFF]) - self.n
        if dof <= 0.0:
            thr = 0.0
        elif self.scale_from_data:  # (1 + S/n) sqrt(scale * dof) with scale = s_min^2 / dof
            thr = (1.0 + self.snr_min) * float(self.s[self.n])
        else:
            thr = (1.0 + self.snr_min) * math.sqrt(dof)
        return max(thr, (self.n + 1) * _EPS * float(self.s[0]))

    def update(self, x, z: float) -> None:
        """Append the row ``[x, z]`` (Algorithm 2) and re-solve the PCA-GTLS problem (Algorithm 1).

        Parameters
        ----------
        x : array_like of shape (n,)
            Regressor row.
        z : float
            Observation.

        Raises
        ------
        numpy.linalg.LinAlgError
            When LAPACK's SVD fails.
        """
        n = self.n
        d = self._d
        d[:n] = x
        d[n] = z
        np.dot(d, self.C_inv, out=self._ds)  # normalised row d* = d C^-1
        V, s, pi = self.V, self.s, self._pi
        np.dot(self._ds, V, out=pi)  # projection V^T d*^T
        nu = z - float(np.dot(d[:n], self.theta))
        if self._vff is None or s[n - 1] <= 0.0:  # nothing to forget before n rows
            lam = self._lam_const
        else:
            # leverage of the new row in the retained directions (x P x^T of RLS)
            lev = self._lev
            np.divide(pi[:n], s[:n], out=lev)
            q = float(np.dot(lev, lev))
            lam = self._forgetting(nu, q)
        M0 = self._M0
        np.multiply(s, math.sqrt(lam), out=self._M0_diag)
        M0[n + 1] = pi
        _, s_new, vt, info = lapack.dgesvd(M0, compute_uv=1, full_matrices=0)
        if info != 0:
            raise np.linalg.LinAlgError(f"recursive SVD failed (LAPACK info {info})")
        np.dot(V, vt.T, out=self._Vtmp)
        V[:] = self._Vtmp
        s[:] = s_new
        sc = self._scalars
        sc[self._NEFF] = lam * sc[self._NEFF] + 1.0
        sc[self._LAM] = lam
        if sc[self._NEFF] > n or self._has_prior:
            self._solve()

    def _solve(self) -> None:
        n = self.n
        k = int(np.count_nonzero(self.s[:n] > self._threshold()))
        if k == n and self.weights is None:
            v = self._v
            np.dot(self.C_inv, self.V[:, n], out=v)
            vn = float(v[n])
            if abs(vn) > 1e-12 * math.sqrt(float(np.dot(v, v))):
                np.multiply(v[:n], -1.0 / vn, out=self.theta)
                self._scalars[self._RANK] = n
                return
        theta, k, _ = tls_solution(
            self.s, self.V, self.C_inv, k, self.weights, with_directions=False
        )
        self.theta[:] = theta
        self._scalars[self._RANK] = k

    def _directions(self) -> np.ndarray:
        _, _, directions = tls_solution(self.s, self.V, self.C_inv, self.rank, self.weights)
        return directions

    def _covariance(self, directions) -> np.ndarray:
        n_eff = float(self._scalars[self._NEFF])
        cov, _ = tls_covariance(
            self.s, self.V, self.C, self.theta, self.rank, directions, n_eff, self._scale()
        )
        return cov

    def covariance(self) -> np.ndarray:
        """Asymptotic covariance of the current estimate.

        As :func:`~.errors_in_variables.tls_covariance` computes it.

        Returns
        -------
        numpy.ndarray of shape (n, n)
            In the units of theta squared.
        """
        return self._covariance(self._directions())

    def sigma(self) -> np.ndarray:
        """One-sigma uncertainties, inf for parameters on un-excited directions.

        Returns
        -------
        numpy.ndarray of shape (n,)
            In the units of theta.
        """
        directions = self._directions()
        ok = unidentifiable_loading(directions, self.n) <= LOADING_TOL
        cov = self._covariance(directions)
        return np.where(ok, np.sqrt(np.clip(np.diag(cov), 0.0, None)), np.inf)

    @property
    def noise_std(self) -> float:
        """Std of the equation error z - x theta implied by C and the estimated scale."""
        w = np.append(self.theta, -1.0)
        return math.sqrt(self._scale() * float(w @ self.C.T @ self.C @ w))

    def excitation(self) -> ExcitationStatus:
        """Excitation of the tracked augmented matrix at the last update.

        Vaiopoulos 2017, eq. 4.68-4.70.

        Returns
        -------
        ExcitationStatus
            Singular values, threshold and identifiable parameters.
        """
        thr = self._threshold()
        s = self.s[: self.n].copy()
        return _loadings_status(s, thr, s > thr, self._directions(), self.n)
