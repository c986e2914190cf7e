"""One coefficient's regression with its noise model, as the discovery loop fits it.

The columns of a candidate come with their derivatives with respect to the noise sources
(:func:`columns_and_jacobians`), which the errors-in-variables fits read
(:class:`~drake_uav.identification.statistics.errors_in_variables.PropagatedNoise`); :class:`Design`
is one coefficient's regression on some samples with that noise model;
:func:`baseline_design` the catalog's structure of a coefficient; :func:`fit_derivatives`
the whole aircraft's derivatives from one flight, with their joint covariance.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from drake_uav.identification.propulsion import thrust_correction_columns
from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.regressor_noise import (
    AIR_DATA_SOURCES,
    noise_sources,
    observation_sensitivity,
    perturbed,
    source_step,
    source_variances,
)
from drake_uav.identification.statistics.errors_in_variables import (
    BlockMoments,
    PropagatedNoise,
    compensated_normal_equations,
    long_run_covariance,
    moment_scores,
    sandwich_covariance,
    solve_normal_equations,
)
from drake_uav.identification.statistics.regression import RegressionResult, bcls
from drake_uav.model.coefficients import COEFFICIENTS, regressor_matrix
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["ColumnFunction", "Perturbations", "columns_and_jacobians", "Design",
           "baseline_names", "baseline_design", "IdentifiedDerivatives", "fit_derivatives"]

ColumnFunction = Callable[[AeroSamples], Mapping[str, np.ndarray]]


class Perturbations:
    """Samples and their copies with one noise source moved by +-its step.

    The copies (:func:`~drake_uav.identification.samples.regressor_noise.perturbed`) and
    the probe, every source but the air data moved at once, which tells the columns that
    depend on none of them (most) from the others. The copies are made once and shared by
    every column function evaluated on them; calling the object with ``(source, step)``
    gives the copy with ``source`` moved by ``step``.

    Parameters
    ----------
    samples : AeroSamples
        The samples perturbed.
    """

    def __init__(self, samples: AeroSamples):
        self.samples = samples
        self._copies: dict[tuple, AeroSamples] = {}

    def __call__(self, source: str, step: float) -> AeroSamples:
        key = (source, step)
        if key not in self._copies:
            self._copies[key] = perturbed(self.samples, source, step)
        return self._copies[key]

    def probe(self, sources: tuple[str, ...]) -> AeroSamples:
        """The samples with every one of ``sources`` moved by its step.

        Parameters
        ----------
        sources : tuple of str
            The noise sources moved.

        Returns
        -------
        AeroSamples
            The moved copy (made once).
        """
        if sources not in self._copies:
            moved = self.samples
            for source in sources:
                moved = perturbed(moved, source, source_step(source))
            self._copies[sources] = moved
        return self._copies[sources]


def columns_and_jacobians(function: ColumnFunction, samples: AeroSamples | Perturbations,
                           variance):
    """Columns of ``function(samples)`` and their derivatives with respect to the noise sources.

    The air data always, the other sources of ``variance`` (rates, derivatives) where a
    column depends on them, by central differences.

    Parameters
    ----------
    function : callable
        ``function(samples) -> {column name: (N,) values}``.
    samples : AeroSamples or Perturbations
        The samples (a :class:`Perturbations` shares its copies between calls).
    variance : Mapping[str, float]
        Noise source -> variance; its keys are the sources differentiated.

    Returns
    -------
    columns : dict of str to numpy.ndarray
        Column name -> (N,) values.
    jacobians : dict of str to dict of str to numpy.ndarray
        Source -> column name -> (N,) derivative of the column by the source.
    """
    variants = samples if isinstance(samples, Perturbations) else Perturbations(samples)
    columns = dict(function(variants.samples))
    sources = [s for s in AIR_DATA_SOURCES if variance.get(s, 0.0) > 0.0]
    others = tuple(s for s in noise_sources(variance)
                   if s not in AIR_DATA_SOURCES and variance[s] > 0.0)
    probe = function(variants.probe(others)) if others else columns
    if any(not np.array_equal(probe[k], v) for k, v in columns.items()):
        sources += others
    jac = {}
    for signal in sources:
        step = source_step(signal)
        up = function(variants(signal, step))
        if signal not in AIR_DATA_SOURCES and all(np.array_equal(up[k], v)
                                                  for k, v in columns.items()):
            continue
        down = function(variants(signal, -step))
        jac[signal] = {k: (up[k] - down[k]) / (2.0 * step) for k in columns}
    return columns, jac


@dataclasses.dataclass
class Design:
    """One coefficient's regression on some samples, with its noise model.

    The estimator is :func:`~drake_uav.identification.statistics.regression.bcls`; this
    class adds the bookkeeping of the loop (added columns, folds, noise-corrected errors).

    Attributes
    ----------
    names : list of str
        Column names.
    X : numpy.ndarray of shape (N, n)
        Regressor columns.
    z : numpy.ndarray of shape (N,)
        The measured coefficient.
    noise : PropagatedNoise
        The noise of the columns and of the coefficient.
    """

    names: list[str]
    X: np.ndarray
    z: np.ndarray
    noise: PropagatedNoise

    def extended(self, columns: Mapping[str, np.ndarray], jac, prefix: str = "") -> Design:
        """The design with added columns.

        Parameters
        ----------
        columns : Mapping[str, numpy.ndarray]
            Column name -> (N,) values.
        jac : Mapping[str, Mapping[str, numpy.ndarray]]
            Noise source -> column name -> (N,) derivative (:func:`columns_and_jacobians`).
        prefix : str
            Put before the added column names (``"<effect>:"``).

        Returns
        -------
        Design
            The extended design.
        """
        names = [f"{prefix}{k}" for k in columns]
        X = np.column_stack([self.X, *columns.values()])
        added = {s: np.column_stack([jac[s][k] for k in columns]) for s in jac}
        return Design(self.names + names, X, self.z, self.noise.extended(added, len(columns)))

    def without(self, prefix: str) -> Design:
        """The design without the columns whose names start with ``prefix``.

        Parameters
        ----------
        prefix : str
            Name prefix of the columns removed.

        Returns
        -------
        Design
            The reduced design.
        """
        return self.keeping([name for name in self.names if not name.startswith(prefix)])

    def keeping(self, names: Sequence[str]) -> Design:
        """The design with only the columns ``names``, in its own order.

        Parameters
        ----------
        names : sequence of str
            The columns kept.

        Returns
        -------
        Design
            The reduced design.
        """
        keep = [i for i, name in enumerate(self.names) if name in names]
        noise = PropagatedNoise(len(keep), {s: J[:, keep] for s, J in
                                            self.noise.regressors.items()},
                                self.noise.observation, self.noise.variance)
        return Design([self.names[i] for i in keep], self.X[:, keep], self.z, noise)

    def with_fixed(self, values: Mapping[str, float]) -> Design:
        """The design with the columns ``values`` names fixed at those values, not fitted.

        Their part moves to the measured side, ``z - sum_j v_j x_j``, and so does the noise
        it carries: each source's observation sensitivity loses ``sum_j v_j dx_j/ds``, so
        the bias compensation of the columns that stay is unchanged in kind. Names the
        design does not hold are ignored.

        Parameters
        ----------
        values : Mapping[str, float]
            Column name -> the value it is fixed at (in the column's coefficient units).

        Returns
        -------
        Design
            The design without those columns, its measured side corrected.
        """
        fixed = [i for i, name in enumerate(self.names) if name in values]
        if not fixed:
            return self
        v = np.array([values[self.names[i]] for i in fixed])
        observation = dict(self.noise.observation)
        for source, J in self.noise.regressors.items():
            part = J[:, fixed] @ v
            observation[source] = observation.get(source, 0.0) - part
        reduced = self.keeping([n for n in self.names if n not in values])
        noise = dataclasses.replace(reduced.noise, observation=observation)
        return Design(reduced.names, reduced.X, self.z - self.X[:, fixed] @ v, noise)

    def moments(self, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """Noise-corrected normal equations ``(X^T X - C_xx, X^T z - c_xz)`` on ``rows``.

        Parameters
        ----------
        rows : array_like or slice, optional
            The samples summed over; None: all.

        Returns
        -------
        A : numpy.ndarray of shape (n, n)
            Compensated normal matrix.
        b : numpy.ndarray of shape (n,)
            Compensated right-hand side.
        """
        return compensated_normal_equations(self.X, self.z, self.noise, rows)

    def solve(self, rows=None) -> np.ndarray:
        """The bias-compensated estimate on ``rows``.

        Parameters
        ----------
        rows : array_like or slice, optional
            The samples fitted; None: all.

        Returns
        -------
        numpy.ndarray of shape (n,)
            The estimate.
        """
        return solve_normal_equations(*self.moments(rows))

    def block_moments(self, edges: Sequence[int]) -> BlockMoments:
        """The moments of the design summed over the blocked folds ``edges``.

        Parameters
        ----------
        edges : sequence of int
            Fold boundaries, from 0 to N.

        Returns
        -------
        BlockMoments
            The per-fold sums.
        """
        return BlockMoments.of(self.X, self.z, self.noise, edges)

    def scores(self, theta: np.ndarray) -> np.ndarray:
        """Per-sample terms of the noise-corrected normal equations at ``theta``.

        Parameters
        ----------
        theta : numpy.ndarray of shape (n,)
            The parameters.

        Returns
        -------
        numpy.ndarray of shape (N, n)
            The scores
            (:func:`~drake_uav.identification.statistics.errors_in_variables.moment_scores`).
        """
        return moment_scores(self.X, self.z, theta, self.noise)

    def inverse_normal_matrix(self) -> np.ndarray:
        """``A^-1`` of the noise-corrected normal matrix (pseudo-inverse).

        Returns
        -------
        numpy.ndarray of shape (n, n)
            The (pseudo-)inverse.
        """
        return np.linalg.pinv(self.moments()[0])

    def result(self, confidence: float = 0.95,
               scores_covariance: np.ndarray | None = None) -> RegressionResult:
        """The bias-compensated fit (:func:`~drake_uav.identification.statistics.regression.bcls`).

        Parameters
        ----------
        confidence : float
            Two-sided confidence level of the significance test.
        scores_covariance : numpy.ndarray of shape (n, n), optional
            Covariance of the summed scores (None: from these samples alone).

        Returns
        -------
        RegressionResult
            The fit.
        """
        return bcls(self.X, self.z, self.noise, names=self.names, confidence=confidence,
                    scores_covariance=scores_covariance)


def baseline_names(params: FixedWingParams, coefficient: str) -> list[str]:
    """The aircraft's derivative names for ``coefficient`` (a constant term always).

    Parameters
    ----------
    params : FixedWingParams
        The aircraft.
    coefficient : str
        One of ``CL, CD, CY, Cl, Cm, Cn``.

    Returns
    -------
    list of str
        ``<coefficient>_<signal>`` names, the constant ``<coefficient>_0`` first.

    Examples
    --------
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> baseline_names(aerosonde(), "CL")[0]
    'CL_0'
    """
    names = [n for n in params.derivatives if n.split("_", 1)[0] == coefficient]
    if f"{coefficient}_0" not in names:
        names.insert(0, f"{coefficient}_0")
    return names


def baseline_design(samples: AeroSamples, params: FixedWingParams, coefficient: str) -> Design:
    """The design of the catalog's terms of ``coefficient``.

    For C_D also the terms of a thrust identified from the flight
    (:func:`~drake_uav.identification.propulsion.thrust_correction_columns`), fitted again
    with every effect on the drag axis.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    params : FixedWingParams
        The aircraft (its derivative names).
    coefficient : str
        One of ``CL, CD, CY, Cl, Cm, Cn``.

    Returns
    -------
    Design
        The baseline design.
    """
    names = baseline_names(params, coefficient)
    with_thrust = coefficient == "CD"

    def columns(smp):
        X = regressor_matrix(names, smp.aligned(coefficient).condition, params.b, params.c)
        out = dict(zip(names, X.T, strict=True))
        return out | thrust_correction_columns(smp) if with_thrust else out

    variance = source_variances(samples, coefficient)
    cols, jac = columns_and_jacobians(columns, samples, variance)
    noise = PropagatedNoise(
        columns=len(cols),
        regressors={s: np.column_stack([j[k] for k in cols]) for s, j in jac.items()},
        observation={s: v for s, v in observation_sensitivity(samples, coefficient,
                                                              params).items() if s in variance},
        variance=variance,
    )
    return Design(names=list(cols), X=np.column_stack(list(cols.values())),
                   z=np.asarray(samples.coefficients[coefficient], dtype=float), noise=noise)


@dataclasses.dataclass(frozen=True)
class IdentifiedDerivatives:
    """The aircraft model's derivatives identified from one flight (:func:`fit_derivatives`).

    Indexing by a coefficient (``derivatives["CL"]``) gives its fit.

    Attributes
    ----------
    fits : Mapping[str, RegressionResult]
        Coefficient (``"CL"`` ...) -> its bias-compensated fit (method "BCLS").
    names : tuple of str
        Every derivative name, coefficient after coefficient.
    estimate : numpy.ndarray of shape (n,)
        Estimates in ``names`` order.
    covariance : numpy.ndarray of shape (n, n)
        Joint covariance: the six fits share sensor noise (e.g. the sideslip vane enters
        C_Y, C_l and C_n), so their errors are correlated; the diagonal blocks are the fits'
        own covariances.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> derivatives = fit_derivatives(samples, aerosonde(), coefficients=("CL",))
    >>> derivatives.names
    ('CL_0', 'CL_alpha', 'CL_q', 'CL_elevator')
    >>> derivatives["CL"].method, derivatives.sigma.shape
    ('BCLS', (4,))
    """

    fits: Mapping[str, RegressionResult]
    names: tuple[str, ...]
    estimate: np.ndarray
    covariance: np.ndarray

    def __getitem__(self, coefficient: str) -> RegressionResult:
        """The fit of one coefficient.

        Parameters
        ----------
        coefficient : str
            One of the fitted coefficients.

        Returns
        -------
        RegressionResult
            Its fit.
        """
        return self.fits[coefficient]

    @property
    def sigma(self) -> np.ndarray:
        """(n,) standard errors in ``names`` order."""
        return np.sqrt(np.diag(self.covariance))


def fit_derivatives(samples: AeroSamples, params: FixedWingParams,
                    coefficients: Sequence[str] = COEFFICIENTS) -> IdentifiedDerivatives:
    """Fits the aircraft's derivative structure (:func:`baseline_names`) to every sample.

    The same errors-in-variables corrected fits as the discovery loop's baseline, on
    the whole flight. The long-run covariance of all the fits' scores together gives
    their joint covariance.

    Parameters
    ----------
    samples : AeroSamples
        The measured coefficients and their regressors.
    params : FixedWingParams
        The aircraft (its derivative names).
    coefficients : sequence of str
        The coefficients fitted.

    Returns
    -------
    IdentifiedDerivatives
        The fits, their estimates and joint covariance.

    Raises
    ------
    ValueError
        For an unknown coefficient.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from drake_uav.identification import samples_from_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> derivatives = fit_derivatives(samples, aerosonde(), coefficients=("CL", "Cm"))
    >>> derivatives.names[:4]
    ('CL_0', 'CL_alpha', 'CL_q', 'CL_elevator')
    >>> bool(derivatives["Cm"].estimate[derivatives["Cm"].names.index("Cm_alpha")] < 0)
    True
    """
    designs = [baseline_design(samples, params, k) for k in coefficients]
    scores = np.hstack([d.scores(d.solve()) for d in designs])
    S = long_run_covariance(scores)
    edges = np.cumsum([0] + [len(d.names) for d in designs])
    blocks = [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    fits = {k: d.result(scores_covariance=S[b, b])
            for k, d, b in zip(coefficients, designs, blocks, strict=True)}
    A_inv = np.zeros_like(S)
    for d, b in zip(designs, blocks, strict=True):
        A_inv[b, b] = d.inverse_normal_matrix()
    return IdentifiedDerivatives(
        fits=fits, names=tuple(n for d in designs for n in d.names),
        estimate=np.concatenate([fits[k].estimate for k in coefficients]),
        covariance=sandwich_covariance(A_inv, S))
