"""RecursiveIdentifier: on-line identification of a model linear in its parameters.

:class:`AeroRegressors` turns the aircraft's air data, rates, controls and body
coefficients into the regressor row and observation of one coefficient of the
aircraft's coefficient model, so the identifier can run inside a flight diagram.

The system samples a regressor row x (the terms of a coefficient model such as
1, alpha, q_n, delta_e) and an observation z (the measured coefficient) every ``period`` seconds
and updates a recursive estimator of ``identification.recursive``: recursive PCA-GTLS
(``method="tls"``, Vaiopoulos 2017, Algorithms 1-2) or RLS (``method="ols"``), with a constant
or variable forgetting factor. The estimator state lives entirely in the discrete state, so a
simulation is reproducible from the context alone; outputs only read that state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import LeafSystem

from drake_uav.identification import RecursiveOLS, RecursiveTLS, VariableForgetting
from drake_uav.model import (
    COEFFICIENTS,
    AeroCondition,
    CoefficientModel,
    CompiledFunction,
    FixedWingModel,
    body_to_lift_drag,
    regressor_matrix,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["RecursiveIdentifier", "RecursiveIdentifierParams", "AeroRegressors", "METHODS"]

METHODS = ("tls", "ols")
"""Recursive estimators: PCA-GTLS (:class:`RecursiveTLS`), least squares (:class:`RecursiveOLS`)."""


@dataclass(frozen=True)
class RecursiveIdentifierParams:
    """Settings of :class:`RecursiveIdentifier` (validated by :meth:`validate`)."""

    names: tuple[str, ...]
    """Parameter names (n), in the order of the regressor row."""
    error_std: tuple[float, ...]
    """(n+1) noise standard deviations of the regressors and of the observation (units of
    each column; Vaiopoulos 2017, eq. 4.40). Positive: give a small value such as 1e-6 for
    an exact column like the constant 1. RLS uses the regressor part for its excitation
    monitor only."""
    method: str = "tls"
    """"tls" (recursive PCA-GTLS) or "ols" (recursive least squares)."""
    forgetting: float = 1.0
    """Constant forgetting factor in (0, 1] (weight per sample of past squared residuals),
    used when ``variable_forgetting`` is None."""
    variable_forgetting: VariableForgetting | None = None
    """VFF settings (Vaiopoulos 2017, eq. 4.107-4.115) or None for a constant factor."""
    snr_min: float = 1.0
    """S/n of the excitation test (Vaiopoulos 2017, eq. 4.68, typically 1..10)."""
    period: float = 0.01
    """Update period [s]."""
    theta0: tuple[float, ...] | None = None
    """Initial estimate (n), zeros if None."""
    covariance0: tuple[tuple[float, ...], ...] | None = None
    """Prior covariance (n x n, row-major tuples) of theta0 for a hybrid start (Vaiopoulos
    2017, eq. 4.4); None starts without prior information."""

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field."""
        n = len(self.names)
        if n < 1 or len(set(self.names)) != n:
            raise ValueError(f"names: need at least one unique name, got {self.names}")
        if len(self.error_std) != n + 1:
            raise ValueError(f"error_std: need {n + 1} entries (n regressors + observation)")
        if not all(math.isfinite(c) and c > 0 for c in self.error_std):
            raise ValueError(f"error_std: entries must be finite and > 0, got {self.error_std}")
        if self.method not in METHODS:
            raise ValueError(f"method: must be one of {METHODS}, got {self.method!r}")
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"forgetting: must be in (0, 1], got {self.forgetting}")
        if self.variable_forgetting is not None:
            self.variable_forgetting.validate()
        if not self.snr_min >= 0.0:
            raise ValueError(f"snr_min: must be >= 0, got {self.snr_min}")
        if not (self.period > 0 and math.isfinite(self.period)):
            raise ValueError(f"period: must be positive, got {self.period}")
        if self.theta0 is not None and len(self.theta0) != n:
            raise ValueError(f"theta0: need {n} entries, got {len(self.theta0)}")
        if self.covariance0 is not None:
            P = np.asarray(self.covariance0, dtype=float)
            if P.shape != (n, n) or not np.allclose(P, P.T) or np.linalg.eigvalsh(P)[0] <= 0:
                raise ValueError(f"covariance0: must be a symmetric positive definite {n}x{n}")

    def make_estimator(self) -> RecursiveOLS | RecursiveTLS:
        """A fresh estimator with these settings (validated)."""
        self.validate()
        n = len(self.names)
        forgetting = self.variable_forgetting or self.forgetting
        if self.method == "ols":
            return RecursiveOLS(
                n,
                forgetting,
                theta0=self.theta0,
                covariance0=self.covariance0,
                noise_std0=self.error_std[-1],
            )
        return RecursiveTLS(
            n,
            self.error_std,
            forgetting=forgetting,
            snr_min=self.snr_min,
            theta0=self.theta0,
            covariance0=self.covariance0,
        )


