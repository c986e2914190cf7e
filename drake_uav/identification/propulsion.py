"""Thrust identified from flight data, together with the body-axis force coefficient C_X.

The accelerometer's body-x specific force ``a_x`` [m/s^2] carries the thrust and the
aerodynamic force (Vaiopoulos 2017, eq. 5.41)::

    m a_x = T + qbar S C_X,   C_X = C_X0 + C_Xa alpha + C_Xa2 alpha^2 + C_Xq q c/(2 Va)
                                    + C_Xde elevator

Both sides are linear in the unknowns once the thrust is written linear in its own
coefficients (:mod:`drake_uav.model.propeller`):

* **With a logged motor speed** (channel ``motor_speed``, rad/s):
  ``T = rho D^2 (C_T0 (nD)^2 + C_T1 (nD) Va + C_T2 Va^2)``, the propeller's
  ``rho n^2 D^4 C_T(J)``. ``C_T0`` is identified, ``C_T1`` too where the held-out
  error asks for it (at one trim point it hardly ever does: with the shaft speed
  nearly constant its term is nearly a multiple of Va); the others stay the catalog
  propeller's. ``C_T2 Va^2`` has the shape of ``qbar S C_X0`` (both scale with Va^2
  alone), so no flight can separate them: an error in it moves C_X0 by
  ``2 D^2 dC_T2 / S`` without changing the total force.
* **Without it**: the catalog propulsion model plus a correction in throttle and
  airspeed, ``T = T_catalog(Va, dT) + k1 dT + k2 dT^2 + k3 dT Va``. The terms vanish at
  zero throttle, where a windmilling propeller's thrust again scales with Va^2 alone
  (a weaker motor or battery changes only the throttle-driven part).

The subset of thrust terms is chosen on held-out blocks of the flight (blocked
cross-validation): the one of fewest terms that no other subset beats by 1 % on both
the observed error and the error without the part the regressors' noise makes (a term
that cancels the pitot's noise in the catalog thrust predicts no thrust better). The
chosen set is fitted by bias-compensated least squares (:func:`~.regression.bcls`):
airspeed, alpha and motor speed are measured with noise, carried into every column by
their sensitivities, with a long-run (Newey-West) covariance for the correlated
residual of smoothed flight data.

**In the discovery.** A force the model lacks along the body x axis (a tow, a pull's x
component) moves ``a_x`` like a thrust error; where it correlates with the throttle (the
airspeed hold opens the throttle against it), the correction terms take part of it. The
discovery loop therefore fits the chosen throttle terms again with C_D
(:func:`thrust_correction_columns`: a thrust taken out of ``a_x`` in excess of the true
one reads as drag, ``cos(alpha) / (qbar S)`` per newton), so an effect on the drag axis
is judged with the thrust free to give back what it took. A force shaped like those
terms stays with the thrust.

**Identifiability.** When the throttle hardly moves, the thrust terms are nearly a
constant and a multiple of Va, and a narrow airspeed range makes those collinear with
``qbar S C_X0``: thrust and drag trade against each other, and a throttle correction is
a constant force (a tow would be the same column). The fit reports the condition number
of the column-equilibrated regressors, the multiple correlation of the thrust columns
with the C_X columns (and a constant, for the throttle correction) and the thrust's
standard deviation relative to its spread over the flight; past the limits it falls
back to the catalog model with an :class:`~.regression.InsufficientExcitationWarning`
instead of returning a thrust the data do not determine.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.identification.samples.flight_data import (
    AIR_DATA,
    RATES,
    SPECIFIC_FORCE,
    GriddedLog,
)
from drake_uav.identification.samples.isolation import smoothed_noise_variance
from drake_uav.identification.samples.segments import delayed
from drake_uav.identification.statistics.blocked_folds import fold_edges, held_out_errors
from drake_uav.identification.statistics.errors_in_variables import (
    BlockMoments,
    PropagatedNoise,
    solve_normal_equations,
)
from drake_uav.identification.statistics.regression import InsufficientExcitationWarning, bcls
from drake_uav.io.flight_log import FlightLogError
from drake_uav.io.propeller_table import PropellerTable
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import AeroCondition, body_to_lift_drag, signal_values
from drake_uav.model.isolation import differentiate
from drake_uav.model.propeller import (
    THROTTLE_TERMS,
    propeller_thrust,
    revolutions,
    throttle_thrust_airspeed_slopes,
    throttle_thrust_regressors,
    thrust_regressor_airspeed_slopes,
    thrust_regressors,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["ThrustModel", "ThrustPrediction", "ThrustDiagnostics", "HeldOutError",
           "identify_thrust", "thrust_from_gridded_log", "declared_thrust",
           "thrust_correction_columns",
           "thrust_drag_columns", "DRAG_TERMS",
           "PROPELLER_TERMS", "THRUST_COLUMN", "THROTTLE_TERM_UNITS"]

DRAG_TERMS = ("CX_0", "CX_alpha", "CX_alpha2", "CX_q", "CX_elevator")
"""The C_X terms fitted with the thrust (signals of :mod:`drake_uav.model.coefficients`)."""
PROPELLER_TERMS = ("C_T0", "C_T1")
"""The propeller coefficients identified from a logged motor speed."""
THRUST_COLUMN = "thrust:"
"""Name prefix of the thrust-correction columns of C_D (:func:`thrust_correction_columns`)."""
THROTTLE_TERM_UNITS = {"throttle": "N", "throttle2": "N", "throttle_airspeed": "N s/m"}
"""Unit of the thrust coefficient of each throttle term."""

_CANDIDATES = {
    "motor_speed": (("C_T0",), PROPELLER_TERMS),
    "throttle": ((), THROTTLE_TERMS[:1], THROTTLE_TERMS[:2], THROTTLE_TERMS[::2],
                 THROTTLE_TERMS),
}
"""Thrust-term subsets compared by held-out error, per source."""

MAX_CONDITION = 1e4
"""Largest condition number of the column-equilibrated regressors accepted."""
MAX_CORRELATION = 0.999
"""Largest multiple correlation of a thrust column with the C_X columns (and a constant,
for a throttle correction) accepted."""
MAX_RELATIVE_STD = 0.25
"""Largest median thrust standard deviation, relative to the thrust's spread, accepted."""
PARSIMONY = 0.01
"""Relative held-out error by which a subset must beat one of fewer terms (on both errors)."""


