"""CompiledFunction: every node kind against float evaluation and AutoDiffXd, compile work
linear in the expression graph, restricted outputs and the folding of temporaries."""

import math

import numpy as np
import pytest
from pydrake.math import abs as sabs
from pydrake.math import (
    acos,
    asin,
    atan,
    atan2,
    ceil,
    cos,
    cosh,
    exp,
    floor,
    log,
    sin,
    sinh,
    sqrt,
    tan,
    tanh,
)
from pydrake.math import max as smax
from pydrake.math import min as smin
from pydrake.symbolic import (
    Expression,
    ExpressionKind,
    Formula,
    FormulaKind,
    Variable,
    if_then_else,
    logical_and,
    logical_not,
    logical_or,
    uninterpreted_function,
)

import drake_uav.model.compiled as compiled_module
from drake_uav.model.compiled import VECTOR_BATCH, CompiledFunction

_K, _F = ExpressionKind, FormulaKind


def _model(x, u):
    """A small scalar-generic model with shared and single-use subexpressions."""
    r = sqrt(x[0] * x[0] + x[1] * x[1] + 1.0)
    return [r * cos(u[0]), r * sin(u[0]) - x[2] * u[1], x[0] * x[1] / r, (x[2] + u[1]) ** 3]


# ------------------------------------------------------------------- every node kind
def _select(condition, a, b):
    """if_then_else for a Formula, the Python conditional for the bool of a float or
    AutoDiffXd comparison (so the same case runs symbolic and as the AutoDiff reference)."""
    return if_then_else(condition, a, b) if isinstance(condition, Formula) else (
        a if condition else b)


def _both(a, b):
    return logical_and(a, b) if isinstance(a, Formula) else a and b


def _either(a, b):
    return logical_or(a, b) if isinstance(a, Formula) else a or b


def _negation(a):
    return logical_not(a) if isinstance(a, Formula) else not a


def _power(a, b):
    """``a ** b`` with both symbolic; as ``exp(b log a)`` for AutoDiffXd (no such pow)."""
    return a ** b if isinstance(a, Expression) else exp(b * log(a))


# name: (the node kind the case must contain, fn of x = (x0, x1, x2)); x1 < 0 < x0 < 1 < x2.
_NODE_CASES = {
    "constant": (_K.Constant, lambda x: [x[0] * 0.0 + 2.5]),
    "variable": (_K.Var, lambda x: [x[1]]),
    "add": (_K.Add, lambda x: [x[0] + 2.0 * x[1] - x[2] + 0.5]),
    "mul": (_K.Mul, lambda x: [-3.0 * x[0] * x[1] * x[2]]),
    "div": (_K.Div, lambda x: [x[0] / (x[2] + 2.0)]),
    "pow_square": (_K.Pow, lambda x: [x[1] ** 2]),
    "pow_integer": (_K.Pow, lambda x: [x[1] ** 3 + x[2] ** -2]),
    "pow_half": (_K.Pow, lambda x: [x[2] ** 0.5]),
    "pow_real": (_K.Pow, lambda x: [x[2] ** 1.7]),
    "pow_symbolic": (_K.Pow, lambda x: [_power(x[2], x[0])]),
    "sqrt": (_K.Sqrt, lambda x: [sqrt(x[2])]),
    "sin": (_K.Sin, lambda x: [sin(x[1])]),
    "cos": (_K.Cos, lambda x: [cos(x[1])]),
    "tan": (_K.Tan, lambda x: [tan(x[0])]),
    "asin": (_K.Asin, lambda x: [asin(x[0])]),
    "acos": (_K.Acos, lambda x: [acos(x[0])]),
    "atan": (_K.Atan, lambda x: [atan(x[2])]),
    "atan2": (_K.Atan2, lambda x: [atan2(x[1], x[0])]),
    "exp": (_K.Exp, lambda x: [exp(x[1])]),
    "log": (_K.Log, lambda x: [log(x[2])]),
    "abs": (_K.Abs, lambda x: [sabs(x[1])]),
    "sinh": (_K.Sinh, lambda x: [sinh(x[1])]),
    "cosh": (_K.Cosh, lambda x: [cosh(x[1])]),
    "tanh": (_K.Tanh, lambda x: [tanh(x[1])]),
    "min": (_K.Min, lambda x: [smin(x[0], x[1])]),
    "max": (_K.Max, lambda x: [smax(x[0], x[1])]),
    "floor": (_K.Floor, lambda x: [floor(3.0 * x[2])]),
    "ceil": (_K.Ceil, lambda x: [ceil(3.0 * x[2])]),
    "greater": (_F.Gt, lambda x: [_select(x[0] > x[1], x[0], x[2])]),
    "greater_equal": (_F.Geq, lambda x: [_select(x[0] >= x[1], x[0] * x[2], x[1])]),
    "less": (_F.Lt, lambda x: [_select(x[0] < x[1], x[0], -x[2])]),
    "less_equal": (_F.Leq, lambda x: [_select(x[0] <= x[1], x[1], 2.0 * x[2])]),
    "equal": (_F.Eq, lambda x: [_select(x[0] == x[1], x[0], x[2])]),
    "not_equal": (_F.Neq, lambda x: [_select(x[0] != x[1], x[0], x[2])]),
    "and": (_F.And, lambda x: [_select(_both(x[0] > x[1], x[2] > 1.0), x[0], x[2])]),
    "or": (_F.Or, lambda x: [_select(_either(x[0] > x[1], x[2] > 1.0), x[0], x[2])]),
    "not": (_F.Not, lambda x: [_select(_negation(x[0] > x[1]), x[0], x[2])]),
}


