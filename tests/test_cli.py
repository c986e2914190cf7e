"""drake-uav command line: formats, bad logs, exit codes, no half-written reports."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from log_writers import dataflash_from_log, ulog_from_log

import drake_uav
from drake_uav.cli import main
from drake_uav.io.flight_log import FlightLog

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"


@pytest.fixture(scope="module")
def short_log():
    """The first 90 s of the bundled flight."""
    log = FlightLog.load(SAMPLE)
    return log.slice(0.0, 90.0)


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "identify" in out and "trim" in out


def test_trim_command_prints_the_modes(capsys):
    assert main(["trim", "--airspeed", "22"]) == 0
    out = capsys.readouterr().out
    assert "short period" in out and "dutch roll" in out


# The readers of each format have their own tests (test_log_readers.py); here the command
# reads each end to end, the binary formats with --vanes, in the slow run.
@pytest.mark.parametrize("kind", ["csv", pytest.param("bin", marks=pytest.mark.slow),
                                  pytest.param("ulg", marks=pytest.mark.slow)])
def test_identify_reads_each_log_format(kind, short_log, tmp_path, capsys):
    path = tmp_path / f"flight.{kind}"
    args = []
    if kind == "csv":
        short_log.save(path)
    elif kind == "bin":
        dataflash_from_log(short_log, path)
        args = ["--vanes", "VANE.AoA,VANE.SSA"]
    else:
        ulog_from_log(short_log, path)
        args = ["--vanes", "vane_angles.alpha,vane_angles.beta", "--vane-unit", "rad"]
    out = tmp_path / "report"
    assert main(["identify", str(path), "--out", str(out), *args]) == 0  # in-process: faster
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True
    assert "thrust_propwash" in [e["name"] for e in summary["effects"]]
    assert "->" in capsys.readouterr().out


def _bad_logs(log: FlightLog, tmp_path: Path) -> dict[str, tuple[Path, str]]:
    good = tmp_path / "good.csv"
    log.save(good)
    lines = good.read_text().splitlines()
    truncated = tmp_path / "truncated.csv"
    truncated.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][: len(lines[-1]) // 2])
    channels = {n: log[n] for n in log.measured_names}
    no_airspeed = FlightLog(log.time, {k: v for k, v in channels.items()
                                       if k != "pitot_airspeed"}, units=log.units)
    nan = dict(channels)
    nan["vane_alpha"] = nan["vane_alpha"].copy()
    nan["vane_alpha"][500:520] = np.nan
    backwards = log.time.copy()
    backwards[700] = backwards[698]
    bad = {"missing": (tmp_path / "missing.csv", "pitot_airspeed"),
           "nan": (tmp_path / "nan.csv", "vane_alpha"),
           "backwards": (tmp_path / "backwards.csv", "time"),
           "truncated": (truncated, "truncated")}
    no_airspeed.save(bad["missing"][0])
    FlightLog(log.time, nan, units=log.units, validate=False).save(bad["nan"][0])
    FlightLog(backwards, channels, units=log.units, validate=False).save(bad["backwards"][0])
    return bad


def test_bad_logs_fail_clearly_and_write_no_report(short_log, tmp_path, capsys):
    """In-process: an exception other than the reported error would fail the test."""
    for name, (path, word) in _bad_logs(short_log, tmp_path).items():
        out = tmp_path / f"report_{name}"
        assert main(["identify", str(path), "--out", str(out)]) != 0, name
        stderr = capsys.readouterr().err
        assert "error:" in stderr and word in stderr.lower(), (name, stderr)
        assert not out.exists(), name
    assert main(["identify", str(tmp_path / "absent.bin")]) != 0
    assert "absent.bin" in capsys.readouterr().err


def test_the_console_script_exits_with_the_error_code(tmp_path):
    done = subprocess.run([sys.executable, "-m", "drake_uav.cli", "identify",
                           str(tmp_path / "absent.bin")], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 2
    assert "error:" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("args, message", [
    (["{absent}"], "no such file (the LOG argument)"),
    (["{empty}"], "empty file"),
    (["{log}", "--out", "{log}"], "is an existing file; give a folder"),
    (["{log}", "--aircraft", "cessna"], "--aircraft cessna: not a catalog aircraft"),
    (["{log}", "--aircraft", "{bad_toml}"], "not valid TOML"),
    (["{log}", "--sensor-spec", "{absent}"], "the --sensor-spec argument"),
    (["{log}", "--segment", "10-20"], "expected auto or START:END"),
    (["{log}", "--max-gap", "0"], "argument --max-gap: expected a finite number > 0 s"),
    (["{odd}"], "name the format with --format"),
])
def test_bad_arguments_fail_fast_without_a_traceback(args, message, tmp_path):
    """Checked before the analysis stack loads: exit 2 within 2 s, one line, no report."""
    paths = {"absent": tmp_path / "absent.bin", "empty": tmp_path / "empty.bin",
             "log": tmp_path / "flight.bin", "bad_toml": tmp_path / "plane.toml",
             "odd": tmp_path / "flight.txt"}
    paths["empty"].touch()
    for name in ("log", "odd"):
        paths[name].write_bytes(b"\xa3\x95\x80")
    paths["bad_toml"].write_text("mass = = 3\n")
    argv = [a.format(**paths) for a in args]
    code = ("import sys, time; t = time.perf_counter(); from drake_uav.cli import main; "
            f"rc = main(['identify', *{argv!r}, '--out', {str(tmp_path / 'out')!r}] "
            f"if '--out' not in {argv!r} else ['identify', *{argv!r}]); "
            "print(rc, 'pydrake' in sys.modules, time.perf_counter() - t)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    rc, drake_loaded, _ = done.stdout.split()
    assert rc == "2" and drake_loaded == "False", done
    assert message in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_the_cli_suffix_table_is_the_readers_table():
    from drake_uav.cli import _LOG_SUFFIXES
    from drake_uav.io.streams import FORMATS

    assert _LOG_SUFFIXES == FORMATS


class _ReadDone(Exception):
    """Raised in place of the analysis: the test stops once the log is read."""


@pytest.mark.parametrize("kind", ["csv", "parquet", "tlog", "bin", "ulg"])
@pytest.mark.parametrize("option", [["--vanes", "VANE.AoA,VANE.SSA"], ["--max-gap", "0.3"],
                                    ["--extra-channels", "BAT.Temp"], ["--segment", "5:20"]])
def test_every_reading_option_reaches_the_reader_or_is_refused(kind, option, short_log,
                                                              tmp_path, capsys, monkeypatch):
    """Each reading option is either taken by the format's reader (which may refuse a field
    the log lacks, naming the file) or refused in one line before any work; none ends in a
    reader's TypeError."""
    from drake_uav.identification import pipeline
    from drake_uav.io.tlog_writer import write_tlog

    path = tmp_path / f"flight.{kind}"
    log = short_log.slice(0.0, 25.0)
    {"csv": log.save, "parquet": log.save, "tlog": lambda p: write_tlog(log, p),
     "bin": lambda p: dataflash_from_log(log, p), "ulg": lambda p: ulog_from_log(log, p),
     }[kind](path)

    def stop(*args, **kwargs):
        raise _ReadDone

    monkeypatch.setattr(pipeline, "identify", stop)
    refused = {("--vanes", "csv"), ("--vanes", "parquet"), ("--vanes", "tlog"),
               ("--max-gap", "parquet"), ("--extra-channels", "csv"),
               ("--extra-channels", "parquet")}
    argv = ["identify", str(path), "--out", str(tmp_path / "report"), *option]
    if (option[0], kind) in refused:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"error: {option[0]}:"), err
    else:  # read, or refused by the reader itself for a field this log lacks
        try:
            code = main(argv)
        except _ReadDone:
            return
        errors = [line for line in capsys.readouterr().err.splitlines()
                  if line.startswith("error:")]
        assert code == 2 and len(errors) == 1 and errors[0].startswith(f"error: {path}: ")
