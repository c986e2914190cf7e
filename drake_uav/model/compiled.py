"""Compilation of scalar-generic functions: symbolic trace -> straight-line Python.

A model function written once for float, ``AutoDiffXd`` and ``Expression`` is
traced with symbolic inputs; :class:`CompiledFunction` writes the trace as
straight-line Python with shared subexpressions (and, on request, its Jacobians
by forward-mode differentiation of the same trace). The generated source runs on
Python floats (one sample) or elementwise on numpy arrays (a batch of samples).
The plant, the estimators and the identifiers use it where a model is evaluated
in a loop; it is never a second copy of the equations.

How (docs/codegen.md has the measurements behind it):

1. The traced outputs are one Drake expression graph in which a subexpression the
   function reuses is one shared node. :class:`_Emitter` visits every distinct node
   once: a node met again is recognised by its identity (the address of its shared
   cell, confirmed by ``Expression.EqualTo``), so compile time is linear in the size
   of the graph, not in the number of paths through it.
2. Each node becomes a statement of a small intermediate form: an operation tree
   whose leaves are operands (inputs, temporaries, literals). Statements with equal
   trees share one temporary; Jacobian entries are built from the same statements
   by the chain rule.
3. :func:`_render` prints the statements as Python, folding every temporary used
   once into the statement that uses it (an added negation becomes a subtraction).
   It works on the trees; no generated text is parsed or rewritten.
"""

from __future__ import annotations

import ctypes
import math
import operator
import struct
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.symbolic import Expression, ExpressionKind, Formula, FormulaKind, Variable, sin

from drake_uav.model.scalar import as_list

__all__ = ["CompiledFunction", "VECTOR_BATCH"]

_K = ExpressionKind
_UNARY = {
    _K.Sqrt: "_sqrt", _K.Sin: "_sin", _K.Cos: "_cos", _K.Tan: "_tan", _K.Asin: "_asin",
    _K.Acos: "_acos", _K.Atan: "_atan", _K.Exp: "_exp", _K.Log: "_log", _K.Abs: "_abs",
    _K.Sinh: "_sinh", _K.Cosh: "_cosh", _K.Tanh: "_tanh", _K.Floor: "_floor",
    _K.Ceil: "_ceil",
}
_RELATIONS = {FormulaKind.Gt: ">", FormulaKind.Geq: ">=", FormulaKind.Lt: "<",
              FormulaKind.Leq: "<=", FormulaKind.Eq: "==", FormulaKind.Neq: "!="}
_SUPPORTED = {*_UNARY, _K.Add, _K.Mul, _K.Div, _K.Pow, _K.Atan2, _K.Max, _K.Min,
              _K.IfThenElse, *_RELATIONS, FormulaKind.And, FormulaKind.Or, FormulaKind.Not}

# The same generated source runs on Python floats (one sample) or on numpy arrays
# (a batch of samples): only the functions bound to these names differ.
_SCALAR_SCOPE = {
    "_sqrt": math.sqrt, "_sin": math.sin, "_cos": math.cos, "_tan": math.tan,
    "_asin": math.asin, "_acos": math.acos, "_atan": math.atan, "_exp": math.exp,
    "_log": math.log, "_abs": abs, "_sinh": math.sinh, "_cosh": math.cosh,
    "_tanh": math.tanh, "_floor": math.floor, "_ceil": math.ceil, "_atan2": math.atan2,
    "_max": max, "_min": min, "_pow": math.pow, "_copysign": math.copysign,
    "_where": lambda c, a, b: a if c else b, "_and": lambda a, b: a and b,
    "_or": lambda a, b: a or b, "_not": lambda a: not a,
}
_VECTOR_SCOPE = {
    "_sqrt": np.sqrt, "_sin": np.sin, "_cos": np.cos, "_tan": np.tan, "_asin": np.arcsin,
    "_acos": np.arccos, "_atan": np.arctan, "_exp": np.exp, "_log": np.log, "_abs": np.abs,
    "_sinh": np.sinh, "_cosh": np.cosh, "_tanh": np.tanh, "_floor": np.floor,
    "_ceil": np.ceil, "_atan2": np.arctan2, "_max": np.maximum, "_min": np.minimum,
    "_pow": np.power, "_copysign": np.copysign, "_where": np.where,
    "_and": np.logical_and, "_or": np.logical_or, "_not": np.logical_not,
}


# ---------------------------------------------------------------------- operands
class _Operand:
    """A leaf of a statement: its Python spelling is ``text``."""

    __slots__ = ("text",)

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


