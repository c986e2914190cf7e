"""Named physical effects a baseline aerodynamic model may lack.

Each :class:`Effect` turns flight samples (:class:`AeroSamples`) into extra
regressor columns for the coefficients it can enter, and says in one line what
it is physically. The discovery loop (:mod:`drake_uav.identification.discovery.loop`)
tries them against the residual of the baseline fit; :func:`product_candidates`
is the data-driven fallback (products of available signals) used when no named
effect explains the residual.

Accelerometer scale-factor and misalignment errors are not in the library:
their columns are built from the measured specific force, the very data the
force coefficients are computed from, so in equation error they would
"explain" any residual. They are identifiable only in output error.

Kinds: ``"aerodynamic"`` effects change the forces and moments the aircraft
feels (they enter the reconstruction); ``"sensor"`` effects only corrupt the
measured coefficients (they are removed from the data, not added to the
dynamics).

Signals some effects read from ``AeroSamples.signals``: ``height`` (height above
ground [m]), ``roll``, ``pitch``, ``yaw`` [rad].

:func:`logged_effects` turns the log's extra channels (``logged:<channel>`` signals: a
tension, a voltage, an ESC's speed) into data-driven candidates of their own: the
channel, and its product with alpha or beta.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Mapping

import numpy as np

from drake_uav.identification.discovery.evidence import Candidate
from drake_uav.identification.samples.aero_samples import LOGGED, AeroSamples
from drake_uav.identification.samples.segments import delayed
from drake_uav.model.coefficients import LATERAL_COEFFICIENTS as LATERAL
from drake_uav.model.coefficients import LONGITUDINAL_COEFFICIENTS as LONGITUDINAL
from drake_uav.model.coefficients import body_to_lift_drag, signal_values
from drake_uav.model.isolation import differentiate, lever_arm_specific_force
from drake_uav.model.rotations import euler_to_rotmat
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = [
    "Effect",
    "effect_library",
    "logged_effects",
    "LOGGED_FORCE_UNITS",
    "product_candidates",
    "base_signals",
    "BASE_SIGNALS",
    "PRODUCT_KEYS",
    "LONGITUDINAL",
    "LATERAL",
    "FORCES",
    "EXTERNAL_FORCE",
]

FORCES = ("CL", "CD", "CY")

EXTERNAL_FORCE = "an external force"
"""Physical origin of every force effect (:attr:`Effect.origin`): a force along a body axis,
fixed in the NED frame, at or away from the centre of gravity are variants of one
explanation."""

ColumnFunction = Callable[[AeroSamples, FixedWingParams], Mapping[str, np.ndarray]]


@dataclasses.dataclass(frozen=True)
class Effect:
    """A physical effect: its regressor columns per coefficient and what it means.

    Attributes
    ----------
    name : str
        Short name, used in column names (``"<name>:<column>"``) and reports.
    explanation : str
        One line on the physics.
    coefficients : tuple of str
        Coefficients the effect may enter.
    columns : callable
        ``columns(samples, params, coefficient) -> {column name: values}``.
    kind : str
        ``"aerodynamic"`` (changes the dynamics) or ``"sensor"`` (corrupts the data).
    signals : tuple of str
        ``AeroSamples.signals`` entries the effect needs.
    condition : callable or None
        Extra requirement on the data for the effect to be testable.
    blind_folds : int
        Blocked cross-validation folds the effect cannot improve by construction, which the
        evidence rule does not ask it to: 1 for a linear drift, whose middle fold a constant
        fitted on the folds either side already predicts.
    origin : str
        Its physical origin (:attr:`~drake_uav.identification.discovery.evidence.Candidate.
        origin`): effects of one origin are variants of one explanation; empty: its name.

    Examples
    --------
    >>> cubic = Effect("lift_break", "the lift falls off with the cube of alpha", ("CL",),
    ...                lambda samples, params, k: {"alpha3": samples.condition.alpha ** 3})
    >>> cubic.kind
    'aerodynamic'
    """

    name: str
    explanation: str
    coefficients: tuple[str, ...]
    columns: Callable[[AeroSamples, FixedWingParams, str], Mapping[str, np.ndarray]]
    kind: str = "aerodynamic"
    signals: tuple[str, ...] = ()
    condition: Callable[[AeroSamples], bool] | None = None
    blind_folds: int = 0
    origin: str = ""

    def candidate(self, params: FixedWingParams) -> Candidate:
        """The effect as a plant-agnostic candidate of the evidence rule.

        On the samples each coefficient is measured with (:meth:`AeroSamples.aligned`).

        Parameters
        ----------
        params : FixedWingParams
            The aircraft the columns are computed for.

        Returns
        -------
        Candidate
            The candidate.
        """
        return Candidate(self.name, self.explanation, self.coefficients,
                         lambda samples, k: self.columns(samples.aligned(k), params, k),
                         blind_folds=self.blind_folds, kind=self.kind, origin=self.origin)

    @property
    def physical_origin(self) -> str:
        """:attr:`origin`, or the effect's name when none is given."""
        return self.origin or self.name

    def available(self, samples: AeroSamples) -> bool:
        """Whether the samples carry every signal the effect needs (and meet its condition).

        Parameters
        ----------
        samples : AeroSamples
            The samples.

        Returns
        -------
        bool
            True when the effect can be tested on them.
        """
        if not all(s in samples.signals for s in self.signals):
            return False
        return self.condition is None or bool(self.condition(samples))


