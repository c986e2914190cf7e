"""Recovery tubes: a cold solve per failure class, the cached load, and the run-time query.

For the hexacopter variant of the fault scenarios (``hexacopter(f_max=10.0)``), one
failure set per class that keeps closure (single, opposite pair, one-apart pair,
alternating triple) is solved cold into an empty cache folder, then loaded from it.
The membership query is timed for one state and for a batch, with this package's
multilinear interpolation against scipy's ``RegularGridInterpolator`` on the same
stored values, in the same run.

    python benchmarks/bench_tubes.py            # default grid (minutes on two cores)
    python benchmarks/bench_tubes.py --quick    # one class on a coarse first-order grid
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from drake_uav.model.tilt import quaternion_from_tilt
from drake_uav.optimization.reachability import TubeSettings, recovery_tube
from drake_uav.vehicles import hexacopter

CLASSES = {"single": [0], "opposite pair": [0, 3], "one-apart pair": [0, 2],
           "alternating triple": [0, 2, 4]}


def _best_of(function, repeats: int, number: int) -> float:
    """Smallest mean time per call [s] over ``repeats`` runs of ``number`` calls."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            function()
        best = min(best, (time.perf_counter() - start) / number)
    return best


def _states(settings: TubeSettings, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random 13-states on the grid's domain, and their reduced coordinates."""
    reduced = np.random.default_rng(seed).uniform(settings.lower, settings.upper, (count, 4))
    x = np.zeros((count, 13))
    x[:, 3:7] = np.column_stack(quaternion_from_tilt((reduced[:, 0], reduced[:, 1])))
    x[:, 10:12] = reduced[:, 2:]
    return x, reduced


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="coarse grid, seconds")
    args = parser.parse_args()
    settings = TubeSettings.coarse(accuracy="low") if args.quick else TubeSettings()
    params = hexacopter(f_max=10.0)
    classes = dict(list(CLASSES.items())[:1]) if args.quick else CLASSES
    print(f"grid {settings.shape} ({np.prod(settings.shape)} nodes), accuracy "
          f"{settings.accuracy}, horizon {settings.horizon} s")
    with tempfile.TemporaryDirectory() as cache:
        tubes = {}
        for name, failed in classes.items():
            start = time.perf_counter()
            tubes[name] = recovery_tube(params, failed, settings, cache_dir=cache)
            cold = time.perf_counter() - start
            load = _best_of(lambda f=failed: recovery_tube(params, f, settings, cache_dir=cache),
                            repeats=3, number=5)
            x, _ = _states(settings, 20000, seed=1)
            inside = tubes[name].contains(x).mean()
            print(f"{name:>20} {failed}: cold {cold:7.2f} s, cached load {load * 1e3:6.2f} ms "
                  f"({cold / load:,.0f}x), inside {inside:.3f} of the grid's domain")

    tube = tubes["single"]
    scipy_interp = RegularGridInterpolator(tube.values.coordinates, tube.values.values)
    x, reduced = _states(settings, 1000, seed=2)
    np.testing.assert_allclose(tube.values(reduced), scipy_interp(reduced), atol=1e-9)
    one_state, one_reduced = x[0], reduced[:1]
    timings = {
        "own interpolation, 1 point (float path)": _best_of(
            lambda: tube.values.at(one_reduced[0]), 5, 2000),
        "own interpolation, 1 point (array path)": _best_of(
            lambda: tube.values(one_reduced), 5, 2000),
        "scipy RegularGridInterpolator, 1 point": _best_of(lambda: scipy_interp(one_reduced),
                                                            5, 500),
        "own interpolation, 1000 points": _best_of(lambda: tube.values(reduced), 5, 50),
        "scipy RegularGridInterpolator, 1000 points": _best_of(lambda: scipy_interp(reduced),
                                                                5, 20),
        "tube.contains(13-state)": _best_of(lambda: tube.contains(one_state), 5, 2000),
        "tube.value(1000 13-states)": _best_of(lambda: tube.value(x), 5, 50),
    }
    for name, seconds in timings.items():
        print(f"{name:>42}: {seconds * 1e6:9.1f} us")
    ratio = timings["scipy RegularGridInterpolator, 1 point"] \
        / timings["own interpolation, 1 point (float path)"]
    print(f"one-point query: own interpolation {ratio:.1f}x faster than scipy")


if __name__ == "__main__":
    main()
