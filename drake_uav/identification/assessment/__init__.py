"""What a fitted model is worth: output-error reconstruction, the noise floor of the
held-out error, and the identifiability of the derivatives.

* :mod:`.reconstruction`: :func:`~.reconstruction.reconstruct` the flight with a model.
* :mod:`.noise_floor`: the part of the held-out error the sensor noise alone explains.
* :mod:`.identifiability`: derivatives the flight cannot determine.
* :mod:`.logged_rates`: the terms a log's native rates cannot support, and the rates they
  need; :mod:`.rate_needs` names the fixed-wing job's terms and their channels.
"""
