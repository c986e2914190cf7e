"""Command line: ``drake-uav <command> ...``. A thin layer over library functions.

Every option and every output path is checked before any work and before pydrake loads
(:mod:`drake_uav.arguments`, :mod:`drake_uav.reporting.output`): bad input stops with one line
``error: ...`` and exit code 2; a failure while working exits 1; Ctrl-C exits 130 with the one
line ``interrupted``, leaving no half-written output. Outputs follow the overwrite rule of
:mod:`drake_uav.reporting.output` (docs/cli.md).
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import time
import warnings
from pathlib import Path

# Every array of the command-line jobs is small: one BLAS thread is faster than two
# fighting over the cores (an SVD of 5250 x 10 took 56 ms threaded, 0.6 ms on one), and
# campaign workers inherit it. Set before numpy loads; a user's own setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from drake_uav.arguments import OneLineParser, real, seed  # noqa: E402
from drake_uav.reporting.output import (  # noqa: E402
    check_output_file,
    check_output_folder,
    is_replay_page,
    output_folder,
)

__all__ = ["main"]


def _cmd_trim(args: argparse.Namespace) -> int:
    _check_aircraft(args.aircraft)
    from drake_uav.optimization.linearization import mode_analysis
    from drake_uav.optimization.trim import TrimError, trim
    from drake_uav.vehicles.loading import load_fixed_wing

    params = load_fixed_wing(args.aircraft)
    try:
        result = trim(params, args.airspeed, np.radians(args.gamma), args.turn_rate)
    except TrimError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    e, a, r, t = result.controls
    print(f"{params.name} trim at Va = {args.airspeed:g} m/s, gamma = {args.gamma:g} deg, "
          f"turn rate = {args.turn_rate:g} rad/s")
    print(f"  alpha    = {np.degrees(result.alpha):8.4f} deg")
    print(f"  elevator = {np.degrees(e):8.4f} deg   aileron = {np.degrees(a):8.4f} deg")
    print(f"  rudder   = {np.degrees(r):8.4f} deg   throttle = {t:8.4f}")
    print(f"  residual = {result.residual:.2e}")
    if args.turn_rate == 0.0:
        print(mode_analysis(params, result).table())
    return 0


SAMPLE_FLIGHT = "sample_flight.parquet"
"""Bundled flight (drake_uav/data/): a simulated Aerosonde identification flight with an
effect its catalog model lacks."""


class _Progress:
    """Prints a step's message, and its duration when it took more than a second."""

    def __init__(self):
        self._start = None
        self._message = None

    def __call__(self, message: str) -> None:
        self.finish()
        self._start, self._message = time.perf_counter(), message
        print(f"... {message}", flush=True)

    def finish(self) -> None:
        if self._start is not None:
            elapsed = time.perf_counter() - self._start
            if elapsed > 1.0:
                print(f"    ({self._message}: {elapsed:.1f} s)", flush=True)
        self._start = None


def _vane_fields(text: str) -> list[str]:
    """``"MSG.AoA,MSG.SSA"`` -> the two field names."""
    fields = [f.strip() for f in text.split(",")]
    if len(fields) != 2 or not all("." in f for f in fields):
        raise ValueError(f"--vanes: expected MESSAGE.FIELD,MESSAGE.FIELD, got {text!r}")
    return fields


def _extra_fields(text: str) -> list[str]:
    """``"BAT.Temp,RPM.rpm2"`` -> the field names, each MESSAGE.FIELD."""
    fields = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in fields if not all(f.partition(".")[::2])]
    if bad or not fields:
        raise ValueError(f"--extra-channels: expected MESSAGE.FIELD names separated by commas, "
                         f"got {text!r}")
    return fields


def _vane_sources(text: str, unit: str) -> dict:
    """``"MSG.AoA,MSG.SSA"`` -> FieldSource mapping of the vane channels."""
    from drake_uav.io.streams import FieldSource

    fields = _vane_fields(text)
    scale = np.radians(1.0) if unit == "deg" else 1.0
    return {channel: FieldSource(*field.split(".", 1), unit="rad", scale=scale)
            for channel, field in zip(("vane_alpha", "vane_beta"), fields, strict=True)}