class _Input(_Operand):
    """Entry ``j`` of argument ``i``, named ``a<i>_<j>`` (one object per entry)."""

    __slots__ = ()


class _Temp(_Operand):
    """The result of a statement, named ``t<k>`` (one object per statement)."""

    __slots__ = ()


class _Literal(_Operand):
    """A constant. Equal when spelled alike (``0.0`` and ``-0.0`` differ)."""

    __slots__ = ("value",)

    def __init__(self, value: float | bool):
        if isinstance(value, bool):
            super().__init__(repr(value))
        elif math.isnan(value):
            super().__init__("math.nan")
        elif math.isinf(value):
            super().__init__("math.inf" if value > 0 else "(-math.inf)")
        else:
            super().__init__(repr(float(value)))
        self.value = float(value)

    def __eq__(self, other) -> bool:
        return isinstance(other, _Literal) and other.text == self.text

    def __hash__(self) -> int:
        return hash(self.text)


_ZERO, _ONE, _TWO, _HALF = _Literal(0.0), _Literal(1.0), _Literal(2.0), _Literal(0.5)
_by_text = operator.attrgetter("text")

# Statement trees: (operation, *children); a child is an operand, an int exponent, a
# function or relation name, or another tree. Printed without added parentheses
# (``_PAREN`` adds them), so a tree reads as it is written in _Emitter.
_SUM, _PRODUCT, _NEGATED_PRODUCT, _NEG, _DIFFERENCE = "+", "*", "-*", "neg", "-"
_DIV, _INT_POWER, _CALL, _PAREN, _COMPARE = "/", "**", "call", "()", "compare"


def _is_negation(tree: tuple) -> bool:
    """Whether ``tree`` prints as ``-X`` with ``X`` one operand or one parenthesised group."""
    return tree[0] == _NEGATED_PRODUCT or (tree[0] == _NEG and not isinstance(tree[1], _Literal))


def _temporaries(tree) -> Iterator[_Temp]:
    """Every occurrence of a temporary in ``tree`` (repeats included)."""
    if isinstance(tree, _Temp):
        yield tree
    elif isinstance(tree, tuple):
        for child in tree[1:]:
            yield from _temporaries(child)


# ---------------------------------------------------------------- node identity
_HEADER = object.__basicsize__  # pybind11 keeps the C++ object's address right after it


def _cell_bits(expression: Expression) -> int:
    """The 64 bits of Drake's boxed cell, the only member of an ``Expression``: a
    constant's value, or the kind tag and address of the shared node. O(1), whereas
    Drake's hash and ``to_string`` walk every path of a shared graph."""
    address = ctypes.c_void_p.from_address(id(expression) + _HEADER).value
    return ctypes.c_uint64.from_address(address).value


def _kind_key(expression: Expression) -> ExpressionKind:
    """Fallback identity key: nodes of one kind are told apart by ``EqualTo`` alone."""
    return expression.get_kind()


def _cell_bits_readable() -> bool:
    """Whether :func:`_cell_bits` reads what it should on this Drake build: a constant's
    own bits, one key for a node reached twice, different keys for different nodes."""
    value = 0.123456789012345
    if _cell_bits(Expression(value)) != struct.unpack("<Q", struct.pack("<d", value))[0]:
        return False
    x = Expression(Variable("x"))
    shared, other = sin(x), x * x
    product = shared * other
    reached = [arg for _ in range(2) for arg in product.Unapply()[1]
               if isinstance(arg, Expression) and arg.get_kind() == _K.Sin]
    keys = {_cell_bits(e) for e in (shared, *reached)}
    return len(reached) == 2 and len(keys) == 1 and _cell_bits(other) not in keys


_node_key = _cell_bits if _cell_bits_readable() else _kind_key


