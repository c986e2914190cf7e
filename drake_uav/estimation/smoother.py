"""Rauch-Tung-Striebel fixed-interval smoother over a forward EKF pass.

Given the forward pass of :func:`~drake_uav.estimation.ekf.filter_pass` (priors
``x-_k, P-_k``, posteriors ``x_k, P_k`` and transition matrices ``Phi_k`` of the steps
``k-1 -> k``), the backward pass (Rauch, Tung & Striebel 1965; Simon 2006, eq. 9.102)

    C_k  = P_k Phi_{k+1}^T (P-_{k+1})^-1
    xs_k = x_k + C_k (xs_{k+1} - x-_{k+1})
    Ps_k = P_k + C_k (Ps_{k+1} - P-_{k+1}) C_k^T

gives every sample the estimate conditioned on the whole record, past and future.
The gains are solved for all samples at once; only the two recursions run sample by
sample.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from drake_uav.estimation.ekf import FilterPass

__all__ = ["SmoothedPass", "rts_smooth"]


@dataclasses.dataclass(frozen=True)
class SmoothedPass:
    """Result of :func:`rts_smooth` over N samples."""

    time: np.ndarray
    """Sample times [s] (N)."""
    state: np.ndarray
    """Smoothed state (N, n)."""
    covariance: np.ndarray
    """Smoothed covariance (N, n, n)."""

    @property
    def std(self) -> np.ndarray:
        """Smoothed standard deviations (N, n)."""
        return np.sqrt(np.einsum("kii->ki", self.covariance))


def rts_smooth(forward: FilterPass) -> SmoothedPass:
    """The Rauch-Tung-Striebel backward pass over ``forward`` (see the module docstring)."""
    x_post, P_post = forward.state, forward.covariance
    x_prior, P_prior = forward.prior_state, forward.prior_covariance
    n = len(x_post)
    xs, Ps = x_post.copy(), P_post.copy()
    if n < 2:
        return SmoothedPass(forward.time, xs, Ps)
    # C_k^T = (P-_{k+1})^-1 Phi_{k+1} P_k (both covariances symmetric).
    gains = np.linalg.solve(P_prior[1:], forward.transition[1:] @ P_post[:-1])
    gains = np.ascontiguousarray(gains.swapaxes(1, 2))
    x_next, P_next = xs[-1], Ps[-1]
    for k in range(n - 2, -1, -1):
        C = gains[k]
        x_next = x_post[k] + C.dot(x_next - x_prior[k + 1])
        P_next = P_post[k] + C.dot(P_next - P_prior[k + 1]).dot(C.T)
        xs[k], Ps[k] = x_next, P_next
    Ps += Ps.swapaxes(1, 2).copy()
    Ps *= 0.5
    return SmoothedPass(forward.time, xs, Ps)