def _cmd_identify(args: argparse.Namespace) -> int:
    path = _sample_flight() if args.log is None else Path(args.log)
    _check_identify_arguments(args, path)
    from drake_uav.identification.pipeline import IdentifyOptions, identify
    from drake_uav.io.readers import read_log
    from drake_uav.reporting.identification_report import result_warnings, write_report
    from drake_uav.vehicles.loading import load_fixed_wing

    # The modules live until the process ends: the cyclic garbage collector need not walk
    # their objects (about 140,000) again at each full collection and at exit.
    gc.freeze()
    params = load_fixed_wing(args.aircraft)
    propeller = None
    if args.propeller:
        from drake_uav.io.propeller_table import read_propeller_table

        propeller = read_propeller_table(args.propeller)
    spec = None
    if args.sensor_spec:
        from drake_uav.vehicles.loading import load_sensor_spec

        spec = load_sensor_spec(args.sensor_spec)
    progress = _Progress()
    progress(f"reading {path}")
    options = {}
    if args.vanes:
        options["extra"] = _vane_sources(args.vanes, args.vane_unit)
    if args.max_gap is not None:
        options["max_gap"] = args.max_gap
    kind = args.format or _LOG_SUFFIXES[path.suffix.lower()]
    segment = None if args.segment == "auto" else _parse_segment(args.segment)
    if kind in ("bin", "ulg", "tlog"):
        # A servo's full throw is the aircraft's full deflection (docs/flight_logs.md).
        options["deflections"] = params.limits.deflections()
        options["extra_channels"] = [f for f in (args.extra_channels or "").split(",") if f]
    if kind == "bin" and segment is not None:
        options["segment"] = segment  # optional streams are judged inside it
    log = read_log(path, format=args.format, **options)
    options = IdentifyOptions(source=str(path), seed=args.seed, air_data=args.air_data,
                              sensor_noise_std=spec, segment=segment,
                              propulsion=args.propulsion,
                              coefficients=_parse_coefficients(args.coefficients),
                              imu_position=_parse_imu_position(args.imu_position),
                              propeller=propeller)
    run = identify(log, params, options, progress=progress)
    design = None
    if run.near_ties:
        from drake_uav.diagrams.manoeuvre_design import propose_manoeuvre

        progress("designing the manoeuvre that separates the near ties")
        try:
            design = propose_manoeuvre(run, propulsion=args.propulsion)
        except (ValueError, RuntimeError) as error:  # the model does not trim or fly
            print(f"note: no manoeuvre proposed: the identified model could not fly it "
                  f"({error})")
    progress("writing the report")
    out = write_report(run, args.out, design)
    progress.finish()
    for note in run.notes:
        print(f"note: {note}")
    for warning in result_warnings(run):
        print(f"warning: {warning}")
    print(run.discovery.message)
    for k, f in run.noise_floors.items():
        print(f"  {k}: equation-error RMS {f.before:.4g} -> {f.after:.4g} (held-out; "
              f"noise floor {f.floor:.4g})")
    names = ("Va [m/s]", "alpha [deg]", "beta [deg]", "p [deg/s]", "q [deg/s]", "r [deg/s]")
    scale = (1.0, *[np.degrees(1.0)] * 5)
    for name, b, a, s in zip(names, run.reconstruction_before.mae,
                             run.reconstruction_after.mae, scale, strict=True):
        print(f"  reconstruction MAE {name}: {b * s:.3g} -> {a * s:.3g}")
    print(f"report: {out / 'report.html'}")
    return 0


def _sample_flight() -> Path:
    path = Path(__file__).parent / "data" / SAMPLE_FLIGHT
    print(f"no log given: using the bundled sample flight {path.name}")
    return path


