"""Compile time and per-call cost of the code generator (CompiledFunction), before and after.

1. Compile time of the shared chain ``y = sin(y) cos(y) + x`` iterated 8, 12, 14, 16, 50
   and 200 times (value code), for the CompiledFunction of this tree and for the one of
   revision 1da2fc3 (its module read with ``git show`` into a temporary directory and
   imported), side by side in this run. The 1da2fc3 tracer walks every path of the graph
   (2**n of them), so it runs only up to ``--old-depth``; deeper chains print its time
   extrapolated from the two deepest measured ones (their growth per level).
2. The fixed-wing model: compile time of ``CompiledFixedWingModel(FixedWingModel(
   aerosonde()))`` with its state-derivative and batch code, the CPU time per call of
   ``.field("state_derivative")`` on Python lists (what the plant calls once per integrator
   stage) and of ``.evaluate_batch`` per sample over a log, and of the value and Jacobian
   of the ``ModelBasedAirDataModel`` dynamics (the larger part of an EKF step); both
   generators' code timed interleaved, best of ``--repeats``.
3. With ``--candidates``: the same state derivative through CasADi (``Function``, one
   call and ``map`` over the log), JAX (``jit``, ``vmap``) and numba (``njit``), each when
   installed. They run the generated straight-line code on their own symbolic or typed
   values, so the equations are the same. Printed: build time, CPU time per call with the
   arguments as Python lists (as the plant reads its ports) and as numpy arrays, and per
   sample of a log.

CPU time (``time.process_time``) so other load on a shared machine inflates it less than
wall time. Headline figures as FIGURE lines (benchmarks/figures.py).

Run: python benchmarks/bench_codegen.py [--repeats 5] [--old-depth 16] [--candidates] [--quick]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import math
import pathlib
import subprocess
import tempfile
import time

import numpy as np
from figures import figure
from pydrake.math import cos, sin

import drake_uav.model.fixed_wing as fixed_wing
from drake_uav.estimation import ModelBasedAirDataModel
from drake_uav.model.compiled import CompiledFunction
from drake_uav.model.fixed_wing import CompiledFixedWingModel, FixedWingModel
from drake_uav.vehicles.fixed_wing import aerosonde

BASE = "1da2fc3"
DEPTHS = (8, 12, 14, 16, 50, 200)
LOG_SAMPLES = 10_000
CALLS = 2000  # per timed repetition of a single-sample call
HERE = pathlib.Path(__file__).resolve().parent
# A cruise state (pNED, quaternion, uvw, pqr), controls (elevator, aileron, rudder,
# throttle), wind NED: the point of the per-call figures.
STATE = [10.0, -5.0, -100.0, 0.999, 0.01, 0.04, 0.02, 24.5, 0.3, 1.2, 0.02, -0.01, 0.03]
CONTROLS = [-0.05, 0.01, 0.002, 0.55]
WIND = [1.0, -0.5, 0.1]
NO_WRENCH = [0.0] * 6
NO_WIND_RATE = [0.0] * 3
# ModelBasedAirDataModel: Va, alpha, beta, wind NED; p, q, r, roll, pitch, yaw, controls.
EKF_STATE = [25.0, 0.06, 0.02, 3.0, -2.0, 0.2]
EKF_INPUTS = [0.05, 0.1, -0.05, 0.1, 0.05, 1.0, *CONTROLS]


def load_base(revision: str):
    """The CompiledFunction class of ``revision`` (None when git cannot show it, e.g. in
    an exported tree)."""
    try:
        source = subprocess.run(
            ["git", "-C", str(HERE), "show", f"{revision}:drake_uav/model/compiled.py"],
            capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    path = pathlib.Path(tempfile.mkdtemp()) / f"compiled_{revision}.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location(f"compiled_{revision}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.CompiledFunction


def is_linear(cls) -> bool:
    """Whether a CompiledFunction walks each distinct node once (it counts them)."""
    return hasattr(cls, "node_count")


def shared_chain(depth: int):
    def chain(x):
        y = x[0]
        for _ in range(depth):
            y = sin(y) * cos(y) + x[0]
        return [y]
    return chain


def cpu(run) -> float:
    start = time.process_time()
    run()
    return time.process_time() - start


def chain_compile_times(generators: dict, old_depth: int) -> dict[str, dict[int, float]]:
    """CPU seconds to compile each chain depth, per generator (None: not run)."""
    times = {label: {} for label in generators}
    for depth in DEPTHS:
        for label, cls in generators.items():
            if is_linear(cls) or depth <= old_depth:
                times[label][depth] = cpu(lambda cls=cls, n=depth: cls(shared_chain(n), (1,)))
            else:
                times[label][depth] = None
    return times


def extrapolated(times: dict[int, float | None], depth: int) -> float:
    """Time at ``depth`` from the deepest measured one and the growth per level between
    the two deepest (2 per level, the growth of the path count, when only one)."""
    measured = sorted(d for d, v in times.items() if v is not None)
    last = measured[-1]
    growth = 2.0
    if len(measured) > 1:
        before = measured[-2]
        growth = (times[last] / times[before]) ** (1.0 / (last - before))
    return times[last] * growth ** (depth - last)


def print_chain(times: dict[str, dict[int, float]]) -> None:
    labels = list(times)
    print("1. Shared chain y = sin(y) cos(y) + x, compile time [s] (CPU)")
    print(f"   {'depth':>5}  " + "  ".join(f"{label:>14}" for label in labels)
          + ("  ratio" if len(labels) == 2 else ""))
    for depth in DEPTHS:
        cells, values = [], []
        for label in labels:
            value = times[label][depth]
            if value is None:
                value = extrapolated(times[label], depth)
                cells.append(f"~{value:.3g}".rjust(14))
            else:
                cells.append(f"{value:>14.3f}")
            values.append(value)
        ratio = f"  {values[0] / values[1]:.3g}x" if len(values) == 2 else ""
        print(f"   {depth:>5}  " + "  ".join(cells) + ratio)
    if len(labels) == 2:
        print(f"   (~: extrapolated with the growth per level of the two deepest measured; "
              f"ratio = {labels[0]} / {labels[1]})")


@contextlib.contextmanager
def generator(cls):
    """CompiledFixedWingModel built with ``cls`` as its CompiledFunction."""
    saved = fixed_wing.CompiledFunction
    fixed_wing.CompiledFunction = cls
    try:
        yield
    finally:
        fixed_wing.CompiledFunction = saved


def log_arguments(count: int, seed: int = 7) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    x = np.tile(STATE, (count, 1)) + rng.normal(0.0, 0.01, (count, 13))
    x[:, 3:7] /= np.linalg.norm(x[:, 3:7], axis=1, keepdims=True)
    controls = np.tile(CONTROLS, (count, 1)) + rng.normal(0.0, 0.01, (count, 4))
    return x, controls, np.tile(WIND, (count, 1))


def per_call_cases(cls) -> dict:
    """name -> function timing one repetition of a case with ``cls`` as the generator
    [s for the compile, s per call or per sample for the others]."""
    x, controls, wind = log_arguments(LOG_SAMPLES)
    built = {}

    def compile_model() -> float:
        start = time.process_time()
        with generator(cls):
            built["model"] = CompiledFixedWingModel(FixedWingModel(aerosonde()))
            built["derivative"] = built["model"].field("state_derivative")
            built["model"].evaluate_batch(x[:2], controls[:2], wind[:2])  # builds its code
        return time.process_time() - start

    def one_call() -> float:
        derivative, calls = built["derivative"], 20_000
        start = time.process_time()
        for _ in range(calls):
            derivative(STATE, CONTROLS, WIND, NO_WRENCH, NO_WIND_RATE)
        return (time.process_time() - start) / calls

    def batch() -> float:  # best of three: one call takes only milliseconds
        return min(cpu(lambda: built["model"].evaluate_batch(x, controls, wind))
                   for _ in range(3)) / LOG_SAMPLES

    ekf_model = ModelBasedAirDataModel(aerosonde())
    sizes = [len(ekf_model.state_names), len(ekf_model.input_names), len(ekf_model.noise_names)]
    ekf_point = [np.array(EKF_STATE), np.array(EKF_INPUTS), np.zeros(sizes[2])]

    def ekf_step() -> float:
        if "dynamics" not in built:
            built["dynamics"] = cls(ekf_model.dynamics, sizes, dict.fromkeys(range(3)))
        run, calls = built["dynamics"].value_and_jacobian, 5000
        start = time.process_time()
        for _ in range(calls):
            run(*ekf_point)
        return (time.process_time() - start) / calls

    return {"compile": compile_model, "state_derivative": one_call, "evaluate_batch": batch,
            "ekf_dynamics": ekf_step}


def fixed_wing_figures(generators: dict, repeats: int) -> dict[str, dict[str, float]]:
    """Best CPU seconds of each case and generator, the generators interleaved in
    alternating order (a warm-up round first: the first model built pays for imports and
    caches of either)."""
    cases = {label: per_call_cases(cls) for label, cls in generators.items()}
    best = {label: dict.fromkeys(cases[label], math.inf) for label in generators}
    for round_ in range(repeats + 1):
        order = list(cases) if round_ % 2 else list(cases)[::-1]  # alternate who goes first
        for label in order:
            for name, case in cases[label].items():
                seconds = case()
                if round_ > 0:
                    best[label][name] = min(best[label][name], seconds)
    return best


def print_fixed_wing(best: dict[str, dict[str, float]]) -> None:
    labels = list(best)
    rows = (("compile", "model, state-derivative and batch code [s]", 1.0),
            ("state_derivative", "field('state_derivative'), per call [us]", 1e6),
            ("evaluate_batch", f"evaluate_batch, {LOG_SAMPLES} samples, per sample [us]", 1e6),
            ("ekf_dynamics", "EKF dynamics value + Jacobian, per call [us]", 1e6))
    print("\n2. Fixed-wing model (Aerosonde) and the model-based air-data EKF, CPU time")
    print(f"   {'':<52}" + "".join(f"{label:>12}" for label in labels)
          + ("  ratio" if len(labels) == 2 else ""))
    for key, text, scale in rows:
        values = [best[label][key] * scale for label in labels]
        ratio = f"  {values[0] / values[1]:.3g}x" if len(values) == 2 else ""
        print(f"   {text:<52}" + "".join(f"{v:>12.3f}" for v in values) + ratio)


# ---------------------------------------------------------------------- candidates
def state_derivative_function() -> CompiledFunction:
    """The state derivative alone (arguments state, controls, wind NED, wrench)."""
    model = FixedWingModel(aerosonde())
    return CompiledFunction(lambda x, u, w, r: model.evaluate(x, u, w, r).state_derivative,
                            (13, 4, 3, 6), name="state derivative")


def _functions(module, names: dict[str, str]) -> dict:
    """The generated code's function names bound to ``module``'s functions."""
    unary = ("sqrt", "sin", "cos", "tan", "exp", "log", "sinh", "cosh", "tanh", "floor",
             "ceil")
    return {"math": math, **{f"_{n}": getattr(module, n) for n in unary},
            **{f"_{n}": getattr(module, m) for n, m in names.items()}}


def python_cases(function: CompiledFunction) -> dict:
    """This generator: the float and batch code written again from the traced graph."""
    again = function.restricted(range(function.output_size))
    run = again.program
    return {"lists": run, "arrays": lambda *args: run(*[a.tolist() for a in args]),
            "batch": again.batch_value}


def casadi_cases(function: CompiledFunction) -> dict:
    """CasADi: the generated code run on SX symbols, one ``Function``, and its ``map``."""
    import casadi as ca

    scope = _functions(ca, {"asin": "asin", "acos": "acos", "atan": "atan", "abs": "fabs",
                            "atan2": "atan2", "max": "fmax", "min": "fmin", "pow": "power",
                            "copysign": "copysign", "where": "if_else", "and": "logic_and",
                            "or": "logic_or", "not": "logic_not"})
    scope["_array"] = lambda values: ca.vertcat(*values)
    exec(function.source(), scope)
    symbols = [ca.SX.sym(f"a{i}", n) for i, n in enumerate(function.arg_sizes)]
    one = ca.Function("f", symbols, [scope["compiled"](*[ca.vertsplit(s) for s in symbols])])
    batch = one.map(LOG_SAMPLES, "serial")
    run = lambda *args: one(*args).full().ravel()  # noqa: E731
    return {"lists": run, "arrays": run,
            "batch": lambda *args: batch(*[a.T for a in args]).full().T}


def jax_cases(function: CompiledFunction) -> dict:
    """JAX: the generated code under ``jit`` (arrays in), and ``vmap`` of it."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    scope = _functions(jnp, {"asin": "arcsin", "acos": "arccos", "atan": "arctan",
                             "abs": "abs", "atan2": "arctan2", "max": "maximum",
                             "min": "minimum", "pow": "power", "copysign": "copysign",
                             "where": "where", "and": "logical_and", "or": "logical_or",
                             "not": "logical_not"})
    scope["_array"] = jnp.stack
    exec(function.source(), scope)
    one, batch = jax.jit(scope["compiled"]), jax.jit(jax.vmap(scope["compiled"]))
    return {"lists": lambda *args: np.asarray(one(*[np.asarray(a) for a in args])),
            "arrays": lambda *args: np.asarray(one(*args)),
            "batch": lambda *args: np.asarray(batch(*args))}


