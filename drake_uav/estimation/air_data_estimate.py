"""Air data without vanes, estimated offline: forward EKF and RTS smoother per segment.

:func:`estimate_air_data` estimates the airspeed, alpha, beta and the NED wind over a
flight from what a real log holds (IMU, attitude, GPS velocity, pitot and, for the
specific-force relation, the elevator and rudder commands) with
:class:`~drake_uav.estimation.vaneless_models.VanelessAirDataModel`: a forward pass of
the EKF core (:func:`~drake_uav.estimation.ekf.filter_pass`) then the
Rauch-Tung-Striebel backward pass (:func:`~drake_uav.estimation.smoother.rts_smooth`),
each segment of the log on its own. It never reads truth channels or the simulator's
noise metadata. Accuracy and cost on simulated flights: ``docs/estimation.md``
(Air data without vanes).

The wind of a segment whose heading hardly changes (heading spread below
:data:`~drake_uav.estimation.compatibility.MIN_HEADING_SPREAD`) is not observable: on a
straight track the wind across it trades with an error of the logged heading (a heading
20 deg off moved the estimated wind of a straight simulated flight by 9 m/s), which a turn
would tell apart. Such a segment's wind is withheld (NaN, ``wind_observable`` False, a
note); its air data are kept, because the heading error moves the wind, not the
air-relative velocity the flow angles come from (the same flight's alpha and beta stayed
within 0.3 deg).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence

import numpy as np

from drake_uav.estimation.air_data_models import MIN_START_AIRSPEED
from drake_uav.estimation.compatibility import MIN_HEADING_SPREAD
from drake_uav.estimation.compatibility_air_data import heading_spread
from drake_uav.estimation.ekf import ExtendedKalmanFilter, filter_pass
from drake_uav.estimation.gps import DEFAULT_GPS_LATENCY
from drake_uav.estimation.noise import sensor_std
from drake_uav.estimation.signals import ATTITUDE, GPS_VELOCITY, IMU, LOG_CHANNELS, Cumulative
from drake_uav.estimation.smoother import rts_smooth
from drake_uav.estimation.vaneless_models import COEFFICIENT_NAMES, VanelessAirDataModel
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.model.air_data import air_data_from_velocity, dynamic_pressure
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.rotations import euler_to_rotmat, rotate_back
from drake_uav.vehicles.fixed_wing import FixedWingParams

__all__ = ["NOISE_CHANNELS", "AirDataEstimate", "estimate_air_data"]

_REQUIRED = {"gps_vn": "GPS velocity", "gps_ve": "GPS velocity", "gps_vd": "GPS velocity",
             "pitot": "pitot"}
_SENSOR_SIGNALS = (*IMU, *ATTITUDE, *GPS_VELOCITY, "pitot")
NOISE_CHANNELS = tuple(LOG_CHANNELS[n] for n in _SENSOR_SIGNALS)
"""Log channels whose noise ``estimate_air_data(noise_std=...)`` accepts."""


@dataclasses.dataclass(frozen=True)
class AirDataEstimate:
    """Smoothed air data and wind over the samples of a log (NaN outside the estimated
    segments).

    ``alpha_std``, ``beta_std`` and ``airspeed_std`` map the smoothed covariance of
    the air-relative velocity through the Jacobian of the air-data relation;
    ``wind_std`` is that of the total (mean plus gust) wind.
    """

    time: np.ndarray
    """Sample times of the log [s] (N)."""
    airspeed: np.ndarray
    """True airspeed [m/s] (N)."""
    alpha: np.ndarray
    """Angle of attack [rad] (N)."""
    beta: np.ndarray
    """Sideslip angle [rad] (N)."""
    wind_ned: np.ndarray
    """Wind NED [m/s] (N, 3)."""
    airspeed_std: np.ndarray
    """[m/s] (N)."""
    alpha_std: np.ndarray
    """[rad] (N)."""
    beta_std: np.ndarray
    """[rad] (N)."""
    wind_std: np.ndarray
    """[m/s] (N, 3)."""
    valid: np.ndarray
    """True where a sample was estimated (N, bool)."""
    segments: tuple[tuple[float, float], ...]
    """The estimated stretches [s]: each segment from its first sample with GPS velocity
    and a pitot airspeed above the start threshold to its end."""
    coefficients: tuple[dict[str, float], ...]
    """Smoothed specific-force coefficients of each segment [m^2/kg] (empty dicts
    without the relation)."""
    rejected: dict[str, int]
    """Measurements rejected by the innovation gate, per sensor group."""
    wind_observable: tuple[bool, ...] = ()
    """Per segment: False where the heading hardly changes, so that the wind trades with a
    heading error; ``wind_ned`` and ``wind_std`` are NaN there (module docstring)."""
    notes: tuple[str, ...] = ()
    """One line per segment whose wind is withheld, with its heading spread."""


@functools.cache
def _kinematic_alpha() -> CompiledFunction:
    """Angle of attack [rad] of the air velocity ``R(euler)^T (v_gps - W)`` from
    ``[roll, pitch, yaw, v_gps - W (NED)]``."""
    return CompiledFunction(lambda z: np.array(air_data_from_velocity(
        *rotate_back(euler_to_rotmat(z[0:3]), z[3:6]))[1:2]), (6,), {}, "kinematic_alpha")


@functools.cache
def _air_data_function() -> CompiledFunction:
    return CompiledFunction(lambda v: np.array(air_data_from_velocity(v[0], v[1], v[2])),
                            (3,), {0: None}, "air_data_from_velocity")


def _filter_std(noise_std: Mapping[str, float] | None) -> dict[str, float]:
    """``noise_std`` by filter signal name: keys may be filter names (``"ax"``) or log
    channels (``"imu_ax"``)."""
    by_channel = {LOG_CHANNELS[n]: n for n in _SENSOR_SIGNALS}
    out = {}
    for key, value in (noise_std or {}).items():
        name = key if key in _SENSOR_SIGNALS else by_channel.get(key)
        if name is None:
            raise ValueError(f"noise_std: unknown channel '{key}' (known: "
                             f"{sorted(by_channel)})")
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"noise_std['{key}'] must be positive, got {value}")
        out[name] = float(value)
    return out


def _check_channels(log: FlightLog) -> None:
    """Raises FlightLogError naming the first missing or empty required channel."""
    for name in (*IMU, *ATTITUDE, *_REQUIRED):
        channel = LOG_CHANNELS[name]
        what = _REQUIRED.get(name, "IMU" if name in IMU else "attitude")
        if channel not in log or not np.isfinite(np.asarray(log[channel], float)).any():
            raise FlightLogError(
                f"estimate_air_data: the log has no {what} samples (channel '{channel}'); "
                "air data without vanes need IMU, attitude, GPS velocity and pitot")


def _segment_bounds(log: FlightLog, segments) -> list[tuple[float, float]]:
    bounds = segments if segments is not None else log.metadata.get("segments")
    if not bounds:
        return [(float(log.time[0]), float(log.time[-1]))]
    return [(float(t0), float(t1)) for t0, t1 in bounds]


def _first_usable(measurements: np.ndarray, rho: float) -> int | None:
    """First row with a full GPS velocity and a pitot airspeed above the start threshold."""
    gps = np.isfinite(measurements[:, 0:3]).all(axis=1)
    with np.errstate(invalid="ignore"):
        ok = gps & (measurements[:, 3] >= dynamic_pressure(MIN_START_AIRSPEED, rho))
    first = np.flatnonzero(ok)
    return int(first[0]) if first.size else None


class _Output:
    """The per-sample arrays of an :class:`AirDataEstimate` as segments fill them."""

    def __init__(self, n: int, period: float):
        self.period = period
        self.values = {k: np.full(n, np.nan) for k in (
            "airspeed", "alpha", "beta", "airspeed_std", "alpha_std", "beta_std")}
        self.wind, self.wind_std = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
        self.valid = np.zeros(n, bool)

    def fill(self, rows: slice, time: np.ndarray, steps: np.ndarray,
             model: VanelessAirDataModel, state, covariance) -> None:
        """Air data, wind and their stds of the smoothed ``state`` and ``covariance`` at
        the filter's ``steps`` (log rows), interpolated linearly to every row of ``rows``."""
        air, J = _air_data_function().batch_value_and_jacobian(state[:, 0:3])
        P_air = J @ covariance[:, 0:3, 0:3] @ J.swapaxes(1, 2)
        std = np.sqrt(np.einsum("kii->ki", P_air))
        # Total wind = S x with S selecting the mean (and gust) states of each axis.
        S = np.zeros((3, len(model.state_names)))
        S[[0, 1, 2], [3, 4, 5]] = 1.0
        if model.gust:
            S[[0, 1], [6, 7]] = 1.0
        wind_std = np.sqrt(np.einsum("ij,kjl,il->ki", S, covariance, S))
        t, t_steps = time[rows], time[steps]
        for i, name in enumerate(("airspeed", "alpha", "beta")):
            self.values[name][rows] = np.interp(t, t_steps, air[:, i])
            self.values[f"{name}_std"][rows] = np.interp(t, t_steps, std[:, i])
        wind = state @ S.T
        for i in range(3):
            self.wind[rows, i] = np.interp(t, t_steps, wind[:, i])
            self.wind_std[rows, i] = np.interp(t, t_steps, wind_std[:, i])
        self.valid[rows] = True

    def withhold_wind(self, rows: slice) -> None:
        """The wind over ``rows`` as not estimated (NaN): the flight does not observe it."""
        self.wind[rows] = np.nan
        self.wind_std[rows] = np.nan

    def recentre(self, rows: slice, steps: np.ndarray, model: VanelessAirDataModel,
                 euler: np.ndarray, gps: np.ndarray, fresh: np.ndarray) -> None:
        """Shifts alpha over ``rows`` so that the segment's mean vertical wind is zero, and
        adds the uncertainty of that mean to ``alpha_std``; ``euler`` (the filter's
        attitude inputs), ``gps`` and ``fresh`` (new GPS samples) are at the filter's
        ``steps``.

        The mean vertical wind is not observable from GPS and pitot in straight flight
        (it trades with the flow angle); the filter's Gauss-Markov prior does not hold
        it at zero in turbulence. The kinematic angle of attack of the air velocity
        ``R^T (v_gps - W)`` with the smoothed horizontal wind and no vertical wind is
        unbiased when the mean vertical wind is zero; alpha moves by the mean of its
        difference to the smoothed alpha over the GPS samples. That mean has the
        uncertainty of the mean of a Gauss-Markov process over the segment,
        ``sigma_w sqrt(2 tau_w / T) / Va``.
        """
        if not fresh.any():
            return
        at = steps[fresh]
        air = gps[fresh] - np.column_stack([self.wind[at, 0:2], np.zeros(len(at))])
        kinematic = _kinematic_alpha().batch_value(np.column_stack([euler[fresh], air]))[:, 0]
        self.values["alpha"][rows] += float(np.mean(kinematic - self.values["alpha"][at]))
        self.wind[rows, 2] -= float(np.mean(self.wind[rows, 2]))
        duration = max(float(rows.stop - rows.start) * self.period, model.gust_tau[2])
        airspeed = float(np.mean(self.values["airspeed"][rows]))
        offset_std = model.gust_sigma[2] * np.sqrt(2.0 * model.gust_tau[2] / duration) / airspeed
        std = self.values["alpha_std"][rows]
        self.values["alpha_std"][rows] = np.hypot(std, offset_std)