def _normalised(samples, params) -> dict:
    """The coefficient model's regressor signals (normalised rates: b p / 2Va, ...)."""
    return signal_values(samples.condition, params.b, params.c)


def _same_for_all(function: ColumnFunction):
    def columns(samples, params, coefficient):
        return function(samples, params)
    return columns


def _stall(samples, params):
    a = samples.condition.alpha
    return {"alpha3": a**3, "alpha4": a**4}


def _alphadot(samples, params):
    return {"alphadot": _normalised(samples, params)["alphadot"]}


def _propwash(samples, params):
    return {"Tc": samples.condition.thrust_coefficient}


def _control_nonlinearity(samples, params):
    c = samples.condition
    return {"elevator2": c.elevator**2, "alpha_elevator": c.alpha * c.elevator,
            "aileron_abs_aileron": c.aileron * np.abs(c.aileron),
            "rudder_abs_rudder": c.rudder * np.abs(c.rudder)}


def _cross_coupling(samples, params, coefficient):
    c = samples.condition
    if coefficient in LONGITUDINAL:
        return {"aileron_abs": np.abs(c.aileron), "rudder_abs": np.abs(c.rudder)}
    return {"elevator": c.elevator}


def _rate_coupling(samples, params):
    signals = _normalised(samples, params)
    pn, qn, rn = signals["p"], signals["q"], signals["r"]
    return {"p_r": pn * rn, "p_q": pn * qn, "q_r": qn * rn}


def _to_coefficient(force_x, force_y, force_z, samples, coefficient):
    """Maps body-axis force-coefficient columns to the CL / CD / CY column."""
    if coefficient == "CY":
        return force_y
    # (CL, CD) are linear in (C_X, C_Z), so columns map like coefficients.
    lift, drag = body_to_lift_drag(force_x, force_z, samples.condition.alpha)
    return lift if coefficient == "CL" else drag


def _force_columns(vectors: Mapping[str, np.ndarray], samples, coefficient):
    """Columns of body-axis force directions (N, 3), as coefficient columns."""
    return {name: _to_coefficient(v[:, 0], v[:, 1], v[:, 2], samples, coefficient)
            for name, v in vectors.items()}


def _per_unit_force(samples, params):
    # Divides by the same measured qbar as the coefficients: the errors-in-variables
    # correction of the discovery loop accounts for the shared airspeed noise.
    return params.mass / (samples.dynamic_pressure * params.S)


def _body_force(samples, params, coefficient):
    k = _per_unit_force(samples, params)[:, None]
    axes = np.eye(3)
    return _force_columns({f"force_{a}": k * axes[i] for i, a in enumerate("xyz")},
                          samples, coefficient)


def _ned_force(samples, params, coefficient):
    rotation = euler_to_rotmat(np.array([samples.signals[s] for s in ("roll", "pitch", "yaw")]))
    k = _per_unit_force(samples, params)[:, None]
    # Row i of the body -> NED rotation is NED axis i in body components.
    return _force_columns({f"force_{axis}": k * rotation[i].T
                           for i, axis in enumerate(("north", "east", "down"))},
                          samples, coefficient)


def _lever_arm(samples, params, coefficient):
    k = _per_unit_force(samples, params)[:, None]
    c = samples.condition
    per_metre = lever_arm_specific_force(samples.rate_derivatives,
                                         np.column_stack([c.p, c.q, c.r]))
    return _force_columns({f"lever_arm_{axis}": k * per_metre[:, i]
                           for i, axis in enumerate("xyz")}, samples, coefficient)


