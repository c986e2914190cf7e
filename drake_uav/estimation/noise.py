"""Noise levels the filters are tuned with: sensor noise by channel, the wind random walk,
the Dryden gust rates, and the random walk of the estimated derivatives.

How these values were chosen and what they give on simulated flights is in
``docs/estimation.md`` (Tuning).
"""

from __future__ import annotations

from drake_uav.estimation.signals import ATTITUDE, GPS_VELOCITY
from drake_uav.model.dryden import dryden_scales
from drake_uav.vehicles.sensors import SensorSuiteParams

__all__ = ["WIND_PSD", "TURBULENT_DERIVATIVE_WALK", "gust_rate_psd", "sensor_std"]

WIND_PSD = {"wind_n": 0.3, "wind_e": 0.3, "wind_d": 0.45}
"""Wind random-walk density [m^2/s^3] for light low-altitude turbulence: about
``3 a sigma^2`` of the Dryden filters (a = Va / L) at 25 m/s and 100 m."""

TURBULENT_DERIVATIVE_WALK = 1e-5
"""Random-walk density of the derivatives of the parameter filter in turbulence, as a
fraction of their initial variance per second [1/s]. It keeps the filter's memory
finite, so that the slow errors of the air-flow angles entering the bilinear regressors
(which the linearisation does not carry into the covariance) do not accumulate into
overconfident derivatives."""


def gust_rate_psd(level: str, airspeed: float, altitude: float) -> tuple[float, float, float]:
    """Density [m^2/s^3] of the Dryden gust rates (u, v, w) above the break frequencies.

    The spectra of ``s H(s)`` for the filters of Vaiopoulos 2017, eq. 2.11 level off at
    ``2 sigma_u^2 a_u`` (first order) and ``3 sigma^2 a`` (second order), with
    ``a = airspeed / L``; MIL-F-8785C scales of the turbulence ``level`` ("light",
    "moderate", "severe") at ``altitude`` [m], ``airspeed`` in m/s.
    """
    scales = dryden_scales(level, altitude)
    a = airspeed / scales.lengths
    sigma = scales.sigmas
    return (float(2.0 * sigma[0] ** 2 * a[0]), float(3.0 * sigma[1] ** 2 * a[1]),
            float(3.0 * sigma[2] ** 2 * a[2]))


def sensor_std(sensors: SensorSuiteParams | None = None) -> dict[str, float]:
    """Per-sample noise standard deviation of every sensor channel by filter signal name
    (:mod:`~drake_uav.estimation.signals`), in the channel's unit.

    From the suite's white-noise levels (default: Vaiopoulos 2017, Table 7); channels of
    sensors that are not fitted keep the Table 7 value.
    """
    table7 = SensorSuiteParams.seed_table7()
    out = {}
    groups = (("imu", "accel", ("ax", "ay", "az")), ("imu", "gyro", ("p", "q", "r")),
              ("attitude", "angles", ATTITUDE), ("gps", "velocity", GPS_VELOCITY),
              ("pitot", "dynamic_pressure", ("pitot",)),
              ("vanes", "angles", ("alpha_vane", "beta_vane")))
    for sensor, group, names in groups:
        params = getattr(sensors, sensor, None) if sensors is not None else None
        params = getattr(table7, sensor) if params is None else params
        std = getattr(params, group).arrays(len(names), f"{sensor}.{group}")["noise_std"]
        out.update(zip(names, std.tolist(), strict=True))
    return out