class ThrustPrediction(NamedTuple):
    """Thrust of a :class:`ThrustModel` on arrays of samples.

    Attributes
    ----------
    thrust : numpy.ndarray
        T [N].
    std : numpy.ndarray
        Standard deviation of T from the coefficients' covariance [N] (0: catalog).
    airspeed_slope : numpy.ndarray
        dT/dVa at the logged throttle or motor speed [N/(m/s)].

    Examples
    --------
    >>> import numpy as np
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> catalog = ThrustModel(aerosonde(), "catalog", (), np.zeros(0), np.zeros((0, 0)))
    >>> prediction = catalog.thrust(np.array([20.0, 25.0]), np.array([0.5, 0.8]))
    >>> prediction.thrust.round(1).tolist(), prediction.std.tolist()
    ([154.2, 446.1], [0.0, 0.0])
    """

    thrust: np.ndarray
    std: np.ndarray
    airspeed_slope: np.ndarray


@dataclasses.dataclass(frozen=True)
class ThrustDiagnostics:
    """How well the flight determines the thrust.

    Attributes
    ----------
    condition : float
        Condition number of the column-equilibrated regressors (C_X and thrust).
    correlation : float
        Largest multiple correlation of a thrust column with the C_X columns (and a constant,
        for a throttle correction) [-].
    relative_std : float
        Median thrust standard deviation over the thrust's spread (std over the flight).
    held_out_rmse : Mapping[tuple of str, HeldOutError]
        Held-out RMS errors of m a_x [N] per candidate thrust-term subset.
    identifiable : bool
        Whether the flight tells thrust from drag (else the catalog model is kept).
    message : str
        Why the catalog was kept, or empty.

    Examples
    --------
    >>> import warnings
    >>> from importlib.resources import files
    >>> from drake_uav.identification.samples.flight_data import gridded_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> grid = gridded_log(log, aerosonde())
    >>> flight = grid.log
    >>> with warnings.catch_warnings(record=True):       # the throttle hardly moves here
    ...     model = identify_thrust(aerosonde(), flight.time, flight.stack(SPECIFIC_FORCE),
    ...                             flight.stack(RATES), flight.stack(AIR_DATA), grid.controls)
    >>> model.diagnostics.identifiable, model.diagnostics.message.split(" (")[0]
    (False, 'thrust and C_X0 are confounded')
    """

    condition: float
    correlation: float
    relative_std: float
    held_out_rmse: Mapping[tuple[str, ...], HeldOutError]
    identifiable: bool
    message: str


