import base64
import json
from html.parser import HTMLParser

import numpy as np
import pytest
from matplotlib.artist import Artist
from matplotlib.figure import Figure

from drake_uav.identification.statistics.residuals import diagnose
from drake_uav.reporting import Report, figures, format_value, json_ready
from drake_uav.reporting.output import MANIFEST

FS = 50.0  # Hz
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def flight():
    """A small before/after pair: the baseline residual holds a 1.5 Hz oscillation."""
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) / FS
    after = 0.02 * rng.standard_normal(n)
    before = after + 0.05 * np.sin(2 * np.pi * 1.5 * t)
    return t, before, after, diagnose(before, FS), diagnose(after, FS)


class _FailingArtist(Artist):
    """Raises while the figure is drawn, like a plot hitting bad data mid-write."""

    def draw(self, renderer):
        raise RuntimeError("figure failed to draw")


class _Page(HTMLParser):
    """The parts of report.html a reader sees: headings, table rows, images, links, text."""

    def __init__(self, page: str):
        super().__init__()
        self.headings: list[tuple[str, str]] = []
        self.tables: list[list[list[str]]] = []
        self.images: list[dict[str, str]] = []
        self.links: list[str] = []
        self.tags: list[str] = []
        self.text: list[str] = []
        self._open: list[str] = []
        self._cell: list[str] | None = None
        self.feed(page)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.images.append(attrs)
        if tag in ("img", "meta", "br", "hr"):  # void elements: no end tag
            return
        self._open.append(tag)
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "a":
            self.links.append(attrs["href"])

    def handle_endtag(self, tag):
        assert self._open and self._open[-1] == tag, (self._open, tag)  # well-formed
        self._open.pop()
        if tag in ("td", "th"):
            self.tables[-1][-1].append("".join(self._cell))
            self._cell = None
        elif tag in ("h1", "h2", "h3"):
            self.headings.append((tag, self.text[-1]))

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


def _failing_figure():
    fig = Figure()
    fig.add_artist(_FailingArtist())
    return fig


def _full_report(flight):
    t, before, after, d_before, d_after = flight
    diags = {"before": d_before, "after": d_after}
    va = 20 + np.sin(t)
    rep = Report("Identification of the sample flight")
    rep.add_heading("Summary")
    rep.add_text("The baseline model **lacks** an effect.\n\n- first point\n- uses `C_D_Tc`\n\n"
                 "Raw <script>alert(1)</script> stays text.")
    rep.add_key_values({"equation-error RMS before": 0.0412345, "after": 0.0201,
                        "effect found": True, "missing": None})
    rep.add_table([{"parameter": "C_D_0", "estimate": 0.0312345, "sigma": 0.0011, "t": 28.4},
                   {"parameter": "C_D_Tc", "estimate": 0.123456, "sigma": np.float64(0.01),
                    "t": np.inf}],
                  caption="Identified parameters", formats={"estimate": ".4f", "t": ".1f"})
    rep.add_table([[1, "a|b", 2.5e-7]], header=["n", "name", "value"])
    rep.add_figure(figures.residual_time_series(t, {"C_D": before}, {"C_D": after}),
                   "Residual before and after", name="residual")
    rep.add_figure(lambda: figures.autocorrelation_plot(diags), "Autocorrelation")
    rep.add_figure(lambda: figures.normal_probability_plot(diags), "Normal probability plot")
    rep.add_figure(lambda: figures.spectral_density_plot(diags), "Spectral density")
    rep.add_figure(lambda: figures.reconstruction_plot(
        t, {"Va": va, "alpha": 0.05 + 0 * t}, {"Va": va + 0.5, "alpha": 0.06 + 0 * t},
        {"Va": va + 0.1}), "Reconstruction")
    return rep


