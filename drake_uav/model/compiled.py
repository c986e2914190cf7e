"""Compilation of scalar-generic functions: symbolic trace -> straight-line Python.

A model function written once for float, ``AutoDiffXd`` and ``Expression`` is
traced with symbolic inputs; :class:`CompiledFunction` writes the trace as
straight-line Python with shared subexpressions (and, on request, its Jacobians
by forward-mode differentiation of the same trace). The generated source runs on
Python floats (one sample) or elementwise on numpy arrays (a batch of samples).
The plant, the estimators and the identifiers use it where a model is evaluated
in a loop; it is never a second copy of the equations.
"""

from __future__ import annotations

import functools
import math
import re
from collections import Counter
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.symbolic import Expression, ExpressionKind, Formula, FormulaKind, Variable

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
_SPECIAL = {"math.nan": math.nan, "math.inf": math.inf, "(-math.inf)": -math.inf}
_ZERO, _ONE = "0.0", "1.0"

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


def _literal(value: float) -> str:
    value = float(value)
    if math.isnan(value):
        return "math.nan"
    if math.isinf(value):
        return "math.inf" if value > 0 else "(-math.inf)"
    return repr(value)


def _is_literal(text: str) -> bool:
    """Literals are everything but temporaries ``t<k>`` and inputs ``a<i>_<j>``."""
    return text[0] not in "ta"


def _constant(text: str) -> float:
    return _SPECIAL[text] if text in _SPECIAL else float(text)