@dataclasses.dataclass(frozen=True)
class ThrustModel:
    """An identified (or catalog) thrust model; :meth:`thrust` evaluates it on samples.

    Attributes
    ----------
    params : FixedWingParams
        The catalog aircraft (its propulsion model is the fallback and the fixed part).
    source : str
        "motor_speed" (propeller C_T(J)), "throttle" (catalog plus correction) or "catalog".
    terms : tuple of str
        Names of the identified thrust coefficients.
    coefficients : numpy.ndarray
        Their values (C_T0, C_T1 [-]; throttle terms [N], [N], [N s/m]).
    covariance : numpy.ndarray
        Their covariance.
    drag_terms : tuple of str
        Names of the C_X coefficients fitted together with the thrust.
    drag_coefficients : numpy.ndarray
        Their values [-] (empty for the catalog).
    drag_sigma : numpy.ndarray
        Their standard deviations [-].
    diagnostics : ThrustDiagnostics or None
        How well the flight determined the thrust (None for a model built by hand).

    Examples
    --------
    >>> import numpy as np
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> catalog = ThrustModel(aerosonde(), "catalog", (), np.zeros(0), np.zeros((0, 0)))
    >>> float(catalog.thrust(20.0, 0.5).thrust.round(1))
    154.2
    """

    params: FixedWingParams
    source: str
    terms: tuple[str, ...]
    coefficients: np.ndarray
    covariance: np.ndarray
    drag_terms: tuple[str, ...] = DRAG_TERMS
    drag_coefficients: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    drag_sigma: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    diagnostics: ThrustDiagnostics | None = None

    def thrust(self, airspeed, throttle, motor_speed=None) -> ThrustPrediction:
        """Thrust, its standard deviation and dT/dVa on samples.

        Parameters
        ----------
        airspeed : array_like
            Airspeed [m/s].
        throttle : array_like
            Throttle [0..1].
        motor_speed : array_like, optional
            Motor speed [rad/s], for a model identified from it.

        Returns
        -------
        ThrustPrediction
            Thrust [N], its standard deviation [N] and dT/dVa [N/(m/s)].
        """
        base = _base_thrust(self.params, self.source, self.terms, airspeed, throttle,
                            motor_speed)
        if not self.terms:
            return ThrustPrediction(base.value, np.zeros_like(base.value), base.slope)
        columns = _thrust_columns(self.params, self.source, airspeed, throttle, motor_speed,
                                  self.terms)
        value = base.value + columns.value @ self.coefficients
        std = np.sqrt(np.maximum(np.einsum("...j,jk,...k->...", columns.value, self.covariance,
                                           columns.value), 0.0))
        return ThrustPrediction(value, std, base.slope + columns.slope @ self.coefficients)


def catalog_propeller(params: FixedWingParams) -> tuple[float, tuple[float, float, float]]:
    """Propeller diameter and thrust coefficients of the params' propulsion model.

    A :class:`~drake_uav.vehicles.fixed_wing.MotorPropeller` gives its own. The momentum
    model of Beard & McLain (2012, sec. 4.3), ``0.5 rho S_prop C_prop ((k dT)^2 - Va^2)``,
    is a disc of area S_prop with no ``(nD) Va`` term (C_T1 = 0), whose Va^2 term is
    ``C_T2 = -S_prop C_prop / (2 D^2)``; it has no shaft speed, so no C_T0 (NaN).

    Parameters
    ----------
    params : FixedWingParams
        The aircraft.

    Returns
    -------
    diameter : float
        Propeller diameter D [m].
    coefficients : (float, float, float)
        ``(C_T0, C_T1, C_T2)`` [-].

    Raises
    ------
    ValueError
        For a propulsion model with neither a propeller diameter nor a disc area.
    """
    prop = params.propulsion
    if hasattr(prop, "C_T2") and hasattr(prop, "diameter"):
        return float(prop.diameter), (float(prop.C_T0), float(prop.C_T1), float(prop.C_T2))
    if hasattr(prop, "S_prop") and hasattr(prop, "C_prop"):
        diameter = math.sqrt(4.0 * prop.S_prop / math.pi)
        return diameter, (math.nan, 0.0, -prop.S_prop * prop.C_prop / (2.0 * diameter**2))
    raise ValueError(f"identify_thrust: params.propulsion ({type(prop).__name__}) has no "
                     "propeller diameter (diameter or S_prop) to use with motor_speed")


class _Signal(NamedTuple):
    value: np.ndarray
    slope: np.ndarray
    """d(value)/dVa."""


def _catalog_thrust(params: FixedWingParams, airspeed, throttle) -> np.ndarray:
    """The params' propulsion thrust [N] on arrays (per sample for float-only models)."""
    rho, prop = params.rho, params.propulsion
    airspeed, throttle = np.broadcast_arrays(np.asarray(airspeed, float),
                                             np.asarray(throttle, float))
    try:
        return np.asarray(prop.thrust_torque(airspeed, throttle, rho)[0], dtype=float)
    except TypeError:  # scalar-generic models built on pydrake.math take one sample at a time
        return np.array([prop.thrust_torque(float(v), float(d), rho)[0]
                         for v, d in zip(airspeed.ravel(), throttle.ravel(), strict=True)]
                        ).reshape(airspeed.shape)


