"""Property-based test of the command line's options: malformed values of every option of every
sub-command stop with exit code 2 and one ``error:`` line, never a traceback, and touch no file.

Each example is a command line of one sub-command whose options are left out, given a valid
value, given random text, or given a value that is invalid by construction; at least one option
(or argument) is invalid, so every example must stop before any work: the default suite runs a
few examples per sub-command in well under a second each, the slow run many more.
"""

import contextlib
import hashlib
import io
import tempfile
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import drake_uav
from drake_uav.campaigns.definition import Campaign
from drake_uav.campaigns.runner import run_campaign
from drake_uav.cli import FAULT_SCENARIOS, main
from drake_uav.io.flight_log import FlightLog

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"

# Random text of the kind a careless user types: any printable character but a path separator
# (relative names stay inside the example's folder); NUL and lone surrogates cannot be in argv.
_JUNK = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00/"),
                max_size=12).filter(lambda t: not t.startswith(".")
                                    and t not in (*FAULT_SCENARIOS, "all"))  # would fly
_NOT_A_NUMBER = st.sampled_from(["nan", "inf", "-inf", "x", "", "1,5", "0x10", "1e999"])


def _values(*texts: str) -> st.SearchStrategy[str]:
    return st.sampled_from(texts)


def _number_outside(*texts: str) -> st.SearchStrategy[str]:
    """Numbers outside an option's bounds, or text that is no finite number."""
    return st.one_of(_values(*texts), _NOT_A_NUMBER)


_SEED_BAD = _values("-1", "1.5", "x", str(2**32), "")
_AIRCRAFT = (_values("aerosonde", "unatrap"), _values("cessna", "{absent_toml}", "{bad_toml}",
                                                      "{negative_mass_toml}"))
_OUT = (_values("report", "{empty_dir}"),
        _values("{user_dir}", "{file}", ".", "..", "/proc/drake_uav_out", "{log}"))
_FORMAT = (_values("csv"), _values("xls", "CSV", "txt"))
_LOG = (_values("{log}"), _values("{absent_log}", "{empty_log}", "{odd_log}", "{user_dir}"))

