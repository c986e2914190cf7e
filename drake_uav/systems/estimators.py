"""EKF LeafSystems: air data and wind (model-free and model-based) and aerodynamic derivatives.

Each system runs :class:`~drake_uav.estimation.ekf.ExtendedKalmanFilter` (the
core also used offline by :func:`~drake_uav.estimation.ekf.run_filter`) in one
periodic discrete update; the whole filter (estimate, covariance, last inputs,
last sensor samples, counters) lives in the discrete state, and the outputs only
read it. The sensor ports take the held outputs of
:class:`~drake_uav.systems.sensors.SensorSuite` directly:

* a channel is a new sample when its value changed since the last update
  (sample-and-hold sensors at any rate: the availability mask of Vaiopoulos 2017);
* an unconnected measurement port means that sensor is absent;
* a NaN sample is skipped and counted once; a NaN input (IMU, attitude) is
  replaced by the previous value and counted;
* the GPS velocity is moved forward by the receiver latency with the IMU
  (strapdown integration over the latency window);
* inputs the model smooths (the air-data filters' attitude, with the gyro) are
  smoothed sample by sample, as :func:`~drake_uav.estimation.ekf.run_filter`
  does offline;
* the filter starts once the sensors it needs for the wind triangle (Vaiopoulos 2017
  eq. 5.24-5.25) have delivered a sample.

Timing: when the EKF updates at the same instants as the sensors, it reads the
samples taken one period earlier; commands (``controls``) are delayed by one
period inside the system so they match those samples.
"""

from __future__ import annotations

import dataclasses
import math
import operator
from collections.abc import Sequence

import numpy as np
from pydrake.systems.framework import LeafSystem

from drake_uav.estimation import (
    DEFAULT_GPS_LATENCY,
    AirDataModel,
    EkfNoise,
    ExtendedKalmanFilter,
    ModelBasedAirDataModel,
    ParameterModel,
    is_new_sample,
    ned_acceleration,
)
from drake_uav.model.air_data import air_data_from_velocity
from drake_uav.vehicles.fixed_wing import FixedWingParams
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = [
    "EkfSystemParams",
    "AirDataEkf",
    "ModelBasedAirDataEkf",
    "ParameterEkf",
]


@dataclasses.dataclass(frozen=True)
class EkfSystemParams:
    """Settings shared by the EKF systems.

    Attributes:
        aircraft: the aircraft (gravity, air density; for the model-based filters
            also the identified model used in the prediction).
        sensors: sensor suite whose noise levels tune the filter (default Vaiopoulos 2017
            Table 7).
        noise: explicit filter noise; None: the model's ``default_noise(sensors)``.
        period: update period [s] (the IMU period).
        gps_latency: GPS receiver latency [s] removed with the IMU.
        gate_probability: innovation gate (see ``ExtendedKalmanFilter``).
    """

    aircraft: FixedWingParams
    sensors: SensorSuiteParams | None = None
    noise: EkfNoise | None = None
    period: float = 0.01
    gps_latency: float = DEFAULT_GPS_LATENCY
    gate_probability: float = 0.9999

    def validate(self) -> EkfSystemParams:
        """Raises ValueError naming the first invalid field; returns self."""
        if not (math.isfinite(self.period) and self.period > 0):
            raise ValueError(f"EkfSystemParams.period must be positive, got {self.period}")
        if not (math.isfinite(self.gps_latency) and self.gps_latency >= 0):
            raise ValueError(f"EkfSystemParams.gps_latency must be >= 0, got {self.gps_latency}")
        if not 0.0 < self.gate_probability <= 1.0:
            raise ValueError("EkfSystemParams.gate_probability must be in (0, 1], got "
                             f"{self.gate_probability}")
        if self.sensors is not None:
            self.sensors.validate()
        return self


# Entries of the sensor ports that the air-data filters measure.
_GPS_VELOCITY, _DYNAMIC_PRESSURE, _VANES = slice(3, 6), slice(0, 1), slice(0, 2)