class RecursiveIdentifier(LeafSystem):
    """On-line parameter identification, updated periodically (discrete state only).

    ============  ======  ====================================================================
    port          size    meaning [units]
    ============  ======  ====================================================================
    regressors    n       input: regressor row x (units of each term, e.g. rad, -, 1)
    observation   1       input: observed z (e.g. a measured aerodynamic coefficient, -)
    estimate      n       output: parameters theta (units of z per unit of each regressor)
    sigma         n       output: one-sigma uncertainty of theta (inf: not identifiable)
    excitation    n       output: 1 if the data excite the parameter enough (Vaiopoulos 2017,
                          eq. 4.68), else 0
    forgetting    1       output: forgetting factor used at the last update (-)
    ============  ======  ====================================================================

    Inputs are sampled at t = 0, period, 2 period, ...; outputs depend only on the discrete
    state (no direct feedthrough).
    """

    def __init__(self, params: RecursiveIdentifierParams):
        super().__init__()
        self._est = params.make_estimator()
        self._params = params
        self._regressor_std = np.asarray(params.error_std[:-1], dtype=float)
        n = len(params.names)
        self.n = n
        self._x = self.DeclareVectorInputPort("regressors", n)
        self._z = self.DeclareVectorInputPort("observation", 1)
        self.DeclareDiscreteState(self._est.state.copy())
        self.DeclarePeriodicDiscreteUpdateEvent(params.period, 0.0, self._update)
        state_only = {self.xd_ticket()}
        self.DeclareVectorOutputPort("estimate", n, self._calc_estimate, state_only)
        self.DeclareVectorOutputPort("sigma", n, self._calc_sigma, state_only)
        self.DeclareVectorOutputPort("excitation", n, self._calc_excitation, state_only)
        self.DeclareVectorOutputPort("forgetting", 1, self._calc_forgetting, state_only)

    @property
    def params(self) -> RecursiveIdentifierParams:
        """The settings this system was built with."""
        return self._params

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, in the order of the estimate output."""
        return self._params.names

    def _load(self, context):
        self._est.set_state(context.get_discrete_state_vector().get_value())
        return self._est

    def _update(self, context, discrete_state) -> None:
        est = self._load(context)
        est.update(self._x.Eval(context), float(self._z.Eval(context)[0]))
        discrete_state.set_value(est.state)

    def _calc_estimate(self, context, output) -> None:
        output.SetFromVector(context.get_discrete_state_vector().get_value()[: self.n])

    def _calc_sigma(self, context, output) -> None:
        output.SetFromVector(self._load(context).sigma())

    def _status(self, context):
        est = self._load(context)
        if isinstance(est, RecursiveTLS):
            return est.excitation()
        return est.excitation(self._regressor_std, self._params.snr_min)

    def _calc_excitation(self, context, output) -> None:
        output.SetFromVector(self._status(context).identifiable.astype(float))

    def _calc_forgetting(self, context, output) -> None:
        output.SetFromVector([self._load(context).forgetting_factor])


class AeroRegressors(LeafSystem):
    """Regressor row and observed value of one aerodynamic coefficient (direct feedthrough).

    ===================  ====  ==============================================================
    port                 size  meaning [units]
    ===================  ====  ==============================================================
    air_data             3     input: Va [m/s], alpha, beta [rad]
    state                13    input: plant state (body rates p, q, r [rad/s] are used)
    controls             4     input: elevator, aileron, rudder [rad], throttle [0..1]
    aero_coefficients    6     input: body-axis C_X, C_Y, C_Z, C_l, C_m, C_n [-]
    regressors           n     output: the signals of ``names`` (``regressor_matrix``) [-]
    observation          1     output: the coefficient (C_L, C_D from C_X, C_Z and alpha) [-]
    ===================  ====  ==============================================================

    ``names`` defaults to the terms of ``coefficient`` in the aircraft's
    coefficient model. The condition is :meth:`FixedWingModel.aero_condition`
    (controls saturated, thrust coefficient from the propulsion model), as in
    the plant.
    """

    def __init__(self, aircraft: FixedWingParams, coefficient: str,
                 names: tuple[str, ...] | None = None):
        super().__init__()
        if coefficient not in COEFFICIENTS:
            raise ValueError(f"coefficient: unknown {coefficient!r}; use one of {COEFFICIENTS}")
        self.names = tuple(CoefficientModel(aircraft.derivatives).term_names(coefficient)
                           if names is None else names)
        regressor_matrix(self.names, AeroCondition(25.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                         aircraft.b, aircraft.c)  # raises ValueError for an unknown name
        self.coefficient = coefficient
        model = FixedWingModel(aircraft)

        def row(air_data, omega, controls):
            cond = model.aero_condition(air_data, omega, controls)
            return regressor_matrix(self.names, cond, aircraft.b, aircraft.c)

        # The row as straight-line code (traced once): no condition object per sample.
        self._row = CompiledFunction(row, (3, 3, 4), {}, f"{coefficient} regressors").program
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._state = self.DeclareVectorInputPort("state", 13)
        self._controls = self.DeclareVectorInputPort("controls", 4)
        self._coefficients = self.DeclareVectorInputPort("aero_coefficients", 6)
        self.DeclareVectorOutputPort("regressors", len(self.names), self._calc_regressors)
        self.DeclareVectorOutputPort("observation", 1, self._calc_observation)

    def _calc_regressors(self, context, output) -> None:
        output.SetFromVector(self._row(self._air.Eval(context).tolist(),
                                       self._state.Eval(context)[10:13].tolist(),
                                       self._controls.Eval(context).tolist()))

    def _calc_observation(self, context, output) -> None:
        cx, cy, cz, cl, cm, cn = self._coefficients.Eval(context).tolist()
        if self.coefficient in ("CL", "CD"):  # wind axes: needs alpha
            lift, drag = body_to_lift_drag(cx, cz, float(self._air.Eval(context)[1]))
            value = lift if self.coefficient == "CL" else drag
        else:
            value = {"CY": cy, "Cl": cl, "Cm": cm, "Cn": cn}[self.coefficient]
        output.SetAtIndex(0, value)