# Sub-command -> (words before the options, positional arguments, options). Positionals and
# options are (name, valid values, invalid values); a flag's valid value is "" (given alone).
COMMANDS = {
    "trim": (["trim"], [], [
        ("--aircraft", *_AIRCRAFT),
        ("--airspeed", _values("25", "18.5"), _number_outside("0", "-3")),
        ("--gamma", _values("0", "5"), _number_outside("90", "-95")),
        ("--turn-rate", _values("0", "0.1"), _NOT_A_NUMBER),
    ]),
    "identify": (["identify"], [("log", *_LOG)], [
        ("--format", *_FORMAT),
        ("--aircraft", *_AIRCRAFT),
        ("--out", *_OUT),
        ("--vanes", _values("VANE.AoA,VANE.SSA"), _values("VANE", "a,b", "A.b,c", "")),
        ("--vane-unit", _values("deg", "rad"), _values("grad", "")),
        ("--extra-channels", _values("BAT.Temp"), _values("BAT", ",", "a.", "BAT.Temp,RPM")),
        ("--seed", _values("0", "7"), _SEED_BAD),
        ("--air-data", _values("auto", "vanes"), _values("pitot", "")),
        ("--propulsion", _values("data", "catalog"), _values("none")),
        ("--max-gap", _values("0.5"), _number_outside("0", "-1")),
        ("--segment", _values("auto", "10:20"), _values("10-20", "20:10", "nan:5", "x", "1:inf")),
        ("--sensor-spec", st.nothing(), _values("{absent_toml}", "{bad_toml}", "{empty_log}")),
        ("--propeller", st.nothing(), _values("{absent_toml}", "{bad_toml}", "{empty_log}",
                                              "{log}")),
        ("--imu-position", _values("0.1,0,0"), _values("1,2", "a,b,c", "nan,0,0", "")),
        ("--coefficients", _values("CL,CD", "Cm"), _values("CX", "", "cl", "CL,,CZ")),
    ]),
    "track": (["track"], [], [
        ("--mode", _values("rti", "nlp"), _values("fast", "")),
        ("--duration", _values("30"), _number_outside("0", "-5", "1.5", "2")),
        ("--offset", _values("0.5", "-1"), _number_outside("1e6", "-101")),
        ("--roll-offset", _values("10"), _number_outside("90", "-120")),
        ("--gust", _values("0", "0.5"), _number_outside("-1")),
        ("--noise", _values(""), st.nothing()),
        ("--seed", _values("0", "3"), _SEED_BAD),
        ("--out", *_OUT),
    ]),
    "fault": (["fault"], [
        ("scenario", st.nothing(), _values("V", "iia", "I,II", "", "all ")),
    ], [
        ("--out", st.nothing(), _values("{user_dir}", "{file}", ".", "..", "/proc/f", "{log}")),
        ("--tube-cache", st.nothing(), _values("{file}", "{log}")),
        ("--coarse-tube", st.nothing(), st.nothing()),
    ]),
    "replay": (["replay"], [("log", *_LOG)], [
        ("--format", *_FORMAT),
        ("--html", _values("page.html"), _values("{log}", "{file}", "{user_dir}", "{empty_dir}")),
        ("--live", _values(""), st.nothing()),
        ("--speed", _values("1", "4"), _number_outside("0", "-1")),
    ]),
    "campaign run": (["campaign", "run"], [
        ("scenario", _values("main_job"),
         _values("os:sep", "os:getcwd", "no_such_scenario", "no_such_module:run", "")),
    ], [
        ("--seeds", _values("0:2", "1,5"), _values("5:1", "x", "-1:2", "0:99999999999", "")),
        ("--grid", _values("speed=20,25"), _values("speed", "=1", "")),
        ("--dist", _values("wind=uniform:0:5", "k=choice:[1,2]"),
         _values("wind=uniform:5:0", "wind=gauss:0:1", "wind", "wind=normal:0:-1",
                 "wind=uniform:a:b", "k=choice:5")),
        ("--param", _values("duration=60"), _values("duration", "=5")),
        ("--out", _values("c.parquet"),
         _values("{file}", "{other_parquet}", "{user_dir}", "/proc/c.parquet")),
        ("--workers", _values("0", "2"), _values("-1", "x", "1.5", "100000")),
        ("--scheduler", st.nothing(), _values("foo", "tcp:/x", "")),
        ("--report", _values("rep"), _values("{user_dir}", "{file}", ".")),
        ("--quiet", _values(""), st.nothing()),
    ]),
    "campaign compare": (["campaign", "compare"], [
        ("baseline", _values("{results}"), _values("{absent}", "{other_parquet}", "{file}")),
        ("result", _values("{results}"), _values("{absent}", "{other_parquet}", "{empty_log}")),
    ], [
        ("--alpha", _values("0.05"), _number_outside("0", "1", "-0.1")),
        ("--metrics", st.nothing(), _values("no_such_metric", ",")),
        ("--json", _values(""), st.nothing()),
        ("--report", _values("rep"), _values("{user_dir}", "{file}", "{results_dir}")),
    ]),
    "campaign report": (["campaign", "report"], [
        ("result", _values("{results}"), _values("{absent}", "{other_parquet}", "{file}")),
    ], [
        ("--baseline", _values("{results}"), _values("{absent}", "{other_parquet}")),
        ("--alpha", _values("0.05"), _number_outside("0", "1")),
        ("--out", _values("rep"), _values("{user_dir}", "{file}", "{results_dir}", ".")),
    ]),
}


def _campaign_scenario(seed: int, params: dict) -> dict:
    return {"ok": True, "value": float(seed)}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, str]:
    """Files the commands read (never written): a log, campaign results, bad files."""
    folder = tmp_path_factory.mktemp("inputs")
    paths = {"log": folder / "flight.csv", "absent_log": folder / "absent.csv",
             "empty_log": folder / "empty.csv", "odd_log": folder / "flight.txt",
             "absent_toml": folder / "absent.toml", "bad_toml": folder / "bad.toml",
             "negative_mass_toml": folder / "heavy.toml", "absent": folder / "absent.parquet",
             "other_parquet": folder / "other.parquet",
             "results_dir": folder / "results", "results": folder / "results" / "c.parquet"}
    FlightLog.load(SAMPLE).slice(0.0, 20.0).save(paths["log"])
    paths["empty_log"].touch()
    paths["odd_log"].write_text("time,x\n0,1\n")
    paths["bad_toml"].write_text("mass = = 3\n")
    paths["negative_mass_toml"].write_text('base = "aerosonde"\nmass = -5.0\n')
    pq.write_table(pa.table({"altitude": [1.0, 2.0]}), paths["other_parquet"])
    run_campaign(Campaign(_campaign_scenario, (0, 1)), paths["results"], workers=0,
                 progress=False)
    return {name: str(path) for name, path in paths.items()}


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "folder" for p in sorted(folder.rglob("*"))}