# ----------------------------------------------------------------------- emitter
class _Emitter:
    """Turns a Drake expression graph into statements, with forward-mode derivatives.

    Each distinct node of the graph is expanded once (``node_count`` counts them);
    statements with equal trees share one temporary. With ``seeds`` (input name ->
    seed index) every node also gets its partial derivatives by the chain rule,
    kept sparse (absent means zero).
    """

    def __init__(self, variable_names: Mapping[int, str], seeds: Mapping[str, int] | None):
        self._inputs = {vid: _Input(name) for vid, name in variable_names.items()}
        self._seeds = seeds
        self._table: dict[tuple, _Temp] = {}
        self._seen: dict[object, list[tuple[Expression, _Operand]]] = {}
        self._derivatives: dict[_Operand, dict[int, _Operand]] = {}
        self.statements: list[tuple[_Temp, tuple]] = []
        self.used_variables: set[str] = set()
        self.node_count = 0

    # ------------------------------------------------------------ statement helpers
    def _new(self, tree: tuple) -> _Temp:
        temp = self._table.get(tree)
        if temp is None:
            temp = self._table[tree] = _Temp(f"t{len(self._table)}")
            self.statements.append((temp, tree))
        return temp

    def _mul(self, *factors: _Operand) -> _Operand:
        factors = [f for f in factors if f != _ONE]
        if any(f == _ZERO for f in factors):
            return _ZERO
        if not factors:
            return _ONE
        if len(factors) == 1:
            return factors[0]
        return self._new((_PRODUCT, *sorted(factors, key=_by_text)))

    def _sum(self, terms: list[_Operand]) -> _Operand:
        terms = [t for t in terms if t != _ZERO]
        if not terms:
            return _ZERO
        if len(terms) == 1:
            return terms[0]
        return self._new((_SUM, *sorted(terms, key=_by_text)))

    def _neg(self, term: _Operand) -> _Operand:
        return _ZERO if term == _ZERO else self._new((_NEG, term))

    def _div(self, numerator: _Operand, denominator: _Operand) -> _Operand:
        return _ZERO if numerator == _ZERO else self._new((_DIV, numerator, denominator))

    def _quotient(self, a: _Operand, b: _Operand, c: _Operand, d: _Operand) -> _Operand:
        """``(a - b c) / d`` in one statement (``a``, ``c`` may be zero)."""
        if c == _ZERO:
            return self._div(a, d)
        if a == _ZERO:
            return self._new((_DIV, (_PRODUCT, (_NEG, b), c), d))
        return self._new((_DIV, (_PAREN, (_DIFFERENCE, a, (_PRODUCT, b, c))), d))

    def derivatives(self, operand: _Operand) -> dict[int, _Operand]:
        """Sparse partial derivatives of an emitted operand by seed index."""
        return self._derivatives.get(operand, {})

    # ---------------------------------------------------------------- traversal
    def _leaf(self, node) -> _Operand | None:
        if isinstance(node, float | int):
            return _Literal(float(node))
        kind = node.get_kind()
        if isinstance(node, Formula):
            if kind in (FormulaKind.True_, FormulaKind.False_):
                return _Literal(kind == FormulaKind.True_)
            return None
        if kind == _K.Constant:
            return _Literal(node.Evaluate())
        if kind == _K.NaN:
            return _Literal(math.nan)
        if kind == _K.Var:
            (var,) = node.GetVariables()
            operand = self._inputs[var.get_id()]
            self.used_variables.add(operand.text)
            if self._seeds is not None and operand.text in self._seeds:
                self._derivatives[operand] = {self._seeds[operand.text]: _ONE}
            return operand
        return None

    def _recall(self, key, node: Expression) -> _Operand | None:
        """The operand of an expanded node identical to ``node``, if any."""
        for seen, operand in self._seen.get(key, ()):
            if seen.EqualTo(node):
                return operand
        return None

    def emit(self, root) -> _Operand:
        """Operand of ``root``'s value; derivatives via :meth:`derivatives`.

        Depth-first, arguments left to right (the order fixes the temporaries'
        numbers). A node met before is looked up, not walked again.
        """
        results: list[_Operand] = []
        stack: list[tuple] = [(root, None)]
        while stack:
            node, pending = stack.pop()
            if pending is not None:
                kind, count, key = pending
                operand = self._combine(kind, results[len(results) - count:])
                del results[len(results) - count:]
                if key is not None:  # kept alive with the node: its address stays unique
                    self._seen.setdefault(key, []).append((node, operand))
                results.append(operand)
                continue
            operand, key = self._leaf(node), None
            if operand is None and isinstance(node, Expression):
                key = _node_key(node)
                operand = self._recall(key, node)
            if operand is not None:
                results.append(operand)
                continue
            kind = node.get_kind()
            if kind not in _SUPPORTED:
                raise NotImplementedError(f"cannot compile symbolic node of kind {kind}")
            _, args = node.Unapply()
            self.node_count += 1
            stack.append((node, (kind, len(args), key)))
            stack.extend((arg, None) for arg in reversed(args))
        return results[0]

    def _combine(self, kind, args: list[_Operand]) -> _Operand:
        operand = self._new(self._format(kind, args))
        if self._seeds is not None and operand not in self._derivatives:
            partials = self._partials(kind, args, operand)
            if partials:
                self._derivatives[operand] = partials
        return operand

    @staticmethod
    def _format(kind, args: list[_Operand]) -> tuple:
        """The statement tree of node ``kind(args)``."""
        if kind == _K.Add:  # args[0] is the constant term
            terms = sorted(args[1:], key=_by_text)
            return (_SUM, *terms) if args[0].value == 0.0 else (_SUM, args[0], *terms)
        if kind == _K.Mul:  # args[0] is the constant factor
            product = sorted(args[1:], key=_by_text)
            if args[0].value == 1.0:
                return (_PRODUCT, *product)
            if args[0].value == -1.0:
                return (_NEGATED_PRODUCT, *product)
            return (_PRODUCT, args[0], *product)
        if kind == _K.Div:
            return (_DIV, *args)
        if kind == _K.Pow:
            base, exponent = args
            if isinstance(exponent, _Literal) and exponent.value == 2.0:
                return (_PRODUCT, base, base)
            if isinstance(exponent, _Literal) and exponent.value.is_integer():
                return (_INT_POWER, base, int(exponent.value))
            return (_CALL, "_pow", base, exponent)
        if kind in _UNARY:
            return (_CALL, _UNARY[kind], args[0])
        if kind in (_K.Atan2, _K.Max, _K.Min, _K.IfThenElse):
            name = {_K.Atan2: "_atan2", _K.Max: "_max", _K.Min: "_min"}.get(kind, "_where")
            return (_CALL, name, *args)
        if kind in _RELATIONS:
            return (_PAREN, (_COMPARE, _RELATIONS[kind], *args))
        if kind in (FormulaKind.And, FormulaKind.Or):
            name = "_and" if kind == FormulaKind.And else "_or"
            tree = args[0]
            for arg in args[1:]:
                tree = (_CALL, name, tree, arg)
            return tree
        return (_CALL, "_not", args[0])  # FormulaKind.Not, the last of _SUPPORTED

    def _partials(self, kind, args: list[_Operand], t: _Temp) -> dict[int, _Operand]:
        """Chain rule for node ``t = kind(args)``."""
        if isinstance(kind, FormulaKind) or kind in (_K.Floor, _K.Ceil):
            return {}
        d = [self.derivatives(a) for a in args]
        out, cofactors = {}, {}
        for j in sorted(set().union(*d)):
            if kind == _K.Mul:
                # d(c f_1 ... f_n) = sum_i (c prod_{l != i} f_l) df_i: one cofactor per factor.
                terms = []
                for i in range(1, len(args)):
                    if j in d[i]:
                        if i not in cofactors:
                            cofactors[i] = self._mul(*args[:i], *args[i + 1:])
                        terms.append(self._mul(cofactors[i], d[i][j]))
                value = self._sum(terms)
            else:
                value = self._partial(kind, args, t, [di.get(j, _ZERO) for di in d])
            if value != _ZERO:
                out[j] = value
        return out

    def _power_partial(self, base: _Operand, exponent: _Operand, t: _Temp,
                       da: list[_Operand]) -> _Operand:
        """Derivative of ``t = base ** exponent``."""
        if isinstance(exponent, _Literal):
            e = exponent.value
            if e == 2.0:
                slope = self._mul(_TWO, base)
            elif e == 0.5:
                slope = self._new((_DIV, _HALF, t))
            elif e.is_integer():
                slope = self._new((_PRODUCT, exponent, (_INT_POWER, base, int(e) - 1)))
            else:
                slope = self._new((_PRODUCT, exponent, (_CALL, "_pow", base, _Literal(e - 1.0))))
            return self._mul(slope, da[0])
        log_term = self._mul(self._new((_CALL, "_log", base)), da[1])
        base_term = self._mul(self._new((_DIV, exponent, base)), da[0])
        return self._mul(t, self._sum([log_term, base_term]))

    def _partial(self, kind, args: list[_Operand], t: _Temp, da: list[_Operand]) -> _Operand:
        """Derivative of ``t = kind(args)`` given the arguments' derivatives ``da``."""
        a = args[0]
        if kind == _K.Add:
            return self._sum(da[1:])
        if kind == _K.Div:
            return self._quotient(da[0], t, da[1], args[1])
        if kind == _K.Pow:
            return self._power_partial(args[0], args[1], t, da)
        if kind == _K.Exp:
            return self._mul(t, da[0])
        if kind == _K.Cos:  # shares sin(a) with a sine of the same argument
            return self._neg(self._mul(self._new((_CALL, "_sin", a)), da[0]))
        if kind in _SLOPES:
            return self._mul(self._new(_SLOPES[kind](a, t)), da[0])
        if kind == _K.Atan2:
            y, x = args
            return self._quotient(self._mul(x, da[0]), y, da[1],
                                  self._new((_SUM, (_PRODUCT, x, x), (_PRODUCT, y, y))))
        if kind in (_K.Max, _K.Min):
            relation = ">=" if kind == _K.Max else "<="
            return self._new((_CALL, "_where", (_COMPARE, relation, *args), da[0], da[1]))
        if kind == _K.IfThenElse:
            return self._new((_CALL, "_where", a, da[1], da[2]))
        raise NotImplementedError(f"cannot differentiate symbolic node of kind {kind}")