MIN_HEADING_SPREAD = 0.5
"""Smallest circular spread 1 - |mean(exp(i psi))| of the heading for the steady-wind test:
on a straight leg the wind columns equal a constant force and cannot be told apart."""


def _heading_varies(samples) -> bool:
    yaw = samples.signals["yaw"]
    return 1.0 - abs(np.mean(np.exp(1j * yaw))) >= MIN_HEADING_SPREAD


def _wind_left(samples, params, coefficient):
    c = samples.condition
    yaw = samples.signals["yaw"]
    # A steady wind W left in the air data errs Va by -(W_N cos psi + W_E sin psi) and
    # beta by (W_N sin psi - W_E cos psi) / Va (level flight): regress on both shapes.
    if coefficient in LATERAL:
        return {"wind_cos_yaw": np.cos(yaw) / c.airspeed, "wind_sin_yaw": np.sin(yaw) / c.airspeed}
    return {"wind_cos_yaw": np.cos(yaw) / c.airspeed**2,
            "wind_sin_yaw": np.sin(yaw) / c.airspeed**2}


_SURFACE_COEFFICIENTS = {"elevator": LONGITUDINAL, "aileron": LATERAL, "rudder": LATERAL}


def _thrust_error(samples: AeroSamples, delay: float | None) -> np.ndarray:
    """The real thrust minus the modelled one [N] when the throttle acts ``delay`` [s] after
    its logged command (None: its first-order term, per second of delay). Only the
    throttle's part of the thrust lags, not its change with the airspeed."""
    airspeed = samples.condition.airspeed
    if delay is None:
        error = -differentiate(samples.time, samples.thrust)
        if samples.thrust_airspeed_slope is not None:
            error += samples.thrust_airspeed_slope * differentiate(samples.time, airspeed)
        return error
    error = delayed(samples.time, samples.thrust, delay) - samples.thrust
    if samples.thrust_airspeed_slope is not None:
        error += samples.thrust_airspeed_slope * (
            airspeed - delayed(samples.time, airspeed, delay))
    return error


def _actuator_delay(delay: float | None):
    """Columns of a servo delay. With the delay ``delay`` [s] the data-compatibility check
    measured, every command as the aircraft saw it, shifted by that delay, minus the logged
    one: a surface's column has its control derivative as parameter, the thrust's 1. With
    None (no delay measured), the first-order terms: ``delta(t - tau) ~ delta(t) - tau
    d(delta)/dt``, minus the command rates, the delay [s] times the derivative as
    parameter. The first order misses much of a delay of a command that moves within the
    delay (the safety pilot's throttle in turbulence): what it leaves on C_D, several times
    the noise floor of the default sensors, was taken up by drag terms beside it. A thrust
    from the logged shaft speed already follows the throttle as the motor did: no throttle
    column then (it would be the thrust's own noise, which the measured C_D carries too)."""
    def shift(samples, values):
        if delay is None:
            return -differentiate(samples.time, values)
        return delayed(samples.time, values, delay) - values

    suffix = "rate" if delay is None else "delayed"

    def columns(samples, params, coefficient):
        out = {}
        for surface, affected in _SURFACE_COEFFICIENTS.items():
            if coefficient in affected:
                out[f"{surface}_{suffix}"] = shift(samples,
                                                    getattr(samples.condition, surface))
        if coefficient in ("CL", "CD") and not samples.thrust_from_shaft_speed:
            per_force = 1.0 / (samples.dynamic_pressure * samples.reference_area)
            error = _thrust_error(samples, delay) * per_force
            lift, drag = body_to_lift_drag(error, 0.0 * error, samples.condition.alpha)
            out[f"throttle_{suffix}"] = lift if coefficient == "CL" else drag
        return out
    return columns


def _ground_effect(samples, params, coefficient):
    h = np.maximum(samples.signals["height"], 0.0)
    # McCormick's induced-drag factor: fraction of free-air induced drag lost near ground.
    x = (16.0 * h / params.b) ** 2
    phi = 1.0 / (1.0 + x)
    return {"ground": phi, "ground_alpha": phi * samples.condition.alpha}


DRIFT_TIME_SCALE = 100.0
"""Time unit [s] of the drift columns: their parameters are changes per 100 s."""


