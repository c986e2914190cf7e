"""Vehicle parameters: validated dataclasses and the catalog of known aircraft.

Fixed-wing aircraft (:class:`FixedWingParams`, catalog ``aerosonde()``,
``aerosonde_mavsim()``, ``unatrap()``, TOML files through
:func:`load_fixed_wing`), multirotors (:class:`MultirotorParams`,
``quadrotor_x()``, ``quadrotor_plus()``, ``hexacopter()``) and the sensor suite
(:class:`SensorSuiteParams` and one dataclass per sensor). SI units; invalid
values raise ``ValueError`` naming the field.
"""

from drake_uav.vehicles.fixed_wing import (
    ControlLimits,
    FixedWingParams,
    MotorPropeller,
    Propulsion,
    aerosonde,
    aerosonde_mavsim,
    fixed_wing_catalog,
    unatrap,
)
from drake_uav.vehicles.loading import load_fixed_wing
from drake_uav.vehicles.multirotor import (
    MultirotorParams,
    hexacopter,
    quadrotor_plus,
    quadrotor_x,
)
from drake_uav.vehicles.sensors import (
    AttitudeParams,
    BaroParams,
    ChannelErrors,
    GpsParams,
    ImuParams,
    PitotParams,
    SensorSuiteParams,
    VaneParams,
)

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
