"""The equations, with no Drake systems: every layer above calls these.

Each function works for float, ``AutoDiffXd`` and ``symbolic.Expression``
entries (and, where it says so, elementwise on numpy arrays of samples):

* :mod:`~drake_uav.model.rotations`: quaternions (w, x, y, z), rotation matrices,
  3-2-1 Euler angles and their kinematics (NED / FRD frames).
* :mod:`~drake_uav.model.coefficients`: the stability-derivative coefficient
  model, linear in named parameters.
* :mod:`~drake_uav.model.air_data`: airspeed, alpha and beta from the
  air-relative velocity and back.
* :mod:`~drake_uav.model.fixed_wing`: the fixed-wing equations of motion.
* :mod:`~drake_uav.model.multirotor`: the multirotor rigid body and allocation.
* :mod:`~drake_uav.model.tilt`: the tilt (body z against the vertical) and its
  rotational dynamics with the heading left out, for the recovery tubes.
* :mod:`~drake_uav.model.dryden`: the Dryden turbulence shaping filters.
* :mod:`~drake_uav.model.isolation`: the measured coefficients from flight signals.
* :mod:`~drake_uav.model.compiled`: a scalar-generic function as generated
  float code (values, Jacobians, batches over a log).
"""

from drake_uav.model.air_data import air_data_from_velocity, velocity_from_air_data
from drake_uav.model.coefficients import (
    COEFFICIENTS,
    SIGNALS,
    AeroCondition,
    CoefficientModel,
    body_to_lift_drag,
    lift_drag_to_body,
    regressor_matrix,
    signal_value,
    signal_values,
    split_derivative_name,
    validate_derivative_names,
)
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.dryden import TurbulenceScales, dryden_psd, dryden_scales
from drake_uav.model.fixed_wing import (
    CONTROL_NAMES,
    STATE_NAMES,
    CompiledFixedWingModel,
    FixedWingEvaluation,
    FixedWingModel,
)
from drake_uav.model.isolation import differentiate
from drake_uav.model.multirotor import (
    motor_wrench,
    multirotor_derivatives,
    multirotor_dynamics,
    produced_thrusts,
)
from drake_uav.model.multirotor import specific_force as multirotor_specific_force
from drake_uav.model.rotations import (
    euler_rates,
    euler_to_quat,
    euler_to_rotmat,
    quat_derivative,
    quat_multiply,
    quat_to_euler,
    quat_to_rotmat,
    rotmat_to_quat,
)

__all__ = [
    "COEFFICIENTS",
    "CONTROL_NAMES",
    "SIGNALS",
    "STATE_NAMES",
    "AeroCondition",
    "CoefficientModel",
    "CompiledFixedWingModel",
    "CompiledFunction",
    "FixedWingEvaluation",
    "FixedWingModel",
    "TurbulenceScales",
    "air_data_from_velocity",
    "body_to_lift_drag",
    "differentiate",
    "dryden_psd",
    "dryden_scales",
    "euler_rates",
    "euler_to_quat",
    "euler_to_rotmat",
    "lift_drag_to_body",
    "motor_wrench",
    "multirotor_derivatives",
    "multirotor_dynamics",
    "multirotor_specific_force",
    "produced_thrusts",
    "quat_derivative",
    "quat_multiply",
    "quat_to_euler",
    "quat_to_rotmat",
    "regressor_matrix",
    "rotmat_to_quat",
    "signal_value",
    "signal_values",
    "split_derivative_name",
    "validate_derivative_names",
    "velocity_from_air_data",
]
