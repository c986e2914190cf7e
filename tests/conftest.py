"""Test-session settings.

Every array of the tests is small: one BLAS thread per process is faster than several
fighting over the cores, the more so with one pytest-xdist worker per core (the command line
sets the same for its jobs, ``drake_uav.cli``). Set before numpy loads; a user's own setting
wins.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