class _Slot:
    """One filter's bookkeeping packed into a slice of the discrete state.

    Layout: x (n), P (n*n), u_prev (m_u, last input used), raw_prev (m_y, last sensor
    values), rejected (groups), nan_y (m_y), nan_u (m_u), [nis, dof, started].
    """

    def __init__(self, ekf: ExtendedKalmanFilter, start: int):
        n, nu, ny = ekf.n_states, ekf.n_inputs, ekf.n_measurements
        sizes = (("x", n), ("P", n * n), ("u_prev", nu), ("raw_prev", ny),
                 ("rejected", len(ekf.group_names)), ("nan_y", ny), ("nan_u", nu),
                 ("scalars", 3))
        self.ekf, self.slices = ekf, {}
        for name, size in sizes:
            self.slices[name] = slice(start, start + size)
            start += size
        self.stop = start
        (self._x, self._P, self._u_prev, self._raw_prev, self._rejected, self._nan_y,
         self._nan_u, self._scalars) = self.slices.values()
        self._started = self.stop - 1

    def initial(self) -> np.ndarray:
        """Initial contents: not started, no sample seen yet."""
        values = np.zeros(self.stop - self._x.start)
        offset = self._x.start
        values[self._raw_prev.start - offset:self._raw_prev.stop - offset] = np.nan
        return values

    def get(self, state: np.ndarray, name: str) -> np.ndarray:
        return state[self.slices[name]]

    def covariance(self, state: np.ndarray) -> np.ndarray:
        n = self.ekf.n_states
        return state[self._P].reshape(n, n)

    def started(self, state: np.ndarray) -> bool:
        return bool(state[self._started])

    def step(self, state: np.ndarray, u: Sequence[float], raw: Sequence[float],
             y: Sequence[float], dt: float) -> None:
        """Advances the filter stored in ``state`` (modified in place) by one period [s].

        ``u`` is the input sample, ``raw`` the held sensor values (a changed value is a
        new sample) and ``y`` the measurements made from them, as sequences of floats.
        """
        ekf = self.ekf
        u_prev = state[self._u_prev]
        u = np.array(self._finite_inputs(state, u, u_prev))
        available = self._available(state, raw)
        y = np.array(y)
        if not state[self._started]:
            available &= np.isfinite(y)
            x0 = ekf.model.initial_state(u, y, available)
            if not np.all(np.isfinite(x0)):
                return
            x, P = x0, ekf.initial_covariance
        else:
            if ekf.model.smoothed_inputs:
                u = ekf.model.smooth_inputs(u_prev, u, dt)
            x, P = ekf.predict(state[self._x], self.covariance(state),
                               ekf.midpoint_input(u_prev, u), dt)
        result = ekf.update(x, P, u, y, available, diagnostics=False)
        state[self._x] = result.x
        state[self._P] = result.P.reshape(-1)
        u_prev[:] = u
        if np.count_nonzero(result.rejected):
            state[self._rejected] += result.rejected
        state[self._scalars] = (result.nis, result.dof, 1.0)

    def _finite_inputs(self, state: np.ndarray, u: Sequence[float],
                       u_prev: np.ndarray) -> Sequence[float]:
        """``u`` with its non-finite entries replaced by the previous input (counted)."""
        if all(map(math.isfinite, u)):
            return u
        bad = [not math.isfinite(v) for v in u]
        state[self._nan_u] += bad
        return [p if b else v for v, p, b in zip(u, u_prev.tolist(), bad, strict=True)]

    def _available(self, state: np.ndarray, raw: Sequence[float]) -> np.ndarray:
        """Channels with a new sample (bool; a NaN sample is counted once and the update
        skips it); keeps ``raw`` for the next period."""
        stored = state[self._raw_prev]
        previous = stored.tolist()
        stored[:] = raw
        if math.isnan(sum(raw) + sum(previous)):  # NaN samples (or none seen yet)
            fresh = is_new_sample(raw, previous)
            state[self._nan_y] += fresh & np.isnan(raw)
            return fresh
        return np.array([a != b for a, b in zip(raw, previous, strict=True)])


def _delayed_controls(held: np.ndarray, current: np.ndarray, started: bool) -> list[float]:
    """The commands of one period earlier, kept in ``held`` (a view of the discrete state,
    then overwritten with ``current``); ``current`` itself before the filter starts."""
    previous = held.tolist() if started else current.tolist()
    held[:] = current
    return previous


class _GpsDelay:
    """Ring buffer of the strapdown velocity change, packed into the discrete state."""

    def __init__(self, latency: float, period: float, gravity: float, start: int):
        self.lag = int(round(latency / period))
        self.gravity = gravity
        # cumulative velocity change (3), previous NED acceleration (3), ring (lag + 1, 3), index
        self.start, self.stop = start, start + 6 + 3 * (self.lag + 1) + 1

    def correction(self, state: np.ndarray, specific_force: list[float], euler: list[float],
                   dt: float) -> list[float]:
        """Adds this period's velocity change; returns the change over the latency [m/s]."""
        if self.lag == 0:
            return [0.0, 0.0, 0.0]
        s = state[self.start:self.stop]
        values = s.tolist()  # three-vectors: float arithmetic beats numpy
        accel = ned_acceleration(specific_force, euler, self.gravity).tolist()
        index, slots = int(values[-1]), self.lag + 1
        cumulative = values[0:3]
        if index > 0:
            cumulative = [c + 0.5 * (a + b) * dt
                          for c, a, b in zip(cumulative, accel, values[3:6], strict=True)]
        s[0:6] = cumulative + accel
        start = 6 + 3 * (index % slots)
        s[start:start + 3] = cumulative
        s[-1] = index + 1
        if index < self.lag:  # the ring's first entry is the start (zero change)
            return cumulative
        oldest = 6 + 3 * ((index + 1) % slots)
        return [c - o for c, o in zip(cumulative, values[oldest:oldest + 3], strict=True)]


