"""Measured aerodynamic coefficients from flight data (Vaiopoulos 2017, sec. 5.5 and 5.6).

From the body specific force (accelerometer), body rates, their derivatives,
the air data, the thrust model and the inertia, the six coefficients follow
from Newton-Euler (Vaiopoulos 2017, eq. 5.41), written once in
:mod:`drake_uav.model.isolation` (:func:`~drake_uav.model.isolation.force_coefficients`,
:func:`~drake_uav.model.isolation.moment_coefficients`). This module prepares the
sampled signals those formulas take.

Angular accelerations come from a Savitzky-Golay differentiating filter: a
local cubic least-squares fit over a window of about 0.2 s. It has zero phase
lag (centred window), passes the rigid-body band below ~5 Hz almost
unattenuated, and suppresses gyro noise far better than finite differences;
the window is a parameter. The force coefficients come from instantaneous
samples: they and their regressors (air data, rates, controls) go through the
same Savitzky-Golay smoothing. The derivative is a weighted sum of the rate
increments, each the integral of the angular acceleration over one sample
interval, so the moments are a filter of interval averages: their regressors
take the interval averages (of the cubic through the four nearest samples for
sampled signals, exact for held controls) through the same weights. Either way
a coefficient and its regressors see one and the same filter, whose distortion
then cancels in the regression instead of showing up as a spurious rate, delay
or unsteady effect (turbulence makes the air data and the controls of a
stabilised aircraft rough enough for the difference between the two filters to
matter).

:func:`monte_carlo_sigma` is the uncertainty propagation of sec. 5.6 (uniform
marginals joined by a Gaussian copula, Gaussian errors, 95% coverage interval
turned into a normal-equivalent standard deviation); :func:`monte_carlo_sigmas` does it
for several outputs of one function from one set of draws.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import NamedTuple

import numpy as np
from scipy.signal import savgol_coeffs
from scipy.special import ndtr

from drake_uav.identification.samples.aero_samples import SHAFT_SPEED, AeroSamples, MomentInputs
from drake_uav.identification.samples.aero_samples import logged as logged_key
from drake_uav.model.air_data import dynamic_pressure
from drake_uav.model.coefficients import COEFFICIENTS, AeroCondition
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.isolation import (
    differentiate,
    force_coefficients,
    moment_coefficients,
)
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = [
    "differentiate",
    "isolate_coefficients",
    "smoothed_noise_variance",
    "NOISE_CHANNELS",
    "monte_carlo_sigma",
    "monte_carlo_sigmas",
    "interval_averages",
    "INTERVAL_KERNEL",
]


NOISE_CHANNELS = ("airspeed", "alpha", "beta", "p", "q", "r", "ax", "ay", "az")
"""Signals whose noise variance the isolation tracks."""


def _smoothing_coefficients(time: np.ndarray, window: float, polyorder: int) -> np.ndarray:
    step = float(np.median(np.diff(time)))
    length = min(int(round(window / step)) | 1, len(time) - (1 - len(time) % 2))
    return savgol_coeffs(length, polyorder)


def _increment_weights(time: np.ndarray, window: float, polyorder: int) -> np.ndarray:
    """(2m,) weights of the Savitzky-Golay derivative written on the sample increments.

    ``sum_i d_i y_(k+i) = sum_j w_j (y_(k+j+1) - y_(k+j)) / step``, j = -m .. m-1: a
    filter of the increment rates (interval averages of the derivative), unit DC gain.
    """
    step = float(np.median(np.diff(time)))
    length = min(int(round(window / step)) | 1, len(time) - (1 - len(time) % 2))
    d = savgol_coeffs(length, polyorder, deriv=1, delta=step, use="dot")
    return -np.cumsum(d)[:-1] * step


INTERVAL_KERNEL = np.array([-1.0, 13.0, 13.0, -1.0]) / 24.0
"""Weights of ``y_(k-1) .. y_(k+2)`` in the average over ``[t_k, t_(k+1)]`` of the cubic
through them."""


def interval_averages(values: np.ndarray) -> np.ndarray:
    """Averages over the sample intervals of a smooth, uniformly sampled signal.

    The average of the cubic through the four nearest samples (the quadratic through
    three at the first and last interval): exact to O(step^4). The trapezoid
    ``(y_k + y_(k+1)) / 2`` falls short of the true average of a sinusoid of frequency
    ``w`` by ``(w step)^2 / 12``, 0.3 % at 1.5 Hz and 50 Hz, and would bias the
    damping derivatives of the moments by as much.

    Parameters
    ----------
    values : numpy.ndarray of shape (N, ...)
        The samples, along the first axis.

    Returns
    -------
    numpy.ndarray of shape (N - 1, ...)
        The interval averages.

    Raises
    ------
    ValueError
        With fewer than 3 samples.
    """
    y = np.asarray(values, dtype=float)
    if y.shape[0] < 3:
        raise ValueError(f"interval_averages: need >= 3 samples, got {y.shape[0]}")
    inner = np.tensordot(INTERVAL_KERNEL, np.stack([y[:-3], y[1:-2], y[2:-1], y[3:]]), 1)
    first = (5.0 * y[0] + 8.0 * y[1] - y[2]) / 12.0
    last = (-y[-3] + 8.0 * y[-2] + 5.0 * y[-1]) / 12.0
    return np.concatenate([first[None], inner, last[None]])


def _interval_filter(weights: np.ndarray, interval_values: np.ndarray) -> np.ndarray:
    """Values at the N samples from (N - 1, ...) values on the intervals between them,
    by the increment ``weights`` (the ends are padded with the end intervals)."""
    m = len(weights) // 2
    padded = np.concatenate([np.repeat(interval_values[:1], m, axis=0), interval_values,
                             np.repeat(interval_values[-1:], m, axis=0)])
    return np.apply_along_axis(lambda v: np.convolve(v, weights[::-1], mode="valid"), 0,
                               padded)


def smoothed_noise_variance(time: np.ndarray, raw: np.ndarray, window: float = 0.2,
                            polyorder: int = 3) -> np.ndarray:
    """White-noise variance left in the Savitzky-Golay smoothed ``raw``, per column.

    The raw noise variance is read from ``raw - smooth(raw)``, which removes the
    (smooth) flight signal and keeps ``(1 - 2 h0 + sum h^2)`` of white noise; the
    smoothed signal keeps ``sum h^2`` of it (``h`` the filter coefficients).

    Parameters
    ----------
    time : numpy.ndarray of shape (N,)
        Uniform sample times [s].
    raw : numpy.ndarray of shape (N,) or (N, m)
        The raw samples.
    window : float
        Filter length [s].
    polyorder : int
        Filter polynomial order.

    Returns
    -------
    numpy.ndarray
        Noise variance of each column after smoothing, in the unit of ``raw`` squared.
    """
    h = _smoothing_coefficients(time, window, polyorder)
    detail = raw - differentiate(time, raw, window, polyorder, deriv=0)
    raw_variance = np.var(detail, axis=0) / (1.0 - 2.0 * h[len(h) // 2] + h @ h)
    return raw_variance * (h @ h)


def isolate_coefficients(
    params: FixedWingParams,
    time: np.ndarray,
    specific_force: np.ndarray,
    rates: np.ndarray,
    air_data: np.ndarray,
    controls: np.ndarray,
    thrust: np.ndarray | None = None,
    signals: Mapping[str, np.ndarray] | None = None,
    derivative_window: float = 0.2,
    raw_noise_variance: Mapping[str, float] | None = None,
    moment_controls: np.ndarray | None = None,
    thrust_airspeed_slope: np.ndarray | None = None,
    logged: Mapping[str, tuple[np.ndarray, str]] | None = None,
    thrust_correction_terms: tuple[str, ...] = (),
    thrust_from_shaft_speed: bool = False,
    thrust_speed_slope: np.ndarray | None = None,
    shaft_speed: np.ndarray | None = None,
) -> AeroSamples:
    """Measured coefficients (Vaiopoulos 2017, eq. 5.41) from uniformly sampled flight data.

    All signals are smoothed by the Savitzky-Golay filter of length
    ``derivative_window`` that also differentiates the rates.

    Forces and moments see held (stepwise) controls differently. The
    accelerometer samples the force at an instant: ``controls`` are the
    surfaces and throttle in effect at each sample. The angular accelerations
    come from the rate increments, integrals over the sample intervals:
    ``moment_controls`` row k is the average of the controls over
    ``[t_k, t_(k+1))`` (the last row is not used). By default the interval
    averages are those of ``controls`` by :func:`interval_averages` (right for
    controls that vary smoothly). The moment coefficients' regressors are in
    :attr:`AeroSamples.moments` (:meth:`AeroSamples.aligned`).

    Parameters
    ----------
    params : FixedWingParams
        The aircraft (mass, inertia, reference lengths, propulsion model).
    time : numpy.ndarray of shape (N,)
        Uniform sample times [s].
    specific_force : numpy.ndarray of shape (N, 3)
        Accelerometer, body axes [m/s^2].
    rates : numpy.ndarray of shape (N, 3)
        Body rates p, q, r [rad/s].
    air_data : numpy.ndarray of shape (N, 3)
        Airspeed [m/s], alpha [rad], beta [rad].
    controls : numpy.ndarray of shape (N, 4)
        Elevator, aileron, rudder [rad] and throttle [0..1] in effect at each sample.
    thrust : numpy.ndarray of shape (N,), optional
        Thrust [N]; default the params' propulsion model at the measured airspeed and
        throttle (then the same for forces and moments).
    signals : Mapping[str, numpy.ndarray], optional
        Other signals (attitude, height, ...) carried into :attr:`AeroSamples.signals`.
    derivative_window : float
        Length of the smoothing and differentiating filter [s].
    raw_noise_variance : Mapping[str, float], optional
        White-noise variance of the raw ``airspeed, alpha, beta, p, q, r, ax, ay, az``
        samples (e.g. from sensor specifications); missing entries are estimated from the
        data.
    moment_controls : numpy.ndarray of shape (N, 4), optional
        The controls averaged over the sample intervals, as the moments see them.
    thrust_airspeed_slope : numpy.ndarray of shape (N,), optional
        dT/dVa [N/(m/s)] of a ``thrust`` computed from the measured airspeed (an identified
        thrust model), which the errors-in-variables corrections carry; None for a thrust
        measured directly.
    logged : Mapping[str, (numpy.ndarray, str)], optional
        Extra channels of the log (a tension, a voltage) -> (raw samples (N,), unit): they
        go through the same filters as the regressors into ``signals["logged:<channel>"]``,
        with their noise variance (``raw_noise_variance`` may give it under the same key).
    thrust_correction_terms : tuple of str
        The throttle terms an identified thrust model was fitted with
        (:attr:`AeroSamples.thrust_correction_terms`).
    thrust_from_shaft_speed : bool
        Whether ``thrust`` comes from the logged shaft speed
        (:attr:`AeroSamples.thrust_from_shaft_speed`).
    thrust_speed_slope : numpy.ndarray of shape (N,), optional
        d(thrust)/d(shaft speed) [N/(rad/s)] of a ``thrust`` computed from the logged shaft
        speed, which carries the speed's noise (:attr:`AeroSamples.thrust_speed_slope`).
    shaft_speed : numpy.ndarray of shape (N,), optional
        The logged shaft speed [rad/s] with ``thrust_speed_slope``: its noise variance is
        read from it unless ``raw_noise_variance`` declares it (key ``motor_speed``).

    Returns
    -------
    AeroSamples
        The six measured coefficients and their regressors; :attr:`AeroSamples.moments`
        holds what the moment coefficients see.

    Raises
    ------
    ValueError
        Naming the array whose shape or values are wrong.

    Examples
    --------
    >>> import numpy as np
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> time = np.arange(200) / 50.0
    >>> wave = np.sin(np.pi * time)
    >>> specific_force = np.column_stack([0.1 * wave, 0.0 * wave, -9.81 + 0.5 * wave])
    >>> rates = np.column_stack([0.05 * wave, 0.1 * wave, 0.0 * wave])
    >>> air_data = np.column_stack([20.0 + wave, 0.05 + 0.02 * wave, 0.01 * wave])
    >>> controls = np.column_stack([-0.05 + 0.02 * wave, 0 * wave, 0 * wave, 0.5 + 0 * wave])
    >>> samples = isolate_coefficients(aerosonde(), time, specific_force, rates, air_data,
    ...                                controls)
    >>> sorted(samples.coefficients), samples.coefficients["CL"].shape
    (['CD', 'CL', 'CY', 'Cl', 'Cm', 'Cn'], (200,))
    """
    time = np.asarray(time, dtype=float)
    arrays = _checked_arrays(len(time), specific_force=specific_force, rates=rates,
                             air_data=air_data, controls=controls,
                             moment_controls=moment_controls)
    extra = _checked_signals(signals, len(time))
    channels = _checked_signals({logged_key(k): v for k, (v, _) in (logged or {}).items()},
                                len(time))
    filters = _Filters(time, derivative_window)
    model = FixedWingModel(params)
    if (thrust_speed_slope is None) != (shaft_speed is None) or (
            thrust_speed_slope is not None and thrust is None):
        raise ValueError("isolate_coefficients: thrust_speed_slope and shaft_speed go "
                         "together, with the thrust computed from that shaft speed")
    speed_channel = {} if shaft_speed is None else _checked_signals(
        {SHAFT_SPEED: shaft_speed}, len(time))
    measured_thrust = None if thrust is None else tuple(
        None if v is None else np.asarray(v, dtype=float)
        for v in (thrust, thrust_airspeed_slope, thrust_speed_slope))
    forces = _force_samples(params, model, filters, arrays, measured_thrust)
    moments = _moment_samples(params, model, filters, arrays, measured_thrust)
    coefficients = dict(zip(COEFFICIENTS, forces.coefficients + moments.coefficients,
                            strict=True))
    noise_variance, moment_gain = _noise_variance(filters, arrays, raw_noise_variance,
                                                  channels | speed_channel)
    view = forces.view
    samples = AeroSamples(
        time=time, condition=forces.condition, coefficients=coefficients,
        dynamic_pressure=view.q_bar, throttle=view.controls[:, 3], thrust=view.thrust,
        rate_derivatives=differentiate(time, arrays["rates"], derivative_window),
        specific_force=forces.specific_force,
        signals={**extra, **{k: filters.sample(v) for k, v in channels.items()}},
        noise_variance=noise_variance, thrust_airspeed_slope=view.thrust_slope,
        thrust_correction_terms=tuple(thrust_correction_terms),
        thrust_from_shaft_speed=bool(thrust_from_shaft_speed),
        thrust_speed_slope=view.speed_slope, reference_area=params.S,
        signal_units={logged_key(k): unit for k, (_, unit) in (logged or {}).items()},
    )
    view = moments.view
    return dataclasses.replace(samples, moments=MomentInputs(
        condition=moments.condition, dynamic_pressure=view.q_bar, throttle=view.controls[:, 3],
        thrust=view.thrust, thrust_airspeed_slope=view.thrust_slope,
        thrust_speed_slope=view.speed_slope, rate_derivatives=moments.rate_derivatives,
        logged={k: filters.interval(interval_averages(v)) for k, v in channels.items()},
        noise_variance={k: v * moment_gain for k, v in noise_variance.items()}))


def _checked_arrays(n: int, **arrays) -> dict[str, np.ndarray]:
    """The (N, 3) or (N, 4) input arrays as floats; ``ValueError`` naming a bad one."""
    out = {}
    for name, value in arrays.items():
        if value is None:
            continue
        value = np.asarray(value, dtype=float)
        width = 4 if name.endswith("controls") else 3
        if value.shape != (n, width):
            raise ValueError(f"isolate_coefficients: {name} must have shape ({n}, {width}), "
                             f"got {value.shape}")
        if not np.all(np.isfinite(value)):
            bad = int(np.argwhere(~np.isfinite(value))[0, 0])
            raise ValueError(f"isolate_coefficients: {name} is not finite at sample {bad}")
        out[name] = value
    return out


def _checked_signals(signals: Mapping[str, np.ndarray] | None, n: int) -> dict[str, np.ndarray]:
    extra = {k: np.asarray(v, dtype=float) for k, v in (signals or {}).items()}
    for name, value in extra.items():
        if value.shape != (n,):
            raise ValueError(f"isolate_coefficients: signal '{name}' must have shape ({n},)")
    return extra


class _Filters:
    """The two faces of one Savitzky-Golay filter of ``window`` [s] on uniform ``time``.

    :meth:`sample` smooths instantaneous samples; :meth:`interval` turns values on the
    N - 1 sample intervals into values at the samples through the derivative's own
    increment weights (:func:`_increment_weights`).
    """

    def __init__(self, time: np.ndarray, window: float):
        self.time = time
        self.window = window
        self.weights = _increment_weights(time, window, 3)

    def sample(self, values: np.ndarray) -> np.ndarray:
        return differentiate(self.time, values, self.window, deriv=0)

    def interval(self, interval_values: np.ndarray) -> np.ndarray:
        return _interval_filter(self.weights, interval_values)


class _ControlView(NamedTuple):
    """Filtered air data, controls and propulsion as one set of coefficients sees them."""

    air: np.ndarray
    """(N, 3) airspeed [m/s], alpha, beta [rad]."""
    controls: np.ndarray
    """(N, 4) surfaces [rad] and throttle."""
    q_bar: np.ndarray
    """Dynamic pressure [Pa]."""
    thrust: np.ndarray
    """Thrust [N]."""
    thrust_slope: np.ndarray | None
    """d(thrust)/d(airspeed) of the propulsion model [N/(m/s)], None if thrust is measured."""
    speed_slope: np.ndarray | None
    """d(thrust)/d(shaft speed) [N/(rad/s)] of a thrust from the logged shaft speed."""
    torque: np.ndarray
    """Propeller torque [N m]."""


def _control_view(model: FixedWingModel, raw_air, raw_controls, filt,
                  raw_measured_thrust=None) -> _ControlView:
    """Raw (sample or interval) air data and controls through ``filt``, with the
    dynamic pressure, thrust, thrust slope and propeller torque they imply."""
    air, u = filt(raw_air), filt(raw_controls)
    if np.any(air[:, 0] <= 1.0):
        bad = int(np.argmax(air[:, 0] <= 1.0))
        raise ValueError(f"isolate_coefficients: airspeed {air[bad, 0]:.3g} m/s at "
                         f"sample {bad} is too low to normalise the forces")
    # The propeller model is strongly nonlinear in throttle: evaluate it on the raw
    # values, then filter the result like every other signal.
    raw_thrust, raw_torque = model.thrust(raw_air[:, 0], raw_controls[:, 3])
    speed_slope = None
    if raw_measured_thrust is None:
        step = 0.01
        slope = filt((model.thrust(raw_air[:, 0] + step, raw_controls[:, 3])[0]
                      - model.thrust(raw_air[:, 0] - step, raw_controls[:, 3])[0])
                     / (2 * step))
        thrust = filt(raw_thrust)
    else:
        raw_value, raw_slope, raw_speed_slope = raw_measured_thrust
        slope = None if raw_slope is None else filt(raw_slope)
        speed_slope = None if raw_speed_slope is None else filt(raw_speed_slope)
        thrust = filt(raw_value)
    torque = filt(np.broadcast_to(raw_torque, raw_air[:, 0].shape).astype(float))
    q_bar = dynamic_pressure(air[:, 0], model.params.rho)
    return _ControlView(air, u, q_bar, thrust, slope, speed_slope, torque)


class _Isolated(NamedTuple):
    """Coefficients and the regressor condition of one view (forces or moments)."""

    view: _ControlView
    condition: AeroCondition
    coefficients: tuple
    """(C_L, C_D, C_Y) or (C_l, C_m, C_n)."""
    specific_force: np.ndarray | None = None
    rate_derivatives: np.ndarray | None = None


def _condition(view: _ControlView, rates, alpha_dot, wing_area) -> AeroCondition:
    air, u = view.air, view.controls
    return AeroCondition(
        airspeed=air[:, 0], alpha=air[:, 1], beta=air[:, 2], p=rates[:, 0], q=rates[:, 1],
        r=rates[:, 2], elevator=u[:, 0], aileron=u[:, 1], rudder=u[:, 2],
        flap=np.zeros(len(air)), alphadot=alpha_dot,
        thrust_coefficient=view.thrust / (view.q_bar * wing_area),
    )


def _force_samples(params, model, filters: _Filters, arrays, measured_thrust) -> _Isolated:
    """Forces: instantaneous samples through the Savitzky-Golay smoothing."""
    raw_air = arrays["air_data"]
    view = _control_view(model, raw_air, arrays["controls"], filters.sample, measured_thrust)
    f, w = filters.sample(arrays["specific_force"]), filters.sample(arrays["rates"])
    coefficients = force_coefficients(f, view.thrust, view.q_bar, view.air[:, 1],
                                      params.mass, params.S)
    alpha_dot = differentiate(filters.time, raw_air[:, 1], filters.window)
    return _Isolated(view, _condition(view, w, alpha_dot, params.S), coefficients,
                     specific_force=f)


def _moment_samples(params, model, filters: _Filters, arrays, measured_thrust) -> _Isolated:
    """Moments: interval averages through the derivative's own increment weights."""
    controls = arrays.get("moment_controls")
    interval_controls = (interval_averages(arrays["controls"]) if controls is None
                         else controls[:-1])
    step = np.diff(filters.time)[:, None]
    raw_air = arrays["air_data"]
    view = _control_view(model, interval_averages(raw_air), interval_controls, filters.interval,
                         None if measured_thrust is None else tuple(
                             None if v is None else interval_averages(v)
                             for v in measured_thrust))
    w = filters.interval(interval_averages(arrays["rates"]))
    w_dot = filters.interval(np.diff(arrays["rates"], axis=0) / step)
    coefficients = moment_coefficients(w_dot, w, params.inertia, view.torque, view.q_bar,
                                       params.S, params.b, params.c)
    alpha_dot = filters.interval(np.diff(raw_air[:, 1]) / step[:, 0])
    return _Isolated(view, _condition(view, w, alpha_dot, params.S), coefficients,
                     rate_derivatives=w_dot)


