"""Vehicle parameters: validated dataclasses and the catalog of known aircraft.

Fixed-wing aircraft (:class:`FixedWingParams`, catalog ``aerosonde()``,
``aerosonde_mavsim()``, ``unatrap()``, TOML files through
:func:`load_fixed_wing`), multirotors (:class:`MultirotorParams`,
``quadrotor_x()``, ``quadrotor_plus()``, ``hexacopter()``) and the sensor suite
(:class:`SensorSuiteParams` and one dataclass per sensor). SI units; invalid
values raise ``ValueError`` naming the field.
"""

import importlib

_HOMES = {
    "AttitudeParams": "drake_uav.vehicles.sensors",
    "BaroParams": "drake_uav.vehicles.sensors",
    "ChannelErrors": "drake_uav.vehicles.sensors",
    "ControlLimits": "drake_uav.vehicles.fixed_wing",
    "FixedWingParams": "drake_uav.vehicles.fixed_wing",
    "GpsParams": "drake_uav.vehicles.sensors",
    "ImuParams": "drake_uav.vehicles.sensors",
    "MotorPropeller": "drake_uav.vehicles.fixed_wing",
    "MultirotorParams": "drake_uav.vehicles.multirotor",
    "PitotParams": "drake_uav.vehicles.sensors",
    "Propulsion": "drake_uav.vehicles.fixed_wing",
    "SensorSuiteParams": "drake_uav.vehicles.sensors",
    "VaneParams": "drake_uav.vehicles.sensors",
    "aerosonde": "drake_uav.vehicles.fixed_wing",
    "aerosonde_mavsim": "drake_uav.vehicles.fixed_wing",
    "fixed_wing_catalog": "drake_uav.vehicles.fixed_wing",
    "hexacopter": "drake_uav.vehicles.multirotor",
    "load_fixed_wing": "drake_uav.vehicles.loading",
    "quadrotor_plus": "drake_uav.vehicles.multirotor",
    "quadrotor_x": "drake_uav.vehicles.multirotor",
    "unatrap": "drake_uav.vehicles.fixed_wing",
}
"""Where each exported name lives: submodules load on first use, so that the command line
can check its arguments without importing Drake."""

__all__ = [
    "AttitudeParams",
    "BaroParams",
    "ChannelErrors",
    "ControlLimits",
    "FixedWingParams",
    "GpsParams",
    "ImuParams",
    "MotorPropeller",
    "MultirotorParams",
    "PitotParams",
    "Propulsion",
    "SensorSuiteParams",
    "VaneParams",
    "aerosonde",
    "aerosonde_mavsim",
    "fixed_wing_catalog",
    "hexacopter",
    "load_fixed_wing",
    "quadrotor_plus",
    "quadrotor_x",
    "unatrap",
]


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'drake_uav.vehicles' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name]), name)
