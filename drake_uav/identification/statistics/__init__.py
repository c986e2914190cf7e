"""Estimators and statistics that know nothing of aircraft: batch and recursive
regression with
errors in the regressors, Cramer-Rao bounds, residual statistics and blocked folds.

* :mod:`.regression`: :func:`~.regression.ols`, :func:`~.regression.tls`,
  :func:`~.regression.pca_tls`, :func:`~.regression.bcls`, one
  :class:`~.regression.RegressionResult`.
* :mod:`.errors_in_variables`: the core those estimators share (noise moments, bias
  compensation, sandwich covariance).
* :mod:`.recursive`: recursive least squares and total least squares with forgetting.
* :mod:`.crlb`: Cramer-Rao bounds.
* :mod:`.residuals`: whiteness, spectrum and drift of a residual.
* :mod:`.blocked_folds`: held-out errors on contiguous blocks (blocked cross-validation).

Nothing here imports the other parts of :mod:`drake_uav.identification`.
"""
