"""The identification's public docstrings are numpydoc, and their examples run.

Every public function, method and class of :mod:`drake_uav.identification` that takes
arguments documents them in a ``Parameters`` section, and every one that returns a value
has a ``Returns`` section, and every one that raises a ``Raises`` section (read from the
source: a ``return <value>`` or a ``raise`` in its own body).
Every name the package and its sub-packages export has ``Examples``, and every example
of the package runs as a doctest (cheap: small arrays or a short span of the bundled
sample flight).
"""

import ast
import doctest
import importlib
import pkgutil
from pathlib import Path

import pytest

PACKAGE = "drake_uav.identification"
ROOT = Path(importlib.import_module(PACKAGE).__file__).parent
SUBPACKAGES = ("", ".statistics", ".samples", ".discovery", ".assessment")


def _section(doc: str, name: str) -> bool:
    """Whether ``doc`` has a numpydoc section ``name`` (its title, then dashes)."""
    lines = [line.strip() for line in doc.splitlines()]
    return any(a == name and b and set(b) == {"-"} for a, b in zip(lines, lines[1:], strict=False))


def _own_nodes(node: ast.FunctionDef):
    """The nodes of ``node``'s own body, not those of a nested function or class."""
    todo = list(node.body)
    while todo:
        child = todo.pop()
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda
                      | ast.ClassDef):
            continue
        yield child
        todo.extend(ast.iter_child_nodes(child))


def _returns_value(node: ast.FunctionDef) -> bool:
    """Whether ``node``'s own body has ``return <value>``."""
    return any(isinstance(c, ast.Return) and c.value is not None for c in _own_nodes(node))


def _raises(node: ast.FunctionDef) -> bool:
    """Whether ``node``'s own body has ``raise <exception>``."""
    return any(isinstance(c, ast.Raise) and c.exc is not None for c in _own_nodes(node))


def _arguments(node: ast.FunctionDef) -> list[str]:
    """The documented arguments of ``node``: all but ``self`` and ``cls``."""
    a = node.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def _is_property(node: ast.FunctionDef) -> bool:
    """Whether ``node`` is a property (documented as an attribute: no sections)."""
    return any(ast.unparse(d).split(".")[-1] in ("property", "cached_property")
               for d in node.decorator_list)


def _public_definitions():
    """(where, node) of every public function, class and method of the package.

    A method is public when its class is, or when its class is a private base of a public
    class of the same module (its public methods are then the public class's).
    """
    for path in sorted(ROOT.rglob("*.py")):
        tree = ast.parse(path.read_text())
        bases = {b.id for node in tree.body if isinstance(node, ast.ClassDef)
                 and not node.name.startswith("_") for b in node.bases
                 if isinstance(b, ast.Name)}
        for node in tree.body:
            if isinstance(node, ast.ClassDef) and node.name in bases:
                # a private base class: its public methods are the public classes'
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                        yield f"{path.relative_to(ROOT)}:{node.name}.{item.name}", item
            if not isinstance(node, ast.FunctionDef | ast.ClassDef) or node.name.startswith("_"):
                continue
            if isinstance(node, ast.FunctionDef):
                yield f"{path.relative_to(ROOT)}:{node.name}", node
            elif isinstance(node, ast.ClassDef):
                yield f"{path.relative_to(ROOT)}:{node.name}", node
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                        yield f"{path.relative_to(ROOT)}:{node.name}.{item.name}", item


def _problems(node) -> list[str]:
    """What the docstring of ``node`` lacks: Parameters when it takes arguments (a class:
    its ``__init__``), Returns when it returns a value, Raises when it raises, Attributes
    for a dataclass."""
    doc = ast.get_docstring(node) or ""
    if not doc:
        return ["no docstring"]
    problems = []
    if isinstance(node, ast.ClassDef):
        is_dataclass = any("dataclass" in ast.unparse(d) for d in node.decorator_list)
        init = next((i for i in node.body if isinstance(i, ast.FunctionDef)
                     and i.name == "__init__"), None)
        if init is not None and _arguments(init) and not _section(doc, "Parameters"):
            problems.append("no Parameters section (its __init__ takes arguments)")
        if is_dataclass and not (_section(doc, "Attributes") or _section(doc, "Parameters")):
            problems.append("no Attributes section (a dataclass)")
        return problems
    if _is_property(node):
        return problems
    if _arguments(node) and not _section(doc, "Parameters"):
        problems.append("no Parameters section")
    if _returns_value(node) and not (_section(doc, "Returns") or _section(doc, "Yields")):
        problems.append("no Returns section")
    if _raises(node) and not _section(doc, "Raises"):
        problems.append("no Raises section")
    return problems


def test_public_docstrings_are_numpydoc():
    missing = [f"{where}: {p}" for where, node in _public_definitions()
               for p in _problems(node)]
    assert not missing, "\n".join(missing)


def _exported():
    """(module name, exported name) of every name the package and its sub-packages export."""
    seen = set()
    for sub in SUBPACKAGES:
        module = importlib.import_module(PACKAGE + sub)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if callable(obj) and id(obj) not in seen:
                seen.add(id(obj))
                yield PACKAGE + sub, name


EXPORTED = list(_exported())


def test_every_exported_name_has_an_example():
    without = [f"{m}.{n}" for m, n in EXPORTED
               if ">>>" not in (getattr(importlib.import_module(m), n).__doc__ or "")]
    assert not without, "no Examples: " + ", ".join(without)


def _examples():
    """Every docstring of the package with examples, as doctests in its module's namespace.

    The exported names' docstrings are among them (see the test above); the others' run
    too, so that no example of the package goes stale.
    """
    finder = doctest.DocTestFinder()
    tests = []
    for info in pkgutil.walk_packages(importlib.import_module(PACKAGE).__path__, PACKAGE + "."):
        module = importlib.import_module(info.name)
        tests += [t for t in finder.find(module, globs=dict(vars(module)))
                  if t.examples and t.name.startswith(module.__name__)]
    return tests


EXAMPLES = _examples()


@pytest.mark.parametrize("test", EXAMPLES, ids=[t.name[len(PACKAGE) + 1:] for t in EXAMPLES])
def test_examples_run(test):
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report = []
    runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)
