"""A report folder: ``report.md``, ``report.html``, PNG figures and ``summary.json``.

:class:`Report` collects ordered sections (headings, markdown text, tables, figures, key-value
summaries); :meth:`Report.write` renders them into a folder::

    out_dir/
        report.md        markdown, figures referenced by file name
        report.html      report.md rendered by Python-Markdown: one self-contained page
                         (figures embedded as base64 PNG, each linked to its file), simple CSS
        fig01_<name>.png one PNG per figure, in order
        summary.json     the caller's summary + "complete": true, "report_title", "report_files"
        drake_uav_manifest.json  the list of the folder's files, written last (the marker of
                         a folder drake_uav wrote, :mod:`drake_uav.reporting.output`)

report.md is the one source of the text: report.html is its rendering with the "tables",
"fenced_code" and "sane_lists" extensions. Raw HTML in markdown text is shown as text, never
passed through. Numeric table columns are right-aligned.

The folder appears atomically and follows the overwrite rule of
:mod:`drake_uav.reporting.output`: everything is written into a hidden sibling
``.<name>.partial-<random>`` and swapped into place only when complete; ``out_dir`` may be
missing, empty or an earlier report (only files its manifest lists), never a folder holding
anything else. An exception while writing (a figure that fails to draw, a full disk) removes the
partial folder and leaves any older report untouched. A process killed mid-write can leave a
``.partial-`` folder behind, never a folder named ``out_dir``.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import math
import os
import re
import xml.etree.ElementTree as etree
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import markdown
import numpy as np
from markdown.treeprocessors import Treeprocessor
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from drake_uav.reporting.output import output_folder

__all__ = ["Report", "format_value", "json_ready"]

#: Keys :meth:`Report.write` adds to ``summary.json``; a caller's summary may not use them.
RESERVED_SUMMARY_KEYS = ("complete", "report_title", "report_files")

#: zlib level of the PNG figures: 3 writes them twice as fast as the default 6, 5 % larger.
PNG_COMPRESSION = 3

#: Python-Markdown extensions report.html is rendered with.
MARKDOWN_EXTENSIONS = ("tables", "fenced_code", "sane_lists")

#: Formatting of a table cell: a format spec (``".3f"``) or a function value -> text.
CellFormat = str | Callable[[Any], str]

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; color: #222;
       max-width: 62rem; margin: 2rem auto; padding: 0 1rem; line-height: 1.45; }
h1 { border-bottom: 2px solid #446; padding-bottom: .3rem; }
h2 { border-bottom: 1px solid #ccd; padding-bottom: .2rem; margin-top: 2rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .92rem; }
th, td { border: 1px solid #ccd; padding: .25rem .6rem; text-align: left;
         font-variant-numeric: tabular-nums; }
th { background: #eef; }
img { max-width: 100%; border: 1px solid #dde; }
code, pre { background: #f4f4f8; font-size: .9rem; }
pre { padding: .6rem; overflow-x: auto; }
"""


# ----------------------------------------------------------------------------- formatting


def format_value(value: Any, fmt: CellFormat | None = None, float_format: str = ".4g") -> str:
    """Text of one table cell.

    ``fmt`` (a format spec or a function) wins; otherwise floats use ``float_format``, integers
    print exactly, booleans as yes/no, None as "-", nan/inf as "nan"/"inf".
    """
    if callable(fmt):
        return str(fmt(value))
    if value is None:
        return "-"
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if fmt is not None:
        return format(value, fmt)
    if isinstance(value, float):
        return format(value, float_format)
    return str(value)


def json_ready(obj: Any, path: str = "summary") -> Any:
    """A copy of ``obj`` that ``json.dumps(..., allow_nan=False)`` accepts.

    numpy scalars/arrays become Python numbers/lists, Paths strings, objects with ``to_dict()``
    and dataclasses dictionaries; nan becomes null and +-inf the strings "inf"/"-inf".
    Raises TypeError naming the path of a value that has no JSON form.
    """
    if obj is None or isinstance(obj, bool | int | str):
        return obj
    if isinstance(obj, float):
        if math.isnan(obj):
            return None
        if math.isinf(obj):
            return "inf" if obj > 0 else "-inf"
        return obj
    if isinstance(obj, np.generic | np.ndarray):
        return json_ready(obj.tolist(), path)
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, Mapping):
        return {str(k): json_ready(v, f"{path}[{k!r}]") for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_ready(v, f"{path}[{i}]") for i, v in enumerate(obj)]
    if hasattr(obj, "to_dict") and callable(obj.to_dict):
        return json_ready(obj.to_dict(), path)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return json_ready(dataclasses.asdict(obj), path)
    raise TypeError(f"{path}: {type(obj).__name__} value has no JSON form")


