"""The package layers hold, and the import-linter contracts would catch an upward import."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = shutil.which("lint-imports")

pytestmark = pytest.mark.skipif(LINT is None, reason="import-linter is not installed "
                                "(pip install -e '.[dev]')")


def _lint(tree: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(tree))
    return subprocess.run([LINT, "--no-cache"], cwd=tree, env=env, capture_output=True,
                          text=True, timeout=120)


def test_contracts_hold_on_the_package():
    done = _lint(ROOT)
    assert done.returncode == 0, done.stdout[-2000:]
    assert "0 broken" in done.stdout


def test_an_upward_import_breaks_the_layers(tmp_path):
    shutil.copytree(ROOT / "drake_uav", tmp_path / "drake_uav",
                    ignore=shutil.ignore_patterns("__pycache__", "data"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    with open(tmp_path / "drake_uav" / "model" / "scalar.py", "a") as f:
        f.write("\nimport drake_uav.systems  # noqa: E402,F401 (an upward import)\n")
    done = _lint(tmp_path)
    assert done.returncode != 0
    assert "drake_uav.model is not allowed to import drake_uav.systems" in done.stdout


def test_no_package_shares_a_module_name():
    tree = ROOT / "drake_uav"
    packages = {p.parent.name for p in tree.rglob("__init__.py")}
    modules = {p.stem: p for p in tree.rglob("*.py") if p.stem != "__init__"}
    shared = {name: str(modules[name].relative_to(ROOT)) for name in packages & set(modules)}
    assert not shared, f"modules named like a package: {shared}"


def test_a_reverse_import_inside_identification_breaks_its_layers(tmp_path):
    shutil.copytree(ROOT / "drake_uav", tmp_path / "drake_uav",
                    ignore=shutil.ignore_patterns("__pycache__", "data"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    statistics = tmp_path / "drake_uav" / "identification" / "statistics" / "crlb.py"
    with open(statistics, "a") as f:
        f.write("\nimport drake_uav.identification.samples.aero_samples  # noqa: E402,F401\n")
    done = _lint(tmp_path)
    assert done.returncode != 0
    assert ("drake_uav.identification.statistics is not allowed to import "
            "drake_uav.identification.samples") in " ".join(done.stdout.split())

