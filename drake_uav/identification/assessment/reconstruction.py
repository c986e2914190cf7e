"""Output-error validation: reconstruct air data and body rates with an identified model.

Vaiopoulos 2017, sec. 6.5.2 integrates the wind-axis force equations (eq. 6.4-6.6),
driven by the logged rates, attitude, thrust and surfaces, with the identified
coefficients, and corrects the integration periodically from GPS because the
gyros are noisy. Here the same dynamics are integrated in their body-axis form
(equal to eq. 6.4-6.6 for a constant wind)::

    d v_r / dt = (qbar S [C_X, C_Y, C_Z] + [T, 0, 0]) / m + g_body(phi, theta) - w x v_r

with (C_X, C_Z) from the identified (C_L, C_D) and the stability triplet from
:func:`air_data_from_velocity`. The body rates are integrated too, with the
identified moment coefficients, so that moment effects show in output error
(Vaiopoulos 2017 drives the force equations with the measured rates instead).

Every ``reset_interval`` seconds the state is reset to the measured air data
and rates (the periodic correction, whose law and period Vaiopoulos 2017 does not give).
Baseline terms are evaluated at the reconstructed state; columns of added
effects on the logged signals; effects of kind ``"sensor"`` are left out (they
describe the data, not the aircraft).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping

import numpy as np

from drake_uav.identification.samples.aero_samples import AeroSamples
from drake_uav.model.air_data import air_data_from_velocity, velocity_from_air_data
from drake_uav.model.coefficients import (
    COEFFICIENTS,
    AeroCondition,
    lift_drag_to_body,
    signal_values,
    split_derivative_name,
)
from drake_uav.model.fixed_wing import FixedWingModel, body_gravity, body_velocity_rate
from drake_uav.model.rotations import euler_to_rotmat
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["Reconstruction", "reconstruct"]


@dataclasses.dataclass(frozen=True)
class Reconstruction:
    """Measured and reconstructed air data and body rates, and their mean absolute errors.

    Attributes
    ----------
    time : numpy.ndarray of shape (N,)
        [s].
    measured : numpy.ndarray of shape (N, 6)
        Va [m/s], alpha, beta [rad], p, q, r [rad/s] from the log.
    reconstructed : numpy.ndarray of shape (N, 6)
        The integrated model.
    reset_interval : float
        [s] between the restarts from the measured state.
    divergences : int
        Integrations that blew up (non-finite or airspeed beyond twice the logged maximum)
        and were restarted early from the measurements; their samples are left out.

    Examples
    --------
    >>> import numpy as np
    >>> from importlib.resources import files
    >>> from drake_uav.identification import baseline_names, samples_from_log
    >>> from drake_uav.model.coefficients import COEFFICIENTS
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> catalog = aerosonde().derivatives                 # the catalog model, name -> value
    >>> models = {k: (tuple(names), np.array([catalog.get(n, 0.0) for n in names]),
    ...               np.zeros((len(samples), len(names))))   # no effect columns
    ...           for k in COEFFICIENTS for names in [baseline_names(aerosonde(), k)]}
    >>> result = reconstruct(samples, aerosonde(), models)
    >>> result.measured.shape, result.divergences
    ((1000, 6), 0)
    """

    time: np.ndarray
    measured: np.ndarray
    reconstructed: np.ndarray
    reset_interval: float
    divergences: int = 0

    @property
    def mae(self) -> np.ndarray:
        """Mean absolute error of Va [m/s], alpha, beta [rad], p, q, r [rad/s]."""
        return np.nanmean(np.abs(self.reconstructed - self.measured), axis=0)


def _split_terms(names, estimate, design, exclude_prefixes):
    """Baseline (signal, theta) terms and the exogenous sum of effect columns."""
    baseline = []
    exogenous = np.zeros(design.shape[0])
    for i, name in enumerate(names):
        if ":" in name:
            if not any(name.startswith(p + ":") for p in exclude_prefixes):
                exogenous += estimate[i] * design[:, i]
        else:
            baseline.append((split_derivative_name(name)[1], float(estimate[i])))
    return baseline, exogenous


def reconstruct(samples: AeroSamples, params: FixedWingParams,
                models: Mapping[str, tuple[tuple[str, ...], np.ndarray, np.ndarray]],
                exclude_prefixes: Collection[str] = (), reset_interval: float = 5.0
                ) -> Reconstruction:
    """Integrates air-relative velocity and body rates with the identified model.

    The rotational part is the plant's own :meth:`FixedWingModel.angular_acceleration`.

    Parameters
    ----------
    samples : AeroSamples
        The flight; ``samples.signals`` must hold ``roll`` and ``pitch`` [rad].
    params : FixedWingParams
        The aircraft.
    models : Mapping
        Each of ``CL, CD, CY, Cl, Cm, Cn`` -> ``(names, estimate, design)``: the term
        names, their values and the (N, n) regressor matrix on ``samples`` (used for
        effect columns).
    exclude_prefixes : collection of str
        Terms whose name starts with one of these are left out.
    reset_interval : float
        [s] between the restarts from the measured state.

    Returns
    -------
    Reconstruction
        Measured and reconstructed airspeed, alpha, beta, p, q, r and their mean absolute
        errors.

    Raises
    ------
    ValueError
        When a coefficient's model is missing or ``samples`` lack the attitude.

    Examples
    --------
    >>> import numpy as np
    >>> from importlib.resources import files
    >>> from drake_uav.identification import baseline_names, samples_from_log
    >>> from drake_uav.model.coefficients import COEFFICIENTS
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde()).subset(slice(0, 1000))   # 20 s
    >>> catalog = aerosonde().derivatives                 # the catalog model, name -> value
    >>> models = {k: (tuple(names), np.array([catalog.get(n, 0.0) for n in names]),
    ...               np.zeros((len(samples), len(names))))   # no effect columns
    ...           for k in COEFFICIENTS for names in [baseline_names(aerosonde(), k)]}
    >>> mae = reconstruct(samples, aerosonde(), models).mae
    >>> mae.shape, bool(mae[0] < 1.0)                     # Va within 1 m/s on average
    ((6,), True)
    """
    for key in ("roll", "pitch"):
        if key not in samples.signals:
            raise ValueError(f"reconstruct: samples.signals lacks '{key}'")
    if not reset_interval > 0:
        raise ValueError(f"reconstruct: reset_interval must be positive, got {reset_interval}")
    terms = {k: _split_terms(*models[k], exclude_prefixes) for k in COEFFICIENTS}
    c = samples.condition
    measured = np.column_stack([c.airspeed, c.alpha, c.beta, c.p, c.q, c.r])
    out, divergences = _integrate(_derivative(samples, params, terms), samples.time, measured,
                                  reset_interval)
    return Reconstruction(time=samples.time.copy(), measured=measured, reconstructed=out,
                          reset_interval=reset_interval, divergences=divergences)


def _derivative(samples: AeroSamples, params: FixedWingParams, terms):
    """``f(i, y)``: d/dt of y = (u, v, w, p, q, r) [m/s, rad/s] at sample i, driven by the
    logged attitude, surfaces and thrust (module docstring). ``i`` may be an index array
    and ``y`` a (6, W) array: W states at W samples at once."""
    c = samples.condition
    n = len(samples)
    controls = np.column_stack([c.elevator, c.aileron, c.rudder, c.flap])
    model = FixedWingModel(params)
    thrust = samples.thrust
    torque = np.broadcast_to(model.thrust(c.airspeed, samples.throttle)[1], (n,))
    roll, pitch = samples.signals["roll"], samples.signals["pitch"]
    rotation = euler_to_rotmat(np.array([roll, pitch, 0.0 * roll]))  # gravity is yaw-free
    gravity = np.column_stack(body_gravity(rotation, params.gravity))
    m = params.mass

    def derivative(i, y) -> np.ndarray:
        u, v, w, p, q, r = y
        Va, alpha, beta = air_data_from_velocity(u, v, w)
        q_bar_s = model.dynamic_pressure_area(Va)
        cond = AeroCondition(Va, alpha, beta, p, q, r, controls[i, 0], controls[i, 1],
                             controls[i, 2], controls[i, 3], c.alphadot[i], thrust[i] / q_bar_s)
        signals = signal_values(cond, params.b, params.c)
        coef = {k: exogenous[i] + sum(theta * signals[s] for s, theta in baseline)
                for k, (baseline, exogenous) in terms.items()}
        CX, CZ = lift_drag_to_body(coef["CL"], coef["CD"], alpha)
        wrench = model.aerodynamic_wrench(
            (CX, coef["CY"], CZ, coef["Cl"], coef["Cm"], coef["Cn"]), q_bar_s)
        accel = ((wrench[0] + thrust[i]) / m + gravity[i, 0], wrench[1] / m + gravity[i, 1],
                 wrench[2] / m + gravity[i, 2])
        moment = (wrench[3] + torque[i], wrench[4], wrench[5])
        return np.array([*body_velocity_rate((u, v, w), (p, q, r), accel),
                         *model.angular_acceleration((p, q, r), moment)])

    return derivative


def _integrate(derivative, t: np.ndarray, measured: np.ndarray, reset_interval: float):
    """Heun (RK2) integration of ``derivative`` over the sample times ``t``, reset to the
    ``measured`` (N, 6) air data and rates every ``reset_interval`` [s] and after a blow-up
    (non-finite, or airspeed beyond twice the largest measured). Returns the (N, 6)
    reconstructed air data and rates (NaN where an integration blew up) and the number of
    blow-ups.

    The intervals between resets are independent, so they are integrated side by side
    (:func:`_integrate_intervals`); a blow-up moves the later resets, and then the
    intervals are integrated one after the other.
    """
    speed_limit = 2.0 * float(np.max(measured[:, 0]))
    with np.errstate(all="ignore"):
        out = _integrate_intervals(derivative, t, measured, _reset_starts(t, reset_interval),
                                   speed_limit)
    if out is not None:
        return out, 0
    return _integrate_serially(derivative, t, measured, reset_interval, speed_limit)


def _reset_starts(t: np.ndarray, reset_interval: float) -> np.ndarray:
    """Sample indices of the resets of an integration that never blows up."""
    starts, next_reset = [], t[0]
    for i, ti in enumerate(t):
        if ti >= next_reset - 1e-9 or not starts:
            starts.append(i)
            next_reset = ti + reset_interval
    return np.array(starts)


def _integrate_intervals(derivative, t, measured, starts, speed_limit) -> np.ndarray | None:
    """The integration of :func:`_integrate` with every interval between resets stepped at
    once, or None when one of them blows up."""
    n = len(t)
    ends = np.append(starts[1:], n)
    out = np.empty((n, 6))
    y = np.array([*velocity_from_air_data(*measured[starts, :3].T), *measured[starts, 3:].T])
    for j in range(int(np.max(ends - starts))):
        active = starts + j < ends
        i = np.minimum(starts + j, ends - 1)
        out[i[active]] = np.column_stack([*air_data_from_velocity(*y[:3]), *y[3:]])[active]
        following = np.minimum(i + 1, n - 1)
        dt = t[following] - t[i]
        k1 = derivative(i, y)
        k2 = derivative(following, y + dt * k1)
        y = y + 0.5 * dt * (k1 + k2)
        stepped = active & (i + 1 < n)
        blown = ~np.all(np.isfinite(y), axis=0) | (np.linalg.norm(y[:3], axis=0) > speed_limit)
        if np.any(blown & stepped):
            return None
    return out


def _integrate_serially(derivative, t, measured, reset_interval, speed_limit):
    """:func:`_integrate` one sample after the other (resets move after a blow-up)."""
    n = len(t)
    out = np.empty((n, 6))
    next_reset = t[0]
    divergences = 0
    y = None
    with np.errstate(all="ignore"):
        for i in range(n):
            if t[i] >= next_reset - 1e-9 or y is None:
                y = np.array([*velocity_from_air_data(*measured[i, :3]), *measured[i, 3:]])
                next_reset = t[i] + reset_interval
            out[i] = (*air_data_from_velocity(*y[:3]), *y[3:])
            if i + 1 < n:
                dt = t[i + 1] - t[i]
                k1 = derivative(i, y)
                k2 = derivative(i + 1, y + dt * k1)
                y = y + 0.5 * dt * (k1 + k2)
                if not np.all(np.isfinite(y)) or np.linalg.norm(y[:3]) > speed_limit:
                    divergences += 1
                    out[i] = np.nan
                    y = None
    return out, divergences