def test_report_with_every_section_kind(tmp_path, flight):
    out = tmp_path / "run1"
    summary = {"errors": {"rms_before": np.float64(0.0412), "rms_after": 0.0201},
               "parameters": np.array([1.0, np.nan]), "sigma": [np.inf], "diagnosis":
               flight[4]}
    path = _full_report(flight).write(out, summary)
    assert path == out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run1"]  # nothing else left behind
    names = sorted(p.name for p in out.iterdir())
    pngs = [n for n in names if n.endswith(".png")]
    assert len(pngs) == 5 and pngs[0] == "fig01_residual.png"
    assert {"report.md", "report.html", "summary.json", MANIFEST} <= set(names)
    assert all((out / n).read_bytes().startswith(PNG_MAGIC) for n in pngs)
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["written_by"] == "drake_uav" and manifest["kind"] == "report"
    assert manifest["files"] == [n for n in names if n != MANIFEST]
    names.remove(MANIFEST)

    md = (out / "report.md").read_text()
    assert md.startswith("# Identification of the sample flight")
    assert "| C_D_Tc | 0.1235 | 0.01 | inf |" in md
    assert r"a\|b" in md and "2.5e-07" in md
    assert "![Residual before and after](fig01_residual.png)" in md
    assert "- **effect found:** yes" in md and "- **missing:** -" in md

    page = _Page((out / "report.html").read_text())
    assert page.headings == [("h1", "Identification of the sample flight"), ("h2", "Summary")]
    parameters, small = page.tables
    assert parameters == [["parameter", "estimate", "sigma", "t"],
                          ["C_D_0", "0.0312", "0.0011", "28.4"],
                          ["C_D_Tc", "0.1235", "0.01", "inf"]]
    assert small == [["n", "name", "value"], ["1", "a|b", "2.5e-07"]]
    assert "Identified parameters" in page.text  # the caption
    assert "<script>alert(1)</script>" in "".join(page.text) and "script" not in page.tags
    assert {"strong", "code", "ul", "li", "em"} <= set(page.tags)
    assert [i["alt"] for i in page.images] == [
        "Residual before and after", "Autocorrelation", "Normal probability plot",
        "Spectral density", "Reconstruction"]
    # Figures embedded (a self-contained page), each linked to its file in the folder.
    assert all(i["src"].startswith("data:image/png;base64,") for i in page.images)
    assert base64.b64decode(page.images[0]["src"].split(",", 1)[1]) == (
        out / "fig01_residual.png").read_bytes()
    assert page.links == pngs
    assert "Figure 5: Reconstruction" in page.text

    data = json.loads((out / "summary.json").read_text())
    assert data["complete"] is True
    assert data["report_title"] == "Identification of the sample flight"
    assert sorted(data["report_files"]) == names
    assert data["errors"] == {"rms_before": 0.0412, "rms_after": 0.0201}
    assert data["parameters"] == [1.0, None] and data["sigma"] == ["inf"]
    assert data["diagnosis"]["whiteness"]["n_eff"] == pytest.approx(flight[4].n_eff)


def test_html_can_reference_png_files_instead_of_embedding(tmp_path, flight):
    rep = Report("linked", embed_images=False)
    rep.add_figure(figures.autocorrelation_plot(flight[3]), "acf")
    rep.write(tmp_path / "r", {})
    page = _Page((tmp_path / "r" / "report.html").read_text())
    assert [i["src"] for i in page.images] == ["fig01_acf.png"]
    assert page.links == ["fig01_acf.png"]


def test_interrupted_write_leaves_no_report(tmp_path, flight):
    rep = _full_report(flight)
    rep.add_figure(_failing_figure, "breaks while drawing")
    rep.add_text("never reached")
    with pytest.raises(RuntimeError, match="failed to draw"):
        rep.write(tmp_path / "run", {"x": 1})
    assert list(tmp_path.iterdir()) == []  # neither the report nor a partial folder


def test_interrupted_write_keeps_the_older_complete_report(tmp_path, flight):
    out = tmp_path / "run"
    Report("first").add_text("old").add_figure(figures.autocorrelation_plot(flight[3]),
                                               "acf").write(out, {"version": 1})
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rep = Report("second").add_text("new").add_figure(_failing_figure(), "breaks")
    with pytest.raises(RuntimeError):
        rep.write(out, {"version": 2})
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
    # A successful rewrite replaces the whole folder (the old figure file is gone).
    Report("third").add_text("newer").write(out, {"version": 3})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "report.html", "report.md",
                                                     "summary.json"]
    assert json.loads((out / "summary.json").read_text())["version"] == 3
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_refuses_to_replace_a_folder_that_is_not_a_report(tmp_path):
    out = tmp_path / "data"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    with pytest.raises(FileExistsError, match="holds files drake_uav did not write"):
        Report("r").write(out, {})
    assert (out / "notes.txt").read_text() == "keep me"
    with pytest.raises(ValueError, match="out_dir"):
        Report("r").write(tmp_path / "x" / "..", {})


def test_bad_summary_fails_before_anything_is_written(tmp_path):
    with pytest.raises(ValueError, match="complete"):
        Report("r").write(tmp_path / "a", {"complete": False})
    with pytest.raises(TypeError, match=r"summary\['fit'\]\['model'\]"):
        Report("r").write(tmp_path / "b", {"fit": {"model": object()}})
    assert list(tmp_path.iterdir()) == []


