"""The samples type: flight samples ready for regression (:class:`AeroSamples`).

The measured aerodynamic coefficients, their conditions (air data, rates, controls) and
the logged signals on one time base, with the noise variance of each smoothed signal.
:func:`~drake_uav.identification.samples.isolation.isolate_coefficients` builds them; every
later stage (the discovery, the assessment) reads them.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from enum import StrEnum

import numpy as np

from drake_uav.model.coefficients import AeroCondition

__all__ = ["AeroSamples", "MomentInputs", "Signal", "LOGGED", "logged", "MOMENTS", "ATTITUDE",
           "GPS_VELOCITY", "GPS_POSITION", "SHAFT_SPEED"]

class Signal(StrEnum):
    """The named signals of :attr:`AeroSamples.signals` (a logged extra channel is
    ``logged:<channel>``, :func:`logged`). Each is its name as a string too."""

    ROLL = "roll"
    """Roll angle [rad] (body -> NED)."""
    PITCH = "pitch"
    """Pitch angle [rad]."""
    YAW = "yaw"
    """Yaw angle [rad]."""
    HEIGHT = "height"
    """Barometric height [m]."""
    GPS_VN = "gps_vn"
    """GPS velocity north [m/s]."""
    GPS_VE = "gps_ve"
    """GPS velocity east [m/s]."""
    GPS_VD = "gps_vd"
    """GPS velocity down [m/s]."""
    GPS_PN = "gps_pn"
    """GPS position north [m] (from the first fix)."""
    GPS_PE = "gps_pe"
    """GPS position east [m]."""
    GPS_PD = "gps_pd"
    """GPS position down [m]."""


ATTITUDE = (Signal.ROLL, Signal.PITCH, Signal.YAW)
""":attr:`AeroSamples.signals` of the attitude [rad] (body -> NED)."""
GPS_VELOCITY = (Signal.GPS_VN, Signal.GPS_VE, Signal.GPS_VD)
""":attr:`AeroSamples.signals` of the GPS velocity, NED [m/s]."""
GPS_POSITION = (Signal.GPS_PN, Signal.GPS_PE, Signal.GPS_PD)
""":attr:`AeroSamples.signals` of the GPS position, NED [m]."""

SHAFT_SPEED = "motor_speed"
"""Noise source of a thrust computed from the logged propeller shaft speed [rad/s]
(:attr:`AeroSamples.thrust_speed_slope`), in :attr:`AeroSamples.noise_variance`."""

MOMENTS = ("Cl", "Cm", "Cn")
"""Coefficients measured from the angular accelerations."""

LOGGED = "logged:"
"""Prefix of the logged extra channels (a tension, a voltage) in :attr:`AeroSamples.signals`,
:attr:`AeroSamples.noise_variance` and :attr:`AeroSamples.signal_units`."""


def logged(channel: str) -> str:
    """The :attr:`AeroSamples.signals` key of the logged extra channel ``channel``.

    Parameters
    ----------
    channel : str
        The log channel.

    Returns
    -------
    str
        ``"logged:<channel>"``.
    """
    return f"{LOGGED}{channel}"


@dataclasses.dataclass(frozen=True)
class MomentInputs:
    """What the moment coefficients see where it differs from the forces.

    The regressors through the moments' interval filter
    (:func:`~drake_uav.identification.samples.isolation.isolate_coefficients`), on the
    samples' time base.

    Attributes
    ----------
    condition : AeroCondition
        Air data, rates, controls and thrust coefficient as the moments see them.
    dynamic_pressure : numpy.ndarray of shape (N,)
        qbar [Pa].
    throttle : numpy.ndarray of shape (N,)
        [0..1].
    thrust : numpy.ndarray of shape (N,)
        [N].
    thrust_airspeed_slope : numpy.ndarray of shape (N,) or None
        d(thrust)/d(airspeed) [N/(m/s)] (None: thrust measured).
    rate_derivatives : numpy.ndarray of shape (N, 3)
        Body angular accelerations [rad/s^2].
    logged : Mapping[str, numpy.ndarray]
        The logged extra channels (``logged:<channel>``) through the moments' filter.
    noise_variance : Mapping[str, float]
        Noise variance of each smoothed source as the moments see it (units squared).
    """

    condition: AeroCondition
    dynamic_pressure: np.ndarray
    throttle: np.ndarray
    thrust: np.ndarray
    thrust_airspeed_slope: np.ndarray | None
    rate_derivatives: np.ndarray
    logged: Mapping[str, np.ndarray]
    noise_variance: Mapping[str, float]
    thrust_speed_slope: np.ndarray | None = None
    """d(thrust)/d(shaft speed) [N/(rad/s)] of a thrust from the logged shaft speed, or
    None (:attr:`AeroSamples.thrust_speed_slope`)."""

    def subset(self, index) -> MomentInputs:
        """The samples selected by a boolean mask or an index array.

        Parameters
        ----------
        index : numpy.ndarray of bool or int
            The selection.

        Returns
        -------
        MomentInputs
            The selected samples.
        """
        return MomentInputs(
            AeroCondition(*(np.broadcast_to(f, self.throttle.shape)[index]
                            for f in self.condition)),
            self.dynamic_pressure[index], self.throttle[index], self.thrust[index],
            None if self.thrust_airspeed_slope is None else self.thrust_airspeed_slope[index],
            self.rate_derivatives[index], {k: v[index] for k, v in self.logged.items()},
            dict(self.noise_variance),
            None if self.thrust_speed_slope is None else self.thrust_speed_slope[index])


@dataclasses.dataclass(frozen=True)
class AeroSamples:
    """Flight samples ready for regression: the conditions and the measured coefficients.

    Made by :func:`~drake_uav.identification.samples.flight_data.samples_from_log` (or
    :func:`~drake_uav.identification.samples.isolation.isolate_coefficients` from arrays);
    every array has one entry per sample.

    Attributes
    ----------
    time : numpy.ndarray of shape (N,)
        [s], uniformly sampled.
    condition : AeroCondition
        Air data [m/s, rad], body rates [rad/s], controls [rad] and thrust coefficient,
        arrays.
    coefficients : Mapping[str, numpy.ndarray]
        Measured ``CL, CD, CY, Cl, Cm, Cn`` [-].
    dynamic_pressure : numpy.ndarray of shape (N,)
        qbar [Pa].
    throttle : numpy.ndarray of shape (N,)
        [0..1].
    thrust : numpy.ndarray of shape (N,)
        Thrust used in the isolation [N].
    rate_derivatives : numpy.ndarray of shape (N, 3)
        Body angular accelerations [rad/s^2].
    specific_force : numpy.ndarray of shape (N, 3)
        Accelerometer [m/s^2].
    signals : Mapping[str, numpy.ndarray]
        Any other logged signals (altitude, attitude, ...), by name, same length; the
        extra channels of the log, smoothed like the regressors, as ``logged:<channel>``.
    noise_variance : Mapping[str, float]
        Estimated white-noise variance of the smoothed ``airspeed, alpha, beta, p, q, r, ax,
        ay, az`` and ``logged:<channel>`` (units squared), for errors-in-variables
        corrections.
    thrust_airspeed_slope : numpy.ndarray of shape (N,) or None
        d(thrust)/d(airspeed) of the propulsion model [N/(m/s)] (None: thrust measured).
    thrust_correction_terms : tuple of str
        The throttle terms of a thrust identified from this flight
        (:data:`~drake_uav.model.propeller.THROTTLE_TERMS`), which the discovery fits again
        with C_D (:func:`~drake_uav.identification.propulsion.thrust_correction_columns`);
        empty for the catalog's thrust or a measured one.
    thrust_from_shaft_speed : bool
        Whether the thrust comes from the logged shaft speed through the propeller law
        (:mod:`drake_uav.model.propeller`): it then already follows the throttle as the
        motor did, so a command delay puts no error on it.
    thrust_speed_slope : numpy.ndarray of shape (N,) or None
        d(thrust)/d(shaft speed) [N/(rad/s)] of a thrust from the logged shaft speed, which
        carries the speed's noise (:data:`SHAFT_SPEED` in ``noise_variance``) into the
        thrust, the thrust coefficient and C_L, C_D; None otherwise.
    reference_area : float
        Wing area S [m^2] the coefficients refer to.
    moments : MomentInputs or None
        What the moment coefficients see where it differs from the forces (the regressors
        through their interval filter), or None when forces and moments see the same.
    signal_units : Mapping[str, str]
        Unit of each signal of ``signals``.

    Examples
    --------
    >>> from drake_uav.identification.samples.flight_data import samples_from_log
    >>> from importlib.resources import files
    >>> from drake_uav.io.readers import read_log
    >>> from drake_uav.vehicles.fixed_wing import aerosonde
    >>> log = read_log(files("drake_uav") / "data" / "sample_flight.parquet")   # bundled
    >>> samples = samples_from_log(log, aerosonde())
    >>> sorted(samples.coefficients)
    ['CD', 'CL', 'CY', 'Cl', 'Cm', 'Cn']
    >>> samples.aligned("CL") is samples, samples.aligned("Cm") is samples.moment_view
    (True, True)
    >>> samples.aligned("Cm").condition.elevator.shape == samples.time.shape
    True
    """

    time: np.ndarray
    condition: AeroCondition
    coefficients: Mapping[str, np.ndarray]
    dynamic_pressure: np.ndarray
    throttle: np.ndarray
    thrust: np.ndarray
    rate_derivatives: np.ndarray
    specific_force: np.ndarray
    signals: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    noise_variance: Mapping[str, float] = dataclasses.field(default_factory=dict)
    thrust_airspeed_slope: np.ndarray | None = None
    thrust_correction_terms: tuple[str, ...] = ()
    thrust_from_shaft_speed: bool = False
    thrust_speed_slope: np.ndarray | None = None
    reference_area: float = 1.0
    moments: MomentInputs | None = None
    signal_units: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.time)

    def aligned(self, coefficient: str) -> AeroSamples:
        """The samples whose regressors belong with ``coefficient``.

        Parameters
        ----------
        coefficient : str
            ``CL, CD, CY, Cl, Cm`` or ``Cn``.

        Returns
        -------
        AeroSamples
            :attr:`moment_view` for ``Cl, Cm, Cn`` when there is one, else these samples.
        """
        if coefficient in MOMENTS and self.moments is not None:
            return self.moment_view
        return self

    @functools.cached_property
    def moment_view(self) -> AeroSamples | None:
        """These samples as the moment coefficients see them (:attr:`moments` in place of
        the forces' regressors), or None when both see the same."""
        m = self.moments
        if m is None:
            return None
        signals = {k: v for k, v in self.signals.items() if not k.startswith(LOGGED)}
        return dataclasses.replace(
            self, condition=m.condition, dynamic_pressure=m.dynamic_pressure,
            throttle=m.throttle, thrust=m.thrust, thrust_airspeed_slope=m.thrust_airspeed_slope,
            thrust_speed_slope=m.thrust_speed_slope, rate_derivatives=m.rate_derivatives,
            signals={**signals, **m.logged},
            noise_variance=m.noise_variance, moments=None)

    def with_moments(self, update) -> AeroSamples:
        """A copy whose :attr:`moments` (when there are any) is ``update(moments)``.

        Parameters
        ----------
        update : callable
            ``MomentInputs -> MomentInputs``.

        Returns
        -------
        AeroSamples
            The copy (these samples when there are no moments).
        """
        return self if self.moments is None else dataclasses.replace(
            self, moments=update(self.moments))

    def observation_sensitivity(self, coefficient: str) -> dict[str, np.ndarray]:
        """d(measured coefficient)/d(air-data signal) per sample, for noise propagation.

        Every coefficient divides by qbar, so d/dVa = -2 C / Va; the wind-axis
        rotation gives d C_L / d alpha = -C_D and d C_D / d alpha = C_L. A thrust from
        the logged shaft speed moves C_L and C_D with the speed too.

        Parameters
        ----------
        coefficient : str
            The measured coefficient.

        Returns
        -------
        dict of str to numpy.ndarray
            ``airspeed`` [1/(m/s)], ``alpha``, ``beta`` [1/rad] and, with
            :attr:`thrust_speed_slope`, :data:`SHAFT_SPEED` [1/(rad/s)] -> (N,)
            sensitivity.
        """
        value = self.coefficients[coefficient]
        out = {"airspeed": -2.0 * value / self.condition.airspeed}
        if coefficient in ("CL", "CD"):
            # C_X = (m a_x - T) / (qbar S) also moves with the modelled thrust.
            alpha = self.condition.alpha
            rotate = (np.sin(alpha) if coefficient == "CL" else -np.cos(alpha)) / (
                -self.dynamic_pressure * self.reference_area)
            if self.thrust_airspeed_slope is not None:
                out["airspeed"] = out["airspeed"] + rotate * self.thrust_airspeed_slope
            if self.thrust_speed_slope is not None:
                out[SHAFT_SPEED] = rotate * self.thrust_speed_slope
        if coefficient == "CL":
            out["alpha"] = -self.coefficients["CD"]
        elif coefficient == "CD":
            out["alpha"] = self.coefficients["CL"]
        return out

    def perturbed(self, signal: str, delta: float) -> AeroSamples:
        """A copy with ``delta`` added to one air-data signal (or the shaft speed), as the
        forces and the moments see it.

        The dynamic pressure (and a thrust computed from the airspeed) follow the airspeed;
        a thrust from the shaft speed follows :data:`SHAFT_SPEED` through
        :attr:`thrust_speed_slope`, and the thrust coefficient the thrust.

        Parameters
        ----------
        signal : str
            ``airspeed``, ``alpha``, ``beta`` or :data:`SHAFT_SPEED`.
        delta : float
            The step [m/s, rad or rad/s].

        Returns
        -------
        AeroSamples
            The perturbed copy.
        """
        condition, q_bar, thrust = _perturbed_inputs(
            self.condition, self.dynamic_pressure, self.thrust,
            (self.thrust_airspeed_slope, self.thrust_speed_slope), self.reference_area,
            signal, delta)
        return dataclasses.replace(
            self.with_moments(lambda m: dataclasses.replace(m, **dict(zip(
                ("condition", "dynamic_pressure", "thrust"), _perturbed_inputs(
                    m.condition, m.dynamic_pressure, m.thrust,
                    (m.thrust_airspeed_slope, m.thrust_speed_slope), self.reference_area,
                    signal, delta), strict=True)))),
            condition=condition, dynamic_pressure=q_bar, thrust=thrust)

    def subset(self, index) -> AeroSamples:
        """The samples selected by a boolean mask or an index array.

        Parameters
        ----------
        index : numpy.ndarray of bool or int
            The selection.

        Returns
        -------
        AeroSamples
            The selected samples (both views).
        """

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
            thrust_correction_terms=self.thrust_correction_terms,
            thrust_from_shaft_speed=self.thrust_from_shaft_speed,
            thrust_speed_slope=(None if self.thrust_speed_slope is None
                                else pick(self.thrust_speed_slope)),
            reference_area=self.reference_area,
            moments=None if self.moments is None else self.moments.subset(index),
            signal_units=dict(self.signal_units),
        )


