"""Before/after speed of two revisions of drake_uav, measured side by side in one run.

The code of the base revision (default 3edcacf, the code before the model-layer change) is
exported with ``git archive`` into a temporary directory; the "after" code is the working
tree as it is (or ``--after REV``, exported the same way). Each benchmark script runs in
both trees alternately (before/after, then after/before, ...), ``--repeats`` times, in a
fresh process of this same interpreter with ``PYTHONPATH`` pointing at the tree, and the
best value of each FIGURE line (benchmarks/figures.py) is kept: the highest real-time
factor, the lowest cost (the median for a ratio measured inside one run). Alternating and
best-of-N keep the comparison fair when other work shares the machine. The table gives
each figure before and after, the ratio after/before and the speed-up (the ratio for
real-time factors, its inverse for costs).

By default both trees run the benchmark scripts of the "after" tree, so a ratio measures a
change of the code and not of the measurement. Names the scripts import from modules that
the base tree does not have (modules moved since) are taken from the module of the base
tree that defines them; every such substitution is listed under the table.
``--own-scripts`` runs each tree's own scripts instead (figures only from trees whose
scripts print FIGURE lines).

    python benchmarks/compare_revisions.py [--base 3edcacf] [--after REV] [--repeats 3]
        [--quick] [--scripts bench_fixed_wing.py ... | all] [--log-dir DIR]

``--quick`` runs the scripts in their quick modes. The exit status is 1 when a script of the
"after" tree failed (benchmarks/run_quick.py runs
``--quick --base HEAD --repeats 1 --scripts bench_fixed_wing.py``: what uncommitted changes
do to the plant's figures).
"""

from __future__ import annotations

import argparse
import ast
import importlib.abc
import importlib.machinery
import importlib.util
import io
import os
import pathlib
import runpy
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from figures import parse_figures  # noqa: E402  (the helper next to this script)

DEFAULT_BASE = "3edcacf"
DEFAULT_SCRIPTS = ("bench_fixed_wing.py", "bench_identification_flight.py", "bench_estimation.py",
                   "bench_identification.py", "bench_multirotor.py")
"""The scripts of the speed figures (``--scripts all``: every benchmarks/bench_*.py)."""
PACKAGE = "drake_uav"
ALIAS = "ALIAS"

# (FIGURE name, label, target) of the headline figures, in the order of the table.
HEADLINES = (
    ("identification_flight_rtf", "identification flight, 300 s moderate turbulence", ">= 100x"),
    ("flight_rtf", "identification flight, 60 s light turbulence", ""),
    ("flight_airdata_ekf_rtf", "  with an AirDataEkf at 100 Hz", ">= 50x"),
    ("flight_light_rtf", "identification flight, 120 s light turbulence", ""),
    ("flight_identifier_rtf", "  with a RecursiveIdentifier (C_m)", ">= 50x"),
    ("ekf_core_us_airdata", "AirDataEkf core step", "<= 100 us"),
    ("ekf_core_us_model_based_airdata", "ModelBasedAirDataEkf core step", "<= 100 us"),
    ("ekf_core_us_parameter_longitudinal", "ParameterEkf core step, longitudinal", "<= 100 us"),
    ("ekf_core_us_parameter_lateral", "ParameterEkf core step, lateral", "<= 100 us"),
    ("ekf_leaf_us_airdata", "AirDataEkf LeafSystem step", "<= 100 us"),
    ("ekf_leaf_us_model_based_airdata", "ModelBasedAirDataEkf LeafSystem step", "<= 100 us"),
    ("ekf_leaf_us_parameter", "ParameterEkf LeafSystem step per filter", "<= 100 us"),
    ("plant_rtf_default", "plant alone, 60 s doublet, default RK3", ">= 200x"),
    ("plant_alone_rtf", "plant alone, the flight's RK2 at 100 Hz", ">= 200x"),
    ("plant_over_jsbsim_explicit_euler", "plant / JSBSim c172x, 120 Hz, 1 eval. per step",
     ">= 1"),
)


# ------------------------------------------------------------------- inside a tree
class _MovedNames(importlib.abc.MetaPathFinder):
    """Runs a script written for one layout of the package on the code of another.

    A module of the package that the tree does not have becomes a stand-in whose names
    come from the module of the tree that defines them; a module that exists gains the
    same look-up for names it lacks. Each substitution is reported on stderr.
    """

    def __init__(self, package_dir: pathlib.Path):
        self.definitions: dict[str, list[str]] = {}
        for path in sorted(package_dir.rglob("*.py")):
            parts = path.relative_to(package_dir.parent).with_suffix("").parts
            module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            for name in _defined_names(path):
                self.definitions.setdefault(name, []).append(module)
        self.reported: set[tuple[str, str]] = set()

    def find_spec(self, fullname, path, target=None):
        if not fullname.startswith(PACKAGE + "."):
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None:
            return importlib.util.spec_from_loader(fullname, _StandIn(self), is_package=True)
        spec.loader = _WithLookup(spec.loader, self)
        return spec

    def lookup(self, module, name: str):
        if name.startswith("_"):  # private names are never substituted
            raise AttributeError(name)
        owners = [m for m in self.definitions.get(name, []) if m != module.__name__]
        if not owners:
            raise AttributeError(f"module {module.__name__!r} has no attribute {name!r} "
                                 "(and no module of this tree defines it)")
        tail = module.__name__.rsplit(".", 1)[-1]
        owner = next((m for m in owners if m.rsplit(".", 1)[-1] == tail), owners[0])
        if (module.__name__, name) not in self.reported:
            self.reported.add((module.__name__, name))
            print(f"{ALIAS} {module.__name__}.{name} -> {owner}.{name}", file=sys.stderr)
        return getattr(importlib.import_module(owner), name)

    def attach(self, module) -> None:
        if "__getattr__" not in vars(module):
            module.__getattr__ = lambda name, m=module: self.lookup(m, name)


