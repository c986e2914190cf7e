"""Every benchmark and example has a quick mode (``--quick``), which CI runs.

``benchmarks/run_quick.py`` runs every script of benchmarks/ and examples/ with ``--quick``
(``.ci/run`` calls it), so a script without the option would fail there, minutes into CI;
these checks read each script's argument parser instead, in milliseconds.
"""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("run_quick", ROOT / "benchmarks" / "run_quick.py")
run_quick = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(run_quick)


def _options(path: Path) -> dict[str, ast.Call]:
    """The options the script's argparse parser declares (``add_argument`` calls)."""
    calls = [node for node in ast.walk(ast.parse(path.read_text()))
             if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
             and node.func.attr == "add_argument"]
    return {arg.value: call for call in calls for arg in call.args
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str)}


def _keyword(call: ast.Call, name: str):
    return next((k.value.value for k in call.keywords
                 if k.arg == name and isinstance(k.value, ast.Constant)), None)


def test_every_script_is_found():
    names = {path.name for path in run_quick.scripts()}
    on_disk = {p.name for folder in ("benchmarks", "examples")
               for p in (ROOT / folder).glob("*.py")}
    assert names == on_disk - run_quick.HELPERS
    assert {"bench_fixed_wing.py", "compare_revisions.py", "fixed_wing_doublet.py"} <= names


@pytest.mark.parametrize("script", run_quick.scripts(), ids=lambda path: path.name)
def test_script_has_a_documented_quick_flag(script):
    quick = _options(script).get("--quick")
    assert quick is not None, f"{script.relative_to(ROOT)}: no --quick option in its parser"
    assert _keyword(quick, "action") == "store_true"
    assert quick.keywords and any(k.arg == "help" for k in quick.keywords), \
        f"{script.relative_to(ROOT)}: --quick has no help text"
    assert "--quick" in ast.get_docstring(ast.parse(script.read_text())), \
        f"{script.relative_to(ROOT)}: its docstring does not say what --quick does"


@pytest.mark.parametrize("name", sorted(run_quick.HELPERS - {"run_quick.py"}))
def test_helpers_are_imported_modules_not_scripts(name):
    """A file left out of the runner must be a module the scripts import, not a script."""
    module = name.removesuffix(".py")
    helper = ROOT / "benchmarks" / name
    assert "__main__" not in helper.read_text()
    assert any(f"from {module} import" in path.read_text() for path in run_quick.scripts())


def test_ci_runs_the_quick_modes():
    assert "python benchmarks/run_quick.py" in (ROOT / ".ci" / "run").read_text().splitlines()