def _base_thrust(params, source: str, terms, airspeed, throttle, motor_speed,
                 slope: bool = True) -> _Signal:
    """The fixed part of the thrust: with a motor speed the catalog propeller's terms
    that are not identified (``terms``), else the catalog model (slope by central
    differences, 0.01 m/s; None unless ``slope``)."""
    airspeed = np.asarray(airspeed, float)
    if source == "motor_speed":
        diameter, catalog = catalog_propeller(params)
        n_d = _speed_diameter(motor_speed, diameter)
        columns = thrust_regressors(params.rho, n_d, airspeed, diameter)
        slopes = thrust_regressor_airspeed_slopes(params.rho, n_d, airspeed, diameter)
        fixed = [i for i, name in enumerate(("C_T0",) + PROPELLER_TERMS[1:] + ("C_T2",))
                 if name not in terms]
        return _Signal(sum(catalog[i] * columns[i] for i in fixed),
                       sum(catalog[i] * slopes[i] for i in fixed))
    value = _catalog_thrust(params, airspeed, throttle)
    if not slope:
        return _Signal(value, None)
    step = 0.01
    return _Signal(value, (_catalog_thrust(params, airspeed + step, throttle)
                           - _catalog_thrust(params, airspeed - step, throttle)) / (2.0 * step))


def _speed_diameter(motor_speed, diameter: float) -> np.ndarray:
    if motor_speed is None:
        raise ValueError("ThrustModel.thrust: this model was identified from motor_speed; "
                         "pass the logged motor speed [rad/s]")
    return revolutions(np.asarray(motor_speed, float)) * diameter


def thrust_correction_columns(samples: AeroSamples) -> dict[str, np.ndarray]:
    """C_D columns of the identified thrust's correction terms, named ``thrust:<term>``.

    The terms are :attr:`~.isolation.AeroSamples.thrust_correction_terms`; each column is
    the change of the measured C_D per newton-per-unit of the term by which the thrust
    taken out of ``a_x`` exceeds the true one (the isolation reads an excess of thrust as
    drag: minus the C_D of a body-x force).

    Parameters
    ----------
    samples : AeroSamples
        The samples.

    Returns
    -------
    dict of str to numpy.ndarray
        Column name -> (N,) values [1/(N unit)]; empty for a thrust not identified from the
        flight's throttle.
    """
    terms = samples.thrust_correction_terms
    if not terms:
        return {}
    return thrust_drag_columns(samples.condition.alpha, samples.condition.airspeed,
                               samples.throttle,
                               samples.dynamic_pressure * samples.reference_area, terms)


def thrust_drag_columns(alpha, airspeed, throttle, qbar_s, terms=THROTTLE_TERMS
                        ) -> dict[str, np.ndarray]:
    """The C_D columns ``thrust:<term>`` of the throttle thrust terms.

    What a thrust in excess of the true one by each term's unit does to the drag measured
    from ``a_x``.

    Parameters
    ----------
    alpha : array_like
        Angle of attack [rad].
    airspeed : array_like
        Airspeed [m/s].
    throttle : array_like
        Throttle [0..1].
    qbar_s : array_like
        Dynamic pressure times wing area [N].
    terms : sequence of str
        The throttle terms (:data:`~drake_uav.model.propeller.THROTTLE_TERMS`).

    Returns
    -------
    dict of str to numpy.ndarray
        Column name -> values [1/(N unit)].
    """
    per_newton = 1.0 / np.asarray(qbar_s, float)
    drag = -body_to_lift_drag(per_newton, 0.0 * per_newton, alpha)[1]
    values = dict(zip(THROTTLE_TERMS, throttle_thrust_regressors(throttle, airspeed),
                      strict=True))
    return {f"{THRUST_COLUMN}{term}": drag * values[term] for term in terms}


def _thrust_columns(params, source: str, airspeed, throttle, motor_speed,
                    terms) -> _Signal:
    """(N, len(terms)) thrust columns and their airspeed slopes."""
    airspeed = np.asarray(airspeed, float)
    if source == "motor_speed":
        diameter = catalog_propeller(params)[0]
        n_d = _speed_diameter(motor_speed, diameter)
        names = ("C_T0", "C_T1", "C_T2")
        values = thrust_regressors(params.rho, n_d, airspeed, diameter)
        slopes = thrust_regressor_airspeed_slopes(params.rho, n_d, airspeed, diameter)
    else:
        throttle = np.asarray(throttle, float)
        names = THROTTLE_TERMS
        values = throttle_thrust_regressors(throttle, airspeed)
        slopes = throttle_thrust_airspeed_slopes(throttle, airspeed)
    pick = [names.index(t) for t in terms]

    def stacked(columns):
        out = np.zeros(airspeed.shape + (len(pick),))
        for k, i in enumerate(pick):
            out[..., k] = columns[i]
        return out

    return _Signal(stacked(values), stacked(slopes))


class _Data(NamedTuple):
    """Smoothed signals of the fit (arrays of N samples)."""

    airspeed: np.ndarray
    alpha: np.ndarray
    pitch_rate: np.ndarray
    elevator: np.ndarray
    throttle: np.ndarray
    motor_speed: np.ndarray | None
    force: np.ndarray
    """m a_x [N]."""


