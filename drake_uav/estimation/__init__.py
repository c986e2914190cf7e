"""State estimation: the EKF core, its filter models and offline runs over flight logs.

* :mod:`~drake_uav.estimation.ekf`: the continuous-discrete EKF (one filter or a
  batch) and :func:`run_filter`, the core run over logged samples.
* :mod:`~drake_uav.estimation.air_data_models`: the model-free and model-based
  air-data and wind filters (Vaiopoulos 2017, sec. 5.4.3 and 5.4.5).
* :mod:`~drake_uav.estimation.parameter_models`: the aerodynamic-derivative filter
  (Ortiz & Gutierrez 2009, sec. 5).
* :mod:`~drake_uav.estimation.attitude`: attitude inputs smoothed with the gyro.
* :mod:`~drake_uav.estimation.gps`: GPS latency removed with the IMU.
* :mod:`~drake_uav.estimation.noise`: the noise levels the filters are tuned with.
* :mod:`~drake_uav.estimation.signals`: the filter signals, their log channels and
  which held samples are new.
* :mod:`~drake_uav.estimation.offline`: flight logs to filter arrays.
* :mod:`~drake_uav.estimation.smoother`: the Rauch-Tung-Striebel smoother over a
  forward pass (:func:`filter_pass`).
* :mod:`~drake_uav.estimation.vaneless_models`: the air-data filter model for flights
  without vanes (Gauss-Markov vertical wind, free-coefficient specific-force relation).
* :mod:`~drake_uav.estimation.air_data_estimate`: air data without vanes over a log
  (:func:`estimate_air_data`).
"""

from drake_uav.estimation.air_data_estimate import AirDataEstimate, estimate_air_data
from drake_uav.estimation.air_data_models import (
    MIN_START_AIRSPEED,
    AirDataModel,
    ModelBasedAirDataModel,
)
from drake_uav.estimation.attitude import (
    ATTITUDE_TIME_CONSTANT,
    smoothed_attitude,
    smoothed_attitude_std,
)
from drake_uav.estimation.ekf import (
    EkfModel,
    EkfNoise,
    ExtendedKalmanFilter,
    FilterPass,
    FilterRun,
    UpdateResult,
    chi2_bounds,
    filter_pass,
    run_filter,
    wrap_angle,
)
from drake_uav.estimation.gps import DEFAULT_GPS_LATENCY, gps_latency_correction, ned_acceleration
from drake_uav.estimation.noise import (
    TURBULENT_DERIVATIVE_WALK,
    WIND_PSD,
    gust_rate_psd,
    sensor_std,
)
from drake_uav.estimation.offline import FilterData, LogReader
from drake_uav.estimation.parameter_models import (
    LATERAL_COEFFICIENTS,
    LONGITUDINAL_COEFFICIENTS,
    ParameterModel,
)
from drake_uav.estimation.signals import LOG_CHANNELS, fresh_samples, is_new_sample
from drake_uav.estimation.smoother import SmoothedPass, rts_smooth
from drake_uav.estimation.vaneless_models import VanelessAirDataModel

__all__ = [
    "ATTITUDE_TIME_CONSTANT",
    "DEFAULT_GPS_LATENCY",
    "LATERAL_COEFFICIENTS",
    "LOG_CHANNELS",
    "LONGITUDINAL_COEFFICIENTS",
    "MIN_START_AIRSPEED",
    "TURBULENT_DERIVATIVE_WALK",
    "WIND_PSD",
    "AirDataEstimate",
    "AirDataModel",
    "EkfModel",
    "EkfNoise",
    "ExtendedKalmanFilter",
    "FilterData",
    "FilterPass",
    "FilterRun",
    "LogReader",
    "ModelBasedAirDataModel",
    "ParameterModel",
    "SmoothedPass",
    "UpdateResult",
    "VanelessAirDataModel",
    "chi2_bounds",
    "estimate_air_data",
    "filter_pass",
    "fresh_samples",
    "gps_latency_correction",
    "gust_rate_psd",
    "is_new_sample",
    "ned_acceleration",
    "rts_smooth",
    "run_filter",
    "sensor_std",
    "smoothed_attitude",
    "smoothed_attitude_std",
    "wrap_angle",
]
