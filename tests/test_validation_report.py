"""docs/validation.md is written from the detection campaign's rows, never by hand
(benchmarks/validation_report.py, called by ``bench_discovery.py --markdown``)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "validation_report", ROOT / "benchmarks" / "validation_report.py")
validation_report = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(validation_report)

EXPECTED = {"stall_onset": "stall_onset", "tow_force": "constant_body_force"}


def _row(effect, found, **extra):
    names = [n for n in found.split(",") if n]
    expected = EXPECTED[effect]
    return {"suite": "default", "turbulence": "light", "size": 0.3, "effect": effect,
            "found": found, "exact": names == [expected],
            "partial": expected in names and len(names) > 1, "missed": expected not in names,
            "false_findings": sum(n != expected for n in names),
            "family": names == [expected], **extra}


def _rows():
    effect_rows = [
        _row("stall_onset", "stall_onset", excess_explained=0.95),
        _row("stall_onset", "stall_onset,rate_coupling", excess_explained=0.5),
        _row("tow_force", "thrust_propwash", tied=True, family=True,
             excess_explained=float("nan")),
        _row("tow_force", ""),
    ]
    clean_rows = [{"suite": "default", "turbulence": "light", "found": "", "any_finding": False},
                  {"suite": "default", "turbulence": "light",
                   "found": "accelerometer_lever_arm", "any_finding": True},
                  {"suite": "research", "turbulence": "light", "found": "",
                   "any_finding": False}]
    return effect_rows, clean_rows


def test_a_cell_counts_every_class_of_outcome():
    cell = validation_report.cell_summary(*_rows(), suite="default", turbulence="light",
                                          size=0.3, target=0.7, expected=EXPECTED)
    assert cell["clean"] == {"flights": 2, "with_finding": 1,
                             "named": {"accelerometer_lever_arm": 1}}
    assert (cell["runs"], cell["flights_per_effect"]) == (4, 2)
    assert (cell["exact"], cell["partial"], cell["misses"], cell["tied"]) == (1, 1, 2, 1)
    assert (cell["findings"], cell["false_findings"]) == (4, 2)
    assert (cell["detections_explained"], cell["explained_70"]) == (2, 1)
    assert cell["explained_median"] == 0.725
    assert (cell["family"], cell["family_target"]) == (2, None)
    assert cell["effects"]["tow_force"] == {"expected": "constant_body_force", "exact": 0,
                                            "partial": 0, "misnamed": 1, "missed": 1,
                                            "tied": 1, "family": 1}
    assert validation_report.cell_summary(*_rows(), suite="research", turbulence="light",
                                          size=0.3, target=None, expected=EXPECTED) is None


def test_a_run_replaces_its_cells_and_keeps_the_others(tmp_path):
    page = tmp_path / "validation.md"
    options = {"excitation": "multisine", "duration_s": 120.0, "targets": {},
               "expected": EXPECTED}
    validation_report.update(page, *_rows(), command="first", **options)
    data = json.loads(page.with_suffix(".json").read_text())
    data["flights"]["multisine 120 s"]["cells"]["research light 0.2"] = dict(
        data["flights"]["multisine 120 s"]["cells"]["default light 0.3"],
        suite="research", size=0.2)
    page.with_suffix(".json").write_text(json.dumps(data))
    validation_report.update(page, *_rows(), command="second", **options)
    cells = json.loads(page.with_suffix(".json").read_text())["flights"]["multisine 120 s"][
        "cells"]
    assert {key: cell["command"] for key, cell in cells.items()} == {
        "default light 0.3": "second", "research light 0.2": "first"}
    text = page.read_text()
    assert "| default, light, 30% | 1/2 = 50% (9%-91%) | 1/4 = 25% (5%-70%) |" in text
    assert "| tow_force | k N along +x body at the centre of gravity | `constant_body_force` " \
           "| 0/0/1/1 (1) | 0/0/1/1 (1) |" in text
    assert "| tow_force | 0 / 1 | 0 / 1 |" in text   # exact and family side by side
    assert "| 1/4 = 25% (5%-70%) | - | 2/4 = 50% (15%-85%) | - |" in text
    assert text == validation_report.render(json.loads(page.with_suffix(".json").read_text()))


def test_the_committed_page_is_what_its_data_render():
    data = json.loads((ROOT / "docs" / "validation.json").read_text())
    assert (ROOT / "docs" / "validation.md").read_text() == validation_report.render(data)