def test_table_validation_and_cell_formatting():
    rep = Report("t")
    with pytest.raises(ValueError, match="row 1 has 1 cells"):
        rep.add_table([[1, 2], [3]], header=["a", "b"])
    with pytest.raises(ValueError, match="needs a header"):
        rep.add_table([[1, 2]])
    with pytest.raises(ValueError, match="not in the table"):
        rep.add_table([{"a": 1}], formats={"b": ".2f"})
    rep.add_table([{"a": 1}, {"b": 2.0}])  # missing cells are "-"
    assert "| 1 | - |" in rep.to_markdown() and "| - | 2 |" in rep.to_markdown()
    assert format_value(np.float32(0.5), ".2f") == "0.50"
    assert format_value(np.int64(7)) == "7" and format_value(np.bool_(False)) == "no"
    assert format_value(float("nan")) == "nan" and format_value(3.14159, lambda v: "pi") == "pi"
    assert json_ready({"k": (np.int32(2), -np.inf)}) == {"k": [2, "-inf"]}


def test_markdown_text_is_rendered_by_python_markdown():
    text = ("### Head\ntext *it* and [doc](a.html)\n\n```\nx < 1\n```\n\n* one\n* two\n\n"
            "| a | b |\n|---|---|\n| 1 | <b>2</b> |")
    page = _Page(Report("t").add_text(text).to_html())
    assert page.headings == [("h1", "t"), ("h3", "Head")]
    assert page.links == ["a.html"]
    assert {"em", "pre", "code", "ul", "li"} <= set(page.tags) and "b" not in page.tags
    assert "x < 1\n" in page.text
    assert page.tables == [[["a", "b"], ["1", "<b>2</b>"]]]


def test_table_cells_are_literal_and_number_columns_right_aligned():
    rep = Report("t").add_table([{"name": "a*b*c", "value": 1.5, "note": "[x](y)"},
                                 {"name": "_u_", "value": None, "note": "`z`"},
                                 {"name": "Va [m/s]", "value": -2, "note": "C_D_0"}])
    md = rep.to_markdown()
    assert "|---|--:|---|" in md and "| Va [m/s] | -2 | C_D_0 |" in md
    page = _Page(rep.to_html())
    assert page.tables == [[["name", "value", "note"], ["a*b*c", "1.5", "[x](y)"],
                            ["_u_", "-", "`z`"], ["Va [m/s]", "-2", "C_D_0"]]]
    assert not {"em", "a", "code"} & set(page.tags)
    assert rep.to_html().count('style="text-align: right;"') == 4  # header and 3 cells


def test_figures_draw_the_data_they_are_given(flight):
    t, before, after, d_before, d_after = flight
    fig = figures.residual_time_series(t, {"C_L": before, "C_m": after}, {"C_L": after})
    ax_l, ax_m = fig.axes
    assert len(ax_l.get_lines()) == 3 and len(ax_m.get_lines()) == 2  # incl. the zero line
    # Long traces are drawn as their block min/max envelope, in time order.
    x, y = ax_l.get_lines()[1].get_xdata(), ax_l.get_lines()[1].get_ydata()
    assert len(y) <= figures.DISPLAY_POINTS + 3 < t.size
    assert y.max() == after.max() and y.min() == after.min() and np.all(np.diff(x) > 0)
    np.testing.assert_array_equal(y, after[np.searchsorted(t, x)])
    short = figures.residual_time_series(t[:500], after[:500])
    np.testing.assert_array_equal(short.axes[0].get_lines()[0].get_ydata(), after[:500])
    assert f"{np.sqrt(np.mean(before**2)):.3g}" in ax_l.get_legend().get_texts()[0].get_text()

    fig = figures.reconstruction_plot(t, {"alpha": np.full(t.size, 0.1)},
                                      {"alpha": np.full(t.size, 0.12)})
    lines = fig.axes[0].get_lines()
    np.testing.assert_allclose(lines[0].get_ydata(), np.degrees(0.1))
    assert "MAE 1.15 deg" in fig.axes[0].get_legend().get_texts()[1].get_text()
    fig = figures.reconstruction_plot(t, {"airspeed": np.full(t.size, 25.0),
                                          "alpha": np.zeros(t.size), "q": np.zeros(t.size)},
                                      {}, degrees=("alpha", "q"))
    assert [ax.get_ylabel() for ax in fig.axes] == ["airspeed [m/s]", "alpha [deg]", "q [deg/s]"]

    fig = figures.autocorrelation_plot({"before": d_before, "after": d_after})
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_ydata(), d_before.acf)
    fig = figures.normal_probability_plot(d_before, max_points=100)
    assert len(fig.axes[0].get_lines()[0].get_xdata()) == 100
    fig = figures.spectral_density_plot({"before": d_before, "after": d_after})
    assert len(d_before.spectral_peaks) >= 1 and not d_after.spectral_peaks
    peak_markers = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "v"]
    assert [m.get_xdata()[0] for m in peak_markers] == [p.frequency for p in
                                                       d_before.spectral_peaks]
    with pytest.raises(ValueError, match="before"):
        figures.residual_time_series(t, {"C_L": before[:-1]})
