"""Timing helper shared by the benchmarks."""

from __future__ import annotations

import time

__all__ = ["best_of"]


def best_of(repeat: int, fn):
    """(result of the last run, best wall time [s], best CPU time [s]) of ``repeat`` calls."""
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return result, min(walls), min(cpus)
