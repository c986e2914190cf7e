"""The identification's public docstrings are numpydoc, and its package-level examples run.

Every public function, method and class of :mod:`drake_uav.identification` that takes
arguments documents them in a ``Parameters`` section, and every one that returns a value
has a ``Returns`` section (read from the source: a ``return <value>`` in its own body).
The ``Examples`` of the names the package and its sub-packages export run as doctests.
"""

import ast
import doctest
import importlib
from pathlib import Path

import pytest

PACKAGE = "drake_uav.identification"
ROOT = Path(importlib.import_module(PACKAGE).__file__).parent
SUBPACKAGES = ("", ".statistics", ".samples", ".discovery", ".assessment")


def _section(doc: str, name: str) -> bool:
    """Whether ``doc`` has a numpydoc section ``name`` (its title, then dashes)."""
    lines = [line.strip() for line in doc.splitlines()]
    return any(a == name and b and set(b) == {"-"} for a, b in zip(lines, lines[1:], strict=False))


def _returns_value(node: ast.FunctionDef) -> bool:
    """Whether ``node``'s own body (not a nested function's) has ``return <value>``."""
    todo = list(node.body)
    while todo:
        child = todo.pop()
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda
                      | ast.ClassDef):
            continue
        if isinstance(child, ast.Return) and child.value is not None:
            return True
        todo.extend(ast.iter_child_nodes(child))
    return False


def _arguments(node: ast.FunctionDef) -> list[str]:
    """The documented arguments of ``node``: all but ``self`` and ``cls``."""
    a = node.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def _is_property(node: ast.FunctionDef) -> bool:
    return any(ast.unparse(d).split(".")[-1] in ("property", "cached_property")
               for d in node.decorator_list)


def _public_definitions():
    """(where, node, owner class or None) of every public definition of the package."""
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
                        yield f"{path.relative_to(ROOT)}:{node.name}.{item.name}", item, node
            if node.name.startswith("_") if hasattr(node, "name") else True:
                continue
            if isinstance(node, ast.FunctionDef):
                yield f"{path.relative_to(ROOT)}:{node.name}", node, None
            elif isinstance(node, ast.ClassDef):
                yield f"{path.relative_to(ROOT)}:{node.name}", node, None
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                        yield f"{path.relative_to(ROOT)}:{node.name}.{item.name}", item, node


def _problems(node, owner) -> list[str]:
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
    return problems


def test_public_docstrings_are_numpydoc():
    missing = [f"{where}: {p}" for where, node, owner in _public_definitions()
               for p in _problems(node, owner)]
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


@pytest.mark.parametrize(("module", "name"), EXPORTED, ids=[n for _, n in EXPORTED])
def test_examples_run(module, name):
    obj = getattr(importlib.import_module(module), name)
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    globs = dict(vars(importlib.import_module(obj.__module__)))
    for test in finder.find(obj, name, globs=globs):
        runner.run(test)
    assert runner.failures == 0, f"{module}.{name}: {runner.failures} example(s) failed"
