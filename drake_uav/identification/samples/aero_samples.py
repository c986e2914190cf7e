"""The samples type: flight samples ready for regression (:class:`AeroSamples`).

The measured aerodynamic coefficients, their conditions (air data, rates, controls) and
the logged signals on one time base, with the noise variance of each smoothed signal.
:func:`~drake_uav.identification.samples.isolation.isolate_coefficients` builds them; every
later stage (the discovery, the assessment) reads them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from drake_uav.model.coefficients import AeroCondition

__all__ = ["AeroSamples", "LOGGED", "MOMENTS", "ATTITUDE", "GPS_VELOCITY", "GPS_POSITION"]

ATTITUDE = ("roll", "pitch", "yaw")
""":attr:`AeroSamples.signals` of the attitude [rad] (body -> NED)."""
GPS_VELOCITY = ("gps_vn", "gps_ve", "gps_vd")
""":attr:`AeroSamples.signals` of the GPS velocity, NED [m/s]."""
GPS_POSITION = ("gps_pn", "gps_pe", "gps_pd")
""":attr:`AeroSamples.signals` of the GPS position, NED [m]."""

MOMENTS = ("Cl", "Cm", "Cn")
"""Coefficients measured from the angular accelerations."""

LOGGED = "logged:"
"""Prefix of the logged extra channels (a tension, a voltage) in :attr:`AeroSamples.signals`,
:attr:`AeroSamples.noise_variance` and :attr:`AeroSamples.signal_units`."""


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
    """Any other logged signals (altitude, attitude, ...), by name, same length; the
    extra channels of the log, smoothed like the regressors, as ``logged:<channel>``."""
    noise_variance: Mapping[str, float] = dataclasses.field(default_factory=dict)
    """Estimated white-noise variance of the smoothed ``airspeed, alpha, beta, p, q, r, ax,
    ay, az`` and ``logged:<channel>`` (units squared), for errors-in-variables corrections."""
    thrust_airspeed_slope: np.ndarray | None = None
    """d(thrust)/d(airspeed) of the propulsion model [N/(m/s)] (None: thrust measured)."""
    thrust_correction_terms: tuple[str, ...] = ()
    """The throttle terms of a thrust identified from this flight
    (:data:`~drake_uav.model.propeller.THROTTLE_TERMS`), which the discovery fits again
    with C_D (:func:`~drake_uav.identification.propulsion.thrust_correction_columns`);
    empty for the catalog's thrust or a measured one."""
    reference_area: float = 1.0
    """Wing area S [m^2] the coefficients refer to."""
    moment_view: AeroSamples | None = None
    """The same samples with the controls (surfaces, throttle, thrust) as the moment
    coefficients see them, or None when forces and moments see the same controls
    (see :func:`isolate_coefficients`)."""
    signal_units: Mapping[str, str] = dataclasses.field(default_factory=dict)
    """Unit of each logged extra channel of :attr:`signals` (``logged:<channel>``)."""

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
            thrust_correction_terms=self.thrust_correction_terms,
            reference_area=self.reference_area,
            moment_view=None if self.moment_view is None else self.moment_view.subset(index),
            signal_units=dict(self.signal_units),
        )