class _Tracer:
    """Writes a Drake expression DAG as Python statements, with forward-mode derivatives.

    Equal subexpressions share one temporary. With ``seeds`` (input name ->
    seed index) every node also gets its partial derivatives by the chain rule,
    kept sparse (absent means zero).
    """

    def __init__(self, variable_names: Mapping[int, str], seeds: Mapping[str, int] | None):
        self._variables = variable_names
        self._seeds = seeds
        self._table: dict[str, str] = {}
        self._derivatives: dict[str, dict[int, str]] = {}
        self.lines: list[str] = []
        self.used_variables: set[str] = set()

    # ------------------------------------------------------------ emission helpers
    def _new(self, text: str) -> str:
        name = self._table.get(text)
        if name is None:
            name = f"t{len(self._table)}"
            self._table[text] = name
            self.lines.append(f"    {name} = {text}")
        return name

    def _mul(self, *factors: str) -> str:
        factors = [f for f in factors if f != _ONE]
        if any(f == _ZERO for f in factors):
            return _ZERO
        if not factors:
            return _ONE
        if len(factors) == 1:
            return factors[0]
        return self._new(" * ".join(sorted(factors)))

    def _sum(self, terms: list[str]) -> str:
        terms = [t for t in terms if t != _ZERO]
        if not terms:
            return _ZERO
        if len(terms) == 1:
            return terms[0]
        return self._new(" + ".join(sorted(terms)))

    def _neg(self, term: str) -> str:
        return _ZERO if term == _ZERO else self._new(f"-{term}")

    def _div(self, numerator: str, denominator: str) -> str:
        return _ZERO if numerator == _ZERO else self._new(f"{numerator} / {denominator}")

    def _quotient(self, a: str, b: str, c: str, d: str) -> str:
        """``(a - b c) / d`` in one statement (``a``, ``c`` may be zero)."""
        if c == _ZERO:
            return self._div(a, d)
        product = f"{b} * {c}"
        return self._new(f"-{product} / {d}" if a == _ZERO else f"({a} - {product}) / {d}")

    def derivatives(self, name: str) -> dict[int, str]:
        """Sparse partial derivatives of an emitted node by seed index."""
        return self._derivatives.get(name, {})

    # ---------------------------------------------------------------- traversal
    def _leaf(self, node) -> str | None:
        if isinstance(node, float | int):
            return _literal(node)
        if isinstance(node, Formula):
            kind = node.get_kind()
            if kind == FormulaKind.True_:
                return "True"
            if kind == FormulaKind.False_:
                return "False"
            return None
        kind = node.get_kind()
        if kind == _K.Constant:
            return _literal(node.Evaluate())
        if kind == _K.NaN:
            return "math.nan"
        if kind == _K.Var:
            (var,) = node.GetVariables()
            name = self._variables[var.get_id()]
            self.used_variables.add(name)
            if self._seeds is not None and name in self._seeds:
                self._derivatives[name] = {self._seeds[name]: _ONE}
            return name
        return None

    def emit(self, root) -> str:
        """Name (or literal) of ``root``'s value; derivatives via :meth:`derivatives`."""
        results: list[str] = []
        stack: list[tuple[object, tuple | None]] = [(root, None)]
        while stack:
            node, pending = stack.pop()
            if pending is None:
                leaf = self._leaf(node)
                if leaf is not None:
                    results.append(leaf)
                    continue
                _, args = node.Unapply()
                stack.append((node, (node.get_kind(), len(args))))
                stack.extend((arg, None) for arg in reversed(args))
                continue
            kind, count = pending
            args = results[len(results) - count:]
            del results[len(results) - count:]
            results.append(self._combine(kind, args))
        return results[0]

    def _combine(self, kind, args: list[str]) -> str:
        name = self._new(self._format(kind, args))
        if self._seeds is not None and name not in self._derivatives:
            partials = self._partials(kind, args, name)
            if partials:
                self._derivatives[name] = partials
        return name

    @staticmethod
    def _format(kind, args: list[str]) -> str:
        if kind == _K.Add:
            terms = sorted(args[1:])
            return " + ".join(terms if _constant(args[0]) == 0.0 else [args[0], *terms])
        if kind == _K.Mul:
            product = " * ".join(sorted(args[1:]))
            factor = _constant(args[0])
            if factor == 1.0:
                return product
            return f"-({product})" if factor == -1.0 else f"{args[0]} * {product}"
        if kind == _K.Div:
            return f"{args[0]} / {args[1]}"
        if kind == _K.Pow:
            base, exponent = args
            if _is_literal(exponent) and _constant(exponent) == 2.0:
                return f"{base} * {base}"
            if _is_literal(exponent) and _constant(exponent) == int(_constant(exponent)):
                return f"{base} ** {int(_constant(exponent))}"
            return f"_pow({base}, {exponent})"
        if kind in _UNARY:
            return f"{_UNARY[kind]}({args[0]})"
        if kind == _K.Atan2:
            return f"_atan2({args[0]}, {args[1]})"
        if kind in (_K.Max, _K.Min):
            return f"{'_max' if kind == _K.Max else '_min'}({args[0]}, {args[1]})"
        if kind == _K.IfThenElse:
            return f"_where({args[0]}, {args[1]}, {args[2]})"
        if kind in _RELATIONS:
            return f"({args[0]} {_RELATIONS[kind]} {args[1]})"
        if kind in (FormulaKind.And, FormulaKind.Or):
            function = "_and" if kind == FormulaKind.And else "_or"
            text = args[0]
            for arg in args[1:]:
                text = f"{function}({text}, {arg})"
            return text
        if kind == FormulaKind.Not:
            return f"_not({args[0]})"
        raise NotImplementedError(f"cannot compile symbolic node of kind {kind}")

    def _partials(self, kind, args: list[str], t: str) -> dict[int, str]:
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

    def _partial(self, kind, args: list[str], t: str, da: list[str]) -> str:
        a = args[0]
        if kind == _K.Add:
            return self._sum(da[1:])
        if kind == _K.Div:
            return self._quotient(da[0], t, da[1], args[1])
        if kind == _K.Pow:
            base, exponent = args
            if _is_literal(exponent):
                e = _constant(exponent)
                if e == 2.0:
                    slope = self._mul("2.0", base)
                elif e == 0.5:
                    slope = self._new(f"0.5 / {t}")
                elif e == int(e):
                    slope = self._new(f"{_literal(e)} * {base} ** {int(e) - 1}")
                else:
                    slope = self._new(f"{_literal(e)} * _pow({base}, {_literal(e - 1.0)})")
                return self._mul(slope, da[0])
            log_term = self._mul(self._new(f"_log({base})"), da[1])
            base_term = self._mul(self._new(f"{exponent} / {base}"), da[0])
            return self._mul(t, self._sum([log_term, base_term]))
        slopes = {
            _K.Sqrt: lambda: f"0.5 / {t}",
            _K.Sin: lambda: f"_cos({a})",
            _K.Tan: lambda: f"1.0 + {t} * {t}",
            _K.Asin: lambda: f"1.0 / _sqrt(1.0 - {a} * {a})",
            _K.Acos: lambda: f"-1.0 / _sqrt(1.0 - {a} * {a})",
            _K.Atan: lambda: f"1.0 / (1.0 + {a} * {a})",
            _K.Log: lambda: f"1.0 / {a}",
            _K.Abs: lambda: f"_copysign(1.0, {a})",
            _K.Sinh: lambda: f"_cosh({a})",
            _K.Cosh: lambda: f"_sinh({a})",
            _K.Tanh: lambda: f"1.0 - {t} * {t}",
        }
        if kind == _K.Exp:
            return self._mul(t, da[0])
        if kind == _K.Cos:  # shares sin(a) with a sine of the same argument
            return self._neg(self._mul(self._new(f"_sin({a})"), da[0]))
        if kind in slopes:
            return self._mul(self._new(slopes[kind]()), da[0])
        if kind == _K.Atan2:
            y, x = args
            return self._quotient(self._mul(x, da[0]), y, da[1],
                                  self._new(f"{x} * {x} + {y} * {y}"))
        if kind in (_K.Max, _K.Min):
            op = ">=" if kind == _K.Max else "<="
            return self._new(f"_where({args[0]} {op} {args[1]}, {da[0]}, {da[1]})")
        if kind == _K.IfThenElse:
            return self._new(f"_where({args[0]}, {da[1]}, {da[2]})")
        raise NotImplementedError(f"cannot differentiate symbolic node of kind {kind}")


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
    generated statements of the value and Jacobians.
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
        self._programs: dict[tuple[bool, bool], Callable] = {}
        self._statements: dict[bool, int] = {}
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
        out._programs, out._statements = {}, {}
        out._program(vector=False, with_jacobians=bool(out.wrt))
        return out

    @property
    def jacobian_structure(self) -> np.ndarray:
        """(m, k) bool: the Jacobian entries that are not identically zero."""
        self._program(False, True)
        return self._structure

    @property
    def operation_count(self) -> int:
        """Generated statements of the value (and Jacobians, when ``wrt`` names any)."""
        return self._statements[bool(self.wrt)]

    def _trace(self, with_jacobians: bool) -> tuple:
        """(value names, sparse partials, statements, used inputs) of the trace."""
        tracer = _Tracer(self._names, self._seeds if with_jacobians else None)
        values = [tracer.emit(e) for e in self._outputs]
        partials = [tracer.derivatives(v) for v in values]
        return values, partials, tracer.lines, tracer.used_variables

    def _program(self, vector: bool, with_jacobians: bool) -> Callable:
        """The generated function (built on first use)."""
        key = (vector, with_jacobians)
        if key not in self._programs:
            self._programs[key] = self._build(vector, with_jacobians)
        return self._programs[key]

    def _build(self, vector: bool, with_jacobians: bool) -> Callable:
        values, partials, body, used = self._trace(with_jacobians)
        self._statements[with_jacobians] = len(body)
        m, k = self.output_size, self._n_seeds
        params = ", ".join(f"a{i}" for i in range(len(self.arg_sizes)))
        lines = [f"def compiled({params}):"]
        for i, n in enumerate(self.arg_sizes):
            names = [f"a{i}_{j}" if f"a{i}_{j}" in used else "_" for j in range(n)]
            if vector:
                lines += [f"    {name} = a{i}[:, {j}]" for j, name in enumerate(names)
                          if name != "_"]
            elif any(name != "_" for name in names):  # one unpacking of the whole argument
                lines.append(f"    {', '.join(names)}, = a{i}")
        tail = []
        if vector:
            tail.append(f"    _y = _empty((len(a0), {m}))")
            tail += [f"    _y[:, {i}] = {v}" for i, v in enumerate(values)]
            if not with_jacobians:
                tail.append("    return _y")
            else:
                tail.append(f"    _J = _zeros((len(a0), {m * k}))")
                tail += [f"    _J[:, {i * k + j}] = {d}" for i, p in enumerate(partials)
                          for j, d in p.items()]
                tail.append(f"    return _y, _J.reshape(len(a0), {m}, {k})")
        elif not with_jacobians:
            tail.append(f"    return _array([{', '.join(values)}])")
        else:
            # One flat array [value, Jacobian row-major]: literal entries (mostly zeros)
            # come from a template, the others are written in one call.
            entries = values + [p.get(j, _ZERO) for p in partials for j in range(k)]
            template = np.array([_constant(e) if _is_literal(e) else 0.0 for e in entries])
            computed = [i for i, e in enumerate(entries) if not _is_literal(e)]
            self._structure = (np.isin(np.arange(m, m + m * k), computed)
                               | (template[m:] != 0.0)).reshape(m, k)
            tail.append("    _out = _template.copy()")
            if computed:
                written = ", ".join(entries[i] for i in computed)
                tail.append(f"    _out[_computed] = _fromiter(({written},), float, "
                             f"{len(computed)})")
            tail.append("    return _out")
        lines += _inline_single_use(body + tail)
        scope = {"math": math, "_array": _float_array, "_empty": np.empty, "_zeros": np.zeros,
                 "_fromiter": np.fromiter,
                 **(_VECTOR_SCOPE if vector else _SCALAR_SCOPE)}
        if with_jacobians and not vector:
            scope.update(_template=template, _computed=np.array(computed, dtype=np.intp))
        label = f"{'batch' if vector else 'scalar'}{' jacobians' if with_jacobians else ''}"
        exec(compile("\n".join(lines), f"<compiled {self.name} ({label})>", "exec"), scope)
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


