"""Dryden turbulence: length scales, spectra and the exact discrete shaping filters.

The gust components are the Dryden shaping filters of MIL-F-8785C (Vaiopoulos
2017, eq. 2.11) driven by unit-intensity white noise, with ``a = V / L`` [1/s]
(V airspeed [m/s], L length scale [m], sigma rms intensity [m/s]):

    H_u(s) = sigma_u sqrt(2 a_u) / (s + a_u)
    H_v(s) = sigma_v sqrt(3 a_v) (s + a_v/sqrt(3)) / (s + a_v)^2
    H_w(s) = sigma_w sqrt(3 a_w) (s + a_w/sqrt(3)) / (s + a_w)^2

H_v uses L_v where eq. 2.11b prints L_u (docs/references.md).

Scales: :func:`dryden_scales` with ``model="mil-f-8785c"`` (altitude-dependent)
or ``model="seed"`` (the rows of Vaiopoulos 2017, Figure 7, after Beard &
McLain; light and moderate only).

Gusts are body-axis, translational components, as in Vaiopoulos 2017. MIL-F-8785C
orients the low-altitude components along the mean wind instead; over the short
pattern of a small-UAV identification flight the two differ little, and the
body-axis form needs no wind heading.

Discretisation: each filter is the cascade z1 = xi/(s + a), z2 = z1/(s + a),
advanced with its exact transition matrix and the exact covariance of the
integrated white noise (:func:`dryden_transition`). The sampled gusts then have
the continuous process's variance and autocorrelation for any update period,
which an Euler step would not give; the first sample is drawn from the
stationary distribution. :func:`_filter_step`, one update period of the three
filters, is written once, scalar-generic, and runs as compiled code
(:func:`compiled_filter_step`); the Drake systems that hold it are in
:mod:`drake_uav.systems.wind`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from pydrake import math as drake_math
from pydrake.symbolic import if_then_else

from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.rotations import rotate, rotate_back, unit_quat_rotation

__all__ = [
    "TURBULENCE_LEVELS",
    "TURBULENCE_MODELS",
    "WIND_HOLDS",
    "TurbulenceScales",
    "dryden_scales",
    "dryden_psd",
    "dryden_transition",
    "dryden_stationary_factor",
    "dryden_gust",
    "check_turbulence_level",
    "scale_values",
    "compiled_filter_step",
]

TURBULENCE_LEVELS = ("light", "moderate", "severe")
TURBULENCE_MODELS = ("mil-f-8785c", "seed")
WIND_HOLDS = ("first_order", "zero_order")

_FT = 0.3048  # m per ft
_KT = 0.514444  # m/s per knot

# MIL-F-8785C low altitude: wind speed at 20 ft per level [kt].
_W20_KT = {"light": 15.0, "moderate": 30.0, "severe": 45.0}
# MIL-F-8785C medium/high altitude: rms intensity [ft/s] against altitude [ft] for the
# probabilities of exceedance 1e-2 (light), 1e-3 (moderate) and 1e-5 (severe).
_HIGH_ALT_FT = np.array(
    [500, 1750, 3750, 7500, 15000, 25000, 35000, 45000, 55000, 65000, 75000, 80000], float
)
_HIGH_ALT_SIGMA_FPS = {
    "light": np.array([6.6, 6.9, 7.4, 6.7, 4.6, 2.7, 0.4, 0, 0, 0, 0, 0]),
    "moderate": np.array([8.6, 9.6, 10.6, 10.1, 8.0, 6.6, 5.0, 4.2, 2.7, 0, 0, 0]),
    "severe": np.array([15.6, 17.6, 23.0, 23.6, 22.1, 20.0, 16.0, 15.1, 12.1, 7.9, 6.2, 5.1]),
}
_HIGH_ALT_LENGTH_FT = 1750.0

# Vaiopoulos 2017, Figure 7 (after Beard & McLain): (altitude, L_u = L_v, L_w, sigma_u = sigma_v,
# sigma_w) in m and m/s per level. The figure gives no "severe" rows.
_SEED_TABLE = {
    ("low", "light"): (50.0, 200.0, 50.0, 1.06, 0.7),
    ("low", "moderate"): (50.0, 200.0, 50.0, 2.12, 1.4),
    ("medium", "light"): (600.0, 533.0, 533.0, 1.5, 1.5),
    ("medium", "moderate"): (600.0, 533.0, 533.0, 3.0, 3.0),
}
# Altitude [m] that separates the figure's 50 m and 600 m rows (their midpoint).
_SEED_ROW_SPLIT = 325.0

# Output row of the cascade realisation: y = sigma sqrt(k a) (z1 + g a z2).
_GAIN_K = np.array([2.0, 3.0, 3.0])
_GAIN_G = np.array([0.0, 1.0 / math.sqrt(3.0) - 1.0, 1.0 / math.sqrt(3.0) - 1.0])
_OUTPUT_GAINS = tuple(zip(_GAIN_K.tolist(), _GAIN_G.tolist(), strict=True))  # (k, g) per axis


@dataclass(frozen=True)
class TurbulenceScales:
    """Dryden length scales [m] and rms intensities [m/s] of the three gust components."""

    length_u: float
    length_v: float
    length_w: float
    sigma_u: float
    sigma_v: float
    sigma_w: float

    @property
    def lengths(self) -> np.ndarray:
        """(L_u, L_v, L_w) [m]."""
        return np.array([self.length_u, self.length_v, self.length_w])

    @property
    def sigmas(self) -> np.ndarray:
        """(sigma_u, sigma_v, sigma_w) [m/s]."""
        return np.array([self.sigma_u, self.sigma_v, self.sigma_w])


def check_turbulence_level(level: str, model: str) -> None:
    """Raises ValueError naming ``model`` or ``level`` when the pair is unknown or unsupported."""
    if model not in TURBULENCE_MODELS:
        raise ValueError(f"model: unknown turbulence model {model!r}; use {TURBULENCE_MODELS}")
    if level not in TURBULENCE_LEVELS:
        raise ValueError(f"level: unknown turbulence level {level!r}; use {TURBULENCE_LEVELS}")
    if model == "seed" and level == "severe":
        raise ValueError("level: the seed table (model='seed') has no 'severe' rows")


def _mil_low_altitude(level: str, h_ft: float) -> tuple[float, float, float, float]:
    """(L_u = L_v, L_w, sigma_u = sigma_v, sigma_w) in ft and ft/s, 10 ft <= h <= 1000 ft."""
    k = 0.177 + 0.000823 * h_ft
    sigma_w = 0.1 * _W20_KT[level] * _KT / _FT
    return h_ft / k**1.2, h_ft, sigma_w / k**0.4, sigma_w


def _mil_high_altitude(level: str, h_ft: float) -> tuple[float, float, float, float]:
    """(L_u = L_v, L_w, sigma_u = sigma_v, sigma_w) in ft and ft/s, h >= 2000 ft."""
    sigma = float(np.interp(h_ft, _HIGH_ALT_FT, _HIGH_ALT_SIGMA_FPS[level]))
    return _HIGH_ALT_LENGTH_FT, _HIGH_ALT_LENGTH_FT, sigma, sigma


def dryden_scales(level: str, altitude: float, model: str = "mil-f-8785c") -> TurbulenceScales:
    """Length scales and intensities of a turbulence ``level`` at ``altitude`` [m].

    ``model="mil-f-8785c"``: low altitude (below 1000 ft) L_w = h,
    L_u = L_v = h / (0.177 + 0.000823 h)^1.2, sigma_w = 0.1 W20 (W20 = 15, 30, 45 kt),
    sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4 (h in ft, clamped to
    >= 10 ft); medium/high altitude (above 2000 ft) L = 1750 ft and the intensity
    of exceedance probability 1e-2 / 1e-3 / 1e-5; linear interpolation between.
    ``model="seed"``: the rows of Vaiopoulos 2017, Figure 7, the 50 m rows below 325 m and
    the 600 m rows above (light and moderate only).
    """
    check_turbulence_level(level, model)
    if not math.isfinite(altitude):
        raise ValueError(f"altitude: must be finite, got {altitude}")
    return TurbulenceScales(*scale_values(level, altitude, model))


def scale_values(level: str, altitude: float, model: str) -> tuple[float, ...]:
    """(L_u, L_v, L_w, sigma_u, sigma_v, sigma_w) [m, m/s] of validated arguments."""
    if model == "seed":
        band = "low" if altitude < _SEED_ROW_SPLIT else "medium"
        _, l_uv, l_w, s_uv, s_w = _SEED_TABLE[(band, level)]
        return l_uv, l_uv, l_w, s_uv, s_uv, s_w
    h_ft = max(altitude / _FT, 10.0)
    if h_ft <= 1000.0:
        values = _mil_low_altitude(level, h_ft)
    elif h_ft >= 2000.0:
        values = _mil_high_altitude(level, h_ft)
    else:
        f = (h_ft - 1000.0) / 1000.0
        low = _mil_low_altitude(level, 1000.0)
        high = _mil_high_altitude(level, 2000.0)
        values = tuple((1.0 - f) * lo + f * hi for lo, hi in zip(low, high, strict=True))
    l_uv, l_w, s_uv, s_w = (v * _FT for v in values)
    return l_uv, l_uv, l_w, s_uv, s_uv, s_w


def dryden_psd(omega, scales: TurbulenceScales, airspeed: float) -> np.ndarray:
    """One-sided Dryden PSDs (3, n) [(m/s)^2 / (rad/s)] at angular frequencies ``omega``.

    Normalised so that the integral over omega in [0, inf) is sigma^2:
    Phi_u = sigma^2 (2 L / (pi V)) / (1 + (L w / V)^2),
    Phi_v,w = sigma^2 (L / (pi V)) (1 + 3 (L w / V)^2) / (1 + (L w / V)^2)^2.
    """
    w = np.asarray(omega, float)
    out = np.empty((3, w.size))
    for i, (length, sigma) in enumerate(zip(scales.lengths, scales.sigmas, strict=True)):
        x2 = (length * w.ravel() / airspeed) ** 2
        if i == 0:
            out[i] = sigma**2 * 2.0 * length / (math.pi * airspeed) / (1.0 + x2)
        else:
            out[i] = sigma**2 * length / (math.pi * airspeed) * (1.0 + 3.0 * x2) / (1.0 + x2) ** 2
    return out


# Below this x = 2 a dt the moments of exp(-x u) on [0, 1] come from their power series
# (relative error < 1e-13); above it the closed forms have lost fewer than 4 digits.
_SERIES_BELOW = 0.02
_SERIES = tuple(
    tuple((-1) ** n / (math.factorial(n) * (n + m + 1)) for n in reversed(range(6)))
    for m in range(3)
)


class _Symbolic:
    """The ``xp`` namespace of symbolic Expressions: the per-period filter update is
    traced with it once and runs as compiled code (:class:`CompiledFunction`)."""

    exp = staticmethod(drake_math.exp)
    sqrt = staticmethod(drake_math.sqrt)
    maximum = staticmethod(drake_math.max)
    where = staticmethod(if_then_else)

    @staticmethod
    def expm1(v):
        return drake_math.exp(v) - 1.0


def _exp_moments(x, xp=np):
    """(I0, I1, I2) with I_m = integral of u^m exp(-x u) over u in [0, 1]."""
    safe = xp.maximum(x, _SERIES_BELOW)
    e = xp.exp(-safe)
    one_minus = -xp.expm1(-safe)
    closed = (
        one_minus / safe,
        (one_minus - safe * e) / safe**2,
        (2.0 * one_minus - e * safe * (2.0 + safe)) / safe**3,
    )
    return tuple(xp.where(x < _SERIES_BELOW, _horner(c, x), m)
                 for c, m in zip(_SERIES, closed, strict=True))


def _horner(coefficients, x):
    """Polynomial with ``coefficients`` (highest power first) at ``x``."""
    out = 0.0 * x
    for c in coefficients:
        out = out * x + c
    return out


def _transition_terms(a, dt: float, xp=np):
    """(e, l11, l21, l22): exp(-a dt) and the Cholesky factor of the noise covariance.

    The covariance is q_ij = integral over [0, dt] of exp(-2 a s) s^(i+j) ds. Written
    once for ``xp = numpy`` (arrays) and ``_Symbolic`` (the compiled update).
    """
    i0, i1, i2 = _exp_moments(2.0 * a * dt, xp)
    q11, q12, q22 = dt * i0, dt * dt * i1, dt * dt * dt * i2
    l11 = xp.sqrt(q11)
    l21 = q12 / l11
    d = q22 - l21 * l21
    return xp.exp(-a * dt), l11, l21, xp.sqrt(xp.maximum(d, 0.0))


def _stationary_terms(a, xp=np):
    """(s11, s21, s22): Cholesky factor of the stationary covariance of the cascade."""
    s11 = 1.0 / xp.sqrt(2.0 * a)
    return s11, s11 / (2.0 * a), 1.0 / xp.sqrt(8.0 * a * a * a)


def _output(z1, z2, a, sigma, k, g, xp=np):
    """Filter output y = sigma sqrt(k a) (z1 + g a z2)."""
    return sigma * xp.sqrt(k * a) * (z1 + g * a * z2)


def _filter_step(filter_state, noise, plant_state, scales, fixed_airspeed, *, dt: float,
                 steady: tuple, min_airspeed: float, xp=_Symbolic) -> list:
    """One update period of the three filters (written once; traced and compiled).

    ``filter_state`` is the filter's state group (13): cascade states (z1, z2) per
    axis, a started flag, the latest wind sample NED [m/s], the latest gust sample
    body [m/s]; ``noise`` 6 unit Gaussians; ``plant_state`` (13) gives the attitude
    and the airspeed relative to the steady wind unless ``fixed_airspeed`` [m/s]
    (1) is positive; ``scales`` are (L_u, L_v, L_w [m], sigma_u, sigma_v, sigma_w
    [m/s]). Returns the next filter state group (13) and the wind slope (3)
    [m/s^2]. The first sample (flag 0) is drawn from the stationary distribution.
    """
    rotation = unit_quat_rotation(plant_state[3:7])
    steady_body = rotate_back(rotation, steady)
    v = [plant_state[7 + i] - steady_body[i] for i in range(3)]
    airspeed = xp.where(fixed_airspeed[0] > 0.0, fixed_airspeed[0],
                        xp.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
    speed = xp.maximum(airspeed, min_airspeed)
    started = filter_state[6] > 0.0
    z, gust = [], []
    for i, (k, g) in enumerate(_OUTPUT_GAINS):
        a = speed / scales[i]
        e, l11, l21, l22 = _transition_terms(a, dt, xp)
        s11, s21, s22 = _stationary_terms(a, xp)
        n1, n2 = noise[2 * i], noise[2 * i + 1]
        z1, z2 = filter_state[2 * i], filter_state[2 * i + 1]
        z1, z2 = (xp.where(started, e * z1 + l11 * n1, s11 * n1),
                  xp.where(started, e * (dt * z1 + z2) + l21 * n1 + l22 * n2,
                           s21 * n1 + s22 * n2))
        z += (z1, z2)
        gust.append(_output(z1, z2, a, scales[3 + i], k, g, xp))
    gust_ned = rotate(rotation, gust)
    wind = [steady[i] + gust_ned[i] for i in range(3)]
    slope = [(wind[i] - filter_state[7 + i]) / dt for i in range(3)]
    return [*z, 1.0, *wind, *gust, *slope]


@functools.lru_cache(maxsize=32)
def compiled_filter_step(dt: float, steady: tuple, min_airspeed: float) -> CompiledFunction:
    """:func:`_filter_step` compiled for one update period, steady wind and airspeed floor."""
    return CompiledFunction(
        functools.partial(_filter_step, dt=dt, steady=steady, min_airspeed=min_airspeed),
        (13, 6, 13, 6, 1), name="Dryden filter step")


def _lower(m11, m21, m22) -> np.ndarray:
    """(..., 2, 2) lower-triangular matrices from their entries."""
    m11 = np.asarray(m11, float)
    out = np.zeros(m11.shape + (2, 2))
    out[..., 0, 0], out[..., 1, 0], out[..., 1, 1] = m11, m21, m22
    return out


def dryden_transition(a, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of z' = [[-a, 0], [1, -a]] z + [1, 0] xi over ``dt`` [s].

    ``a`` [1/s] is an array of break frequencies V/L. Returns ``(phi, chol)`` of
    shape ``a.shape + (2, 2)``: the transition matrix and the lower Cholesky
    factor of the covariance of the integrated unit-intensity white noise, so
    ``z[k+1] = phi z[k] + chol n[k]`` with ``n ~ N(0, I)`` is exact.
    """
    e, l11, l21, l22 = _transition_terms(np.asarray(a, float), dt)
    return _lower(e, e * dt, e), _lower(l11, l21, l22)


def dryden_stationary_factor(a) -> np.ndarray:
    """Lower Cholesky factor (..., 2, 2) of the stationary covariance of the cascade."""
    return _lower(*_stationary_terms(np.asarray(a, float)))


def dryden_gust(z, a, sigmas) -> np.ndarray:
    """Gust components (..., 3) [m/s] from cascade states z (..., 3, 2) and a = V/L (..., 3)."""
    z = np.asarray(z, float)
    return _output(z[..., 0], z[..., 1], np.asarray(a, float), np.asarray(sigmas, float),
                   _GAIN_K, _GAIN_G)