# ----------------------------------------------------------------------------- markdown

_NUMBER = re.compile(r"^[-+]?(\d[\d,]*\.?\d*|\.\d+)([eE][-+]?\d+)?( ?%)?$|^[-+]?(inf|nan)$")
# Characters that would start markup inside a cell or caption: "_" only at a word edge (inside
# a word, as in C_D_0, it is literal in Python-Markdown and most readers), "]" only where it
# would close a link ("[m/s]" stays as written).
_MARKUP = re.compile(r"[\\`*|]|\](?=[(\[])|(?<!\w)_|_(?!\w)")
# In the alt text of an image every bracket counts.
_ALT_MARKUP = re.compile(r"[\\`*|\[\]]|(?<!\w)_|_(?!\w)")


def _literal(text: str, markup: re.Pattern = _MARKUP) -> str:
    """``text`` as literal markdown on one line (markup characters backslash-escaped)."""
    return markup.sub(lambda m: "\\" + m.group(0), str(text)).replace("\n", " ")


class _LinkFigures(Treeprocessor):
    """Wraps each report figure's ``<img>`` in a link to its PNG file and, when the PNG bytes
    are given, embeds them in ``src`` as a base64 data URI (a page that needs no other file)."""

    def __init__(self, md: markdown.Markdown, files: set[str], pngs: Mapping[str, bytes]):
        super().__init__(md)
        self.files, self.pngs = files, pngs

    def run(self, root: etree.Element) -> None:
        figures = [(parent, img) for parent in root.iter() for img in parent
                   if img.tag == "img" and img.get("src") in self.files]
        for parent, img in figures:  # collected first: the tree changes below
            src = img.get("src")
            link = etree.Element("a", href=src)
            link.tail, img.tail = img.tail, None
            parent.insert(list(parent).index(img), link)
            parent.remove(img)
            link.append(img)
            if src in self.pngs:
                img.set("src", "data:image/png;base64,"
                        + base64.b64encode(self.pngs[src]).decode("ascii"))


def _render_markdown(text: str, figure_files: set[str], pngs: Mapping[str, bytes]) -> str:
    """HTML body of report markdown: raw HTML escaped, figures linked (and embedded)."""
    md = markdown.Markdown(extensions=list(MARKDOWN_EXTENSIONS), output_format="html")
    md.preprocessors.deregister("html_block")
    md.inlinePatterns.deregister("html")
    # After "inline" (priority 20), which creates the <img> elements.
    md.treeprocessors.register(_LinkFigures(md, figure_files, pngs), "link_figures", 15)
    return md.convert(text)


# ----------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class _Heading:
    text: str
    level: int

    def markdown(self) -> list[str]:
        return ["#" * self.level + " " + self.text]


@dataclass(frozen=True)
class _Text:
    text: str

    def markdown(self) -> list[str]:
        return [self.text.strip()]


def _caption(caption: str | None) -> list[str]:
    return [f"*{_literal(caption)}*", ""] if caption else []


@dataclass(frozen=True)
class _Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str | None

    def markdown(self) -> list[str]:
        """A pipe table; a column whose cells are all numbers (or "-") is right-aligned."""
        numeric = [any(_NUMBER.match(c) for c in col) and
                   all(c == "-" or _NUMBER.match(c) for c in col)
                   for col in zip(*self.rows, strict=True)] or [False] * len(self.header)
        return [*_caption(self.caption),
                "| " + " | ".join(_literal(h) for h in self.header) + " |",
                "|" + "|".join("--:" if n else "---" for n in numeric) + "|",
                *("| " + " | ".join(_literal(c) for c in r) + " |" for r in self.rows)]


