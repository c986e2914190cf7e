"""Experiment scaffolding: simulated flights with known effects, for the benchmarks, the
tests and the campaign scenarios built on them.

Not part of the identification API (it may change with the experiments it serves):

* :mod:`.discovery_cases`: the ``discovery`` scenario, one flight with one effect the
  catalog model lacks, then the main job (``drake-uav campaign run discovery``).
* :mod:`.realistic_logs`: the ``realistic_logs`` scenario, the main job on simulated
  autopilot logs of every format.
* :mod:`.drag_aliasing`, :mod:`.imu_offset`, :mod:`.noise_budget`: the studies of
  ``benchmarks/bench_drag_aliasing.py``, ``bench_imu_position.py`` and
  ``bench_noise_budget.py``.

The campaign machinery (:mod:`drake_uav.campaigns`) finds the two scenarios by name; it
imports nothing from here.
"""
