"""What a fitted model is worth: output-error reconstruction, the noise floor of the
held-out error, and the identifiability of the derivatives.

* :mod:`.reconstruction`: :func:`~.reconstruction.reconstruct` the flight with a model.
* :mod:`.noise_floor`: the part of the held-out error the sensor noise alone explains.
* :mod:`.identifiability`: derivatives the flight cannot determine.
"""