@dataclass(frozen=True)
class _KeyValues:
    items: tuple[tuple[str, str], ...]
    caption: str | None

    def markdown(self) -> list[str]:
        return [*_caption(self.caption),
                *(f"- **{_literal(k)}:** {_literal(v)}" for k, v in self.items)]


@dataclass(frozen=True)
class _Figure:
    source: Figure | Callable[[], Figure]
    caption: str
    file_name: str
    number: int

    def markdown(self) -> list[str]:
        return [f"![{_literal(self.caption, _ALT_MARKUP)}]({self.file_name})", "",
                f"*Figure {self.number}: {_literal(self.caption)}*"]

    def render(self, folder: Path, dpi: int) -> bytes:
        """Draws the figure into ``folder/file_name``; returns the PNG bytes."""
        fig = self.source if isinstance(self.source, Figure) else self.source()
        if not isinstance(fig, Figure):
            raise TypeError(f"figure {self.file_name!r}: builder returned {fig!r}")
        FigureCanvasAgg(fig)
        path = folder / self.file_name
        fig.savefig(path, format="png", dpi=dpi, pil_kwargs={"compress_level": PNG_COMPRESSION})
        return path.read_bytes()


def _slug(text: str) -> str:
    slug = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")
    return slug[:40] or "figure"