def _step_inputs(time: np.ndarray, inputs: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Inputs at the filter's ``steps``: the IMU columns averaged over each step (the
    trapezoid integral of the samples over the step divided by its length), the others
    sampled."""
    out = inputs[steps].copy()
    if len(steps) < 2 or np.all(np.diff(steps) == 1):
        return out
    areas = Cumulative(time, inputs[:, 0:6]).values[steps]
    out[1:, 0:6] = np.diff(areas, axis=0) / np.diff(time[steps])[:, None]
    return out


def _steps(available: np.ndarray, decimation: int) -> np.ndarray:
    """Rows the filter steps on: every new GPS sample, the first and last row, and between
    them rows spread evenly so that no step spans more than ``decimation`` samples."""
    anchors = np.union1d(np.flatnonzero(available[:, 0:3].any(axis=1)),
                         [0, len(available) - 1])
    gaps = np.diff(anchors)
    extra = -(-gaps // decimation) - 1  # rows added inside each gap
    gap = np.repeat(np.arange(len(gaps)), extra)
    first = np.repeat(np.cumsum(extra) - extra, extra)
    j = np.arange(len(gap)) - first + 1
    inside = anchors[gap] + np.round(j * gaps[gap] / (extra[gap] + 1)).astype(int)
    return np.union1d(anchors, inside)


def _smooth_segment(ekf: ExtendedKalmanFilter, data, inputs: np.ndarray, rows: slice,
                    decimation: int, out: _Output, rejected: dict[str, int]) -> dict:
    """Forward pass, backward pass and output of the log ``rows`` of one segment; adds
    the gate rejections to ``rejected``; returns the smoothed specific-force
    coefficients (empty without the relation)."""
    model = ekf.model
    steps = rows.start + _steps(data.available[rows], decimation)
    forward = filter_pass(ekf, data.time[steps], _step_inputs(data.time, inputs, steps),
                          data.measurements[steps], data.available[steps])
    smoothed = rts_smooth(forward)
    out.fill(rows, data.time, steps, model, smoothed.state, smoothed.covariance)
    out.recentre(rows, steps, model, forward.inputs[:, 6:9], data.measurements[steps, 0:3],
                 data.available[steps, 0:3].all(axis=1))
    for group, count in zip(ekf.group_names, forward.rejected.tolist(), strict=True):
        rejected[group] += count
    if not model.lift_relation:
        return {}
    values = model.coefficients(smoothed.state[0, -6:])
    return {n: float(c) for n, c in zip(COEFFICIENT_NAMES, values, strict=True)}


def estimate_air_data(log: FlightLog, params: FixedWingParams, *,
                      noise_std: Mapping[str, float] | None = None,
                      segments: Sequence[Sequence[float]] | None = None,
                      lift_relation: bool = True, gust: bool = False,
                      turbulence: str = "light", altitude: float = 100.0,
                      gps_latency: float = DEFAULT_GPS_LATENCY,
                      decimation: int = 5) -> AirDataEstimate:
    """Airspeed, alpha, beta and wind over a flight without vanes (module docstring).

    Args:
        log: the flight; needs IMU, attitude, GPS velocity and pitot channels
            (``imu_*``, ``att_*``, ``gps_v*``, ``pitot_qbar``). Vane and truth channels
            are never read. Missing elevator / rudder commands count as zero.
        params: the aircraft: air density and gravity; with ``lift_relation`` also its
            mass, wing area and span (the loose prior of the coefficients). Its
            aerodynamic coefficients are not used.
        noise_std: per-sample noise standard deviation by channel (log names such as
            ``"imu_az"`` or filter names such as ``"az"``), in the channel's unit.
            Channels not given take the default low-cost suite
            (:class:`~drake_uav.vehicles.sensors.SensorSuiteParams`, Vaiopoulos 2017,
            Table 7). To use noise estimated from the data, pass e.g. the standard
            deviation of each channel's high-pass residual (the sample-to-sample
            difference divided by sqrt(2) on a steady stretch) under the channel's name.
        segments: ``[[t0, t1], ...]`` [s] smoothed separately; default the log's
            ``metadata["segments"]``, else the whole log. Each segment starts at its
            first sample with GPS velocity and a pitot airspeed of at least
            :data:`~drake_uav.estimation.air_data_models.MIN_START_AIRSPEED`, from the
            wind triangle with zero flow angles.
        lift_relation: observe the flow angles through the accelerometer with the
            free-coefficient specific-force relation (see
            :class:`~drake_uav.estimation.vaneless_models.VanelessAirDataModel`);
            False: kinematics only.
        gust: Gauss-Markov states for the horizontal gusts.
        turbulence, altitude: the Dryden prior of the gust model (level, m).
        gps_latency: GPS velocity latency removed with the IMU [s].
        decimation: the filter steps on every new GPS sample and, between them, on
            rows spread evenly so that a step spans at most ``decimation`` samples; the
            IMU is averaged over each step, the pitot and accelerometer samples between
            steps are left out, and the smoothed values are interpolated linearly to
            every sample (docs/estimation.md: cost and accuracy against ``decimation``).

    Raises:
        FlightLogError: naming the channel when IMU, attitude, GPS velocity or pitot
            samples are missing, or when no segment ever has both GPS and airspeed.
    """
    _check_channels(log)
    if not (isinstance(decimation, int) and decimation >= 1):
        raise ValueError(f"decimation must be an integer >= 1, got {decimation!r}")
    model = VanelessAirDataModel(params, gust=gust, lift_relation=lift_relation,
                                 turbulence=turbulence, altitude=altitude,
                                 averaged_imu=decimation > 1)
    data = model.log_data(log, gps_latency)
    inputs = data.inputs
    for i in model.command_inputs:  # commands absent from the log: zero
        inputs[:, i] = np.nan_to_num(inputs[:, i])
    period = float(np.median(np.diff(data.time))) if len(data.time) > 1 else 0.01
    std = {**sensor_std(), **_filter_std(noise_std)}
    for name in IMU:  # the mean of ``decimation`` samples
        std[name] /= np.sqrt(decimation)
    ekf = ExtendedKalmanFilter(model, model.default_noise(std, period=period * decimation))
    out = _Output(len(data.time), period)
    done, coefficients, observable, notes = [], [], [], []
    rejected = dict.fromkeys(ekf.group_names, 0)
    for t0, t1 in _segment_bounds(log, segments):
        inside = np.flatnonzero((data.time >= t0) & (data.time <= t1))
        start = _first_usable(data.measurements[inside], model.rho) if inside.size else None
        if start is None or inside.size - start < 2:
            continue
        rows = slice(inside[start], inside[-1] + 1)
        coefficients.append(_smooth_segment(ekf, data, inputs, rows, decimation, out,
                                            rejected))
        done.append((float(data.time[rows.start]), float(data.time[rows.stop - 1])))
        spread = heading_spread(inputs[rows, 8])
        observable.append(spread >= MIN_HEADING_SPREAD)
        if not observable[-1]:
            out.withhold_wind(rows)
            notes.append(f"wind not estimated over {done[-1][0]:.1f}-{done[-1][1]:.1f} s: the "
                         f"heading hardly changes (spread {spread:.3f} < {MIN_HEADING_SPREAD}), "
                         "so the wind across the track cannot be told from a heading error; "
                         "alpha and beta come from the air-relative velocity, which it does "
                         "not move; fly turns to observe the wind")
    if not done:
        raise FlightLogError("estimate_air_data: no segment has both GPS velocity and a pitot "
                             f"airspeed of at least {MIN_START_AIRSPEED} m/s (channels "
                             "'gps_vn', 'pitot_qbar')")
    v = out.values
    return AirDataEstimate(data.time, v["airspeed"], v["alpha"], v["beta"], out.wind,
                           v["airspeed_std"], v["alpha_std"], v["beta_std"], out.wind_std,
                           out.valid, tuple(done), tuple(coefficients), rejected,
                           tuple(observable), tuple(notes))
