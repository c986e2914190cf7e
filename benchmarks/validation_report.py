"""docs/validation.md: the detection campaign's figures as a page, written by the benchmark.

``python benchmarks/bench_discovery.py ... --markdown docs/validation.md`` summarises the
cells it ran (:func:`cell_summary`), merges them into the page's data file
(``docs/validation.json``: one entry per flight and cell, each with the command that
measured it and its date) and renders the page from every cell in it (:func:`render`), so
a run replaces the cells it measured and keeps the others. The page is never edited by
hand; ``python benchmarks/validation_report.py`` renders it again from the data file, and
``--check`` (or ``--quick``, which CI runs) exits with status 1 when the page is not what
its data file renders.

Data file layout: ``{"flights": {FLIGHT: {"excitation", "duration_s", "cells": {CELL:
{...}}}}}`` with FLIGHT ``"<excitation> <duration> s"`` and CELL ``"<suite> <turbulence>
<size>"``; a cell holds ``suite``, ``turbulence``, ``size``, ``command``, ``measured``
(date), ``clean`` (``flights``, ``with_finding``, ``named``: finding -> count), ``runs``,
``flights_per_effect``, ``exact``, ``partial``, ``tied``, ``misses``, ``findings``,
``false_findings``, ``detections_explained`` (detections whose excess error was above
the floor), ``explained_70`` (of those, the ones explaining at least 70 %),
``explained_median``, ``target`` (the exact rate the cell is held to, or null),
``family`` (flights found exactly or as a member of the family a finding names),
``family_target`` (the family rate the cell is held to, or null) and ``effects`` (effect ->
``expected``, ``exact``, ``partial``, ``misnamed``, ``missed``, ``tied``, ``family``). A
figure that was not recorded is null and rendered as "-".
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import math
import statistics
from pathlib import Path

from drake_uav.campaigns import wilson_interval

__all__ = ["cell_summary", "render", "update"]

DOCS = Path(__file__).resolve().parents[1] / "docs"

FLIGHT_NAMES = {
    "multisine": "The airspeed hold's flight (three-axis multisine, throttle held by the "
                 "airspeed loop)",
    "multisine_throttle": "The throttle flight (a fourth multisine on the throttle)",
}

INJECTED_DESCRIPTIONS = {
    "propwash_drag": "C_D += k T_c",
    "stall_onset": "C_L -= k alpha^3",
    "elevator_roll": "C_l += k delta_e",
    "elevator_squared": "C_m += k delta_e^2",
    "roll_yaw_rate_pitch": "C_m += k p_hat r_hat",
    "alphadot_pitch": "C_m_alphadot = -k in the aircraft flown (a downwash lag)",
    "servo_delay": "surfaces and throttle k s behind the logged commands",
    "tow_force": "k N along +x body at the centre of gravity",
    "tow_below_cg": "the same force 0.3 m below the centre of gravity",
    "drag_drift": "C_D grows by k over the flight",
    "air_data_skew": "pitot and vanes logged k s (whole samples) late against the IMU",
    "pull_to_point": "k N towards a ground point 400 m beside the middle of the track",
    "logged_tension": "a tether along -x body, its tension (mean 3k N, std k N) logged "
                      "as `tension`",
}
"""What each campaign effect puts into the flight (the benchmark's scenario)."""

INTRO = """\
How often the main job names an effect the aircraft's model lacks, and how often it names
one that is not there. Each run flies an identification flight of the aerosonde in
simulation (its length is in each section's title) with one effect the catalog model
lacks (or none: a *clean* flight) and runs `drake-uav identify` with the catalog model
on the measured channels alone, as an autopilot writes them: no truth channel, no
simulator metadata. An effect's *size* is the share it adds to the variation of the
coefficient it acts on. Sensor suites: `default` (the low-cost suite of Vaiopoulos 2017,
Table 7) and `research` (accelerometer 0.02 m/s^2, gyro 0.1 deg/s, vanes 0.1 deg,
dynamic pressure 2 Pa).

How to read the tables:

* *exact*: the injected effect and nothing else; *partial*: it with other findings;
  *misnamed*: other findings without it; *missed*: nothing found.
* *family*: exact, or every finding names the injected effect among the members of its
  family: the report names the family (a drag-axis family, for instance) and lists the
  alternatives the flight cannot tell apart from the finding, its aliases (terms of another
  physical origin whose columns move with its own) and its near ties (docs/main_job.md,
  "Families"). It is the rate at which the job points at the right family of effects and
  nothing else; *exact* is the rate at which it names the right member alone.
* *found or near tie*: exact, partial, or not found but named by the report as a
  near-tied alternative of the finding that took its place (the flight cannot tell them
  apart; docs/main_job.md, "Near ties").
* *findings not injected*: findings other than the injected effect, of all findings.
* *excess explained*: where the effect was found, the share of the held-out error above
  the noise floor that the update removed (1 = down to the floor).
* Rates carry their 95 % Wilson interval. Targets: clean flights with a finding at most
  5 %; exact at least 70 % with the default sensors at 30 %, at least 90 % with
  research-grade ones at 20 %; family at least 95 % with research-grade sensors at 20 %;
  at least 70 % of the excess explained in 70 % of the detections.
"""


def _finite(value) -> bool:
    return value is not None and math.isfinite(value)


def _findings(row: dict) -> list[str]:
    return [name for name in str(row["found"]).split(",") if name]


def cell_summary(effect_rows: list[dict], clean_rows: list[dict], *, suite: str,
                 turbulence: str, size: float, target: float | None,
                 expected: dict[str, str], family_target: float | None = None) -> dict | None:
    """The figures of one cell (suite, turbulence, size) of the campaign's result rows.

    Parameters
    ----------
    effect_rows, clean_rows : list of dict
        Successful rows of the effect and clean campaigns (``bench_discovery._rows``:
        parameters and metrics without their prefixes).
    suite, turbulence : str
        The cell's sensor suite and turbulence level.
    size : float
        The effects' size, a share of the coefficient's variation.
    target : float or None
        The exact-detection rate the cell is held to.
    expected : dict
        Effect name -> the finding that names it.
    family_target : float or None
        The family rate the cell is held to.

    Returns
    -------
    dict or None
        The cell's entry of the data file (module docstring), None when no effect row
        falls in the cell.
    """
    rows = [r for r in effect_rows if (r["suite"], r["turbulence"], r["size"])
            == (suite, turbulence, size)]
    if not rows:
        return None
    clean = [r for r in clean_rows if (r["suite"], r["turbulence"]) == (suite, turbulence)]
    explained = [r["excess_explained"] for r in rows
                 if not r["missed"] and _finite(r.get("excess_explained"))]
    effects = {}
    for effect in dict.fromkeys(r["effect"] for r in rows):
        mine = [r for r in rows if r["effect"] == effect]
        effects[effect] = {
            "expected": expected[effect],
            "exact": sum(bool(r["exact"]) for r in mine),
            "partial": sum(bool(r["partial"]) for r in mine),
            "misnamed": sum(bool(r["missed"]) and bool(_findings(r)) for r in mine),
            "missed": sum(not _findings(r) for r in mine),
            "tied": sum(bool(r.get("tied")) for r in mine),
            "family": sum(bool(r.get("family")) for r in mine)}
    return {
        "suite": suite, "turbulence": turbulence, "size": size,
        "clean": {"flights": len(clean),
                  "with_finding": sum(bool(r["any_finding"]) for r in clean),
                  "named": dict(collections.Counter(
                      n for r in clean for n in _findings(r)).most_common())},
        "runs": len(rows),
        "flights_per_effect": len(rows) // len(effects),
        "exact": sum(bool(r["exact"]) for r in rows),
        "partial": sum(bool(r["partial"]) for r in rows),
        "misses": sum(bool(r["missed"]) for r in rows),
        "tied": sum(bool(r.get("tied")) for r in rows),
        "findings": sum(len(_findings(r)) for r in rows),
        "false_findings": int(sum(r["false_findings"] for r in rows)),
        "detections_explained": len(explained),
        "explained_70": sum(e >= 0.7 for e in explained),
        "explained_median": float(statistics.median(explained)) if explained else None,
        "target": target,
        "family": sum(bool(r.get("family")) for r in rows),
        "family_target": family_target,
        "effects": effects}


def _rate(k, n) -> str:
    if k is None or not n:
        return "-"
    low, high = wilson_interval(k, n)
    return f"{k}/{n} = {k / n:.0%} ({low:.0%}-{high:.0%})"


def _of(k, n) -> str:
    return "-" if k is None or n is None else f"{k} of {n}"


def _cell_name(cell: dict) -> str:
    return f"{cell['suite']}, {cell['turbulence']}, {cell['size']:.0%}"


def _summary_table(cells: list[dict]) -> list[str]:
    lines = ["| sensors, turbulence, size | clean flights with a finding | exact | target "
             "| family | family target | partial | found or near tie | findings not injected "
             "| misses named as a near tie | detections explaining >= 70 % of the excess |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for cell in cells:
        found = (None if cell.get("partial") is None or cell.get("tied") is None
                 else cell["exact"] + cell["partial"] + cell["tied"])
        explained = ("-" if cell.get("explained_70") is None else
                     f"{cell['explained_70']}/{cell['detections_explained']}"
                     + ("" if cell.get("explained_median") is None
                        else f" (median {cell['explained_median']:.2f})"))
        target, family_target = cell.get("target"), cell.get("family_target")
        lines.append(
            f"| {_cell_name(cell)} "
            f"| {_rate(cell['clean']['with_finding'], cell['clean']['flights'])} "
            f"| {_rate(cell['exact'], cell['runs'])} "
            f"| {'-' if target is None else f'>= {target:.0%}'} "
            f"| {_rate(cell.get('family'), cell['runs'])} "
            f"| {'-' if family_target is None else f'>= {family_target:.0%}'} "
            f"| {'-' if cell.get('partial') is None else cell['partial']} "
            f"| {_rate(found, cell['runs'])} "
            f"| {_of(cell.get('false_findings'), cell.get('findings'))} "
            f"| {_of(cell.get('tied'), cell.get('misses'))} | {explained} |")
    return lines


def _effect_table(cells: list[dict]) -> list[str]:
    cells = [c for c in cells if c.get("effects")]
    if not cells:
        return []
    names = list(dict.fromkeys(e for c in cells for e in c["effects"]))
    lines = ["Exact / partial / misnamed / missed flights per effect and cell (in brackets: "
             "misses the report names as a near tie):", "",
             "| effect | put into the flight | expected finding | "
             + " | ".join(_cell_name(c) for c in cells) + " |",
             "|---|---|---|" + "---|" * len(cells)]
    for name in names:
        expected = next(c["effects"][name]["expected"] for c in cells if name in c["effects"])
        counts = []
        for cell in cells:
            e = cell["effects"].get(name)
            counts.append("-" if e is None else
                          f"{e['exact']}/{e['partial']}/{e['misnamed']}/{e['missed']}"
                          + (f" ({e['tied']})" if e.get("tied") else ""))
        lines.append(f"| {name} | {INJECTED_DESCRIPTIONS.get(name, '-')} | `{expected}` | "
                     + " | ".join(counts) + " |")
    return lines + [""] + _family_table(cells, names)


def _family_table(cells: list[dict], names: list[str]) -> list[str]:
    """Exact and family counts per effect and cell, side by side ([] when no cell has
    them)."""
    cells = [c for c in cells if c.get("family") is not None]
    if not cells:
        return []
    lines = ["Exact / family flights per effect and cell (family: found exactly or as a member "
             "of the family a finding names):", "",
             "| effect | " + " | ".join(_cell_name(c) for c in cells) + " |",
             "|---|" + "---|" * len(cells)]
    for name in names:
        counts = []
        for cell in cells:
            e = cell["effects"].get(name)
            counts.append("-" if e is None or e.get("family") is None else
                          f"{e['exact']} / {e['family']}")
        lines.append(f"| {name} | " + " | ".join(counts) + " |")
    return lines


def _clean_lines(cells: list[dict]) -> list[str]:
    lines = []
    for cell in cells:
        clean = cell["clean"]
        named = clean.get("named")
        what = ("nothing found" if not clean["with_finding"] else
                "names not recorded" if not named else
                ", ".join(f"`{n}` x{c}" for n, c in named.items()))
        lines.append(f"* {cell['suite']} sensors, {cell['turbulence']} turbulence: "
                     f"{clean['with_finding']} of {clean['flights']} with a finding ({what}).")
    return list(dict.fromkeys(lines))


def render(data: dict) -> str:
    """The page (Markdown) of a data file's contents (module docstring).

    Parameters
    ----------
    data : dict
        ``{"flights": ...}`` as :func:`update` writes it.

    Returns
    -------
    str
        docs/validation.md, every flight's cells in the order suite, turbulence, size.
    """
    flights = data["flights"]
    commands = list(dict.fromkeys(c["command"] for f in flights.values()
                                  for c in f["cells"].values()))
    dates = sorted({c["measured"] for f in flights.values() for c in f["cells"].values()})
    out = ["# Validation: how often the main job finds what is there", "",
           "<!-- Written by benchmarks/bench_discovery.py --markdown; do not edit by hand. -->",
           "", f"Measured {' to '.join(dict.fromkeys((dates[0], dates[-1])))} by", ""]
    out += [f"    {command}" for command in commands]
    out += ["", *([data["note"], ""] if data.get("note") else []),
            "The next full run of the benchmark with `--markdown docs/validation.md` "
            "rewrites the cells it measures and keeps the others "
            "(`benchmarks/validation_report.py`).", "", INTRO]
    for flight in flights.values():
        cells = sorted(flight["cells"].values(), key=lambda c: (
            c["suite"] != "default", c["turbulence"] != "light", -c["size"]))
        out += [f"## {FLIGHT_NAMES.get(flight['excitation'], flight['excitation'])}, "
                f"{flight['duration_s']:g} s", "",
                f"{cells[0]['flights_per_effect']} flights per effect and cell, "
                f"{cells[0]['clean']['flights']} clean flights per sensor suite and "
                "turbulence level.", ""]
        out += _summary_table(cells) + [""]
        effect_table = _effect_table(cells)
        out += effect_table or ["Per-effect counts: not recorded for these cells."]
        out += [""]
        out += ["Clean flights:", ""] + _clean_lines(cells) + [""]
    return "\n".join(out).rstrip() + "\n"


def update(markdown: Path, effect_rows: list[dict], clean_rows: list[dict], *,
           excitation: str, duration_s: float, command: str,
           targets: dict[tuple[str, float], float], expected: dict[str, str],
           family_targets: dict[tuple[str, float], float] | None = None) -> None:
    """Merges a run's cells into the page's data file and writes the page again.

    Parameters
    ----------
    markdown : Path
        The page; its data file is the same path with the suffix ``.json``.
    effect_rows, clean_rows : list of dict
        The run's successful effect and clean rows.
    excitation : str
        The flights' excitation (``multisine``, ``multisine_throttle``).
    duration_s : float
        The flights' length [s].
    command : str
        The command line that measured them, printed in the page's header.
    targets : dict
        (suite, size) -> the exact-detection rate the cell is held to.
    expected : dict
        Effect name -> the finding that names it.
    family_targets : dict, optional
        (suite, size) -> the family rate the cell is held to.
    """
    store = markdown.with_suffix(".json")
    data = json.loads(store.read_text()) if store.exists() else {"flights": {}}
    flight = data["flights"].setdefault(f"{excitation} {duration_s:g} s", {
        "excitation": excitation, "duration_s": duration_s, "cells": {}})
    data.pop("note", None)  # a note on how earlier figures were recorded
    today = datetime.datetime.now(datetime.UTC).date().isoformat()
    for key in dict.fromkeys((r["suite"], r["turbulence"], r["size"]) for r in effect_rows):
        suite, turbulence, size = key
        cell = cell_summary(effect_rows, clean_rows, suite=suite, turbulence=turbulence,
                            size=size, target=targets.get((suite, size)), expected=expected,
                            family_target=(family_targets or {}).get((suite, size)))
        flight["cells"][f"{suite} {turbulence} {size:g}"] = cell | {
            "command": command, "measured": today}
    store.write_text(json.dumps(data, indent=1) + "\n")
    markdown.write_text(render(data))
    print(f"wrote {markdown} and {store}")


def main() -> None:
    parser = argparse.ArgumentParser(description="Renders docs/validation.md from its data.")
    parser.add_argument("--data", type=Path, default=DOCS / "validation.json",
                        help="the page's data file")
    parser.add_argument("--out", type=Path, default=DOCS / "validation.md", help="the page")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 when the page is not what its data render")
    parser.add_argument("--quick", action="store_true", help="the same as --check")
    args = parser.parse_args()
    page = render(json.loads(args.data.read_text()))
    if not (args.check or args.quick):
        args.out.write_text(page)
    elif args.out.read_text() != page:
        raise SystemExit(f"{args.out}: not what {args.data} renders; run "
                         "python benchmarks/validation_report.py to write it again")


if __name__ == "__main__":
    main()
