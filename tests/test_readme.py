"""The README's code runs as written: every ```python block (in a temporary folder, one
namespace per block, in order), every `drake-uav ...` command parses, every example and
benchmark it names exists, every ```toml aircraft file loads."""

import re
import shlex
from pathlib import Path

import pytest

from drake_uav.cli import _parser
from drake_uav.vehicles import load_fixed_wing

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)


def _blocks(language: str) -> list[tuple[int, str]]:
    """(first line number, code) of each fenced block of ``language``, in order."""
    text = README.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 2, m.group(2)) for m in FENCE.finditer(text)
            if m.group(1) == language]


def _commands(program: str) -> list[tuple[int, list[str]]]:
    """Arguments of every ``program ...`` line of the shell blocks (comments dropped)."""
    out = []
    for line_no, code in _blocks("bash"):
        for i, line in enumerate(code.splitlines()):
            words = shlex.split(line, comments=True)
            if words and words[0] == program:
                out.append((line_no + i, words[1:]))
    return out


PYTHON = _blocks("python")


def test_the_readme_has_code_to_check():
    assert PYTHON and _commands("drake-uav") and _blocks("toml")


@pytest.mark.parametrize("line_no, code", PYTHON, ids=[f"line {n}" for n, _ in PYTHON])
def test_python_block_runs(line_no, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # files the block writes land here
    exec(compile(code, f"README.md, block at line {line_no}", "exec"), {"__name__": "readme"})


def test_every_drake_uav_command_parses(capsys):
    parser = _parser()
    for line_no, args in _commands("drake-uav"):
        try:
            parser.parse_args(args)
        except SystemExit as done:  # --help exits 0 after printing; a bad argument exits 2
            assert done.code == 0, f"README.md line {line_no}: drake-uav {shlex.join(args)}"
    capsys.readouterr()


def test_every_script_it_runs_exists():
    scripts = [(n, args[0]) for n, args in _commands("python") if args[0].endswith(".py")]
    assert scripts
    missing = [(n, s) for n, s in scripts if not (ROOT / s).is_file()]
    assert not missing, missing


def test_toml_aircraft_blocks_load(tmp_path):
    for line_no, code in _blocks("toml"):
        path = tmp_path / f"aircraft_{line_no}.toml"
        path.write_text(code)
        assert load_fixed_wing(path).name, line_no