def _one_minus_square(a: _Operand) -> tuple:
    return (_CALL, "_sqrt", (_DIFFERENCE, _ONE, (_PRODUCT, a, a)))


# d kind(a) / da as a statement tree of the argument a and the node's value t.
_SLOPES: dict[ExpressionKind, Callable[[_Operand, _Temp], tuple]] = {
    _K.Sqrt: lambda a, t: (_DIV, _HALF, t),
    _K.Sin: lambda a, t: (_CALL, "_cos", a),
    _K.Tan: lambda a, t: (_SUM, _ONE, (_PRODUCT, t, t)),
    _K.Asin: lambda a, t: (_DIV, _ONE, _one_minus_square(a)),
    _K.Acos: lambda a, t: (_DIV, _Literal(-1.0), _one_minus_square(a)),
    _K.Atan: lambda a, t: (_DIV, _ONE, (_PAREN, (_SUM, _ONE, (_PRODUCT, a, a)))),
    _K.Log: lambda a, t: (_DIV, _ONE, a),
    _K.Abs: lambda a, t: (_CALL, "_copysign", _ONE, a),
    _K.Sinh: lambda a, t: (_CALL, "_cosh", a),
    _K.Cosh: lambda a, t: (_CALL, "_sinh", a),
    _K.Tanh: lambda a, t: (_DIFFERENCE, _ONE, (_PRODUCT, t, t)),
}


