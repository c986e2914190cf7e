"""From a flight log to regression samples: the measured coefficients and their
regressors on one time base (no fits).

* :mod:`.aero_samples`: the samples type, :class:`~.aero_samples.AeroSamples`.
* :mod:`.flight_data`: a log checked, put on a uniform grid (:func:`~.flight_data.gridded_log`)
  and turned into samples (:func:`~.flight_data.samples_from_log`).
* :mod:`.isolation`: the coefficients from Newton-Euler and the Savitzky-Golay filters.
* :mod:`.air_data_source`, :mod:`.flight_phases`, :mod:`.segments`, :mod:`.decimation`:
  which air data, which spans of the flight, joined how, at which rate.
* :mod:`.regressor_noise`: how each sensor's noise enters the coefficients and regressors.

Imports only :mod:`drake_uav.identification.statistics` of the identification.
"""
