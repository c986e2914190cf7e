"""Runs every benchmark and example in its quick mode and stops at the first that fails.

Each script of benchmarks/ and examples/ (the helper modules excepted) runs with ``--quick``
(and the :data:`QUICK_ARGUMENTS` it has) in a fresh process of this interpreter, in a
scratch folder (so the ``out/`` files the examples write do not land in the tree), with this
tree first on ``PYTHONPATH`` and one numerical-library thread. One line per script gives its
status, wall time and CPU time (of the script and the processes it starts; on a shared
machine the wall time grows with the load, the CPU time much less); a script that exits
non-zero or runs longer than ``--timeout`` has its output printed and ends the run with exit
status 1. CI runs this (``.ci/run``), so a benchmark or an example that no longer runs fails
the build.

    python benchmarks/run_quick.py [SCRIPT ...] [--timeout 240] [--verbose]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("benchmarks", "examples")
HELPERS = frozenset({"figures.py", "timing.py", "run_quick.py"})
"""Modules of benchmarks/ that the scripts import (or this runner): not scripts."""
QUICK_ARGUMENTS = {"compare_revisions.py": ["--base", "HEAD", "--repeats", "1", "--scripts",
                                            "bench_fixed_wing.py"]}
"""Arguments given with ``--quick`` to a script whose quick mode alone is still long."""
ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Thread counts set to 1 for the scripts unless the environment sets them."""


def scripts() -> list[Path]:
    """Every script of benchmarks/ and examples/, sorted by folder then name."""
    return [path for folder in FOLDERS for path in sorted((ROOT / folder).glob("*.py"))
            if path.name not in HELPERS]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(script: Path, scratch: Path, timeout: float, verbose: bool) -> tuple[int, float, str]:
    """(exit status, wall time [s], output) of ``script --quick``; status -1 on a timeout."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]), MPLBACKEND="Agg")
    for name in ONE_THREAD:  # idle BLAS threads spin on a shared machine
        env.setdefault(name, "1")
    start = time.perf_counter()
    try:
        command = [sys.executable, str(script), "--quick", *QUICK_ARGUMENTS.get(script.name, [])]
        done = subprocess.run(command, cwd=scratch, env=env,
                              stdout=None if verbose else subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as expired:
        output = expired.stdout or ""
        return -1, time.perf_counter() - start, (output if isinstance(output, str)
                                                 else output.decode(errors="replace"))
    return done.returncode, time.perf_counter() - start, done.stdout or ""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="script file names (default: all)")
    parser.add_argument("--timeout", type=float, default=240.0, help="per script [s]")
    parser.add_argument("--verbose", action="store_true", help="show every script's output")
    args = parser.parse_args()
    chosen = scripts()
    unknown = set(args.names) - {path.name for path in chosen}
    if unknown:
        parser.error(f"no such script in {' or '.join(FOLDERS)}: {', '.join(sorted(unknown))}")
    if args.names:
        chosen = [path for path in chosen if path.name in args.names]
    total, total_cpu = time.perf_counter(), _children_cpu()
    for script in chosen:
        name = script.relative_to(ROOT)
        cpu = _children_cpu()
        with tempfile.TemporaryDirectory(prefix="drake_uav_quick_") as scratch:
            status, seconds, output = run(script, Path(scratch), args.timeout, args.verbose)
        times = f"{seconds:6.1f} s wall {_children_cpu() - cpu:6.1f} s CPU"
        if status != 0:
            reason = f"timed out after {args.timeout:g} s" if status == -1 else f"exit {status}"
            print(output, end="" if output.endswith("\n") else "\n")
            print(f"FAILED {times}  {name} --quick ({reason})", flush=True)
            return 1
        print(f"ok     {times}  {name} --quick", flush=True)
    print(f"{len(chosen)} scripts in {time.perf_counter() - total:.0f} s wall, "
          f"{_children_cpu() - total_cpu:.0f} s CPU (load average {os.getloadavg()[0]:.1f})",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