class Report:
    """An ordered list of report sections, written to a folder by :meth:`write`.

    Args:
        title: report title (first heading, HTML title, ``report_title`` in summary.json).
        dpi: resolution of the PNG figures [dots per inch].
        embed_images: embed the PNGs in report.html as base64 (self-contained page); otherwise
            the page references the PNG files next to it.

    Every ``add_*`` method returns the report, so calls chain.
    """

    def __init__(self, title: str, *, dpi: int = 110, embed_images: bool = True):
        if not str(title).strip():
            raise ValueError("title must not be empty")
        if not (isinstance(dpi, int) and dpi > 0):
            raise ValueError(f"dpi must be a positive integer, got {dpi!r}")
        self.title = str(title)
        self.dpi = dpi
        self.embed_images = bool(embed_images)
        self._sections: list[_Heading | _Text | _Table | _KeyValues | _Figure] = []
        self._figures = 0

    def add_heading(self, text: str, level: int = 2) -> Report:
        """A section heading, ``level`` 2..6 (level 1 is the title)."""
        if level not in range(2, 7):
            raise ValueError(f"level must be 2..6, got {level}")
        self._sections.append(_Heading(str(text), level))
        return self

    def add_text(self, markdown: str) -> Report:
        """Markdown text: paragraphs, lists, links, code (raw HTML is shown as text)."""
        self._sections.append(_Text(str(markdown)))
        return self

    def add_table(
        self,
        rows: Sequence[Mapping[str, Any]] | Sequence[Sequence[Any]],
        header: Sequence[str] | None = None,
        *,
        caption: str | None = None,
        formats: Mapping[str, CellFormat] | None = None,
        float_format: str = ".4g",
    ) -> Report:
        """A table from dict rows (columns in first-seen key order, missing cells "-") or from
        ``header`` + sequence rows. ``formats`` maps column name -> format spec or function;
        other floats use ``float_format``. Cells are formatted now, so a bad spec fails here.
        """
        rows = list(rows)
        formats = dict(formats or {})
        if rows and all(isinstance(r, Mapping) for r in rows):
            if header is None:
                header = list(dict.fromkeys(k for r in rows for k in r))
            data = [[r.get(h) for h in header] for r in rows]
        elif any(isinstance(r, Mapping) for r in rows):
            raise ValueError("table rows must be all mappings or all sequences")
        else:
            if header is None:
                raise ValueError("a table of sequence rows needs a header")
            data = [list(r) for r in rows]
        header = tuple(str(h) for h in header)
        if not header:
            raise ValueError("table header is empty")
        for i, r in enumerate(data):
            if len(r) != len(header):
                raise ValueError(f"table row {i} has {len(r)} cells, header has {len(header)}")
        unknown = set(formats) - set(header)
        if unknown:
            raise ValueError(f"formats name columns not in the table: {sorted(unknown)}")
        text_rows = tuple(
            tuple(format_value(v, formats.get(h), float_format) for h, v in zip(header, r,
                                                                                 strict=True))
            for r in data
        )
        self._sections.append(_Table(header, text_rows, caption))
        return self

    def add_key_values(
        self,
        items: Mapping[str, Any],
        *,
        caption: str | None = None,
        formats: Mapping[str, CellFormat] | None = None,
        float_format: str = ".4g",
    ) -> Report:
        """A key -> value summary (e.g. errors before/after), formatted like table cells."""
        formats = dict(formats or {})
        pairs = tuple(
            (str(k), format_value(v, formats.get(k), float_format)) for k, v in items.items()
        )
        self._sections.append(_KeyValues(pairs, caption))
        return self

    def add_figure(
        self, figure: Figure | Callable[[], Figure], caption: str, name: str | None = None
    ) -> Report:
        """A matplotlib Figure, or a function building one at write time, saved as PNG.

        ``name`` (default: from the caption) gives the file ``figNN_<name>.png``.
        """
        if not (isinstance(figure, Figure) or callable(figure)):
            raise TypeError(f"figure must be a matplotlib Figure or a callable, got {figure!r}")
        self._figures += 1
        file_name = f"fig{self._figures:02d}_{_slug(name or caption)}.png"
        self._sections.append(_Figure(figure, str(caption), file_name, self._figures))
        return self

    # ------------------------------------------------------------------------- rendering

    def _render_figures(self, folder: Path) -> dict[str, bytes]:
        return {s.file_name: s.render(folder, self.dpi)
                for s in self._sections if isinstance(s, _Figure)}

    def to_markdown(self) -> str:
        """The report as markdown (figures referenced by their PNG file names)."""
        out = [f"# {self.title}", ""]
        for section in self._sections:
            out += [*section.markdown(), ""]
        return "\n".join(out)

    def to_html(self, pngs: Mapping[str, bytes] | None = None) -> str:
        """The report as one HTML page: :meth:`to_markdown` rendered by Python-Markdown;
        ``pngs`` (file name -> bytes) are embedded if given."""
        files = {s.file_name for s in self._sections if isinstance(s, _Figure)}
        body = _render_markdown(self.to_markdown(), files, pngs or {})
        return (
            '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f"<title>{html.escape(self.title)}</title>\n<style>{_CSS}</style>\n</head>\n"
            f"<body>\n{body}\n</body>\n</html>\n"
        )

    # ------------------------------------------------------------------------- writing

    def write(self, out_dir: str | os.PathLike, summary: Mapping[str, Any],
              files: Mapping[str, str] | None = None) -> Path:
        """Writes the report folder atomically (module docstring); returns its absolute path.

        Args:
            out_dir: the report folder: missing, empty or an earlier report (it holds only
                files its manifest lists); replaced only once the new report is complete.
            summary: JSON-able mapping (numpy values allowed, see :func:`json_ready`) written
                to summary.json together with ``"complete": true``.
            files: further text files of the folder, name -> content (a command file).

        Raises:
            ValueError: summary uses a reserved key. TypeError: a summary value has no JSON form.
            OutputRefusedError (a FileExistsError and a ValueError): ``out_dir`` is a file, the
                current folder, unwritable, or a folder holding anything but an earlier report.
            Any exception raised while drawing a figure (nothing is left at ``out_dir``).
        """
        out_dir = Path(out_dir).absolute()
        if out_dir.name in ("", ".", ".."):
            raise ValueError(f"out_dir must name a report folder, got {str(out_dir)!r}")
        clash = [k for k in RESERVED_SUMMARY_KEYS if k in summary]
        if clash:
            raise ValueError(f"summary must not use the reserved keys {clash}")
        data = json_ready(dict(summary))
        json.dumps(data, allow_nan=False)  # fail before touching the disk
        with output_folder(out_dir, "report", what="report folder") as partial:
            pngs = self._render_figures(partial)
            _write_text(partial / "report.md", self.to_markdown())
            _write_text(partial / "report.html",
                        self.to_html(pngs if self.embed_images else None))
            extra = dict(files or {})
            for name, text in extra.items():
                _write_text(partial / name, text)
            written = sorted([*pngs, *extra, "report.md", "report.html", "summary.json"])
            data.update(complete=True, report_title=self.title, report_files=written)
            _write_text(partial / "summary.json",
                        json.dumps(data, indent=2, allow_nan=False) + "\n")
        return out_dir


def _write_text(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