def _perturbed_inputs(condition: AeroCondition, q_bar: np.ndarray, thrust: np.ndarray,
                      slopes: tuple[np.ndarray | None, np.ndarray | None], area: float,
                      signal: str, delta: float
                      ) -> tuple[AeroCondition, np.ndarray, np.ndarray]:
    """The condition, dynamic pressure [Pa] and thrust [N] with ``delta`` added to the
    air-data ``signal`` or the shaft speed: qbar scales with the airspeed squared, the
    modelled thrust follows its airspeed and shaft-speed ``slopes``, and the thrust
    coefficient both (wing area ``area``)."""
    slope, speed_slope = slopes
    if signal == SHAFT_SPEED:
        if speed_slope is None:
            raise ValueError("AeroSamples.perturbed: the thrust does not come from a logged "
                             "shaft speed (no thrust_speed_slope)")
        thrust = thrust + speed_slope * delta
        return condition._replace(thrust_coefficient=thrust / (q_bar * area)), q_bar, thrust
    value = getattr(condition, signal) + delta
    moved = condition._replace(**{signal: value})
    if signal != "airspeed":
        return moved, q_bar, thrust
    q_bar = q_bar * (value / condition.airspeed) ** 2
    if slope is not None:
        thrust = thrust + slope * delta
    return moved._replace(thrust_coefficient=thrust / (q_bar * area)), q_bar, thrust