def _drift(samples, params, coefficient):
    # Log time, never a sample index: joined spans keep their gaps, and the training part
    # and the held-out tail are built separately, so the column must be the same function
    # of time on both (a per-part centring would not be). The baseline's constant and
    # alpha (beta) terms absorb the time origin.
    tau = samples.time / DRIFT_TIME_SCALE
    main = "beta" if coefficient in LATERAL else "alpha"
    return {"drift": tau, f"drift_{main}": tau * getattr(samples.condition, main)}


def effect_library(command_delay: float | None = None) -> list[Effect]:
    """The named effects, in the order they are reported.

    Parameters
    ----------
    command_delay : float, optional
        The delay [s] of the commands the data-compatibility check measured, which the
        servo delay's columns then use (None: their first-order form).

    Returns
    -------
    list of Effect

    Examples
    --------
    >>> [e.name for e in effect_library()][:3]
    ['stall_onset', 'unsteady_alphadot', 'thrust_propwash']
    """
    return [
        Effect("stall_onset", "lift and drag bend away from linear at high angle of attack "
               "(flow separation): higher powers of alpha", LONGITUDINAL,
               _same_for_all(_stall), origin="flow separation"),
        Effect("unsteady_alphadot", "unsteady aerodynamics: downwash lag at the tail makes "
               "lift and pitching moment depend on the rate of change of alpha",
               LONGITUDINAL, _same_for_all(_alphadot), origin="unsteady aerodynamics"),
        Effect("thrust_propwash", "propeller slipstream over wing and tail: forces and moments "
               "grow with the thrust coefficient (C_D_Tc of Vaiopoulos 2017, eq. 6.2)",
               ("CL", "CD", "Cm", "Cn"), _same_for_all(_propwash),
               origin="the propeller slipstream"),
        Effect("control_nonlinearity", "control-surface effectiveness is not linear: squared "
               "deflections and deflection-alpha products", ("CL", "CD", "Cm", "Cl", "Cn", "CY"),
               _same_for_all(_control_nonlinearity), origin="the control surfaces"),
        Effect("control_cross_coupling", "a surface acts on the other axis (e.g. elevator "
               "rolling moment, aileron drag)", ("CL", "CD", "Cm", "Cl", "Cn", "CY"),
               _cross_coupling, origin="the control surfaces"),
        Effect("rate_coupling", "aerodynamic or gyroscopic coupling of body rates "
               "(products of normalised rates)", ("Cl", "Cm", "Cn"),
               _same_for_all(_rate_coupling), origin="rate coupling"),
        Effect("constant_body_force", "a constant body-axis force the model lacks (tow, "
               "payload drag), or equivalently in equation error an accelerometer bias",
               FORCES, _body_force, origin=EXTERNAL_FORCE),
        Effect("ned_force", "a force fixed in the NED frame (weight or mass error, tether "
               "along a fixed direction)", FORCES, _ned_force,
               signals=("roll", "pitch", "yaw"), origin=EXTERNAL_FORCE),
        Effect("accelerometer_lever_arm", "accelerometer away from the centre of gravity: it "
               "also reads angular and centripetal acceleration", FORCES, _lever_arm,
               kind="sensor", origin="the accelerometer's position"),
        Effect("steady_wind_in_air_data", "a steady wind left in the air data: airspeed and "
               "sideslip errors that follow the heading", ("CL", "CD", "CY", "Cl", "Cn", "Cm"),
               _wind_left, kind="sensor", signals=("yaw",), condition=_heading_varies,
               origin="the air data"),
        Effect("actuator_time_delay", "the surfaces lag the logged commands (servo delay): "
               + ("the command rate enters with the delay as coefficient"
                  if command_delay is None else
                  f"the commands act {command_delay * 1e3:.0f} ms after they are logged, as "
                  "the data-compatibility check measured"),
               ("CL", "CD", "Cm", "CY", "Cl", "Cn"), _actuator_delay(command_delay),
               origin="the actuators"),
        Effect("ground_effect", "the ground reduces downwash near the runway: more lift, "
               "less induced drag below about one span", ("CL", "CD", "Cm"), _ground_effect,
               signals=("height",), origin="the ground"),
        Effect("coefficient_drift", "a coefficient that drifts slowly over the flight "
               "(icing, fuel burn, a loosening surface): its constant and its alpha (beta) "
               "derivative change linearly with the log time", LONGITUDINAL + LATERAL,
               _drift, blind_folds=1, origin="a slow change of the aircraft"),
    ]


