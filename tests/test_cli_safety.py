"""The command line never loses a user's file, refuses impossible input up front, stops cleanly.

One test per class of failure: an output folder holding the user's files (the current folder,
an earlier report with notes added), the input log as the replay page, an unwritable output, a
Parquet file that is not campaign results, a non-scenario callable, Ctrl-C, two writers of one
report folder, an aircraft file with an impossible value, and the options of ``track``.
"""

import fcntl
import hashlib
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import drake_uav
from drake_uav.cli import main
from drake_uav.io.flight_log import FlightLog
from drake_uav.reporting.output import (
    MANIFEST,
    OutputRefusedError,
    check_output_folder,
    replace_folder,
)
from drake_uav.reporting.report import Report

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"


def _hashes(folder: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under ``folder`` (the folders too, as '-')."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "-" for p in sorted(folder.rglob("*"))}


def _one_error_line(stderr: str, *words: str) -> None:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    assert "Traceback" not in stderr
    for word in words:
        assert word in lines[0], (word, lines[0])


@pytest.fixture(scope="module")
def short_csv(tmp_path_factory) -> Path:
    """The first 90 s of the bundled flight as a CSV log."""
    path = tmp_path_factory.mktemp("log") / "flight.csv"
    FlightLog.load(SAMPLE).slice(0.0, 90.0).save(path)
    return path


def _user_folder(tmp_path: Path, short_csv: Path) -> Path:
    """A folder of the user's: the flight log, code, and a file named summary.json."""
    folder = tmp_path / "work"
    folder.mkdir()
    (folder / "flight.csv").write_bytes(short_csv.read_bytes())
    (folder / "analysis.py").write_text("import numpy\nprint('my analysis')\n")
    (folder / "summary.json").write_text('{"mine": true}\n')
    return folder


# ----------------------------------------------------------------------------- data loss


def test_out_dot_in_the_users_folder_is_refused_and_every_file_kept(
        tmp_path, short_csv, monkeypatch, capsys):
    """``cd DIR && drake-uav identify flight.csv --out .``: refused before any work."""
    folder = _user_folder(tmp_path, short_csv)
    before = _hashes(folder)
    monkeypatch.chdir(folder)
    assert main(["identify", "flight.csv", "--out", "."]) == 2
    _one_error_line(capsys.readouterr().err, "--out", "current folder")
    assert _hashes(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"]  # nothing beside it either
    # The same folder named by path from elsewhere: it holds the input and the user's files.
    monkeypatch.chdir(tmp_path)
    assert main(["identify", "work/flight.csv", "--out", "work"]) == 2
    _one_error_line(capsys.readouterr().err, "holds the input")
    assert main(["identify", str(short_csv), "--out", "work"]) == 2
    _one_error_line(capsys.readouterr().err, "did not write", "analysis.py")
    assert _hashes(folder) == before


def test_an_earlier_report_with_the_users_notes_is_kept_and_a_clean_one_replaced(
        tmp_path, short_csv, capsys):
    out = tmp_path / "report"
    Report("earlier").add_text("old").write(out, {"run": 1})
    (out / "my_notes.txt").write_text("flight 12: left aileron trim changed\n")
    before = _hashes(out)
    assert main(["identify", str(short_csv), "--out", str(out)]) == 2
    _one_error_line(capsys.readouterr().err, "my_notes.txt", "did not write")
    assert _hashes(out) == before
    # Without the notes, the folder is exactly an earlier report: the new report replaces it.
    (out / "my_notes.txt").unlink()
    assert main(["identify", str(short_csv), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and "run" not in summary
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]


def test_the_folder_rule_of_the_writer(tmp_path, monkeypatch):
    """Missing: created; empty: used; an earlier output: replaced; anything else: refused."""
    def write(out):
        return Report("r").add_text("text").write(out, {})

    assert write(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    (tmp_path / "empty").mkdir()
    write(tmp_path / "empty")
    write(tmp_path / "empty")  # now an earlier report: replaced
    (tmp_path / "empty" / "report.md").unlink()  # a file of it deleted: still replaced
    write(tmp_path / "empty")
    assert json.loads((tmp_path / "empty" / MANIFEST).read_text())["files"] == [
        "report.html", "report.md", "summary.json"]
    cases = {"a user's file": ("user", {"notes.txt": b"mine"}),
             "a forged manifest": ("forged", {MANIFEST: b'{"written_by": "someone"}',
                                              "data.csv": b"1,2"}),
             "a manifest missing a file": ("short", {MANIFEST: json.dumps(
                 {"written_by": "drake_uav", "kind": "report", "files": []}).encode(),
                 "data.csv": b"1,2"})}
    for name, (folder, files) in cases.items():
        (tmp_path / folder).mkdir()
        for file, data in files.items():
            (tmp_path / folder / file).write_bytes(data)
        before = _hashes(tmp_path / folder)
        with pytest.raises(OutputRefusedError, match="did not write"):
            write(tmp_path / folder)
        assert _hashes(tmp_path / folder) == before, name
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(OutputRefusedError, match="is an existing file"):
        write(tmp_path / "file.txt")
    monkeypatch.chdir(tmp_path / "empty")
    with pytest.raises(OutputRefusedError, match="current folder"):
        write(tmp_path / "empty")
    with pytest.raises(OutputRefusedError, match="current folder"):
        write(tmp_path)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial left


def test_replay_never_writes_over_the_log_or_a_file_it_did_not_write(
        tmp_path, short_csv, monkeypatch, capsys):
    log = tmp_path / "flight.csv"
    log.write_bytes(short_csv.read_bytes())
    notes = tmp_path / "notes.html"
    notes.write_text("<p>my page</p>")
    before = _hashes(tmp_path)
    assert main(["replay", str(log), "--html", str(log)]) == 2
    _one_error_line(capsys.readouterr().err, "--html", "is the input")
    assert main(["replay", str(log), "--html", str(notes)]) == 2
    _one_error_line(capsys.readouterr().err, "--html", "not written by drake_uav")
    (tmp_path / "flight.html").mkdir()
    assert main(["replay", str(log)]) == 2  # the default page name is a folder
    _one_error_line(capsys.readouterr().err, "is a folder")
    (tmp_path / "flight.html").rmdir()
    assert _hashes(tmp_path) == before
    # Its own page is replaced.
    page = tmp_path / "replay.html"
    assert main(["replay", str(log), "--html", str(page), "--speed", "4"]) == 0
    first = page.read_bytes()
    assert main(["replay", str(log), "--html", str(page), "--speed", "8"]) == 0
    assert page.read_bytes() != first
    assert _hashes(tmp_path) == {**before, "replay.html": _hashes(tmp_path)["replay.html"]}


@pytest.mark.parametrize("command", [["identify", "{log}"], ["track"]])
def test_an_unwritable_output_is_refused_before_any_work(command, tmp_path, short_csv,
                                                         capsys):
    argv = [a.format(log=short_csv) for a in command]
    assert main([*argv, "--out", "/proc/drake_uav_report"]) == 2
    _one_error_line(capsys.readouterr().err, "--out /proc/drake_uav_report", "cannot write")
    if os.geteuid() != 0:  # root writes into read-only folders
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        assert main([*argv, "--out", str(locked / "report")]) == 2
        _one_error_line(capsys.readouterr().err, "cannot write")


def test_a_folder_of_other_files_is_refused_by_every_writing_command(tmp_path, monkeypatch,
                                                                      capsys):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep")
    results = tmp_path / "c.parquet"
    results.write_bytes(b"PAR1 not really")
    for argv in (["track", "--out", str(folder)],
                 ["campaign", "report", str(results), "--out", str(folder)],
                 ["campaign", "run", "main_job", "--out", str(tmp_path / "new.parquet"),
                  "--report", str(folder)]):
        assert main(argv) == 2, argv
        _one_error_line(capsys.readouterr().err, "did not write", "notes.txt")
    assert _hashes(folder) == {"notes.txt": hashlib.sha256(b"keep").hexdigest()}
    assert not (tmp_path / "new.parquet").exists()


# ----------------------------------------------------------------------------- campaigns


def test_campaign_results_never_overwrite_another_file(tmp_path, capsys):
    other = tmp_path / "other.parquet"
    pq.write_table(pa.table({"altitude": [1.0, 2.0]}), other)
    text = tmp_path / "notes.parquet"
    text.write_text("not parquet at all")
    before = _hashes(tmp_path)
    argv = ["campaign", "run", "main_job", "--seeds", "0:2", "--workers", "0"]
    assert main([*argv, "--out", str(other)]) == 2
    _one_error_line(capsys.readouterr().err, "is not campaign results", "not replaced")
    assert main([*argv, "--out", str(text)]) == 2
    _one_error_line(capsys.readouterr().err, "is not a Parquet file", "not replaced")
    assert main([*argv, "--out", str(tmp_path)]) == 2
    _one_error_line(capsys.readouterr().err, "is a folder")
    assert _hashes(tmp_path) == before


@pytest.mark.parametrize("scenario, message", [
    ("os:sep", "is a str, not a function"),
    ("os:getcwd", "do not take (seed, params)"),
    ("no_such_module:run", "cannot import it"),
    ("no_such_scenario", "unknown (built-in:"),
])
def test_a_scenario_that_is_not_one_is_refused_in_one_line(scenario, message, tmp_path,
                                                           capsys):
    out = tmp_path / "c.parquet"
    assert main(["campaign", "run", scenario, "--seeds", "0:2", "--out", str(out)]) == 2
    _one_error_line(capsys.readouterr().err, f"scenario '{scenario}'", message)
    assert list(tmp_path.iterdir()) == []


def test_the_built_in_scenario_names_are_the_registered_ones():
    """The names checked without loading a module are the ones the modules register."""
    from drake_uav.campaigns.registry import BUILT_IN, scenario, scenario_names

    for name, module in BUILT_IN.items():
        assert scenario(name).__module__ == module
    built_in_modules = set(BUILT_IN.values())
    assert {n for n in scenario_names()
            if scenario(n).__module__ in built_in_modules} == set(BUILT_IN)


# ----------------------------------------------------------------------------- Ctrl-C


def test_ctrl_c_exits_130_with_one_line_and_no_partial_report(tmp_path):
    out = tmp_path / "report"
    job = subprocess.Popen([sys.executable, "-m", "drake_uav.cli", "identify", "--out",
                            str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True, cwd=tmp_path)
    try:
        for line in job.stdout:  # interrupted in the middle of the analysis
            if line.startswith("... discovery round"):
                break
        job.send_signal(signal.SIGINT)
        stdout, stderr = job.communicate(timeout=120)
    finally:
        job.kill()
    assert job.returncode == 130
    *warnings, last = stderr.splitlines()
    assert last == "interrupted" and all(w.startswith("warning: ") for w in warnings), stderr
    assert "report:" not in stdout
    assert list(tmp_path.iterdir()) == []  # no report, no partial folder


def test_ctrl_c_during_the_swap_takes_effect_once_the_report_is_in_place(tmp_path,
                                                                         monkeypatch):
    out = tmp_path / "report"
    Report("first").add_text("old").write(out, {"n": 1})
    real_rename = os.rename

    def rename_then_interrupt(src, dst):
        os.kill(os.getpid(), signal.SIGINT)  # arrives between the two renames of the swap
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        Report("second").add_text("new").write(out, {"n": 2})
    monkeypatch.undo()
    assert json.loads((out / "summary.json").read_text())["n"] == 2
    assert [p.name for p in tmp_path.iterdir()] == ["report"]


# ----------------------------------------------------------------------------- concurrency


@pytest.mark.parametrize("replacements", [150, pytest.param(2000, marks=pytest.mark.slow)])
def test_two_writers_of_one_report_folder_take_turns(replacements, tmp_path):
    """2 processes x N replacements of a small report: no error, nothing left beside it."""
    out = tmp_path / "report"
    code = textwrap.dedent(f"""
        import sys
        from drake_uav.reporting.report import Report
        for i in range({replacements}):
            Report(f"writer {{sys.argv[1]}}").add_text(f"run {{i}}").write({str(out)!r},
                                                                          {{"i": i}})
    """)
    jobs = [subprocess.Popen([sys.executable, "-c", code, tag], stderr=subprocess.PIPE,
                             text=True) for tag in "ab"]
    errors = [job.communicate(timeout=1200)[1] for job in jobs]
    assert [job.returncode for job in jobs] == [0, 0], errors
    assert errors == ["", ""]
    assert [p.name for p in tmp_path.iterdir()] == ["report"]  # no .old nor .partial folder
    summary = json.loads((out / "summary.json").read_text())
    assert summary["i"] == replacements - 1 and summary["complete"] is True


def test_a_check_waits_for_a_swap_in_progress_instead_of_refusing(tmp_path):
    """Another writer holds the parent's lock with its earlier report moved aside: a check
    seeing the listed files but no manifest would refuse a folder that is only being
    replaced; it waits for the lock and then finds the new report."""
    out = tmp_path / "report"
    Report("first").add_text("old").write(out, {"n": 1})
    outcome = []

    def check():
        try:
            outcome.append(check_output_folder(out))
        except OutputRefusedError as err:
            outcome.append(err)

    fd = os.open(tmp_path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # the other writer's swap, halfway
        moved_aside = tmp_path / ".report.old-x"
        os.rename(out, moved_aside)
        checker = threading.Thread(target=check)
        checker.start()
        checker.join(timeout=0.5)
        assert checker.is_alive() and outcome == []  # waiting, not refusing
        os.rename(moved_aside, out)  # the new report in place
    finally:
        os.close(fd)  # releases the lock
    checker.join(timeout=10)
    assert outcome == [out]


def test_the_swap_rechecks_the_target_under_its_lock(tmp_path):
    """A user's file that appears while a report is being written stops the swap."""
    out = tmp_path / "report"
    check_output_folder(out)
    out.mkdir()
    (out / "late.txt").write_text("arrived while the report was written")
    partial = tmp_path / ".report.partial-x"
    partial.mkdir()
    with pytest.raises(OutputRefusedError, match="late.txt"):
        replace_folder(partial, out)
    assert [p.name for p in out.iterdir()] == ["late.txt"]


# ----------------------------------------------------------------------------- input


@pytest.mark.parametrize("line", ["mass = -5.0", "mass = nan"])
def test_an_impossible_aircraft_value_names_the_file_and_the_field(line, tmp_path, capsys):
    path = tmp_path / "heavy.toml"
    path.write_text(f'base = "aerosonde"\n{line}\n')
    assert main(["trim", "--aircraft", str(path)]) == 2
    _one_error_line(capsys.readouterr().err, str(path), "mass")


def test_track_options_are_checked_before_pydrake_loads(tmp_path):
    cases = [(["--duration", "0"], "--duration"), (["--duration", "-5"], "--duration"),
             (["--duration", "nan"], "--duration"), (["--duration", "1.5"], "> 2 s"),
             (["--gust", "-1"], "--gust"), (["--offset", "nan"], "--offset"),
             (["--roll-offset", "95"], "--roll-offset"), (["--seed", "-1"], "--seed"),
             (["--mode", "fast"], "--mode")]
    code = textwrap.dedent(f"""
        import contextlib, io, sys
        from drake_uav.cli import main
        for args in {[args for args, _ in cases]!r}:
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                rc = main(["track", *args, "--out", {str(tmp_path / "plots")!r}])
            print(rc, err.getvalue().strip().replace("\\n", " | "))
        print("pydrake" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    *lines, drake_loaded = done.stdout.splitlines()
    assert drake_loaded == "False" and done.stderr == "", done
    for (args, word), line in zip(cases, lines, strict=True):
        rc, message = line.split(" ", 1)
        assert rc == "2" and message.startswith("error: drake-uav track: argument"), line
        assert word in message and " | " not in message, (args, message)
    assert list(tmp_path.iterdir()) == []