FLAGS = ("--noise", "--live", "--quiet", "--json", "--coarse-tube")
"""Options that take no value: given or not."""


@st.composite
def command_lines(draw, junk_weight: int = 1) -> tuple[str, list[tuple[str, str]]]:
    """(sub-command, [(option or argument, value)]) with at least one value invalid by
    construction; the others left out (options only), valid, invalid or random text."""
    name = draw(st.sampled_from(sorted(COMMANDS)))
    _, positionals, options = COMMANDS[name]
    choices = [*positionals, *options]
    broken = draw(st.sampled_from([i for i, (_, _, bad) in enumerate(choices)
                                   if not bad.is_empty]))
    given = []
    for i, (option, good, bad) in enumerate(choices):
        if i == broken:
            given.append((option, draw(bad)))
        elif option in FLAGS:
            if draw(st.booleans()):
                given.append((option, ""))
        elif not option.startswith("-") or draw(st.booleans()):
            strategies = [good, bad, *[_JUNK] * junk_weight]
            given.append((option, draw(st.one_of([s for s in strategies if not s.is_empty]))))
    return name, given


def _argv(name: str, given: list[tuple[str, str]], paths: dict[str, str]) -> list[str]:
    """The command line, placeholders ``{name}`` replaced by ``paths``."""
    argv = list(COMMANDS[name][0])
    for option, value in given:
        if value.startswith("{") and value.endswith("}"):
            value = paths[value[1:-1]]
        if not option.startswith("-"):
            argv.append(value)
        elif option in FLAGS:
            argv.append(option)
        else:
            argv.append(f"{option}={value}")
    return argv


def _check_refused(example: tuple[str, list[tuple[str, str]]], inputs: dict[str, str]) -> None:
    """Runs the command line in a fresh folder holding a user's files: exit code 2, one
    ``error:`` line, no file touched there nor among the inputs."""
    inputs_folder = Path(inputs["log"]).parent
    before_inputs = _snapshot(inputs_folder)
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
        work = Path(tmp)
        (work / "mine").mkdir()
        (work / "mine" / "notes.txt").write_text("the user's notes")
        (work / "notes.txt").write_text("not an output of drake_uav")
        (work / "empty").mkdir()
        argv = _argv(*example, {**inputs, "user_dir": str(work / "mine"),
                                "file": str(work / "notes.txt"),
                                "empty_dir": str(work / "empty")})
        before = _snapshot(work)
        stderr, stdout = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(stdout):
            rc = main(argv)
        lines = stderr.getvalue().splitlines()
        assert rc == 2, (argv, rc, stderr.getvalue())
        assert len(lines) == 1 and lines[0].startswith("error: "), (argv, lines)
        assert "Traceback" not in stdout.getvalue()
        assert _snapshot(work) == before, argv
    assert _snapshot(inputs_folder) == before_inputs, argv


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(example=command_lines())
def test_malformed_options_stop_with_one_line_and_touch_nothing(example, inputs):
    _check_refused(example, inputs)


@pytest.mark.slow
@settings(max_examples=1500, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(example=command_lines(junk_weight=3))
def test_many_malformed_options_stop_with_one_line_and_touch_nothing(example, inputs):
    _check_refused(example, inputs)


def test_every_option_of_every_sub_command_is_in_the_table():
    """A new option (or sub-command) must join the table above, valid and invalid values."""
    import argparse

    from drake_uav.cli import _parser

    def commands(parser, prefix=""):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield from commands(sub, f"{prefix}{name} ")
                return
        yield prefix.strip(), sorted(a.option_strings[-1] if a.option_strings else a.dest
                                     for a in parser._actions if a.dest != "help")

    table = {name: sorted(n for n, *_ in [*positionals, *options])
             for name, (_, positionals, options) in COMMANDS.items()}
    assert dict(commands(_parser())) == table