BASE_SIGNALS = {"alpha": "alpha", "beta": "beta", "p_hat": "p", "q_hat": "q", "r_hat": "r",
                "elevator": "elevator", "aileron": "aileron", "rudder": "rudder", "Tc": "Tc"}
"""Names of the data-driven base signals -> the coefficient model's regressor signals."""

PRODUCT_KEYS = tuple(itertools.combinations_with_replacement(BASE_SIGNALS, 2))
"""The pairs of :data:`BASE_SIGNALS` whose products are the data-driven candidates."""


def base_signals(samples: AeroSamples, params: FixedWingParams) -> dict[str, np.ndarray]:
    """Signals whose products form the data-driven fallback candidates.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    params : FixedWingParams
        The aircraft (reference lengths of the normalised rates).

    Returns
    -------
    dict of str to numpy.ndarray
        Name (:data:`BASE_SIGNALS`) -> (N,) values.
    """
    signals = _normalised(samples, params)
    return {name: signals[signal] for name, signal in BASE_SIGNALS.items()}


def product_candidates(samples: AeroSamples, params: FixedWingParams
                       ) -> dict[tuple[str, ...], np.ndarray]:
    """Squares and pairwise products of :func:`base_signals`.

    Parameters
    ----------
    samples : AeroSamples
        The samples.
    params : FixedWingParams
        The aircraft.

    Returns
    -------
    dict of (str, str) to numpy.ndarray
        Signal-name pair (:data:`PRODUCT_KEYS`) -> (N,) product.
    """
    signals = base_signals(samples, params)
    return {(a, b): signals[a] * signals[b] for a, b in PRODUCT_KEYS}


LOGGED_FORCE_UNITS = ("N", "N m")
"""Units of a logged channel that is a force or a moment: it enters a coefficient over
``qbar S``, so that its parameter is the share of the force along the coefficient's axis
(or, for a moment coefficient, the arm over the reference length)."""


def _logged_columns(key: str, main: str | None, reference: float):
    """The column of the logged channel ``key`` (times the condition's ``main`` signal
    less ``reference``)."""
    def columns(samples, params, coefficient):
        value = samples.signals[key]
        if samples.signal_units.get(key) in LOGGED_FORCE_UNITS:
            value = value / (samples.dynamic_pressure * samples.reference_area)
        name = key.removeprefix(LOGGED)
        if main is None:
            return {name: value}
        return {f"{name}*{main}": value * (getattr(samples.condition, main) - reference)}
    return columns


def logged_effects(samples: AeroSamples) -> list[Effect]:
    """The data-driven candidates of the log's extra channels.

    Per ``logged:<channel>`` entry of ``samples.signals``: the channel itself on every
    coefficient and its product with alpha (C_L, C_D, C_m) and with beta (C_Y, C_l, C_n);
    a channel in N or N m enters over ``qbar S`` (:data:`LOGGED_FORCE_UNITS`). The product
    takes alpha (beta) about its mean over ``samples``, one constant for the training and
    the held-out parts alike: alpha hardly leaves its trim value, and the plain product
    would be the channel itself again, scaled.

    Parameters
    ----------
    samples : AeroSamples
        The samples.

    Returns
    -------
    list of Effect
        One effect per channel (kind "aerodynamic").
    """
    out = []
    for key in (k for k in samples.signals if k.startswith(LOGGED)):
        channel, unit = key.removeprefix(LOGGED), samples.signal_units.get(key, "1")
        term = f"{channel} / (qbar S)" if unit in LOGGED_FORCE_UNITS else channel
        what = f"the logged channel {channel} [{unit}]"
        out.append(Effect(key, f"{what} moves the coefficient: it enters as {term}",
                          LONGITUDINAL + LATERAL, _logged_columns(key, None, 0.0),
                          signals=(key,), origin=what))
        for main, coefficients in (("alpha", LONGITUDINAL), ("beta", LATERAL)):
            mean = float(np.mean(getattr(samples.condition, main)))
            out.append(Effect(f"{key}*{main}", f"{what} changes the coefficient's {main} "
                              f"derivative: it enters as {term} x ({main} - {mean:.4g} rad)",
                              coefficients, _logged_columns(key, main, mean), signals=(key,),
                              origin=what))
    return out
