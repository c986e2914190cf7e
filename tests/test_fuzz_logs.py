"""Corrupt and truncated logs: every outcome is a FlightLog or one clear error, never a traceback.

Property-based (hypothesis): logs of every format the readers take (ArduPilot ``.bin``,
PX4 ``.ulg``, MAVLink ``.tlog``, CSV, Parquet), seeded from real logs (tests/data) and the
bundled sample flight, are damaged as an SD card, a copy or a hand edit damages them:
truncated at any byte, bytes flipped, the header overwritten, records duplicated or
swapped (a telemetry log's records too: a radio link repeats and reorders them); CSV
columns dropped, cells made empty, NaN or text, rows out of time order, in the
single-time and the time-per-group layouts; Parquet columns of the wrong type, a unit
lost, the footer cut. Then

* ``read_log`` returns a FlightLog or raises FlightLogError with one line naming the file,
  and the parsers print nothing (their reports become at most a few warnings);
* ``drake-uav identify LOG --out REPORT`` exits 0 with a complete report, or exits 2 with
  exactly one ``error:`` line naming the file and no report; it touches no file outside the
  report folder (the folder holding the log, also the current folder, is compared before
  and after).

The default suite runs a few examples per format (derandomised, so CI sees the same ones);
``-m slow`` runs many more, drawn afresh.
"""

from __future__ import annotations

import hashlib
import io
import shutil
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from log_writers import dataflash_from_log, grouped_csv_from_log, ulog_from_log

import drake_uav
from drake_uav.cli import main
from drake_uav.io import FlightLog, FlightLogError, read_log
from drake_uav.io.realistic_ardupilot import write_ardupilot_log
from drake_uav.io.realistic_px4 import write_px4_log
from drake_uav.io.tlog_writer import write_tlog
from drake_uav.vehicles import aerosonde

DATA = Path(__file__).parent / "data"
SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
FORMATS = ("bin", "ulg", "tlog", "csv", "parquet")
MAX_WARNINGS = 12
"""Warnings one read may give: one per problem found, never one per corrupt byte."""