def _noise_variance(filters: _Filters, arrays, raw_noise_variance,
                    logged: Mapping[str, np.ndarray]):
    """White-noise variance of the smoothed channels (:data:`NOISE_CHANNELS` and the
    ``logged`` extra channels and shaft speed) and the factor by which the moments'
    interval filter changes it."""
    time, window = filters.time, filters.window
    noise = np.concatenate([smoothed_noise_variance(time, arrays[k], window)
                            for k in ("air_data", "rates", "specific_force")])
    noise_variance = dict(zip(NOISE_CHANNELS, noise.tolist(), strict=True))
    if logged:
        noise_variance.update(zip(logged, smoothed_noise_variance(
            time, np.column_stack(list(logged.values())), window).tolist(), strict=True))
    gain = float(np.sum(_smoothing_coefficients(time, window, 3) ** 2))
    for name, value in (raw_noise_variance or {}).items():
        if name not in noise_variance:
            raise ValueError(f"isolate_coefficients: raw_noise_variance has unknown '{name}'")
        noise_variance[name] = float(value) * gain
    # White noise through the interval averages and the increment weights.
    sample_weights = np.convolve(filters.weights, INTERVAL_KERNEL)
    return noise_variance, float(sample_weights @ sample_weights) / gain


def monte_carlo_sigma(
    function: Callable[..., np.ndarray],
    ranges: np.ndarray,
    error_std: np.ndarray,
    correlation: np.ndarray | None = None,
    error_correlation: np.ndarray | None = None,
    samples: int = 1_000_000,
    seed: int = 0,
) -> float:
    """Normal-equivalent standard deviation of the error of ``function(*inputs)``.

    Vaiopoulos 2017, sec. 5.6 (eq. 5.43-5.51): inputs uniform over ``ranges`` (n, 2)
    joined by a Gaussian copula with ``correlation`` (n, n); errors Gaussian
    with ``error_std`` (n,) and ``error_correlation``; the error
    ``f(x) - f(x + dx)`` has its 95% coverage interval [U-, U+], and the
    result is ``max(|U-|, |U+|) / 1.96``. ``function`` takes n arrays.

    Parameters
    ----------
    function : callable
        ``function(*inputs) -> array``, vectorised over the draws.
    ranges : ndarray
        (n, 2) lower and upper bound of each input.
    error_std : ndarray
        (n,) standard deviation of each input's error.
    correlation, error_correlation : ndarray, optional
        (n, n) correlation of the inputs (Gaussian copula) and of their errors.
    samples : int
        Number of draws.
    seed : int
        Seed of the draws.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> sigma = monte_carlo_sigma(lambda x: 2.0 * x, np.array([[0.0, 1.0]]),
    ...                           np.array([0.1]), samples=200_000)
    >>> round(sigma, 2)
    0.2
    """
    return monte_carlo_sigmas(lambda *x: {"f": function(*x)}, ranges, error_std, correlation,
                              error_correlation, samples, seed)["f"]