class _AirDataSystem(LeafSystem):
    """Common part of the two air-data filters (ports, GPS delay, outputs)."""

    def __init__(self, params: EkfSystemParams, model, needs_controls: bool):
        super().__init__()
        self.params = params.validate()
        noise = params.noise or model.default_noise(params.sensors, period=params.period)
        self.ekf = ExtendedKalmanFilter(model, noise, params.gate_probability)
        self._imu = self.DeclareVectorInputPort("imu", 6)
        self._attitude = self.DeclareVectorInputPort("attitude", 3)
        self._gps = self.DeclareVectorInputPort("gps", 6)
        self._pitot = self.DeclareVectorInputPort("pitot", 2)
        self._vanes = self.DeclareVectorInputPort("vanes", 2)
        self._controls = self.DeclareVectorInputPort("controls", 4) if needs_controls else None
        self._slot = _Slot(self.ekf, 0)
        self._delay = _GpsDelay(params.gps_latency, params.period, params.aircraft.gravity,
                                self._slot.stop)
        self._held = self._delay.stop  # previous controls (4)
        initial = np.concatenate([self._slot.initial(),
                                  np.zeros(self._delay.stop - self._delay.start), np.zeros(4)])
        self._xd = self.DeclareDiscreteState(initial)
        self.DeclarePeriodicDiscreteUpdateEvent(params.period, 0.0, self._update)
        deps = {self.xd_ticket()}
        self.DeclareVectorOutputPort("air_data", 3, self._calc_air_data,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("wind_ned", 3, self._calc_wind, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("covariance", 36, self._calc_covariance,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("state", 6, self._calc_state, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("nis", 2, self._calc_nis, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("counters", 2, self._calc_counters,
                                     prerequisites_of_calc=deps)

    # ------------------------------------------------------------------ update
    def _optional(self, port, context, entries: slice) -> list[float]:
        """``entries`` of an optional sensor port, NaN when the port has no value."""
        if port.HasValue(context):
            return port.Eval(context)[entries].tolist()
        return [math.nan] * (entries.stop - entries.start)

    def _update(self, context, discrete_state) -> None:
        # Drake hands the update its current values: advance them in place.
        state = discrete_state.get_mutable_value(self._xd)
        imu, attitude = self._imu.Eval(context).tolist(), self._attitude.Eval(context).tolist()
        specific_force = imu[0:3]
        # Sensor values in the model's measurement order (accelerometer first in the
        # model-based filter); the GPS velocity moved forward by its latency.
        gps = self._optional(self._gps, context, _GPS_VELOCITY)
        air = (self._optional(self._pitot, context, _DYNAMIC_PRESSURE)
               + self._optional(self._vanes, context, _VANES))
        change = self._delay.correction(state, specific_force, attitude, self.params.period)
        y = [v + c for v, c in zip(gps, change, strict=True)] + air
        raw = gps + air
        if self._controls is not None:
            raw, y = specific_force + raw, specific_force + y
        u = self._inputs(context, state, imu, attitude)
        self._slot.step(state, u, raw, y, self.params.period)

    def _held_controls(self, context, state) -> list[float]:
        return _delayed_controls(state[self._held:self._held + 4], self._controls.Eval(context),
                                 self._slot.started(state))

    # ----------------------------------------------------------------- outputs
    def _value(self, context) -> np.ndarray:
        return context.get_discrete_state(self._xd).get_value()

    def _x(self, context) -> np.ndarray:
        return self._slot.get(self._value(context), "x")

    def _calc_covariance(self, context, output) -> None:
        output.SetFromVector(self._slot.get(self._value(context), "P"))

    def _calc_state(self, context, output) -> None:
        output.SetFromVector(self._x(context))

    def _calc_wind(self, context, output) -> None:
        output.SetFromVector(self._x(context)[3:6])

    def _calc_nis(self, context, output) -> None:
        output.SetFromVector(self._slot.get(self._value(context), "scalars")[:2])

    def _calc_counters(self, context, output) -> None:
        value = self._value(context)
        output.SetFromVector([self._slot.get(value, "rejected").sum(),
                              self._slot.get(value, "nan_y").sum()
                              + self._slot.get(value, "nan_u").sum()])

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the ``state`` output entries."""
        return self.ekf.model.state_names


class AirDataEkf(_AirDataSystem):
    """Model-free air-data and wind EKF (Vaiopoulos 2017, sec. 5.4.3); see :class:`AirDataModel`.

    ==============  ====  ==========================================================
    Input port      size  content [unit]
    ==============  ====  ==========================================================
    ``imu``         6     specific force ax, ay, az [m/s^2], rates p, q, r [rad/s]
    ``attitude``    3     roll, pitch, yaw [rad]
    ``gps``         6     position [m] (unused), velocity NED [m/s]; optional
    ``pitot``       2     dynamic pressure [Pa], airspeed [m/s] (unused); optional
    ``vanes``       2     alpha, beta [rad]; optional
    ==============  ====  ==========================================================

    ==============  ====  ==========================================================
    Output port     size  content [unit]
    ==============  ====  ==========================================================
    ``air_data``    3     Va [m/s], alpha [rad], beta [rad]
    ``wind_ned``    3     W_N, W_E, W_D [m/s]
    ``covariance``  36    state covariance, row-major 6x6 [SI units squared]
    ``state``       6     u_r, v_r, w_r [m/s] (air-relative, body), W_N, W_E, W_D
    ``nis``         2     NIS of the last update [-], its degrees of freedom
    ``counters``    2     gate rejections, skipped NaN samples (since start)
    ==============  ====  ==========================================================

    All outputs depend on the discrete state only.
    """

    def __init__(self, params: EkfSystemParams):
        super().__init__(params, AirDataModel(params.aircraft), needs_controls=False)

    def _inputs(self, context, state, imu, attitude) -> list[float]:
        return imu + attitude

    def _calc_air_data(self, context, output) -> None:
        x = self._x(context)
        output.SetFromVector(np.array(air_data_from_velocity(x[0], x[1], x[2]), float))


class ModelBasedAirDataEkf(_AirDataSystem):
    """Model-based air-data and wind EKF (Vaiopoulos 2017, sec. 5.4.5); see
    :class:`ModelBasedAirDataModel`. Estimates alpha and beta without vanes from
    the aerodynamic model of ``params.aircraft`` and the accelerometer.

    Ports: those of :class:`AirDataEkf`, with the specific force of ``imu`` used
    as a measurement (the rates remain inputs), ``state`` holding Va [m/s], alpha,
    beta [rad], W_N, W_E, W_D [m/s], and one more input:

    ==============  ====  ==========================================================
    Input port      size  content [unit]
    ==============  ====  ==========================================================
    ``controls``    4     elevator, aileron, rudder [rad], throttle [0..1] (commands)
    ==============  ====  ==========================================================
    """

    def __init__(self, params: EkfSystemParams):
        super().__init__(params, ModelBasedAirDataModel(params.aircraft), needs_controls=True)

    def _inputs(self, context, state, imu, attitude) -> list[float]:
        return imu[3:6] + attitude + self._held_controls(context, state)

    def _calc_air_data(self, context, output) -> None:
        output.SetFromVector(self._x(context)[0:3])


class ParameterEkf(LeafSystem):
    """Augmented-state EKFs of Ortiz & Gutierrez 2009 (eq. 42-50): longitudinal and lateral
    derivatives.

    Two filters on :class:`ParameterModel` (``axis="longitudinal"`` and
    ``"lateral"``), started from the derivatives of ``params.aircraft`` (the
    prior model) once the air data are available; ``turbulence`` (a Dryden
    level, e.g. "light") selects the turbulent-air tuning of
    :meth:`ParameterModel.default_noise`.

    ========================  ====  ================================================
    Input port                size  content [unit]
    ========================  ====  ================================================
    ``air_data``              3     Va [m/s], alpha, beta [rad] (vanes and pitot, or
                                    an air-data EKF)
    ``imu``                   6     specific force [m/s^2], rates p, q, r [rad/s]
    ``attitude``              3     roll, pitch, yaw [rad]
    ``controls``              4     elevator, aileron, rudder [rad], throttle [0..1]
    ``angular_acceleration``  3     p_dot, q_dot, r_dot [rad/s^2]; optional
    ========================  ====  ================================================

    ========================  ====  ================================================
    Output port               size  content [unit]
    ========================  ====  ================================================
    ``derivatives``           L+T   longitudinal then lateral derivatives [-]
                                    (names in ``derivative_names``)
    ``derivatives_std``       L+T   their standard deviations [-]
    ``state``                 9     V [m/s], alpha [rad], q [rad/s], theta, beta
                                    [rad], p, r [rad/s], phi, psi [rad]
    ``nis``                   4     NIS and degrees of freedom, longitudinal and
                                    lateral
    ========================  ====  ================================================

    All outputs depend on the discrete state only.
    """

    # The input ports stacked: air_data, imu, attitude, controls, angular_acceleration.
    _SIGNALS = ("airspeed", "alpha", "beta", "ax", "ay", "az", "p", "q", "r", "roll", "pitch",
                "yaw", "elevator", "aileron", "rudder", "throttle", "p_dot", "q_dot", "r_dot")

    def __init__(self, params: EkfSystemParams, longitudinal: tuple[str, ...] | None = None,
                 lateral: tuple[str, ...] | None = None, turbulence: str | None = None):
        super().__init__()
        self.params = params.validate()
        self.ekfs, self._slots, start = [], [], 0
        for axis, names in (("longitudinal", longitudinal), ("lateral", lateral)):
            model = ParameterModel(params.aircraft, axis, names)
            noise = params.noise if params.noise is not None else model.default_noise(
                params.sensors, turbulence=turbulence)
            ekf = ExtendedKalmanFilter(model, noise, params.gate_probability)
            self.ekfs.append(ekf)
            self._slots.append(_Slot(ekf, start))
            start = self._slots[-1].stop
        self._held = start
        # Each filter's inputs and measurements picked from the stacked ports.
        self._inputs, self._measurements = (
            tuple(operator.itemgetter(*[self._SIGNALS.index(n) for n in getattr(e.model, names)])
                  for e in self.ekfs) for names in ("input_names", "measurement_names"))
        self.derivative_names = tuple(n for e in self.ekfs for n in e.model.parameter_names)
        self._air = self.DeclareVectorInputPort("air_data", 3)
        self._imu = self.DeclareVectorInputPort("imu", 6)
        self._attitude = self.DeclareVectorInputPort("attitude", 3)
        self._controls = self.DeclareVectorInputPort("controls", 4)
        self._omega_dot = self.DeclareVectorInputPort("angular_acceleration", 3)
        initial = np.concatenate([s.initial() for s in self._slots] + [np.zeros(4)])
        self._xd = self.DeclareDiscreteState(initial)
        self.DeclarePeriodicDiscreteUpdateEvent(params.period, 0.0, self._update)
        deps = {self.xd_ticket()}
        n = len(self.derivative_names)
        self.DeclareVectorOutputPort("derivatives", n, self._calc_derivatives,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("derivatives_std", n, self._calc_std,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("state", 9, self._calc_state, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("nis", 4, self._calc_nis, prerequisites_of_calc=deps)

    def _update(self, context, discrete_state) -> None:
        # Drake hands the update its current values: advance them in place.
        state = discrete_state.get_mutable_value(self._xd)
        controls = _delayed_controls(state[self._held:self._held + 4],
                                     self._controls.Eval(context), self._slots[0].started(state))
        omega_dot = (self._omega_dot.Eval(context).tolist() if self._omega_dot.HasValue(context)
                     else [math.nan] * 3)
        signals = (self._air.Eval(context).tolist() + self._imu.Eval(context).tolist()
                   + self._attitude.Eval(context).tolist() + controls + omega_dot)
        for slot, inputs, measurements in zip(self._slots, self._inputs, self._measurements,
                                              strict=True):
            y = measurements(signals)
            slot.step(state, inputs(signals), y, y, self.params.period)

    def _value(self, context) -> np.ndarray:
        return context.get_discrete_state(self._xd).get_value()

    def _calc_derivatives(self, context, output) -> None:
        value = self._value(context)
        output.SetFromVector(np.concatenate([
            s.get(value, "x")[len(e.model.physical_names):]
            for s, e in zip(self._slots, self.ekfs, strict=True)]))

    def _calc_std(self, context, output) -> None:
        value = self._value(context)
        output.SetFromVector(np.concatenate([
            np.sqrt(np.diag(s.covariance(value)))[len(e.model.physical_names):]
            for s, e in zip(self._slots, self.ekfs, strict=True)]))

    def _calc_state(self, context, output) -> None:
        value = self._value(context)
        output.SetFromVector(np.concatenate([
            s.get(value, "x")[:len(e.model.physical_names)]
            for s, e in zip(self._slots, self.ekfs, strict=True)]))

    def _calc_nis(self, context, output) -> None:
        value = self._value(context)
        output.SetFromVector(np.concatenate([s.get(value, "scalars")[:2] for s in self._slots]))