_DEFINITION = re.compile(r"    (t\d+) = (.*)")
_TEMPORARY = re.compile(r"\bt\d+\b")
_INPUT = re.compile(r"a\d+_\d+")
_INLINE_LENGTH = 160  # longest expression a temporary is folded into (bounds the nesting)


def _negated(text: str) -> str | None:
    """``X`` when ``text`` is the negation ``-X`` of one name or one parenthesised group."""
    if text.startswith("-(") and text.endswith(")"):
        depth = 0
        for i, c in enumerate(text[1:], 1):
            depth += (c == "(") - (c == ")")
            if depth == 0:
                return text[1:] if i == len(text) - 1 else None
    if text.startswith("-") and (_TEMPORARY.fullmatch(text[1:]) or _INPUT.fullmatch(text[1:])):
        return text[1:]
    return None


def _take_folded(folded: dict[str, str], used: list[str], match: re.Match) -> str:
    """The folded text of a temporary (removed from ``folded``, noted in ``used``) or
    the name itself."""
    name = match.group()
    if name not in folded:
        return name
    used.append(folded[name])
    return folded.pop(name)


def _inline_single_use(lines: list[str]) -> list[str]:
    """Folds every temporary used exactly once into the expression that uses it.

    A folded negation that is added (``a + (-X)``) becomes a subtraction
    (``a - (X)``), the same IEEE result in one operation fewer. Otherwise the
    operations and their order are unchanged; the generated function just stores
    and loads fewer locals, which is most of the cost of straight-line Python.
    """
    uses = Counter()
    for line in lines:
        definition = _DEFINITION.fullmatch(line)
        uses.update(_TEMPORARY.findall(definition.group(2) if definition else line))
    folded: dict[str, str] = {}
    negations: dict[str, str] = {}  # folded text -> its subtracted form
    out = []
    for line in lines:
        definition = _DEFINITION.fullmatch(line)
        text = definition.group(2) if definition else line
        used: list[str] = []
        text = _TEMPORARY.sub(functools.partial(_take_folded, folded, used), text)
        for piece in used:
            if piece in negations:
                text = text.replace(f" + {piece}", f" - {negations.pop(piece)}", 1)
        if definition is None:
            out.append(text)
        elif uses[definition.group(1)] == 1 and len(text) <= _INLINE_LENGTH:
            folded[definition.group(1)] = f"({text})"
            positive = _negated(text)
            if positive is not None:
                negations[f"({text})"] = f"({positive})"
        else:
            out.append(f"    {definition.group(1)} = {text}")
    return out


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