def monte_carlo_sigmas(
    function: Callable[..., Mapping[str, np.ndarray]],
    ranges: np.ndarray,
    error_std: np.ndarray,
    correlation: np.ndarray | None = None,
    error_correlation: np.ndarray | None = None,
    samples: int = 1_000_000,
    seed: int = 0,
) -> dict[str, float]:
    """:func:`monte_carlo_sigma` of each output of ``function``, from one set of draws.

    Each output's sigma is the one :func:`monte_carlo_sigma` gives for it alone with the
    same ``seed``.

    Parameters
    ----------
    function : callable
        ``function(*inputs) -> {name: array}``, vectorised over the draws.
    ranges : numpy.ndarray of shape (n, 2)
        Lower and upper bound of each input.
    error_std : numpy.ndarray of shape (n,)
        Standard deviation of each input's error.
    correlation, error_correlation : numpy.ndarray of shape (n, n), optional
        Correlation of the inputs (Gaussian copula) and of their errors.
    samples : int
        Number of draws.
    seed : int
        Seed of the draws.

    Returns
    -------
    dict of str to float
        Output name -> normal-equivalent standard deviation of its error.

    Raises
    ------
    ValueError
        When ``ranges`` or ``error_std`` have the wrong shape or sign.

    Examples
    --------
    >>> import numpy as np
    >>> sigmas = monte_carlo_sigmas(lambda x: {"double": 2.0 * x, "same": x},
    ...                             np.array([[0.0, 1.0]]), np.array([0.1]), samples=200_000)
    >>> round(sigmas["double"], 2), round(sigmas["same"], 2)
    (0.2, 0.1)
    """
    ranges = np.asarray(ranges, dtype=float)
    error_std = np.asarray(error_std, dtype=float)
    n = ranges.shape[0]
    if ranges.shape != (n, 2) or np.any(ranges[:, 1] < ranges[:, 0]):
        raise ValueError("monte_carlo_sigma: ranges must be (n, 2) with low <= high")
    if error_std.shape != (n,) or np.any(error_std < 0):
        raise ValueError("monte_carlo_sigma: error_std must be (n,) and non-negative")
    rng = np.random.default_rng(seed)
    corr = np.eye(n) if correlation is None else np.asarray(correlation, dtype=float)
    w = rng.multivariate_normal(np.zeros(n), corr, size=samples, method="cholesky")
    x = ranges[:, 0] + (ranges[:, 1] - ranges[:, 0]) * ndtr(w)  # ndtr: the normal CDF
    err_corr = np.eye(n) if error_correlation is None else np.asarray(error_correlation)
    # Scaled after the draw, so that an input without error (std 0) needs no factorisation
    # of a singular covariance.
    dx = rng.multivariate_normal(np.zeros(n), err_corr, size=samples,
                                 method="cholesky") * error_std
    at, moved = function(*x.T), function(*(x + dx).T)
    out = {}
    for name, value in at.items():
        low, high = np.quantile(value - moved[name], [0.025, 0.975])
        out[name] = float(max(abs(low), abs(high)) / 1.96)
    return out