def _drag_columns(params, data: _Data) -> np.ndarray:
    """(N, 5) columns ``qbar S x`` of :data:`DRAG_TERMS` [N]."""
    airspeed, alpha = data.airspeed, data.alpha
    zero = np.zeros_like(airspeed)
    cond = AeroCondition(airspeed=airspeed, alpha=alpha, beta=zero, p=zero, q=data.pitch_rate,
                         r=zero, elevator=data.elevator)
    signals = signal_values(cond, params.b, params.c)
    q_bar_s = dynamic_pressure(airspeed, params.rho) * params.S
    return np.column_stack([q_bar_s * np.broadcast_to(signals[t.partition("_")[2]],
                                                      airspeed.shape) for t in DRAG_TERMS])


def _design(params, source: str, data: _Data, terms, base: np.ndarray | None = None):
    """Regressors ``[qbar S C_X terms | thrust terms]`` and observation ``m a_x - T_fixed``
    (``base``: the fixed thrust T_fixed [N] when already known)."""
    if base is None:
        base = _base_thrust(params, source, terms, data.airspeed, data.throttle,
                            data.motor_speed, slope=False).value
    drag = _drag_columns(params, data)
    thrust = _thrust_columns(params, source, data.airspeed, data.throttle, data.motor_speed,
                             terms)
    return np.column_stack([drag, thrust.value]), data.force - base


class HeldOutError(NamedTuple):
    """Held-out RMS errors [N] of ``m a_x`` predicted by a thrust-term subset."""

    least_squares: float
    """Of the least-squares fit: the measured ``m a_x`` from the measured regressors."""
    noise_corrected: float
    """Of the bias-compensated fit, without the part the regressors' noise makes."""


def _held_out_error(X: np.ndarray, z: np.ndarray, noise: PropagatedNoise,
                    folds: int) -> HeldOutError:
    """Both errors of the fits predicting each of ``folds`` contiguous blocks from the
    others (blocks, not random samples: neighbouring samples are correlated)."""
    blocks = BlockMoments.of(X, z, noise, fold_edges(len(z), folds))
    corrected = np.sum(held_out_errors(blocks, z, lambda theta: X @ theta.T)[1])
    prediction = X @ solve_normal_equations(*blocks.held_in_least_squares()).T
    fold = np.repeat(np.arange(folds), np.diff(blocks.edges))
    observed = z - prediction[np.arange(len(z)), fold]
    return HeldOutError(float(np.sqrt(np.mean(observed**2))),
                        float(np.sqrt(max(corrected, 0.0) / len(z))))


def _select_terms(params, source: str, data: _Data, folds: int,
                  variance: Mapping[str, float]):
    """The thrust-term subset of fewest terms that no other subset beats by
    :data:`PARSIMONY` on both held-out errors, and every subset's errors.

    Both errors, as the discovery's held-out decisions read them: the pitot's noise enters
    the thrust at the logged airspeed and the throttle-airspeed term alike, and a term
    fitted to cancel it lowers the observed error without predicting the thrust better (on
    a clean flight in moderate turbulence the three throttle terms lower the observed
    error of ``m a_x`` by about a third, the true airspeed's alike); the noise-corrected
    error alone credits a large coefficient on a noisy column with the noise it is
    expected to carry (the propeller's C_T1 with a logged motor speed).
    """
    errors = {terms: _held_out_error(*_noise(params, source, data, terms, variance), folds)
              for terms in _CANDIDATES[source]}

    def beaten(terms) -> bool:
        return any(all(b < a * (1.0 - PARSIMONY) for a, b in zip(errors[terms], other,
                                                                    strict=True))
                   for other in errors.values())

    chosen = min((t for t in errors if not beaten(t)),
                 key=lambda t: (len(t), errors[t].noise_corrected))
    return chosen, errors


def _noise(params, source: str, data: _Data, terms, variance: Mapping[str, float]):
    """Regressor and observation noise of the design, by central differences in each
    noisy source (airspeed, alpha, motor speed) and the accelerometer."""
    X, z = _design(params, source, data, terms)
    base = data.force - z  # the fixed thrust, unchanged by alpha (and, here, motor speed)
    regressors, observation = {}, {"ax": np.full(len(z), params.mass)}
    steps = {"airspeed": 0.01, "alpha": 1e-4, "motor_speed": 0.1}
    for name, step in steps.items():
        if name not in variance:
            continue
        shifted = []
        for sign in (1.0, -1.0):
            moved = data._replace(**{name: getattr(data, name) + sign * step})
            fixed = None if name == "airspeed" or source == "motor_speed" else base
            shifted.append(_design(params, source, moved, terms, fixed))
        regressors[name] = (shifted[0][0] - shifted[1][0]) / (2.0 * step)
        observation[name] = (shifted[0][1] - shifted[1][1]) / (2.0 * step)
    return X, z, PropagatedNoise(X.shape[1], regressors, observation, dict(variance))