def _check_identify_arguments(args: argparse.Namespace, log: Path) -> None:
    """Raises ValueError for a bad argument before the analysis stack is imported."""
    _check_log(log, args.format)
    check_output_folder(args.out, inputs=[log])
    kind = args.format or _LOG_SUFFIXES[log.suffix.lower()]
    if args.vanes:
        _vane_fields(args.vanes)
        if kind not in ("bin", "ulg"):
            raise ValueError(f"--vanes: names fields of .bin and .ulg logs, not of a {kind} "
                             "log; in a CSV or Parquet log the vanes are the vane_alpha and "
                             "vane_beta columns")
    if args.extra_channels:
        _extra_fields(args.extra_channels)
        if kind not in ("bin", "ulg", "tlog"):
            raise ValueError("--extra-channels: names fields of .bin, .ulg and .tlog logs; "
                             "every non-canonical column of a CSV or Parquet log is an extra "
                             "channel")
    _check_aircraft(args.aircraft)
    if args.sensor_spec:
        _check_toml(Path(args.sensor_spec), "--sensor-spec")
    if args.propeller:
        _check_readable(Path(args.propeller), "--propeller")
        if args.propulsion != "data":
            raise ValueError("--propeller: the table gives the thrust from the logged RPM; "
                             "it cannot be used with --propulsion catalog")
        from drake_uav.io.propeller_table import read_propeller_table

        read_propeller_table(args.propeller)  # a bad table stops before the analysis
    if args.max_gap is not None and not args.max_gap > 0:
        raise ValueError(f"--max-gap: must be positive, got {args.max_gap:g}")
    if args.max_gap is not None and kind == "parquet":
        raise ValueError("--max-gap: a Parquet log is a saved FlightLog, already on one time "
                         "base; the option cuts the streams of csv, bin, ulg and tlog logs")
    if args.segment != "auto":
        _parse_segment(args.segment)
    _parse_coefficients(args.coefficients)
    _parse_imu_position(args.imu_position)


def _parse_imu_position(text: str | None) -> tuple[float, float, float] | None:
    """``X,Y,Z`` [m] -> floats; None: the log's own (its autopilot parameters)."""
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise ValueError(f"--imu-position: give X,Y,Z in metres (body axes, forward, right, "
                         f"down from the centre of gravity), e.g. 0.2,0,0.05; got {text!r}")
    return values


_COEFFICIENTS = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
"""The coefficients ``identify`` can fit (``drake_uav.model.coefficients.COEFFICIENTS``,
repeated here so that the checks stay light; tests/test_decision_rules.py checks the two
agree)."""