def _kinds(node) -> set:
    """Every node kind of a small (unshared) expression or formula."""
    if not isinstance(node, Expression | Formula):
        return set()
    kinds = {node.get_kind()}
    if kinds & {_K.Constant, _K.Var}:
        return kinds
    for arg in node.Unapply()[1]:
        kinds |= _kinds(arg)
    return kinds


def _float_reference(fn, x) -> list[float]:
    """``fn`` traced with its own variables and evaluated by Drake in double."""
    variables = [Variable(f"x{i}") for i in range(len(x))]
    outputs = fn(np.array([Expression(v) for v in variables], dtype=object))
    environment = dict(zip(variables, x, strict=True))
    return [o.Evaluate(environment) if isinstance(o, Expression) else float(o) for o in outputs]


def _samples(count: int, seed: int) -> np.ndarray:
    """Points with x1 < 0 < x0 < 1 < x2 (inside every case's domain) but the second,
    where x0 == x1 == 0.25 (the equality branches)."""
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.uniform(0.1, 0.9, count), rng.uniform(-0.9, -0.1, count),
                              rng.uniform(1.1, 2.5, count)])
    points[1, :2] = 0.25
    return points


@pytest.mark.parametrize("case", sorted(_NODE_CASES))
def test_every_node_kind_matches_float_evaluation_and_autodiff(case):
    kind, fn = _NODE_CASES[case]
    compiled = CompiledFunction(fn, (3,), {0: None}, name=case)
    assert kind in set().union(*(_kinds(o) for o in compiled._outputs)), case
    points = _samples(8, seed=3)
    for x in points:
        np.testing.assert_allclose(compiled.value(x), _float_reference(fn, x),
                                   rtol=1e-15, atol=1e-15)
        value, (jacobian,) = compiled.jacobians(x)
        reference_value, (reference,) = compiled.autodiff_jacobians(x)
        np.testing.assert_allclose(value, reference_value, rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(jacobian, reference, rtol=1e-14, atol=1e-15)
    # The batch code (numpy functions on whole columns) agrees with the float code.
    batch = _samples(VECTOR_BATCH + 4, seed=4)
    values, (jacobians,) = compiled.batch_jacobians(batch)
    for b, x in enumerate(batch):
        value, (jacobian,) = compiled.jacobians(x)
        np.testing.assert_allclose(values[b], value, rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(jacobians[b], jacobian, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(compiled.batch_value(batch), values, rtol=1e-15, atol=1e-15)


def test_an_unsupported_node_kind_is_named_in_the_error():
    with pytest.raises(NotImplementedError, match="UninterpretedFunction"):
        CompiledFunction(lambda x: [uninterpreted_function("f", [x[0]]) + 1.0], (1,))


def test_jacobian_structure_and_constant_entries():
    compiled = CompiledFunction(lambda x, u: [x[0] * u[0], 2.0 * x[1], 3.0], (2, 1),
                                {0: None, 1: None})
    np.testing.assert_array_equal(compiled.jacobian_structure,
                                  [[True, False, True], [False, True, False],
                                   [False, False, False]])
    value, jacobian = compiled.value_and_jacobian([2.0, 5.0], [4.0])
    np.testing.assert_array_equal(value, [8.0, 10.0, 3.0])
    np.testing.assert_array_equal(jacobian, [[4.0, 0.0, 2.0], [0.0, 2.0, 0.0], [0.0] * 3])


# --------------------------------------------------------- linear in the expression graph
def _shared_chain(depth: int):
    """``y = sin(y) cos(y) + x`` ``depth`` times: ``depth`` levels of nodes, 2**depth paths."""
    def chain(x):
        y = x[0]
        for _ in range(depth):
            y = sin(y) * cos(y) + x[0]
        return [y]
    return chain


def test_a_200_deep_shared_chain_compiles_with_work_linear_in_its_graph():
    compiled = CompiledFunction(_shared_chain(200), (1,), {0: None})
    # Each distinct node (Add, Mul, sin, cos per level) is walked once, not once per path.
    assert compiled.node_count == 4 * 200
    sizes = {n: CompiledFunction(_shared_chain(n), (1,), {0: None}) for n in (50, 100)}
    sizes[200] = compiled
    operations = {n: c.operation_count for n, c in sizes.items()}
    assert operations[200] - operations[100] == 2 * (operations[100] - operations[50])
    for with_jacobians in (False, True):
        source = {n: len(c.source(False, with_jacobians)) for n, c in sizes.items()}
        growth = (source[200] - source[100]) / (source[100] - source[50])
        assert 1.9 < growth < 2.25, (with_jacobians, source)  # linear (longer names aside)
    x, y = 0.4, 0.4
    for _ in range(200):
        y = math.sin(y) * math.cos(y) + x
    np.testing.assert_allclose(compiled.value([x]), [y], rtol=1e-12)
    value, (jacobian,) = compiled.jacobians([x])
    reference_value, (reference,) = compiled.autodiff_jacobians([x])
    np.testing.assert_allclose(value, reference_value, rtol=1e-12)
    np.testing.assert_allclose(jacobian, reference, rtol=1e-10)


def test_the_identity_fallback_emits_the_same_code(monkeypatch):
    """Without the cell address, nodes are told apart by EqualTo within their kind: the
    same statements (only slower on large graphs)."""
    reference = CompiledFunction(_model, (3, 2), {0: None, 1: None})
    monkeypatch.setattr(compiled_module, "_node_key", compiled_module._kind_key)
    fallback = CompiledFunction(_model, (3, 2), {0: None, 1: None})
    chain = CompiledFunction(_shared_chain(30), (1,))
    assert fallback.source(False, True) == reference.source(False, True)
    assert fallback.node_count == reference.node_count
    assert chain.node_count == 4 * 30


# ------------------------------------------------------------------ the generated code
def test_single_use_temporaries_fold_and_an_added_negation_becomes_a_subtraction():
    compiled = CompiledFunction(lambda x: [x[0] - sin(x[1]) * x[2], sin(x[1]) + x[0] * x[0]],
                                (3,))
    assert compiled.source() == "\n".join([
        "def compiled(a0):",
        "    a0_0, a0_1, a0_2, = a0",
        "    t0 = _sin(a0_1)",
        "    return _array([(a0_0 - ((a0_2 * t0))), (t0 + (a0_0 * a0_0))])",
    ])
    x = [0.3, -1.1, 2.0]
    assert compiled.value(x).tolist() == [x[0] - x[2] * math.sin(x[1]),
                                          math.sin(x[1]) + x[0] * x[0]]


def test_restricted_outputs_match_the_full_function_and_its_jacobians():
    full = CompiledFunction(_model, (3, 2), wrt={0: None, 1: None})
    part = full.restricted([3, 1])
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, u = rng.normal(size=3), rng.normal(size=2)
        value, jacobian = full.value_and_jacobian(x, u)
        sub_value, sub_jacobian = part.value_and_jacobian(x, u)
        np.testing.assert_array_equal(sub_value, value[[3, 1]])
        np.testing.assert_array_equal(sub_jacobian, jacobian[[3, 1]])
        np.testing.assert_allclose(part.autodiff_jacobians(x, u)[0], value[[3, 1]], rtol=1e-14)
    assert part.operation_count < full.operation_count
    with pytest.raises(ValueError, match="^outputs:"):
        full.restricted([4])
    with pytest.raises(ValueError, match="^outputs:"):
        full.restricted([])


def test_long_chains_of_single_use_temporaries_compile_and_stay_exact():
    def chain(x):
        y = x[0]
        for k in range(400):  # every step used once by the next: folded in bounded pieces
            y = sin(y) + 0.001 * k * x[1]
        return [y, y * x[1]]

    compiled = CompiledFunction(chain, (2,))
    x = [0.3, -1.2]
    y = x[0]
    for k in range(400):
        y = math.sin(y) + 0.001 * k * x[1]
    np.testing.assert_allclose(compiled.value(x), [y, y * x[1]], rtol=1e-13)
    batch = compiled.batch_value(np.tile(x, (20, 1)))
    np.testing.assert_array_equal(batch, np.tile(compiled.value(x), (20, 1)))