def _diagnostics(X: np.ndarray, n_drag: int, thrust_std: np.ndarray, thrust: np.ndarray,
                 rmse, source: str) -> ThrustDiagnostics:
    """Condition, collinearity of the thrust columns with the C_X columns (and, for a
    throttle correction, a constant force), and relative thrust uncertainty.

    The constant is a body-x force that does not follow the throttle (a tow, a trimmed
    force): at a nearly constant throttle the correction polynomial is one, and naming it
    the thrust would hide what the discovery can name. A logged motor speed carries the
    thrust's changes through the propeller law, which a constant force does not follow.
    """
    scaled = X / np.maximum(np.linalg.norm(X, axis=0), 1e-300)
    s = np.linalg.svd(scaled, compute_uv=False)
    condition = float(s[0] / max(s[-1], 1e-300))
    drag, correlation = X[:, :n_drag], 0.0
    if source == "throttle":
        drag = np.column_stack([drag, np.ones(len(X))])
    for column in X[:, n_drag:].T:
        fitted = drag @ np.linalg.lstsq(drag, column, rcond=None)[0]
        correlation = max(correlation, float(np.linalg.norm(fitted)
                                             / max(np.linalg.norm(column), 1e-300)))
    relative = float(np.median(thrust_std) / max(np.std(thrust), 1e-9))
    problems = []
    if condition > MAX_CONDITION:
        problems.append(f"condition number {condition:.3g} > {MAX_CONDITION:g}")
    if correlation > MAX_CORRELATION:
        problems.append(f"thrust/C_X correlation {correlation:.6f} > {MAX_CORRELATION}")
    if relative > MAX_RELATIVE_STD:
        problems.append(f"thrust std {relative:.3g} of its spread > {MAX_RELATIVE_STD}")
    message = ("thrust and C_X0 are confounded (" + "; ".join(problems) + "): the throttle "
               "or motor speed varies too little; the catalog propulsion model is kept"
               if problems else "")
    return ThrustDiagnostics(condition, correlation, relative, dict(rmse), not problems,
                             message)


def _smoothed_data(params, time, specific_force, rates, air_data, controls, motor_speed,
                   window: float) -> _Data:
    """The fit's signals through the isolation's Savitzky-Golay smoothing of ``window`` [s]."""
    def smooth(values):
        return differentiate(time, np.asarray(values, float), window, deriv=0)

    air = smooth(air_data)
    if np.any(air[:, 0] <= 1.0):
        raise ValueError("identify_thrust: airspeed below 1 m/s; pass airborne samples only")
    return _Data(airspeed=air[:, 0], alpha=air[:, 1], pitch_rate=smooth(rates[:, 1]),
                 elevator=smooth(controls[:, 0]), throttle=smooth(controls[:, 3]),
                 motor_speed=None if motor_speed is None else smooth(motor_speed),
                 force=params.mass * smooth(specific_force[:, 0]))


_WIDTHS = {"specific_force": (3,), "rates": (3,), "air_data": (3,), "controls": (4,),
           "motor_speed": ()}


def _checked(n: int, **arrays) -> dict[str, np.ndarray | None]:
    """The input arrays (None stays None) as floats of shape (n, width) or (n,)."""
    return {name: None if value is None else _checked_array(name, value, n)
            for name, value in arrays.items()}


def _checked_array(name: str, value, n: int) -> np.ndarray:
    """``value`` as floats; ``ValueError`` naming the array for a wrong shape or a
    non-finite sample."""
    value = np.asarray(value, dtype=float)
    shape = (n, *_WIDTHS[name])
    problem = None
    if value.shape != shape:
        problem = f"must have shape {shape}, got {value.shape}"
    elif not np.all(np.isfinite(value)):
        problem = f"is not finite at sample {int(np.argwhere(~np.isfinite(value))[0, 0])}"
    if problem is not None:
        raise ValueError(f"identify_thrust: {name} {problem}")
    return value