def numba_cases(function: CompiledFunction) -> dict:
    """numba: the float code and the batch code under ``njit``."""
    import numba

    scope = _functions(math, {"asin": "asin", "acos": "acos", "atan": "atan", "abs": "fabs",
                              "atan2": "atan2", "pow": "pow", "copysign": "copysign"})
    scope.update(_max=max, _min=min, _array=np.array,
                 _where=numba.njit(lambda c, a, b: a if c else b))
    exec(function.source(), scope)
    vector = {**_functions(np, {"asin": "arcsin", "acos": "arccos", "atan": "arctan",
                                "abs": "abs", "atan2": "arctan2", "max": "maximum",
                                "min": "minimum", "pow": "power", "copysign": "copysign",
                                "where": "where", "and": "logical_and", "or": "logical_or",
                                "not": "logical_not"}), "_empty": np.empty}
    exec(function.source(vector=True), vector)
    one, batch = numba.njit(scope["compiled"]), numba.njit(vector["compiled"])
    return {"lists": lambda *args: one(*[np.array(a) for a in args]), "arrays": one,
            "batch": batch}


CANDIDATES = {"generated Python": python_cases, "CasADi": casadi_cases, "JAX": jax_cases,
              "numba": numba_cases}


def candidate_figures(repeats: int) -> dict[str, dict[str, float] | None]:
    """Per tool (None: not installed): build seconds (from the traced graph to the first
    results of the single and batch code) and best CPU seconds per call, Python lists in
    (as the plant reads its ports) or numpy arrays in, and per sample of the log; the
    tools interleaved."""
    function = state_derivative_function()
    x, controls, wind = log_arguments(LOG_SAMPLES)
    log = (x, controls, wind, np.zeros((LOG_SAMPLES, 6)))
    lists = (STATE, CONTROLS, WIND, NO_WRENCH)
    arrays = tuple(np.array(a) for a in lists)
    arguments = {"lists": lists, "arrays": arrays, "batch": log}
    reference, figures, built = function.value(*lists), {}, {}
    for name, build in CANDIDATES.items():
        start = time.process_time()
        try:
            built[name] = cases = build(function)
        except ImportError:
            figures[name] = None
            continue
        for key in ("lists", "arrays"):
            np.testing.assert_allclose(cases[key](*arguments[key]), reference, rtol=1e-12)
        np.testing.assert_allclose(cases["batch"](*log)[-1], function.value(
            *[a[-1] for a in log]), rtol=1e-12)
        figures[name] = {"build": time.process_time() - start,
                         **dict.fromkeys(arguments, math.inf)}
    for _ in range(repeats):
        for name, cases in built.items():
            for key, args in arguments.items():
                count = LOG_SAMPLES if key == "batch" else CALLS
                seconds = (cpu(lambda run=cases[key], a=args: run(*a)) if key == "batch" else
                           cpu(lambda run=cases[key], a=args: [run(*a) for _ in range(CALLS)]))
                figures[name][key] = min(figures[name][key], seconds / count)
    return figures


