"""Timing helper shared by the benchmarks."""

from __future__ import annotations

import os
import time

__all__ = ["best_of", "finished_runs"]


def best_of(repeat: int, fn):
    """(result of the last run, best wall time [s], best CPU time [s]) of ``repeat`` calls."""
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return result, min(walls), min(cpus)


def finished_runs(rows: list[dict], wall: float, workers: int, quick: bool) -> list[dict]:
    """Prints how many campaign runs finished in ``wall`` seconds on ``workers`` and the
    first failures; returns the finished rows. In ``quick`` mode a failed run stops the
    script (the CI's quick pass must see it)."""
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"{len(rows) - len(failed)} runs finished, {len(failed)} failed, {wall:.0f} s wall "
          f"on {workers or 1} worker(s), load {os.getloadavg()[0]:.1f}")
    for row in failed[:10]:
        print(f"  {row.get('effect')} seed {row['seed']}: {row['status']} {row.get('error', '')}")
    if failed and quick:
        raise SystemExit(f"{len(failed)} run(s) failed")
    return [r for r in rows if r["status"] == "ok"]