class _WithLookup(importlib.abc.Loader):
    def __init__(self, loader, finder: _MovedNames):
        self._loader, self._finder = loader, finder

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        self._loader.exec_module(module)
        self._finder.attach(module)

    def __getattr__(self, name):
        return getattr(self._loader, name)


class _StandIn(importlib.abc.Loader):
    def __init__(self, finder: _MovedNames):
        self._finder = finder

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        module.__path__ = []
        self._finder.attach(module)


def _defined_names(path: pathlib.Path) -> list[str]:
    """Names a module defines at its top level (classes, functions, assignments)."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (SyntaxError, UnicodeDecodeError):
        return []
    names = []
    for node in tree.body:
        if isinstance(node, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            names.append(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names += [t.id for t in targets if isinstance(t, ast.Name)]
    return names


def run_in_tree(tree: str, moved_names: bool, script: str, args: list[str]) -> None:
    """Runs ``script`` as __main__ on the package of ``tree`` (this process)."""
    tree_path = pathlib.Path(tree).resolve()
    if moved_names:
        sys.meta_path.insert(0, _MovedNames(tree_path / PACKAGE))
    package = importlib.import_module(PACKAGE)
    if tree_path not in pathlib.Path(package.__file__).resolve().parents:
        raise SystemExit(f"tree: {PACKAGE} was imported from {package.__file__}, not {tree}")
    sys.argv = [script, *args]
    sys.path.insert(0, str(pathlib.Path(script).resolve().parent))
    runpy.run_path(script, run_name="__main__")


# ------------------------------------------------------------------------- runner
def export(repo: pathlib.Path, revision: str, into: pathlib.Path) -> pathlib.Path:
    """The files of ``revision`` (git archive) in ``into``."""
    archive = subprocess.run(["git", "-C", str(repo), "archive", "--format=tar", revision],
                             check=True, capture_output=True).stdout
    into.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into


def revision_label(repo: pathlib.Path, revision: str) -> str:
    out = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", revision],
                         capture_output=True, text=True)
    return out.stdout.strip() or revision


def run_script(tree: pathlib.Path, script: pathlib.Path, args: list[str], moved_names: bool,
               threads: int, timeout: float) -> tuple[dict, set[str], str, float, str]:
    """(figures, substitutions, error text or '', seconds, output) of one run of ``script``."""
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONHASHSEED="0")
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[name] = str(threads)
    command = [sys.executable, str(pathlib.Path(__file__).resolve()), "--run-in-tree", str(tree),
               "--moved-names" if moved_names else "--no-moved-names", str(script), *args]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, env=env, capture_output=True, text=True,
                              timeout=timeout, cwd=tempfile.gettempdir())
    except subprocess.TimeoutExpired as timed_out:
        stdout = timed_out.stdout or ""
        stdout = stdout if isinstance(stdout, str) else stdout.decode()
        return parse_figures(stdout), set(), f"timed out after {timeout:.0f} s", timeout, stdout
    seconds = time.perf_counter() - start
    aliases = {line[len(ALIAS) + 1:] for line in done.stderr.splitlines()
               if line.startswith(ALIAS + " ")}
    error = ""
    if done.returncode != 0:
        lines = [line for line in done.stderr.strip().splitlines() if not line.startswith(ALIAS)]
        error = lines[-1] if lines else f"exit status {done.returncode}"
    return parse_figures(done.stdout), aliases, error, seconds, done.stdout + done.stderr


def best(values: list[tuple[float, str, str]]) -> tuple[float, str, str]:
    """The best of the runs' values: highest or lowest; the median for a ratio (its two
    terms were measured side by side in one run, the best of them would be biased)."""
    _, unit, better = values[0]
    if unit == "ratio":
        return (statistics.median(v[0] for v in values), unit, better)
    pick = max if better == "higher" else min
    return pick(values, key=lambda v: v[0])


def table(results: dict[str, dict[str, list]], labels: tuple[str, str]) -> str:
    """The comparison table of the best figures of both sides."""
    merged = {side: {name: best(values) for name, values in runs.items()}
              for side, runs in results.items()}
    present = set(merged["before"]) | set(merged["after"])
    headlines = [(name, label, target) for name, label, target in HEADLINES if name in present]
    others = [(name, name, "") for name in sorted(present - {h[0] for h in headlines})]
    rows = [f"{'figure':50s} {'target':>9s} {'unit':>5s} {labels[0]:>10s} {labels[1]:>10s} "
            f"{'ratio':>6s} {'speed-up':>8s}"]
    for section, entries in (("headline figures", headlines), ("other figures", others)):
        if entries:
            rows.append(f"{section}:")
        for name, label, target in entries:
            before, after = merged["before"].get(name), merged["after"].get(name)
            unit, better = (after or before)[1:]
            text = [f"{value[0]:10.4g}" if value else f"{'n/a':>10s}" for value in (before, after)]
            tail = ""
            if before and after and before[0] != 0 and after[0] != 0:
                ratio = after[0] / before[0]
                tail = f"{ratio:6.2f} {ratio if better == 'higher' else 1.0 / ratio:7.2f}x"
            rows.append(f"  {label[:48]:48s} {target:>9s} {unit:>5s} {text[0]} {text[1]} {tail}")
    return "\n".join(rows)


def compare(args) -> int:
    """Runs the comparison and prints its table; returns 1 when a run of the "after" tree
    failed (its scripts are expected to run), else 0."""
    repo = pathlib.Path(subprocess.run(["git", "-C", str(HERE), "rev-parse", "--show-toplevel"],
                                       check=True, capture_output=True,
                                       text=True).stdout.strip())
    with tempfile.TemporaryDirectory(prefix="drake_uav_compare_") as scratch:
        scratch = pathlib.Path(scratch)
        trees = {"before": export(repo, args.base, scratch / "before")}
        trees["after"] = repo if args.after is None else export(repo, args.after, scratch / "after")
        labels = (revision_label(repo, args.base),
                  "worktree" if args.after is None else revision_label(repo, args.after))
        names = args.scripts or list(DEFAULT_SCRIPTS)
        if names == ["all"]:
            names = sorted(p.name for p in (trees["after"] / "benchmarks").glob("bench_*.py"))
        log_dir = pathlib.Path(args.log_dir) if args.log_dir else None
        if log_dir:
            log_dir.mkdir(parents=True, exist_ok=True)
        results = {"before": {}, "after": {}}
        aliases: set[str] = set()
        errors: dict[tuple[str, str], str] = {}
        print(f"before: {labels[0]} ({trees['before']}), after: {labels[1]} "
              f"({trees['after']}); {args.repeats} alternating runs per script, "
              f"{sys.executable}", flush=True)
        for repeat in range(args.repeats):
            for name in names:
                order = ("before", "after") if repeat % 2 == 0 else ("after", "before")
                for side in order:
                    tree = trees[side]
                    scripts_tree = tree if args.own_scripts else trees["after"]
                    script = scripts_tree / "benchmarks" / name
                    if not script.exists():
                        errors[(name, side)] = "no such script in this tree"
                        continue
                    extra = ["--quick"] if args.quick and "--quick" in script.read_text() else []
                    figures, used, error, seconds, output = run_script(
                        tree, script, extra, moved_names=side == "before" and not args.own_scripts,
                        threads=args.threads, timeout=args.timeout)
                    if log_dir:
                        (log_dir / f"{name[:-3]}.{side}.{repeat}.txt").write_text(output)
                    aliases |= used
                    if error:
                        errors[(name, side)] = error
                    for figure, value in figures.items():
                        results[side].setdefault(figure, []).append(value)
                    print(f"  run {repeat + 1}/{args.repeats} {name:34s} {side:6s} "
                          f"{seconds:6.1f} s, {len(figures)} figures"
                          f"{'; ' + error if error else ''}", flush=True)
        print()
        print(table(results, labels))
        if aliases:
            print(f"\nnames taken from their module in {labels[0]} (moved since):")
            for line in sorted(aliases):
                print(f"  {line}")
        for (name, side), error in sorted(errors.items()):
            print(f"{name} ({side}): {error}")
        return int(any(side == "after" for _, side in errors))


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--run-in-tree":
        tree, flag, script, *rest = sys.argv[2:]
        run_in_tree(tree, flag == "--moved-names", script, rest)
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default=DEFAULT_BASE, help="revision before the change")
    parser.add_argument("--after", default=None,
                        help="revision after the change (default: the working tree)")
    parser.add_argument("--repeats", type=int, default=3, help="alternating runs per script")
    parser.add_argument("--scripts", nargs="*",
                        help="benchmark file names or 'all' (default: the speed figures)")
    parser.add_argument("--quick", action="store_true",
                        help="pass --quick to the scripts that have it (headline figures)")
    parser.add_argument("--own-scripts", action="store_true",
                        help="each tree runs its own benchmark scripts")
    parser.add_argument("--threads", type=int, default=1, help="BLAS/OpenMP threads")
    parser.add_argument("--timeout", type=float, default=3600.0, help="per run [s]")
    parser.add_argument("--log-dir", help="keep the output of every run here")
    sys.exit(compare(parser.parse_args()))


if __name__ == "__main__":
    main()