def print_candidates(figures: dict) -> None:
    print("\n3. State derivative through other tools (same generated code), CPU time")
    print(f"   {'':<18}{'build [s]':>10}{'per call, lists [us]':>22}"
          f"{'per call, arrays [us]':>23}{'per sample, ' + str(LOG_SAMPLES) + ' [us]':>26}")
    for name, values in figures.items():
        if values is None:
            print(f"   {name:<18}{'not installed':>10}")
            continue
        print(f"   {name:<18}{values['build']:>10.2f}{values['lists'] * 1e6:>22.2f}"
              f"{values['arrays'] * 1e6:>23.2f}{values['batch'] * 1e6:>26.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--old-depth", type=int, default=16,
                        help="deepest chain compiled by an exponential tracer (default 16)")
    parser.add_argument("--candidates", action="store_true",
                        help="also time CasADi, JAX and numba (those installed)")
    parser.add_argument("--quick", action="store_true",
                        help="headline figures only: old chain to depth 12, 2 repeats")
    args = parser.parse_args()
    if args.quick:
        args.old_depth, args.repeats = min(args.old_depth, 12), min(args.repeats, 2)
    generators = {"this tree": CompiledFunction}
    base = load_base(BASE)
    if base is not None:
        generators = {BASE: base, **generators}
    else:
        print(f"(revision {BASE} not available here: this tree's figures only)")
    times = chain_compile_times(generators, args.old_depth)
    print_chain(times)
    best = fixed_wing_figures(generators, args.repeats)
    print_fixed_wing(best)
    if args.candidates and not args.quick:
        print_candidates(candidate_figures(args.repeats))
    ours = times["this tree"]
    for depth in (12, 200):  # 12: measured for either tracer (also with --quick)
        if ours[depth] is not None:
            figure(f"codegen_chain{depth}_compile_s", ours[depth], "s", "lower")
    figure("codegen_fixed_wing_compile_s", best["this tree"]["compile"], "s", "lower")
    figure("codegen_state_derivative_us", best["this tree"]["state_derivative"] * 1e6, "us",
           "lower")
    figure("codegen_evaluate_batch_us_per_sample", best["this tree"]["evaluate_batch"] * 1e6,
           "us", "lower")


if __name__ == "__main__":
    main()