def _noise_variance(time, arrays, window: float, raw: Mapping[str, float] | None):
    """Noise variance of the smoothed airspeed, alpha, motor speed and a_x (declared raw
    variances through the smoothing's gain, else read from the data)."""
    channels = {"airspeed": arrays["air_data"][:, 0], "alpha": arrays["air_data"][:, 1],
                "ax": arrays["specific_force"][:, 0]}
    if arrays["motor_speed"] is not None:
        channels["motor_speed"] = arrays["motor_speed"]
    out = {}
    for name, values in channels.items():
        if raw is not None and name in raw:
            impulse = np.zeros(len(time))
            impulse[len(time) // 2] = 1.0
            gain = float(np.sum(differentiate(time, impulse, window, deriv=0) ** 2))
            out[name] = float(raw[name]) * gain
        else:
            out[name] = float(smoothed_noise_variance(time, values[:, None], window)[0])
    return out


def identify_thrust(params: FixedWingParams, time, specific_force, rates, air_data, controls,
                    motor_speed=None, *, window: float = 0.2, folds: int = 5,
                    raw_noise_variance: Mapping[str, float] | None = None) -> ThrustModel:
    """Thrust identified with C_X from airborne, uniformly sampled flight data.

    The ten parameters are the flight's arrays (as
    :func:`~drake_uav.identification.samples.isolation.isolate_coefficients` takes them)
    and three keyword-only settings.

    Parameters
    ----------
    params : FixedWingParams
        The aircraft (its catalog propulsion model).
    time : array_like
        (N,) [s], uniform.
    specific_force, rates, air_data, controls : array_like
        (N, 3) [m/s^2], (N, 3) [rad/s], (N, 3) [Va m/s, alpha rad, beta rad] and (N, 4)
        [elevator, aileron, rudder rad, throttle 0..1], as
        :func:`~drake_uav.identification.samples.isolation.isolate_coefficients` takes them.
    motor_speed : array_like, optional
        (N,) [rad/s].
    window : float
        The Savitzky-Golay smoothing [s].
    folds : int
        The number of held-out blocks.
    raw_noise_variance : Mapping, optional
        The raw white-noise variance of ``airspeed, alpha, motor_speed, ax`` where known.

    Returns
    -------
    ThrustModel
        The propeller's C_T0, C_T1 with a motor speed, a throttle/airspeed correction of
        the catalog model without it, or (with an
        :class:`~.statistics.regression.InsufficientExcitationWarning`) the catalog model
        when the data cannot tell thrust from C_X0 (:class:`ThrustDiagnostics`).

    Raises
    ------
    ValueError
        When the flight is too short for the held-out blocks or an array's shape is wrong.

    Examples
    --------
    >>> import warnings
    >>> from importlib.resources import files
    >>> from drake_uav.identification.samples.flight_data import gridded_log
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> grid = gridded_log(log, aerosonde())
    >>> flight = grid.log
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     model = identify_thrust(aerosonde(), flight.time, flight.stack(SPECIFIC_FORCE),
    ...                             flight.stack(RATES), flight.stack(AIR_DATA), grid.controls)
    >>> model.source, caught[0].category.__name__     # too little throttle: the catalog
    ('catalog', 'InsufficientExcitationWarning')
    """
    time = np.asarray(time, dtype=float)
    arrays = _checked(len(time), specific_force=specific_force, rates=rates,
                      air_data=air_data, controls=controls, motor_speed=motor_speed)
    if len(time) < 10 * folds:
        raise ValueError(f"identify_thrust: {len(time)} samples are too few for {folds} "
                         "held-out blocks")
    source = "throttle" if motor_speed is None else "motor_speed"
    if source == "motor_speed":
        catalog_propeller(params)  # a diameter is needed
    data = _smoothed_data(params, time, arrays["specific_force"], arrays["rates"],
                          arrays["air_data"], arrays["controls"], arrays["motor_speed"],
                          window)
    variance = _noise_variance(time, arrays, window, raw_noise_variance)
    terms, rmse = _select_terms(params, source, data, folds, variance)
    catalog = ThrustModel(params, "catalog", (), np.zeros(0), np.zeros((0, 0)))
    if not terms:
        diagnostics = ThrustDiagnostics(math.nan, math.nan, math.nan, rmse, True,
                                        "the catalog model predicts best on held-out data")
        return dataclasses.replace(catalog, diagnostics=diagnostics)
    X, z, noise = _noise(params, source, data, terms, variance)
    fit = bcls(X, z, noise, names=DRAG_TERMS + tuple(terms))
    n = len(DRAG_TERMS)
    model = ThrustModel(params, source, tuple(terms), fit.estimate[n:], fit.covariance[n:, n:],
                        drag_coefficients=fit.estimate[:n], drag_sigma=fit.sigma[:n])
    prediction = model.thrust(data.airspeed, data.throttle, data.motor_speed)
    diagnostics = _diagnostics(X, n, prediction.std, prediction.thrust, rmse, source)
    if not diagnostics.identifiable:
        warnings.warn(f"identify_thrust: {diagnostics.message}", InsufficientExcitationWarning,
                      stacklevel=2)
        return dataclasses.replace(catalog, diagnostics=diagnostics)
    return dataclasses.replace(model, diagnostics=diagnostics)


def declared_thrust(grid: GriddedLog, params: FixedWingParams,
                    propeller: PropellerTable) -> dict[str, object]:
    """The thrust of a flight from a declared propeller table and the logged shaft speed:
    ``T = rho n^2 D^4 C_T(J)`` with the table's quadratic C_T(J), nothing fitted.

    Parameters
    ----------
    grid : GriddedLog
        The flight on its grid; it must hold ``motor_speed`` [rad/s].
    params : FixedWingParams
        The aircraft (its air density).
    propeller : PropellerTable
        The declared table (:func:`~drake_uav.io.propeller_table.read_propeller_table`).

    Returns
    -------
    dict
        ``thrust`` [N], ``thrust_airspeed_slope`` [N/(m/s)] (at the logged shaft speed),
        ``thrust_speed_slope`` [N/(rad/s)] and ``shaft_speed`` [rad/s] (which carry the
        speed's noise into the thrust), no ``thrust_correction_terms``,
        ``thrust_from_shaft_speed`` True: the keyword arguments of
        :func:`~drake_uav.identification.samples.isolation.isolate_coefficients`.

    Raises
    ------
    FlightLogError
        When the log holds no shaft speed.
    """
    uniform = grid.log
    if "motor_speed" not in uniform:
        raise FlightLogError(f"{propeller.source}: a declared propeller table needs the "
                             "propeller's shaft speed in the log (motor_speed: an RPM sensor, "
                             "or the one ESC's esc_rpm_0); none is logged")
    diameter, coefficients = propeller.diameter, propeller.thrust_coefficients
    speed, airspeed = uniform["motor_speed"], uniform["pitot_airspeed"]
    slopes = thrust_regressor_airspeed_slopes(params.rho, _speed_diameter(speed, diameter),
                                              airspeed, diameter)

    def thrust(shaft_speed):
        return propeller_thrust(params.rho, _speed_diameter(shaft_speed, diameter), airspeed,
                                diameter, coefficients)

    return {"thrust": thrust(speed),
            "thrust_airspeed_slope": sum(c * x for c, x in zip(coefficients, slopes,
                                                               strict=True)),
            "thrust_correction_terms": (), "thrust_from_shaft_speed": True,
            **_shaft_speed_noise_path(thrust, speed)}


SPEED_STEP = 0.1
"""Finite-difference step of the shaft speed [rad/s] for d(thrust)/d(speed)."""


def _shaft_speed_noise_path(thrust, speed: np.ndarray) -> dict[str, np.ndarray]:
    """``thrust_speed_slope`` (central difference of ``thrust(speed)`` [N/(rad/s)]) and
    ``shaft_speed``: the isolation's keywords that carry the speed's noise into a thrust
    computed from it."""
    return {"thrust_speed_slope": (thrust(speed + SPEED_STEP) - thrust(speed - SPEED_STEP))
            / (2.0 * SPEED_STEP), "shaft_speed": speed}


def thrust_from_gridded_log(grid: GriddedLog, params: FixedWingParams,
                            throttle_delay: float | None = None) -> dict[str, object]:
    """The thrust of a flight identified with C_X (:func:`identify_thrust`), as the
    isolation takes it: the main job's thrust step, between
    :func:`~drake_uav.identification.samples.flight_data.gridded_log` and
    :func:`~drake_uav.identification.samples.flight_data.isolated_samples`.

    The thrust comes from the motor speed when logged, else from a throttle and airspeed
    correction of the catalog model; when the flight cannot tell thrust from drag it
    falls back to the catalog model with a warning.

    Parameters
    ----------
    grid : GriddedLog
        The flight on its grid.
    params : FixedWingParams
        The aircraft (its catalog propulsion model).
    throttle_delay : float, optional
        A servo delay measured before [s] (the data-compatibility check's command time
        skew). The throttle correction is fitted on the throttle that delay late, as the
        motor saw it, while the coefficients are still isolated with the logged one, so
        the delay stays in them for the discovery to name (its thrust column takes the
        difference). Without it, a throttle that moves within the delay biases the
        correction's terms, and their error reaches C_L as a body-x force.

    Returns
    -------
    dict
        ``thrust`` [N], ``thrust_airspeed_slope`` [N/(m/s)] and
        ``thrust_correction_terms`` and ``thrust_from_shaft_speed`` (from the shaft speed,
        also ``thrust_speed_slope`` and ``shaft_speed``, :func:`declared_thrust`), the
        keyword arguments of
        :func:`~drake_uav.identification.samples.isolation.isolate_coefficients`; empty
        when the catalog model predicts best or the data cannot tell.

    Raises
    ------
    FlightLogError
        When the flight is too short for the held-out blocks of the thrust fit.
    """
    uniform, controls = grid.log, grid.controls
    speed = uniform["motor_speed"] if "motor_speed" in uniform else None
    seen = controls
    if throttle_delay is not None and speed is None:
        seen = controls.copy()
        seen[:, 3] = delayed(uniform.time, controls[:, 3], throttle_delay)
    try:
        model = identify_thrust(params, uniform.time, uniform.stack(SPECIFIC_FORCE),
                                uniform.stack(RATES), uniform.stack(AIR_DATA), seen, speed,
                                raw_noise_variance=grid.noise_variance)
    except ValueError as err:
        raise FlightLogError(f"thrust from pitot_airspeed, imu_ax and cmd_throttle: {err}"
                             ) from None
    if not model.terms:
        return {}
    airspeed = uniform["pitot_airspeed"]
    value, _, slope = model.thrust(airspeed, controls[:, 3], speed)
    out = {"thrust": value, "thrust_airspeed_slope": slope,
           "thrust_correction_terms": model.terms if model.source == "throttle" else (),
           "thrust_from_shaft_speed": model.source == "motor_speed"}
    if model.source == "motor_speed":
        out |= _shaft_speed_noise_path(
            lambda shaft_speed: model.thrust(airspeed, controls[:, 3], shaft_speed)[0], speed)
    return out
