"""Measured aerodynamic coefficients from flight data (seed S0 sec. 5.5 and 5.6).

From the body specific force (accelerometer), body rates, their derivatives,
the air data, the thrust model and the inertia, the six coefficients follow
from Newton-Euler (seed S0 eq. 5.41)::

    C_X = (m a_x - T) / (qbar S),  C_Y = m a_y / (qbar S),  C_Z = m a_z / (qbar S)
    (C_L, C_D) from (C_X, C_Z) by the wind-axis rotation (aerodynamics module)
    [C_l b, C_m c, C_n b] qbar S = J w_dot + w x J w - [tau_p, 0, 0]

Angular accelerations come from a Savitzky-Golay differentiating filter: a
local cubic least-squares fit over a window of about 0.2 s. It has zero phase
lag (centred window), passes the rigid-body band below ~5 Hz almost
unattenuated, and suppresses gyro noise far better than finite differences;
the window is a parameter. Every other signal (specific force, rates, air
data, controls) goes through the same Savitzky-Golay smoothing, so that the
measured coefficients and their regressors see one and the same filter: the
filter's distortion then cancels in the regression instead of showing up as a
spurious rate effect.

:func:`monte_carlo_sigma` is the uncertainty propagation of sec. 5.6 (uniform
marginals joined by a Gaussian copula, Gaussian errors, 95% coverage interval
turned into a normal-equivalent standard deviation).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter
from scipy.stats import norm

from drake_uav.systems.aerodynamics import (
    COEFFICIENTS,
    AeroCondition,
    body_to_lift_drag,
)
from drake_uav.systems.fixed_wing import FixedWingModel
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = [
    "AeroSamples",
    "MOMENTS",
    "differentiate",
    "isolate_coefficients",
    "smoothed_noise_variance",
    "NOISE_CHANNELS",
    "monte_carlo_sigma",
]


MOMENTS = ("Cl", "Cm", "Cn")
"""Coefficients measured from the angular accelerations."""


@dataclasses.dataclass(frozen=True)
class AeroSamples:
    """Flight samples ready for regression: the conditions and the measured coefficients."""

    time: np.ndarray
    """[s], uniformly sampled."""
    condition: AeroCondition
    """Air data [m/s, rad], body rates [rad/s], controls [rad] and thrust coefficient, arrays."""
    coefficients: Mapping[str, np.ndarray]
    """Measured ``CL, CD, CY, Cl, Cm, Cn`` [-]."""
    dynamic_pressure: np.ndarray
    """qbar [Pa]."""
    throttle: np.ndarray
    """[0..1]."""
    thrust: np.ndarray
    """Thrust used in the isolation [N]."""
    rate_derivatives: np.ndarray
    """(N, 3) body angular accelerations [rad/s^2]."""
    specific_force: np.ndarray
    """(N, 3) accelerometer [m/s^2]."""
    signals: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    """Any other logged signals (altitude, attitude, ...), by name, same length."""
    noise_variance: Mapping[str, float] = dataclasses.field(default_factory=dict)
    """Estimated white-noise variance of the smoothed ``airspeed, alpha, beta, p, q, r, ax,
    ay, az`` (units squared), for errors-in-variables corrections."""
    thrust_airspeed_slope: np.ndarray | None = None
    """d(thrust)/d(airspeed) of the propulsion model [N/(m/s)] (None: thrust measured)."""
    reference_area: float = 1.0
    """Wing area S [m^2] the coefficients refer to."""
    moment_view: AeroSamples | None = None
    """The same samples with the controls (surfaces, throttle, thrust) as the moment
    coefficients see them, or None when forces and moments see the same controls
    (see :func:`isolate_coefficients`)."""

    def __len__(self) -> int:
        return len(self.time)

    def aligned(self, coefficient: str) -> AeroSamples:
        """The samples whose controls belong with ``coefficient``: the moment view for
        ``Cl, Cm, Cn`` when there is one, else these samples."""
        if coefficient in MOMENTS and self.moment_view is not None:
            return self.moment_view
        return self

    def observation_sensitivity(self, coefficient: str) -> dict[str, np.ndarray]:
        """d(measured coefficient)/d(air-data signal) per sample, for noise propagation.

        Every coefficient divides by qbar, so d/dVa = -2 C / Va; the wind-axis
        rotation gives d C_L / d alpha = -C_D and d C_D / d alpha = C_L.
        """
        value = self.coefficients[coefficient]
        out = {"airspeed": -2.0 * value / self.condition.airspeed}
        if coefficient in ("CL", "CD") and self.thrust_airspeed_slope is not None:
            # C_X = (m a_x - T) / (qbar S) also moves with the modelled thrust.
            dcx = -self.thrust_airspeed_slope / (self.dynamic_pressure * self.reference_area)
            alpha = self.condition.alpha
            rotate = np.sin(alpha) if coefficient == "CL" else -np.cos(alpha)
            out["airspeed"] = out["airspeed"] + rotate * dcx
        if coefficient == "CL":
            out["alpha"] = -self.coefficients["CD"]
        elif coefficient == "CD":
            out["alpha"] = self.coefficients["CL"]
        return out

    def perturbed(self, signal: str, delta: float) -> AeroSamples:
        """A copy with ``delta`` added to one air-data signal (``airspeed``, ``alpha``, ``beta``);
        the dynamic pressure follows the airspeed."""
        value = getattr(self.condition, signal) + delta
        condition = self.condition._replace(**{signal: value})
        view = None if self.moment_view is None else self.moment_view.perturbed(signal, delta)
        if signal != "airspeed":
            return dataclasses.replace(self, condition=condition, moment_view=view)
        q_bar = self.dynamic_pressure * (value / self.condition.airspeed) ** 2
        thrust = self.thrust
        if self.thrust_airspeed_slope is not None:
            thrust = thrust + self.thrust_airspeed_slope * delta
        condition = condition._replace(thrust_coefficient=thrust / (q_bar * self.reference_area))
        return dataclasses.replace(self, condition=condition, dynamic_pressure=q_bar,
                                   thrust=thrust, moment_view=view)

    def subset(self, index) -> AeroSamples:
        """The samples selected by a boolean mask or an index array."""

        def pick(values):
            return values[index]

        return AeroSamples(
            time=pick(self.time),
            condition=AeroCondition(*(pick(np.broadcast_to(f, self.time.shape))
                                      for f in self.condition)),
            coefficients={k: pick(v) for k, v in self.coefficients.items()},
            dynamic_pressure=pick(self.dynamic_pressure),
            throttle=pick(self.throttle),
            thrust=pick(self.thrust),
            rate_derivatives=pick(self.rate_derivatives),
            specific_force=pick(self.specific_force),
            signals={k: pick(v) for k, v in self.signals.items()},
            noise_variance=dict(self.noise_variance),
            thrust_airspeed_slope=(None if self.thrust_airspeed_slope is None
                                   else pick(self.thrust_airspeed_slope)),
            reference_area=self.reference_area,
            moment_view=None if self.moment_view is None else self.moment_view.subset(index),
        )


def differentiate(time: np.ndarray, values: np.ndarray, window: float = 0.2,
                  polyorder: int = 3, deriv: int = 1) -> np.ndarray:
    """Time derivative of uniformly sampled ``values`` (along axis 0) by Savitzky-Golay.

    ``window`` is the filter length [s]; ``deriv=0`` gives the smoothed signal
    itself. Raises ``ValueError`` for non-uniform sampling or a window shorter
    than the polynomial needs.
    """
    time = np.asarray(time, dtype=float)
    dt = np.diff(time)
    if len(time) < 3 or np.any(dt <= 0):
        raise ValueError("differentiate: time must be strictly increasing with >= 3 samples")
    step = float(np.median(dt))
    if np.max(np.abs(dt - step)) > 1e-6 * max(step, 1e-12) + 1e-9:
        raise ValueError("differentiate: samples must be uniform in time (resample first)")
    length = int(round(window / step)) | 1
    if length <= polyorder:
        raise ValueError(
            f"differentiate: window {window} s holds {length} samples, needs > {polyorder}")
    length = min(length, len(time) - (1 - len(time) % 2))
    return savgol_filter(values, length, polyorder, deriv=deriv, delta=step, axis=0,
                         mode="interp")


NOISE_CHANNELS = ("airspeed", "alpha", "beta", "p", "q", "r", "ax", "ay", "az")
"""Signals whose noise variance the isolation tracks."""


def _smoothing_coefficients(time: np.ndarray, window: float, polyorder: int) -> np.ndarray:
    step = float(np.median(np.diff(time)))
    length = min(int(round(window / step)) | 1, len(time) - (1 - len(time) % 2))
    return savgol_coeffs(length, polyorder)


def smoothed_noise_variance(time: np.ndarray, raw: np.ndarray, window: float = 0.2,
                            polyorder: int = 3) -> np.ndarray:
    """White-noise variance left in the Savitzky-Golay smoothed ``raw`` (per column).

    The raw noise variance is read from ``raw - smooth(raw)``, which removes the
    (smooth) flight signal and keeps ``(1 - 2 h0 + sum h^2)`` of white noise; the
    smoothed signal keeps ``sum h^2`` of it (``h`` the filter coefficients).
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
) -> AeroSamples:
    """Measured coefficients (seed S0 eq. 5.41) from uniformly sampled flight data.

    All signals are smoothed by the Savitzky-Golay filter of length
    ``derivative_window`` [s] that also differentiates the rates.
    ``raw_noise_variance`` gives the white-noise variance of the raw
    ``airspeed, alpha, beta, p, q, r, ax, ay, az`` samples (e.g. from sensor
    specifications); missing entries are estimated from the data.

    Forces and moments see held (stepwise) controls at different times. The
    accelerometer samples the force at an instant: ``controls`` are the
    surfaces and throttle in effect at each sample. The angular accelerations
    come from a centred derivative of the rates, which averages the moment
    over the samples around each instant: ``moment_controls`` are the controls
    as that average sees them (for held commands: their value at the centres
    of the hold intervals). When given, the moment coefficients' regressors
    are built from them (:meth:`AeroSamples.aligned`); by default both are
    ``controls`` (controls that vary smoothly).

    Shapes: ``specific_force`` (N, 3) [m/s^2], ``rates`` (N, 3) [rad/s],
    ``air_data`` (N, 3) [Va m/s, alpha rad, beta rad], ``controls`` and
    ``moment_controls`` (N, 4) [elevator, aileron, rudder rad, throttle].
    ``thrust`` [N] defaults to the params' propulsion model at the measured
    airspeed and throttle (then the same for forces and moments).
    """
    time = np.asarray(time, dtype=float)
    n = len(time)
    arrays = {"specific_force": specific_force, "rates": rates, "air_data": air_data,
              "controls": controls}
    if moment_controls is not None:
        arrays["moment_controls"] = moment_controls
    for name, value in arrays.items():
        value = np.asarray(value, dtype=float)
        width = 4 if name.endswith("controls") else 3
        if value.shape != (n, width):
            raise ValueError(f"isolate_coefficients: {name} must have shape ({n}, {width}), "
                             f"got {value.shape}")
        if not np.all(np.isfinite(value)):
            bad = int(np.argwhere(~np.isfinite(value))[0, 0])
            raise ValueError(f"isolate_coefficients: {name} is not finite at sample {bad}")
        arrays[name] = value

    def smooth(values):
        return differentiate(time, values, derivative_window, deriv=0)

    raw_rates = arrays["rates"]
    f, w, air = (smooth(arrays[k]) for k in ("specific_force", "rates", "air_data"))
    airspeed, alpha, beta = air[:, 0], air[:, 1], air[:, 2]
    if np.any(airspeed <= 1.0):
        bad = int(np.argmax(airspeed <= 1.0))
        raise ValueError(f"isolate_coefficients: airspeed {airspeed[bad]:.3g} m/s at sample "
                         f"{bad} is too low to normalise the forces")
    q_bar = 0.5 * params.rho * airspeed**2
    q_bar_s = q_bar * params.S
    measured_thrust = None if thrust is None else smooth(np.asarray(thrust, dtype=float))
    alpha_dot = differentiate(time, alpha, derivative_window)

    def controls_view(raw_controls):
        """(condition, thrust [N], d thrust / d airspeed, propeller torque [N m], throttle)."""
        u = smooth(raw_controls)
        # The propeller model is strongly nonlinear in throttle: evaluate it on the raw
        # samples, then smooth the result like every other signal.
        model = FixedWingModel(params)
        raw_airspeed = arrays["air_data"][:, 0]
        raw_thrust, raw_torque = model.thrust(raw_airspeed, raw_controls[:, 3])
        slope, force = None, measured_thrust
        if measured_thrust is None:
            step = 0.01
            slope = smooth((model.thrust(raw_airspeed + step, raw_controls[:, 3])[0]
                            - model.thrust(raw_airspeed - step, raw_controls[:, 3])[0])
                           / (2 * step))
            force = smooth(raw_thrust)
        torque = smooth(np.broadcast_to(raw_torque, (n,)).astype(float))
        condition = AeroCondition(
            airspeed=airspeed, alpha=alpha, beta=beta, p=w[:, 0], q=w[:, 1], r=w[:, 2],
            elevator=u[:, 0], aileron=u[:, 1], rudder=u[:, 2], flap=np.zeros(n),
            alphadot=alpha_dot, thrust_coefficient=force / q_bar_s,
        )
        return condition, force, slope, torque, u[:, 3]

    force_inputs = controls_view(arrays["controls"])
    moment_inputs = (force_inputs if moment_controls is None
                     else controls_view(arrays["moment_controls"]))
    condition, force_thrust, slope, _, throttle = force_inputs
    m = params.mass
    CX = (m * f[:, 0] - force_thrust) / q_bar_s
    CY = m * f[:, 1] / q_bar_s
    CZ = m * f[:, 2] / q_bar_s
    CL, CD = body_to_lift_drag(CX, CZ, alpha)
    w_dot = differentiate(time, raw_rates, derivative_window)
    J = params.inertia
    moment = w_dot @ J.T + np.cross(w, w @ J.T)
    moment[:, 0] -= moment_inputs[3]
    coefficients = dict(zip(COEFFICIENTS, (
        CL, CD, CY,
        moment[:, 0] / (q_bar_s * params.b),
        moment[:, 1] / (q_bar_s * params.c),
        moment[:, 2] / (q_bar_s * params.b),
    ), strict=True))
    noise = np.concatenate([smoothed_noise_variance(time, arrays[k], derivative_window)
                            for k in ("air_data", "rates", "specific_force")])
    noise_variance = dict(zip(NOISE_CHANNELS, noise.tolist(), strict=True))
    gain = float(np.sum(_smoothing_coefficients(time, derivative_window, 3) ** 2))
    for name, value in (raw_noise_variance or {}).items():
        if name not in noise_variance:
            raise ValueError(f"isolate_coefficients: raw_noise_variance has unknown '{name}'")
        noise_variance[name] = float(value) * gain
    extra = {k: np.asarray(v, dtype=float) for k, v in (signals or {}).items()}
    for name, value in extra.items():
        if value.shape != (n,):
            raise ValueError(f"isolate_coefficients: signal '{name}' must have shape ({n},)")
    samples = AeroSamples(
        time=time, condition=condition, coefficients=coefficients, dynamic_pressure=q_bar,
        throttle=throttle, thrust=force_thrust, rate_derivatives=w_dot,
        specific_force=f, signals=extra, noise_variance=noise_variance,
        thrust_airspeed_slope=slope, reference_area=params.S,
    )
    if moment_controls is None:
        return samples
    view_condition, view_thrust, view_slope, _, view_throttle = moment_inputs
    return dataclasses.replace(samples, moment_view=dataclasses.replace(
        samples, condition=view_condition, thrust=view_thrust,
        thrust_airspeed_slope=view_slope, throttle=view_throttle))


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

    Seed S0 sec. 5.6 (eq. 5.43-5.51): inputs uniform over ``ranges`` (n, 2)
    joined by a Gaussian copula with ``correlation`` (n, n); errors Gaussian
    with ``error_std`` (n,) and ``error_correlation``; the error
    ``f(x) - f(x + dx)`` has its 95% coverage interval [U-, U+], and the
    result is ``max(|U-|, |U+|) / 1.96``. ``function`` takes n arrays.
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
    x = ranges[:, 0] + (ranges[:, 1] - ranges[:, 0]) * norm.cdf(w)
    err_corr = np.eye(n) if error_correlation is None else np.asarray(error_correlation)
    err_cov = err_corr * np.outer(error_std, error_std)
    dx = rng.multivariate_normal(np.zeros(n), err_cov, size=samples, method="cholesky")
    eps = function(*x.T) - function(*(x + dx).T)
    low, high = np.quantile(eps, [0.025, 0.975])
    return float(max(abs(low), abs(high)) / 1.96)