FAST = settings(max_examples=12, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
FAST_CLI = settings(FAST, max_examples=2)
SLOW = settings(FAST, max_examples=150, derandomize=False)
SLOW_CLI = settings(FAST, max_examples=25, derandomize=False)


# ------------------------------------------------------------------------------ corpus
@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> dict[str, list[Path]]:
    """Seed logs per format: real autopilot logs and a 30 s slice of the bundled sample
    written in each format (a fixed-wing flight every reader accepts), for ``.bin`` and
    ``.ulg`` both with every channel at one rate and as a realistic autopilot log (ground
    segment, servo parameters, flight modes, sensors at their own rates), for ``.tlog``
    at the log's rate and at telemetry rates, for CSV with one time column and with a time
    column per group."""
    folder = tmp_path_factory.mktemp("corpus")
    sample = FlightLog.load(SAMPLE).slice(0.0, 30.0)
    return {
        "bin": [DATA / "ardupilot_center_0003.bin", dataflash_from_log(sample, folder / "s.bin"),
                write_ardupilot_log(sample, folder / "r.bin", seed=3).path],
        "ulg": [DATA / "px4_sample_log_small.ulg", ulog_from_log(sample, folder / "s.ulg"),
                write_px4_log(sample, folder / "r.ulg", seed=3).path],
        "tlog": [write_tlog(sample.slice(0.0, 10.0), folder / "s.tlog"),
                 write_tlog(sample, folder / "low.tlog",
                            rates={"imu": 10, "attitude": 10, "commands": 3, "air": 5,
                                   "position": 2})],
        "csv": [sample.save(folder / "s.csv"),
                grouped_csv_from_log(sample.slice(0.0, 10.0), folder / "g.csv",
                                     {"imu": 100, "commands": 3, "gps": 5})],
        "parquet": [sample.save(folder / "s.parquet")],
    }


# --------------------------------------------------------------------------- mutations
# Strategies draw a small description of the damage (what hypothesis prints for a failing
# example); the apply functions make the damaged bytes from it.
@st.composite
def byte_damage(draw, size: int) -> tuple:
    """A truncation, flipped bytes, an overwritten header, or duplicated / swapped records
    (byte ranges copied or exchanged, so whole messages repeat or change places)."""
    kind = draw(st.sampled_from(["truncate", "flip", "header", "duplicate", "swap"]))
    if kind == "truncate":
        return kind, draw(st.integers(1, size - 1))
    if kind == "flip":
        return kind, draw(st.lists(st.tuples(st.integers(0, size - 1), st.integers(1, 255)),
                                   min_size=1, max_size=16))
    if kind == "header":
        return kind, draw(st.binary(min_size=1, max_size=600))
    start = draw(st.integers(0, size - 2))
    length = draw(st.integers(1, min(4000, size - start - 1)))
    if kind == "duplicate":
        return kind, start, length, draw(st.integers(0, size)), draw(st.integers(1, 3))
    return kind, start, length, draw(st.integers(start + length, size - 1))


def damage_bytes(raw: bytes, damage: tuple) -> bytes:
    kind, *args = damage
    if kind == "truncate":
        return raw[:args[0]]
    if kind == "flip":
        out = bytearray(raw)
        for at, xor in args[0]:
            out[at] ^= xor
        return bytes(out)
    if kind == "header":
        return args[0] + raw[len(args[0]):]
    start, length, *rest = args
    piece = raw[start:start + length]
    if kind == "duplicate":
        at, times = rest
        return raw[:at] + piece * times + raw[at:]
    other = rest[0]  # swap with a range after it
    second = raw[other:other + length]
    return raw[:start] + second + raw[start + length:other] + piece + raw[other + len(second):]


CELLS = ("", "nan", "NaN", "inf", "-inf", "abc", "1e400", "0x1F", "1;5", "--", "1e300", "  ")
HEADERS = ("x [furlong]", "imu_ax", "time [h]", "imu_p [m]", "", "[]", "time [s]")


@st.composite
def csv_damage(draw, columns: int, rows: int, size: int) -> tuple:
    """A column dropped, a cell empty / NaN / inf / text / absurd, rows out of time order or
    repeated, a column's name or unit mangled, or damage to the bytes."""
    kind = draw(st.sampled_from(["column", "cell", "swap_rows", "repeat_row", "header",
                                 "bytes"]))
    if kind == "bytes":
        return kind, draw(byte_damage(size))
    column, row = draw(st.integers(0, columns - 1)), draw(st.integers(0, rows - 2))
    if kind == "cell":
        return kind, column, row, draw(st.sampled_from(CELLS))
    if kind == "swap_rows":
        return kind, row, draw(st.integers(row + 1, rows - 1))
    if kind == "header":
        return kind, column, draw(st.sampled_from(HEADERS))
    return kind, column, row


def damage_csv(raw: bytes, damage: tuple) -> bytes:
    kind, *args = damage
    if kind == "bytes":
        return damage_bytes(raw, args[0])
    lines = raw.decode().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    table = [line.split(",") for line in lines[head:]]  # header, then the rows
    if kind == "column":
        table = [[c for j, c in enumerate(cells) if j != args[0]] for cells in table]
    elif kind == "cell":
        column, row, text = args
        table[1 + row][column] = text
    elif kind == "swap_rows":
        a, b = args
        table[1 + a], table[1 + b] = table[1 + b], table[1 + a]
    elif kind == "repeat_row":
        table.insert(1 + args[1], table[1 + args[1]])
    else:
        table[0][args[0]] = args[1]
    return ("\n".join(lines[:head] + [",".join(cells) for cells in table]) + "\n").encode()


@st.composite
def parquet_damage(draw, columns: int, size: int) -> tuple:
    """A column of the wrong type (text, integer, boolean, null, float32), a column or its
    unit dropped, the footer cut, or damage to the bytes."""
    kind = draw(st.sampled_from(["dtype", "column", "unit", "footer", "bytes"]))
    if kind == "bytes":
        return kind, draw(byte_damage(size))
    if kind == "footer":
        return kind, draw(st.integers(1, min(4000, size - 1)))
    column = draw(st.integers(0, columns - 1))
    if kind == "dtype":
        return kind, column, draw(st.sampled_from(["string", "int", "bool", "null",
                                                   "float32"]))
    return kind, column


def damage_parquet(raw: bytes, damage: tuple) -> bytes:
    kind, *args = damage
    if kind == "bytes":
        return damage_bytes(raw, args[0])
    if kind == "footer":
        return raw[:len(raw) - args[0]]
    table = pq.read_table(io.BytesIO(raw))
    i, field = args[0], table.schema.field(args[0])
    if kind == "column":
        table = table.remove_column(i)
    elif kind == "unit":
        table = table.set_column(i, field.with_metadata({}), table.column(i))
    else:
        values = table.column(i).to_numpy()
        array = {"string": lambda: pa.array([f"{v:.3f}" for v in values]),
                 "int": lambda: pa.array(values.astype(np.int64)),
                 "bool": lambda: pa.array(values > np.median(values)),
                 "null": lambda: pa.nulls(len(values), pa.float64()),
                 "float32": lambda: pa.array(values.astype(np.float32))}[args[1]]()
        table = table.set_column(i, pa.field(field.name, array.type, metadata=field.metadata),
                                 array)
    sink = io.BytesIO()
    pq.write_table(table, sink)
    return sink.getvalue()


def damaged(draw, corpus: dict[str, list[Path]], kind: str, folder: Path) -> Path:
    """A damaged copy of one of ``kind``'s seed logs in ``folder``."""
    seed = draw(st.sampled_from(corpus[kind]))
    raw = seed.read_bytes()
    if kind == "csv":
        lines = raw.decode().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        columns, rows = len(lines[head].split(",")), len(lines) - head - 1
        raw = damage_csv(raw, draw(csv_damage(columns, rows, len(raw))))
    elif kind == "parquet":
        columns = pq.read_schema(seed).__len__()
        raw = damage_parquet(raw, draw(parquet_damage(columns, len(raw))))
    else:
        raw = damage_bytes(raw, draw(byte_damage(len(raw))))
    path = folder / f"flight{seed.suffix.lower()}"
    path.write_bytes(raw)
    return path


# ------------------------------------------------------------------------------ checks
def snapshot(folder: Path, leave_out: Path | None = None) -> dict[str, str]:
    """Relative path -> content digest of every file under ``folder`` (``leave_out`` and
    what it holds excepted)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*"))
            if p.is_file() and not (leave_out and p.is_relative_to(leave_out))}


def check_read(path: Path, capfd) -> None:
    """read_log (with the options ``drake-uav identify`` gives an autopilot log) gives a
    FlightLog or one FlightLogError line naming the file; the parsers print nothing and the
    folder is unchanged."""
    options = ({"deflections": aerosonde().limits.deflections(), "extra_channels": []}
               if path.suffix in (".bin", ".ulg") else {})
    before = snapshot(path.parent)
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            log = read_log(path, **options)
        except FlightLogError as err:
            message = str(err)
            assert str(path) in message and "\n" not in message, message
        else:
            assert len(log) > 0
    printed = capfd.readouterr()
    assert printed.out == "" and printed.err == "", (printed.out + printed.err)[:500]
    assert len(caught) <= MAX_WARNINGS, [str(w.message) for w in caught]
    assert snapshot(path.parent) == before


def check_identify(path: Path, capfd, monkeypatch) -> None:
    """``drake-uav identify`` exits 0 with a report or 2 with one ``error:`` line naming the
    file; nothing outside the report folder changes (the log's folder is the current one)."""
    folder, out = path.parent, path.parent / "report"
    monkeypatch.chdir(folder)
    before = snapshot(folder)
    capfd.readouterr()
    with warnings.catch_warnings():  # main() installs its one-line warning format
        code = main(["identify", str(path), "--out", str(out)])
    printed = capfd.readouterr()
    errors = [line for line in printed.err.splitlines() if line.startswith("error:")]
    assert code in (0, 2), (code, printed.err[-2000:])
    if code == 0:
        assert (out / "report.html").is_file() and (out / "summary.json").is_file()
        assert errors == []
    else:
        assert len(errors) == 1 and str(path) in errors[0], printed.err[-2000:]
        assert not out.exists()
    assert snapshot(folder, leave_out=out) == before


def fresh(tmp_path: Path) -> Path:
    """An empty folder for one example (hypothesis runs many in one test call)."""
    folder = tmp_path / "case"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    return folder


# ------------------------------------------------------------------------------- tests
@pytest.mark.parametrize("kind", FORMATS)
@FAST
@given(data=st.data())
def test_damaged_log_reads_or_fails_cleanly(kind, data, corpus, tmp_path, capfd):
    check_read(damaged(data.draw, corpus, kind, fresh(tmp_path)), capfd)


@pytest.mark.parametrize("kind", FORMATS)
@FAST_CLI
@given(data=st.data())
def test_identify_on_damaged_log_reports_or_fails_cleanly(kind, data, corpus, tmp_path, capfd,
                                                          monkeypatch):
    check_identify(damaged(data.draw, corpus, kind, fresh(tmp_path)), capfd, monkeypatch)


@pytest.mark.slow
@pytest.mark.parametrize("kind", FORMATS)
@SLOW
@given(data=st.data())
def test_many_damaged_logs_read_or_fail_cleanly(kind, data, corpus, tmp_path, capfd):
    check_read(damaged(data.draw, corpus, kind, fresh(tmp_path)), capfd)


@pytest.mark.slow
@pytest.mark.parametrize("kind", FORMATS)
@SLOW_CLI
@given(data=st.data())
def test_identify_on_many_damaged_logs(kind, data, corpus, tmp_path, capfd, monkeypatch):
    check_identify(damaged(data.draw, corpus, kind, fresh(tmp_path)), capfd, monkeypatch)


def test_corrupt_bin_gives_one_line_not_one_per_byte(corpus, tmp_path, capfd):
    """150 zeroed bytes inside a .bin: pymavlink's per-byte reports become one warning."""
    raw = bytearray(corpus["bin"][1].read_bytes())
    middle = len(raw) // 2
    raw[middle:middle + 150] = bytes(150)
    path = tmp_path / "corrupt.bin"
    path.write_bytes(bytes(raw))
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_log(path)
    printed = capfd.readouterr()
    assert printed.out == "" and printed.err == ""
    corrupt = [str(w.message) for w in caught if "skipped" in str(w.message)]
    assert len(corrupt) == 1 and corrupt[0].startswith(f"{path}: "), corrupt


def test_absurd_value_is_refused_at_the_reader(tmp_path):
    """A number no sensor logs (a flipped exponent bit) is refused naming file, channel and
    time, before any estimate uses it."""
    sample = FlightLog.load(SAMPLE).slice(0.0, 5.0)
    q = sample["imu_q"].copy()
    q[100] = 4.5e85
    channels = {n: (q if n == "imu_q" else sample[n]) for n in sample.measured_names}
    log = FlightLog(sample.time, channels, {}, {n: sample.unit(n) for n in channels}, {})
    path = log.save(tmp_path / "absurd.parquet")
    with pytest.raises(FlightLogError) as raised:
        read_log(path)
    assert str(raised.value) == (
        f"{path}: channel imu_q holds 4.5e+85 rad/s at t = {sample.time[100]:.6g} s (sample "
        "100; 1 such sample(s)), beyond any sensor's range (|value| > 100000 rad/s): "
        "corrupt data")


def test_parquet_with_a_cut_footer_fails_on_one_line(corpus, tmp_path):
    """pyarrow's message spans lines; the error the command prints is one line."""
    path = tmp_path / "cut.parquet"
    path.write_bytes(corpus["parquet"][0].read_bytes()[:-100])
    with pytest.raises(FlightLogError) as raised:
        read_log(path)
    message = str(raised.value)
    assert message.startswith(f"{path}: not a readable Parquet file (") and "\n" not in message


def test_flight_log_error_is_one_line():
    """A parser's message quoted in a FlightLogError keeps its words, not its line breaks."""
    error = FlightLogError("f.parquet: not a readable Parquet file (Couldn't deserialize "
                           "thrift: Invalid data\nDeserializing page header failed.\n)")
    assert str(error) == ("f.parquet: not a readable Parquet file (Couldn't deserialize "
                          "thrift: Invalid data Deserializing page header failed. )")


def test_parquet_time_in_float32_is_refused(corpus, tmp_path):
    """float32 sample times jitter by a part in 10^4 at 30 s: refused at the reader, before
    the job's differentiation finds them non-uniform."""
    path = tmp_path / "float32.parquet"
    path.write_bytes(damage_parquet(corpus["parquet"][0].read_bytes(), ("dtype", 0, "float32")))
    with pytest.raises(FlightLogError) as raised:
        read_log(path)
    assert str(raised.value) == (f"{path}: column 'time' is stored as float; sample times "
                                 "need float64 (double) to stay uniform")
