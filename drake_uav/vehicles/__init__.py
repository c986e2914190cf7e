"""Vehicle parameter dataclasses and the catalog of known aircraft."""

from drake_uav.vehicles.fixed_wing import (
    FixedWingParams,
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

__all__ = [
    "FixedWingParams",
    "aerosonde",
    "aerosonde_mavsim",
    "unatrap",
    "fixed_wing_catalog",
    "load_fixed_wing",
    "MultirotorParams",
    "quadrotor_x",
    "quadrotor_plus",
    "hexacopter",
]