# ------------------------------------------------------------------------ printing
_INLINE_LENGTH = 160  # longest expression a temporary is folded into (bounds the nesting)


class _Printer:
    """Python spelling of statement trees; a folded temporary prints as its own
    expression in parentheses (once: it is used once)."""

    def __init__(self):
        self.folded: dict[_Temp, str] = {}
        self.subtracted: dict[_Temp, str] = {}  # folded negation -> its subtracted form

    def fold(self, temp: _Temp, text: str, tree: tuple) -> None:
        self.folded[temp] = text
        if _is_negation(tree):  # "-X" added to something is "- (X)"
            self.subtracted[temp] = f"({text[1:]})"

    def tree(self, node) -> str:
        if isinstance(node, _Operand):
            if node in self.folded:
                self.subtracted.pop(node, None)
                return f"({self.folded.pop(node)})"
            return node.text
        if isinstance(node, int | str):
            return str(node)
        op, *args = node
        if op == _SUM:
            return self._sum(args)
        if op in (_PRODUCT, _NEGATED_PRODUCT):
            product = " * ".join(self.tree(a) for a in args)
            return product if op == _PRODUCT else f"-({product})"
        if op == _NEG:
            return f"-{self.tree(args[0])}"
        if op == _CALL:
            return f"{args[0]}({', '.join(self.tree(a) for a in args[1:])})"
        if op == _PAREN:
            return f"({self.tree(args[0])})"
        if op == _COMPARE:
            return f"{self.tree(args[1])} {args[0]} {self.tree(args[2])}"
        return f"{self.tree(args[0])} {op} {self.tree(args[1])}"  # -, /, **

    def _sum(self, terms: list) -> str:
        text = self.tree(terms[0])
        for term in terms[1:]:
            if term in self.subtracted:
                del self.folded[term]
                text += f" - {self.subtracted.pop(term)}"
            else:
                text += f" + {self.tree(term)}"
        return text