def _parse_coefficients(text: str) -> tuple[str, ...]:
    """``"CL,CD,Cm"`` -> the names, in the order given, each once."""
    names = tuple(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    unknown = [name for name in names if name not in _COEFFICIENTS]
    if unknown or not names:
        raise ValueError(f"--coefficients {text}: "
                         + (f"unknown {', '.join(unknown)}; " if unknown else "")
                         + f"expected names of {','.join(_COEFFICIENTS)} separated by commas "
                         "(CL is the lift, Cl the rolling moment)")
    return names


_LOG_SUFFIXES = {".csv": "csv", ".bin": "bin", ".ulg": "ulg", ".parquet": "parquet",
                 ".pq": "parquet", ".tlog": "tlog"}
"""Log suffix -> format (the readers' table, repeated here so that the checks stay light;
tests/test_cli.py checks the two agree)."""


def _check_log(log: Path, format: str | None) -> None:
    """Raises ValueError unless ``log`` is a readable file of a known (or given) format."""
    _check_readable(log, "LOG")
    if format is None and log.suffix.lower() not in _LOG_SUFFIXES:
        formats = ",".join(sorted(set(_LOG_SUFFIXES.values())))
        raise ValueError(f"{log}: unknown log format {log.suffix or '(no suffix)'!r}; name "
                         f"the format with --format {{{formats}}}")


def _check_readable(path: Path, what: str) -> None:
    if not path.exists():
        raise ValueError(f"{path}: no such file (the {what} argument)")
    if not path.is_file():
        raise ValueError(f"{path}: not a file (the {what} argument)")
    try:
        with path.open("rb") as stream:
            empty = not stream.read(1)
    except OSError as err:
        raise ValueError(f"{path}: cannot be read ({err.strerror or err})") from None
    if empty:
        raise ValueError(f"{path}: empty file")


def _check_toml(path: Path, what: str) -> dict:
    import tomllib

    _check_readable(path, what)
    try:
        return tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not valid TOML ({err}) (the {what} file)") from None


def _check_aircraft(name: str) -> None:
    from drake_uav.vehicles.catalog_names import FIXED_WING_NAMES

    if name in FIXED_WING_NAMES:
        return
    if not name.endswith(".toml"):
        raise ValueError(f"--aircraft {name}: not a catalog aircraft "
                         f"({', '.join(FIXED_WING_NAMES)}) nor a parameter .toml file")
    base = _check_toml(Path(name), "--aircraft").get("base")
    if base is not None and base not in FIXED_WING_NAMES:
        raise ValueError(f"{name}: base = {base!r} is not a catalog aircraft "
                         f"({', '.join(FIXED_WING_NAMES)})")


def _parse_segment(text: str) -> tuple[float, float]:
    """``"T0:T1"`` [s] -> (T0, T1)."""
    try:
        start, end = (float(part) for part in text.split(":"))
    except ValueError:
        raise ValueError(f"--segment {text}: expected auto or START:END in seconds of log "
                         "time, e.g. 120:300") from None
    if not (np.isfinite(start) and np.isfinite(end)):
        raise ValueError(f"--segment {text}: START and END must be finite numbers of seconds")
    if not start < end:
        raise ValueError(f"--segment {text}: START must be before END")
    return start, end


def _replay_page(args: argparse.Namespace) -> Path | None:
    """The page ``replay`` writes (None: served live), checked (docs/cli.md, the overwrite
    rule)."""
    log = Path(args.log)
    _check_log(log, args.format)
    if args.live:
        if args.html:
            raise ValueError("--html: not written with --live (the replay is served instead)")
        return None
    return check_output_file(args.html or log.with_suffix(".html"), ours=is_replay_page,
                             what="--html", inputs=[log])


def _cmd_replay(args: argparse.Namespace) -> int:
    page = _replay_page(args)
    from drake_uav.io.readers import read_log
    from drake_uav.reporting.replay import export_replay_html, replay

    log = read_log(args.log, format=args.format)
    if args.live:
        from pydrake.geometry import StartMeshcat

        meshcat = StartMeshcat()
        replay(log, meshcat, speed=args.speed)
        print(f"replaying {args.log} at {meshcat.web_url()} (Ctrl-C to stop)", flush=True)
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            return 0
    out = export_replay_html(log, page, speed=args.speed)
    print(f"replay: {out}")
    return 0


def _cmd_track(args: argparse.Namespace) -> int:
    check_output_folder(args.out)
    from drake_uav.diagrams.tracking import (
        build_terminal_set,
        fly_tracking,
        solve_time_stats,
        tracking_reference,
    )
    from drake_uav.optimization.nmpc import NmpcSettings
    from drake_uav.reporting.tracking_figures import write_tracking_plots
    from drake_uav.systems.state_sensor import StateNoise
    from drake_uav.vehicles.multirotor import hexacopter

    params = hexacopter()
    print("... terminal sets along the bundled 6-waypoint trajectory", flush=True)
    terminal = build_terminal_set(params, tracking_reference(params))
    duration = terminal.end_time + 2.0 if args.duration is None else args.duration
    print(f"... flying {duration:g} s with the {args.mode} NMPC", flush=True)
    run = fly_tracking(params, terminal, duration, settings=NmpcSettings(mode=args.mode),
                       offset=(args.offset, 0.0, 0.0),
                       attitude_offset=np.radians(args.roll_offset),
                       gust_sigma=args.gust, seed=args.seed,
                       sensor_noise=StateNoise() if args.noise else None)
    stats = solve_time_stats(run)
    print(f"position RMSE after 2 s: {100 * run.rmse(2.0):.2f} cm "
          f"(max error after 2 s {100 * run.position_error[run.time >= 2].max():.2f} cm)")
    print(f"solve time: median {1e3 * stats['median']:.1f} ms, p95 {1e3 * stats['p95']:.1f} "
          f"ms, max {1e3 * stats['max']:.1f} ms; fallback steps {int((run.status != 0).sum())}"
          f" of {len(run.status)}")
    for path in write_tracking_plots(run, Path(args.out)):
        print(f"plot: {path}")
    return 0


FAULT_SCENARIOS = ("I", "IIa", "IIb", "IIIa", "IIIb", "IVa", "IVb")
"""Names of the ch. 6 scenarios (drake_uav.diagrams.fault_scenarios.SCENARIOS, repeated so
that the checks run before pydrake loads; tests/test_faults_cli.py checks they agree)."""


def _check_fault_arguments(args: argparse.Namespace) -> tuple[str, ...]:
    """The scenario names to fly; raises ``ValueError`` for an unknown name or an output
    folder the overwrite rule refuses (docs/cli.md)."""
    if args.scenario != "all" and args.scenario not in FAULT_SCENARIOS:
        raise ValueError(f"fault {args.scenario}: unknown scenario; choose one of "
                         f"{', '.join(FAULT_SCENARIOS)} or all")
    check_output_folder(args.out)
    if args.tube_cache is not None and Path(args.tube_cache).exists() \
            and not Path(args.tube_cache).is_dir():
        raise ValueError(f"--tube-cache {args.tube_cache}: not a folder")
    return FAULT_SCENARIOS if args.scenario == "all" else (args.scenario,)


def _cmd_fault(args: argparse.Namespace) -> int:
    names = _check_fault_arguments(args)
    from drake_uav.diagrams.fault_scenarios import (
        fault_vehicle,
        fly_scenario,
        scenario,
        scenario_tubes,
    )
    from drake_uav.optimization.reachability import TubeSettings
    from drake_uav.reporting.fault_figures import (
        summary_row,
        summary_table,
        write_fault_outputs,
    )

    params = fault_vehicle()
    tubes = scenario_tubes(params, TubeSettings.coarse() if args.coarse_tube else None,
                           args.tube_cache)
    out = Path(args.out)
    rows, files = [], []
    with output_folder(out, "fault scenarios") as partial:
        for name in names:
            sc = scenario(name)
            print(f"... {name}: {sc.description}", flush=True)
            run = fly_scenario(sc, params, tube_for=tubes)
            rows.append(summary_row(name, run))
            print(f"    category {run.category.name} at {run.switch_time:.3g} s; "
                  + (f"touchdown at {run.touchdown.time:.2f} s, "
                     f"{run.touchdown.vertical_speed:.2f} m/s down" if run.touchdown
                     else "in the air at the end"), flush=True)
            files += [p.name for p in write_fault_outputs(run, name, partial)]
        table = summary_table(rows)
        (partial / "summary.md").write_text(
            "# Motor-failure scenarios (Argyropoulos 2020, ch. 6)\n\nNED, north = x and east "
            "= -y of the source; fault vehicle: hexacopter with f_max = 10 N.\n\n" + table
            + "\n")
    for name in files:
        print(f"    {out / name}")
    print(table)
    print(f"summary: {out / 'summary.md'}")
    return 0


def _add_log_arguments(command: argparse.ArgumentParser, optional: bool) -> None:
    """The flight-log argument and its ``--format`` option of a sub-command."""
    command.add_argument("log", nargs="?" if optional else None,
                         help="flight log (.csv, .bin, .ulg, .tlog, .parquet)")
    command.add_argument("--format", choices=("csv", "bin", "ulg", "tlog", "parquet"),
                         help="log format (default: from the file extension)")


def _trim_parser(sub) -> None:
    """The ``trim`` sub-command."""
    trim = sub.add_parser("trim", help="trim a fixed wing and print its modes",
                          description="Trim a fixed-wing aircraft and print the trim and the "
                                      "classical modes of its linearisation.")
    trim.add_argument("--aircraft", default="aerosonde",
                      help="catalog name (aerosonde, unatrap, ...) or a params .toml file")
    trim.add_argument("--airspeed", type=real(above=0.0, unit="m/s"), default=25.0,
                      help="airspeed [m/s]")
    trim.add_argument("--gamma", type=real(above=-90.0, below=90.0, unit="deg"), default=0.0,
                      help="flight path angle [deg]")
    trim.add_argument("--turn-rate", type=real(unit="rad/s"), default=0.0,
                      help="turn rate [rad/s]")
    trim.set_defaults(handler=_cmd_trim)


def _identify_parser(sub) -> None:
    """The ``identify`` sub-command."""
    ident = sub.add_parser(
        "identify", help="fit the model to a flight log, find the missing effect, report",
        description="Fit the aerodynamic model to a flight log, study the residual, trace it "
                    "to the physical effect the model lacks, add it, and write a report with "
                    "the errors before and after. Without LOG, runs on a bundled sample flight.")
    _add_log_arguments(ident, optional=True)
    ident.add_argument("--aircraft", default="aerosonde",
                       help="catalog name or a params .toml file (default: aerosonde)")
    ident.add_argument("--out", default="drake_uav_report",
                       help="report folder: new, empty, or an earlier report (replaced); a "
                            "folder holding other files is refused (docs/cli.md)")
    ident.add_argument("--vanes", metavar="MSG.AOA,MSG.SSA",
                       help="log fields of the alpha and beta vanes (.bin message or .ulg "
                            "topic and field), e.g. VANE.AoA,VANE.SSA")
    ident.add_argument("--vane-unit", choices=("deg", "rad"), default="deg",
                       help="unit of the vane fields (default: deg)")
    ident.add_argument("--extra-channels", metavar="MSG.FIELD,...",
                       help="more logged fields (.bin message or .ulg topic and field) tested "
                            "as candidate explanations, beside the battery voltage and current "
                            "and the ESC speed, e.g. BAT.Temp,RPM.rpm2")
    ident.add_argument("--seed", type=seed, default=0,
                       help="seed of the Monte-Carlo uncertainty of the measured coefficients")
    ident.add_argument("--air-data", choices=("auto", "vanes", "estimate", "ahrs"),
                       default="auto",
                       help="alpha and beta from the vanes, estimated from IMU, attitude, GPS "
                            "and pitot (smoother), or the autopilot's own AHRS estimate "
                            "(ArduPlane AOA/SSA); auto: vanes when logged, else estimate")
    ident.add_argument("--propulsion", choices=("data", "catalog"), default="data",
                       help="thrust identified with the drag from the data (from the RPM when "
                            "logged; the catalog model when the throttle hardly varies, with a "
                            "warning), or the aircraft's propulsion model")
    ident.add_argument("--propeller", metavar="FILE",
                       help="declared propeller table (.csv or .toml: diameter [m], J, C_T, "
                            "optionally C_Q or C_P; docs/main_job.md): the thrust from the "
                            "logged RPM and C_T(J), nothing of it fitted")
    ident.add_argument("--max-gap", type=real(above=0.0, unit="s"), metavar="SECONDS",
                       help="longest gap inside a stream before the log is cut into segments "
                            "(default 0.5 s)")
    ident.add_argument("--segment", default="auto", metavar="auto|START:END",
                       help="log time span to use [s]; auto: the airborne segments")
    ident.add_argument("--sensor-spec", metavar="FILE",
                       help="declared sensor noise (TOML table [noise_std]: channel = { std = "
                            "..., unit = \"...\" }); default: estimated from the data")
    ident.add_argument("--imu-position", metavar="X,Y,Z",
                       help="where the IMU sits from the centre of gravity [m], body axes "
                            "forward, right, down; the accelerometers are moved to the centre "
                            "of gravity (default: the log's INS_POS<n>_* or EKF2_IMU_POS_* "
                            "parameters, else none)")
    ident.add_argument("--coefficients", default=",".join(_COEFFICIENTS),
                       metavar="CL,CD,...",
                       help="coefficients to fit, of CL,CD,CY (lift, drag, side force), "
                            "Cl,Cm,Cn (roll, pitch, yaw moments); one that does not vary in "
                            "the log is skipped with a note (default: all six)")
    ident.set_defaults(handler=_cmd_identify)


def _track_parser(sub) -> None:
    """The ``track`` sub-command."""
    track = sub.add_parser(
        "track", help="fly the bundled trajectory with the tracking NMPC, print RMSE, plot",
        description="Track a minimum-snap trajectory with the hexacopter and the tracking "
                    "NMPC with time-varying terminal sets; print the position RMSE and the "
                    "solve-time statistics and write plots.")
    track.add_argument("--mode", choices=("rti", "nlp"), default="rti",
                       help="real-time iteration (one SQP step) or the full NLP")
    track.add_argument("--duration", type=real(above=2.0, unit="s",
                                               why="the errors are measured after 2 s"),
                       help="simulated time [s] (default: trajectory + 2 s)")
    track.add_argument("--offset", type=real(at_least=-100.0, at_most=100.0, unit="m"),
                       default=0.5, help="initial north offset [m]")
    track.add_argument("--roll-offset", type=real(above=-90.0, below=90.0, unit="deg"),
                       default=10.0, help="initial roll [deg]")
    track.add_argument("--gust", type=real(at_least=0.0, unit="N"), default=0.0,
                       help="gust force std [N]")
    track.add_argument("--noise", action="store_true",
                       help="the controller reads a noisy state (2 cm, 0.01 rad, 5 cm/s, "
                            "0.02 rad/s std)")
    track.add_argument("--seed", type=seed, default=0, help="seed of the gusts and the noise")
    track.add_argument("--out", default="drake_uav_track",
                       help="plot folder: new, empty, or earlier plots (replaced); a folder "
                            "holding other files is refused (docs/cli.md)")
    track.set_defaults(handler=_cmd_track)


def _fault_parser(sub) -> None:
    """The ``fault`` sub-command."""
    fault = sub.add_parser(
        "fault", help="fly the motor-failure scenarios of Argyropoulos 2020, ch. 6",
        description="Fly one or all of the seven motor-failure scenarios (I, IIa, IIb, IIIa, "
                    "IIIb, IVa, IVb) of Argyropoulos 2020, ch. 6 on the fault hexacopter "
                    "(f_max = 10 N): the failure is classified into categories I-IV and the "
                    "category's controller flies it. Coordinates are NED with north = x and "
                    "east = -y of the source. Writes per scenario a 3-D path with the unsafe "
                    "disc, the states, the thrusts with the failed motors marked, and a log "
                    "that 'drake-uav replay' draws, plus summary.md.")
    fault.add_argument("scenario", help=f"{', '.join(FAULT_SCENARIOS)} or all")
    fault.add_argument("--out", default="drake_uav_fault",
                       help="output folder: new, empty, or earlier fault outputs (replaced); "
                            "a folder holding other files is refused (docs/cli.md)")
    fault.add_argument("--tube-cache", default=None,
                       help="folder of the recovery tubes' cache (default: the library's)")
    fault.add_argument("--coarse-tube", action="store_true",
                       help="coarse recovery tubes (seconds to compute, for a quick look)")
    fault.set_defaults(handler=_cmd_fault)


def _replay_parser(sub) -> None:
    """The ``replay`` sub-command."""
    play = sub.add_parser(
        "replay", help="3-D replay of a flight log in Meshcat (static HTML or live)",
        description="Replay a fixed-wing or multirotor flight log in 3-D: vehicle, trail, "
                    "reference, unsafe disc, failed motors in red. Writes one self-contained "
                    "HTML page (no server, no network), or serves it live with --live.")
    _add_log_arguments(play, optional=False)
    play.add_argument("--html", help="output page (default: the log's name with .html); an "
                                     "existing file is replaced only if it is a replay page, "
                                     "never the log")
    play.add_argument("--live", action="store_true", help="serve it in Meshcat instead")
    play.add_argument("--speed", type=real(above=0.0), default=1.0,
                      help="replay speed (default 1)")
    play.set_defaults(handler=_cmd_replay)


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="drake-uav",
        description="Small unmanned aircraft on Drake: trim, simulate, estimate and identify.",
        epilog="Exit codes: 0 done, 1 failed while working (or a campaign regression), 2 bad "
               "input (one line error: ...), 130 interrupted (Ctrl-C). Outputs are written "
               "only into a new or empty folder or over an earlier output of drake-uav, never "
               "over other files (docs/cli.md).",
    )
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    _trim_parser(sub)
    _identify_parser(sub)
    _track_parser(sub)
    _fault_parser(sub)
    _replay_parser(sub)

    from drake_uav.campaigns.command import add_campaign_parser

    add_campaign_parser(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line each, without the source line they were raised from."""
    print(f"warning: {message}", file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``drake-uav`` console script; returns the exit code: 0 done,
    1 failed while working, 2 bad input (one line ``error: ...``), 130 interrupted."""
    warnings.showwarning = _show_warning
    try:
        parser = _parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        return args.handler(args)
    except ValueError as err:
        print(f"error: {_one_line(err)}", file=sys.stderr)
        return 2
    except OSError as err:  # the disk, not the input: a full disk, a folder removed meanwhile
        print(f"error: {_one_line(err)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__


if __name__ == "__main__":
    sys.exit(main())
