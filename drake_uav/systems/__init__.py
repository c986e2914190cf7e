"""Drake LeafSystems, thin over the equations of :mod:`drake_uav.model`.

* Plants: :class:`FixedWingPlant` (13 states), :class:`MultirotorPlant`
  (motor faults); both support Drake scalar conversion.
* Environment and sensing: :class:`DrydenWind` (Dryden turbulence over a
  steady wind, :class:`DrydenParams`), :class:`SensorSuite` (the sampled
  low-cost sensor suite, one :class:`SampledSensors` inside).
* Excitation and disturbances: :class:`ExcitationSource` with
  :class:`Doublet`, :class:`ThreeTwoOneOne`, :class:`Multisine` and
  :func:`orthogonal_multisines`; :class:`AerodynamicIncrement` (an effect the
  model lacks, injected as an external wrench).
* Control: :class:`SafetyPilot` (the identification flight's weak hold loops,
  :class:`SafetyPilotGains`), :class:`NmpcController` (the multirotor's tracking
  NMPC), :class:`NoisyStateSensor` (:class:`StateNoise`: a noisy state measurement
  for the controller).
* On-line estimation and identification: :class:`AirDataEkf`,
  :class:`ModelBasedAirDataEkf`, :class:`ParameterEkf`,
  :class:`RecursiveIdentifier` and :class:`AeroRegressors`.
"""

from drake_uav.systems.disturbances import AerodynamicIncrement
from drake_uav.systems.estimators import (
    AirDataEkf,
    EkfSystemParams,
    ModelBasedAirDataEkf,
    ParameterEkf,
)
from drake_uav.systems.excitation import (
    SURFACES,
    Doublet,
    ExcitationSource,
    Multisine,
    ThreeTwoOneOne,
    doublet,
    excitation_controls,
    low_peak_factor_phases,
    multisine,
    orthogonal_multisines,
    relative_peak_factor,
    schroeder_phases,
    three_two_one_one,
)
from drake_uav.systems.fixed_wing import FixedWingPlant, FixedWingPlant_
from drake_uav.systems.identifiers import (
    AeroRegressors,
    RecursiveIdentifier,
    RecursiveIdentifierParams,
)
from drake_uav.systems.multirotor import MultirotorPlant, MultirotorPlant_
from drake_uav.systems.nmpc_controller import NmpcController
from drake_uav.systems.safety_pilot import SafetyPilot, SafetyPilotGains
from drake_uav.systems.sensors import SampledSensors, SensorSuite
from drake_uav.systems.state_sensor import NoisyStateSensor, StateNoise, add_noisy_state_sensor
from drake_uav.systems.wind import DrydenFilter, DrydenParams, DrydenWind

__all__ = [
    "SURFACES",
    "NoisyStateSensor",
    "StateNoise",
    "add_noisy_state_sensor",
    "AeroRegressors",
    "AerodynamicIncrement",
    "AirDataEkf",
    "Doublet",
    "DrydenFilter",
    "DrydenParams",
    "DrydenWind",
    "EkfSystemParams",
    "ExcitationSource",
    "FixedWingPlant",
    "FixedWingPlant_",
    "ModelBasedAirDataEkf",
    "MultirotorPlant",
    "MultirotorPlant_",
    "NmpcController",
    "Multisine",
    "ParameterEkf",
    "RecursiveIdentifier",
    "RecursiveIdentifierParams",
    "SafetyPilot",
    "SafetyPilotGains",
    "SampledSensors",
    "SensorSuite",
    "ThreeTwoOneOne",
    "doublet",
    "excitation_controls",
    "low_peak_factor_phases",
    "multisine",
    "orthogonal_multisines",
    "relative_peak_factor",
    "schroeder_phases",
    "three_two_one_one",
]