def _render(statements: list[tuple[_Temp, tuple]], tail: list[list]) -> list[str]:
    """Python lines of ``statements`` and the ``tail`` lines (lists of code text and
    operands), every temporary used exactly once folded into its use.

    The operations and their order are unchanged (a folded negation that is added
    becomes a subtraction: the same IEEE result); the generated function just stores
    and loads fewer locals, which is most of the cost of straight-line Python.
    """
    uses = Counter()
    for _, tree in statements:
        uses.update(_temporaries(tree))
    for parts in tail:
        uses.update(p for p in parts if isinstance(p, _Temp))
    printer, out = _Printer(), []
    for temp, tree in statements:
        text = printer.tree(tree)
        if uses[temp] == 1 and len(text) <= _INLINE_LENGTH:
            printer.fold(temp, text, tree)
        else:
            out.append(f"    {temp.text} = {text}")
    for parts in tail:
        out.append("".join(printer.tree(p) if isinstance(p, _Operand) else p for p in parts))
    return out


VECTOR_BATCH = 16
"""Batch size from which compiled functions evaluate on numpy arrays instead of per sample."""


class CompiledFunction:
    """A scalar-generic function of vector arguments with value and Jacobians compiled.

    ``fn(*args)`` must accept numpy arrays of float, ``AutoDiffXd`` or
    ``Expression`` (sizes ``arg_sizes``) and return a 1-D sequence. ``wrt``
    maps an argument index to the entries to differentiate by (``None``: all;
    empty: value only).

    ``fn`` is traced once with symbolic inputs; the trace is written as
    straight-line Python with shared subexpressions, and its Jacobians by
    forward-mode differentiation of the same trace. The generated code runs on
    floats (:meth:`value`, :meth:`jacobians`) or elementwise on a batch of
    samples (:meth:`batch_value`, :meth:`batch_jacobians`).
    :meth:`autodiff_jacobians` evaluates ``fn`` with ``AutoDiffXd`` instead (the
    reference the tests compare with). ``operation_count`` is the number of
    generated statements of the value and Jacobians; ``node_count`` the number of
    distinct nodes of the traced expression graph (each walked once).
    """

    def __init__(self, fn: Callable, arg_sizes: Sequence[int],
                 wrt: Mapping[int, Sequence[int] | None] | None = None, name: str = "fn"):
        self.fn = fn
        self.arg_sizes = tuple(int(n) for n in arg_sizes)
        self.wrt = {int(i): tuple(range(self.arg_sizes[i])) if idx is None else tuple(idx)
                    for i, idx in (wrt or {}).items()}
        self.name = name
        symbols = [[Variable(f"a{i}_{j}") for j in range(n)] for i, n in enumerate(self.arg_sizes)]
        self._names = {v.get_id(): f"a{i}_{j}"
                       for i, vs in enumerate(symbols) for j, v in enumerate(vs)}
        traced = fn(*[np.array([Expression(v) for v in vs], dtype=object) for vs in symbols])
        self._outputs = [o if isinstance(o, Expression) else Expression(float(o)) for o in traced]
        self.output_size = len(self._outputs)
        seeds = [f"a{i}_{j}" for i, idx in self.wrt.items() for j in idx]
        self._n_seeds = len(seeds)
        self._blocks, start = [], 0
        for idx in self.wrt.values():
            self._blocks.append((start, start + len(idx)))
            start += len(idx)
        self._seeds = {name: k for k, name in enumerate(seeds)}
        self._reset()

    def _reset(self) -> None:
        """Drops the generated code and builds the float code of the value (and Jacobians)."""
        self._programs: dict[tuple[bool, bool], Callable] = {}
        self._sources: dict[tuple[bool, bool], str] = {}
        self._traces: dict[bool, tuple] = {}
        self._program(vector=False, with_jacobians=bool(self.wrt))

    def restricted(self, outputs: Sequence[int], name: str | None = None) -> CompiledFunction:
        """The same function with only the entries ``outputs`` (indices into its
        result), from the same trace: the generated code computes just what those
        entries need. Arguments and ``wrt`` are unchanged."""
        outputs = [int(i) for i in outputs]
        if not outputs or not all(0 <= i < self.output_size for i in outputs):
            raise ValueError(f"outputs: need indices in [0, {self.output_size}), got {outputs}")
        out = object.__new__(CompiledFunction)
        out.__dict__.update(self.__dict__)
        out.fn = _Selection(self.fn, outputs)
        out.name = name or f"{self.name} {outputs}"
        out._outputs = [self._outputs[i] for i in outputs]
        out.output_size = len(outputs)
        out._reset()
        return out

    @property
    def jacobian_structure(self) -> np.ndarray:
        """(m, k) bool: the Jacobian entries that are not identically zero."""
        self._program(False, True)
        return self._structure

    @property
    def operation_count(self) -> int:
        """Generated statements of the value (and Jacobians, when ``wrt`` names any)."""
        return len(self._trace(bool(self.wrt))[2])

    @property
    def node_count(self) -> int:
        """Distinct nodes of the traced expression graph (the work of a trace)."""
        return self._trace(bool(self.wrt))[4]

    def _trace(self, with_jacobians: bool) -> tuple:
        """(value operands, sparse partials, statements, used inputs, node count)."""
        if with_jacobians not in self._traces:
            emitter = _Emitter(self._names, self._seeds if with_jacobians else None)
            values = [emitter.emit(e) for e in self._outputs]
            partials = [emitter.derivatives(v) for v in values]
            self._traces[with_jacobians] = (values, partials, emitter.statements,
                                            emitter.used_variables, emitter.node_count)
        return self._traces[with_jacobians]

    def source(self, vector: bool = False, with_jacobians: bool = False) -> str:
        """The generated Python of one program: for one sample or a batch (``vector``),
        of the value or of the value and Jacobians."""
        self._program(vector, with_jacobians)
        return self._sources[(vector, with_jacobians)]

    def _program(self, vector: bool, with_jacobians: bool) -> Callable:
        """The generated function (built on first use)."""
        key = (vector, with_jacobians)
        if key not in self._programs:
            self._programs[key] = self._build(vector, with_jacobians)
        return self._programs[key]

    def _unpacking(self, vector: bool, used: set[str]) -> list[str]:
        """Lines binding the input names the code uses, from the arguments."""
        lines = []
        for i, n in enumerate(self.arg_sizes):
            names = [f"a{i}_{j}" if f"a{i}_{j}" in used else "_" for j in range(n)]
            if vector:
                lines += [f"    {name} = a{i}[:, {j}]" for j, name in enumerate(names)
                          if name != "_"]
            elif any(name != "_" for name in names):  # one unpacking of the whole argument
                lines.append(f"    {', '.join(names)}, = a{i}")
        return lines

    def _vector_tail(self, values: list, partials: list, with_jacobians: bool) -> list[list]:
        m, k = self.output_size, self._n_seeds
        tail = [[f"    _y = _empty((len(a0), {m}))"]]
        tail += [[f"    _y[:, {i}] = ", v] for i, v in enumerate(values)]
        if not with_jacobians:
            return [*tail, ["    return _y"]]
        tail.append([f"    _J = _zeros((len(a0), {m * k}))"])
        tail += [[f"    _J[:, {i * k + j}] = ", d] for i, p in enumerate(partials)
                 for j, d in p.items()]
        return [*tail, [f"    return _y, _J.reshape(len(a0), {m}, {k})"]]

    def _scalar_jacobian_tail(self, values: list, partials: list) -> tuple[list[list], dict]:
        """One flat array [value, Jacobian row-major]: literal entries (mostly zeros)
        come from a template, the others are written in one call."""
        m, k = self.output_size, self._n_seeds
        entries = values + [p.get(j, _ZERO) for p in partials for j in range(k)]
        template = np.array([e.value if isinstance(e, _Literal) else 0.0 for e in entries])
        computed = [i for i, e in enumerate(entries) if not isinstance(e, _Literal)]
        self._structure = (np.isin(np.arange(m, m + m * k), computed)
                           | (template[m:] != 0.0)).reshape(m, k)
        tail = [["    _out = _template.copy()"]]
        if computed:
            written = [part for i in computed for part in (entries[i], ", ")]
            tail.append(["    _out[_computed] = _fromiter((", *written[:-1],
                         f",), float, {len(computed)})"])
        tail.append(["    return _out"])
        return tail, {"_template": template, "_computed": np.array(computed, dtype=np.intp)}

    def _build(self, vector: bool, with_jacobians: bool) -> Callable:
        values, partials, statements, used, _ = self._trace(with_jacobians)
        params = ", ".join(f"a{i}" for i in range(len(self.arg_sizes)))
        scope = {"math": math, "_array": _float_array, "_empty": np.empty, "_zeros": np.zeros,
                 "_fromiter": np.fromiter, **(_VECTOR_SCOPE if vector else _SCALAR_SCOPE)}
        if vector:
            tail = self._vector_tail(values, partials, with_jacobians)
        elif with_jacobians:
            tail, constants = self._scalar_jacobian_tail(values, partials)
            scope.update(constants)
        else:
            listed = [part for v in values for part in (v, ", ")]
            tail = [["    return _array([", *listed[:-1], "])"]]
        lines = [f"def compiled({params}):", *self._unpacking(vector, used),
                 *_render(statements, tail)]
        label = f"{'batch' if vector else 'scalar'}{' jacobians' if with_jacobians else ''}"
        source = self._sources[(vector, with_jacobians)] = "\n".join(lines)
        exec(compile(source, f"<compiled {self.name} ({label})>", "exec"), scope)
        return scope["compiled"]

    def _split(self, J: np.ndarray) -> list[np.ndarray]:
        return [J[..., a:b] for a, b in self._blocks]

    def value(self, *args) -> np.ndarray:
        """``fn(*args)`` for one sample of float arguments (compiled, no derivatives)."""
        return self._program(False, False)(*[as_list(a) for a in args])

    @property
    def program(self) -> Callable:
        """The compiled value code itself: :meth:`value` for arguments that are already
        Python lists of floats (no conversion)."""
        return self._program(False, False)

    def batch_value(self, *args) -> np.ndarray:
        """:meth:`value` for (B, size) arguments, run once on numpy arrays: (B, m)."""
        return self._program(True, False)(*[np.asarray(a, float) for a in args])

    def value_and_jacobian(self, *args) -> tuple[np.ndarray, np.ndarray]:
        """Value (m,) and the Jacobian (m, k) w.r.t. all ``wrt`` entries side by side
        (in the order of ``wrt``) for one sample: the compiled code's single result."""
        out = self._program(False, True)(*[as_list(a) for a in args])
        m = self.output_size
        return out[:m], out[m:].reshape(m, self._n_seeds)

    def jacobians(self, *args) -> tuple[np.ndarray, list[np.ndarray]]:
        """Value and the Jacobians w.r.t. the ``wrt`` entries for one sample (compiled)."""
        value, J = self.value_and_jacobian(*args)
        return value, self._split(J)

    def batch_value_and_jacobian(self, *args) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`value_and_jacobian` for (B, size) arguments: (B, m) and (B, m, k).

        Small batches run the float code per sample; from ``VECTOR_BATCH``
        samples on, the same code runs once on numpy arrays.
        """
        if len(args[0]) < VECTOR_BATCH:
            scalar = self._program(False, True)
            out = np.array([scalar(*[as_list(a[b]) for a in args]) for b in range(len(args[0]))])
            m = self.output_size
            return out[:, :m], out[:, m:].reshape(len(out), m, self._n_seeds)
        return self._program(True, True)(*[np.asarray(a, float) for a in args])

    def batch_jacobians(self, *args) -> tuple[np.ndarray, list[np.ndarray]]:
        """:meth:`jacobians` for (B, size) arguments: values (B, m), Jacobians (B, m, k)."""
        value, J = self.batch_value_and_jacobian(*args)
        return value, self._split(J)

    def autodiff_jacobians(self, *args) -> tuple[np.ndarray, list[np.ndarray]]:
        """Value and Jacobians computed by ``AutoDiffXd`` on ``fn`` itself (reference)."""
        args = [np.asarray(a, float) for a in args]
        seeds = np.concatenate([args[i][list(idx)] for i, idx in self.wrt.items()])
        ad_seeds = InitializeAutoDiff(seeds)[:, 0]
        ad_args = [np.array([AutoDiffXd(v) for v in a], dtype=object) for a in args]
        k = 0
        for i, idx in self.wrt.items():
            for j in idx:
                ad_args[i][j] = ad_seeds[k]
                k += 1
        out = np.array([o if isinstance(o, AutoDiffXd) else AutoDiffXd(float(o))
                        for o in self.fn(*ad_args)], dtype=object)
        value = ExtractValue(out)[:, 0]
        gradient = ExtractGradient(out)
        if gradient.shape[1] != seeds.size:  # every output constant
            gradient = np.zeros((out.size, seeds.size))
        blocks, k = [], 0
        for idx in self.wrt.values():
            blocks.append(gradient[:, k:k + len(idx)])
            k += len(idx)
        return value, blocks


class _Selection:
    """``fn`` with only some entries of its result (the reference of a restricted
    :class:`CompiledFunction`)."""

    def __init__(self, fn: Callable, outputs: Sequence[int]):
        self.fn, self.outputs = fn, tuple(outputs)

    def __call__(self, *args) -> list:
        result = self.fn(*args)
        return [result[i] for i in self.outputs]


def _float_array(values) -> np.ndarray:
    return np.array(values, dtype=float)
