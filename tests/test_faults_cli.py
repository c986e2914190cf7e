"""``drake-uav fault``: options checked before pydrake loads, outputs only into a new or
empty folder, the log readable by the replay."""

import subprocess
import sys

import pytest

from drake_uav.cli import FAULT_SCENARIOS, main


def test_the_cli_names_are_the_scenarios():
    from drake_uav.diagrams.fault_scenarios import SCENARIOS

    assert FAULT_SCENARIOS == tuple(SCENARIOS)


@pytest.mark.parametrize("args, message", [
    (["V"], "fault V: unknown scenario; choose one of I, IIa, IIb, IIIa, IIIb, IVa, IVb or all"),
    (["I", "--out", "{full}"], "holds files drake_uav did not write (keep.txt)"),
    (["I", "--out", "{file}"], "is an existing file; give a folder for the output"),
    (["I", "--tube-cache", "{file}"], "--tube-cache"),
])
def test_bad_options_stop_before_pydrake_with_one_line(tmp_path, args, message):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    (tmp_path / "file").write_text("x")
    argv = [a.format(full=tmp_path / "full", file=tmp_path / "file") for a in args]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    code = ("import sys; from drake_uav.cli import main; "
            f"rc = main(['fault', *{argv!r}]); print(rc, 'pydrake' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    rc, drake_loaded = done.stdout.split()
    assert rc == "2" and drake_loaded == "False", done
    assert message in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert (tmp_path / "full" / "keep.txt").read_text() == "mine"


@pytest.mark.slow
def test_scenario_I_writes_plots_summary_and_a_replayable_log(tmp_path, capsys):
    from drake_uav.io.flight_log import FlightLog
    from drake_uav.reporting.replay import replay_track

    out = tmp_path / "faults"
    assert main(["fault", "I", "--out", str(out)]) == 0
    print(capsys.readouterr().out)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["I.csv", "I_path_3d.png", "I_states.png", "I_thrusts.png",
                     "drake_uav_manifest.json", "summary.md"]
    log = FlightLog.load(out / "I.csv")
    track = replay_track(log)
    assert track.kind == "multirotor" and log.metadata["failed_motors"] == [3, 4]
    assert log.metadata["failure_time"] == 10.0 and log.metadata["category"] == "I"
    after = log.time >= 10.0
    assert (track.motor_health[after][:, [3, 4]] == 0).all()
    assert (track.motor_health[~after] == 1).all()
    assert "| I | 3,4 | 10 | I |" in (out / "summary.md").read_text()
    # An earlier output and nothing else is replaced whole; one holding a user's file is not.
    assert main(["fault", "I", "--out", str(out)]) == 0
    (out / "mine.txt").write_text("the user's")
    assert main(["fault", "I", "--out", str(out)]) == 2
    assert (out / "mine.txt").read_text() == "the user's"
