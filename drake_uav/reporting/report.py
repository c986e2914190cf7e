"""A report folder: ``report.md``, ``report.html``, PNG figures and ``summary.json``.

:class:`Report` collects ordered sections (headings, markdown text, tables, figures, key-value
summaries); :meth:`Report.write` renders them into a folder::

    out_dir/
        report.md        markdown, figures referenced by file name
        report.html      self-contained page (figures embedded as base64 PNG), simple CSS
        fig01_<name>.png one PNG per figure, in order
        summary.json     the caller's summary + "complete": true, "report_title", "report_files"

The folder appears atomically: everything is written into a hidden sibling
``.<name>.partial-<random>`` and renamed to ``out_dir`` only when complete; an existing report
folder is moved aside and deleted only after the new one is in place. An exception while writing
(a figure that fails to draw, a full disk) removes the partial folder and leaves any older
report untouched. A process killed mid-write can leave a ``.partial-`` folder behind, never a
folder named ``out_dir``.

HTML rendering of markdown text covers a small subset: paragraphs, ``#`` headings, ``-``/``*``
bullet lists, fenced code blocks, ``**bold**``, ``*italic*``, ``inline code`` and
``[text](url)`` links; everything else is shown as escaped text.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import math
import os
import re
import shutil
import tempfile
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["Report", "format_value", "json_ready", "markdown_to_html"]

#: Keys :meth:`Report.write` adds to ``summary.json``; a caller's summary may not use them.
RESERVED_SUMMARY_KEYS = ("complete", "report_title", "report_files")

#: Formatting of a table cell: a format spec (``".3f"``) or a function value -> text.
CellFormat = str | Callable[[Any], str]

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; color: #222;
       max-width: 62rem; margin: 2rem auto; padding: 0 1rem; line-height: 1.45; }
h1 { border-bottom: 2px solid #446; padding-bottom: .3rem; }
h2 { border-bottom: 1px solid #ccd; padding-bottom: .2rem; margin-top: 2rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .92rem; }
th, td { border: 1px solid #ccd; padding: .25rem .6rem; text-align: left; }
th { background: #eef; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
table.kv th { background: #f6f6fb; font-weight: 600; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: .3rem; }
figure { margin: 1.2rem 0; }
figure img { max-width: 100%; border: 1px solid #dde; }
figcaption { font-style: italic; font-size: .92rem; }
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


_INLINE = [
    (re.compile(r"\*\*(.+?)\*\*"), r"<strong>\1</strong>"),
    (re.compile(r"(?<![\w*])\*(?!\s)(.+?)(?<!\s)\*(?![\w*])"), r"<em>\1</em>"),
    (re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)"), r'<a href="\2">\1</a>'),
]


def _inline_html(text: str) -> str:
    parts = text.split("`")
    if len(parts) % 2 == 0:  # unbalanced backtick: treat the last one literally
        parts[-2:] = ["`".join(parts[-2:])]
    out = []
    for i, part in enumerate(parts):
        escaped = html.escape(part, quote=True)
        if i % 2:
            out.append(f"<code>{escaped}</code>")
            continue
        for pattern, repl in _INLINE:
            escaped = pattern.sub(repl, escaped)
        out.append(escaped)
    return "".join(out)


def markdown_to_html(text: str) -> str:
    """HTML of the markdown subset listed in the module docstring (input is escaped)."""
    out: list[str] = []
    para: list[str] = []
    items: list[str] = []
    code: list[str] | None = None

    def flush() -> None:
        if para:
            out.append(f"<p>{_inline_html(' '.join(para))}</p>")
            para.clear()
        if items:
            out.append("<ul>" + "".join(f"<li>{_inline_html(i)}</li>" for i in items) + "</ul>")
            items.clear()

    for line in text.splitlines():
        stripped = line.strip()
        if code is not None:
            if stripped.startswith("```"):
                out.append(f"<pre><code>{html.escape(chr(10).join(code))}</code></pre>")
                code = None
            else:
                code.append(line)
            continue
        heading = re.match(r"(#{1,6})\s+(.*)", stripped)
        bullet = re.match(r"[-*]\s+(.*)", stripped)
        if stripped.startswith("```"):
            flush()
            code = []
        elif not stripped:
            flush()
        elif heading:
            flush()
            level = len(heading.group(1))
            out.append(f"<h{level}>{_inline_html(heading.group(2))}</h{level}>")
        elif bullet:
            if para:
                flush()
            items.append(bullet.group(1))
        else:
            if items:
                flush()
            para.append(stripped)
    flush()
    if code is not None:
        out.append(f"<pre><code>{html.escape(chr(10).join(code))}</code></pre>")
    return "\n".join(out)


def _md_cell(text: str) -> str:
    return text.replace("|", r"\|").replace("\n", " ")


_NUMBER = re.compile(r"^[-+]?(\d[\d,]*\.?\d*|\.\d+)([eE][-+]?\d+)?( ?%)?$|^[-+]?(inf|nan)$")


# ----------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class _Heading:
    text: str
    level: int


@dataclass(frozen=True)
class _Text:
    markdown: str


@dataclass(frozen=True)
class _Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str | None


@dataclass(frozen=True)
class _KeyValues:
    items: tuple[tuple[str, str], ...]
    caption: str | None


@dataclass(frozen=True)
class _Figure:
    source: Figure | Callable[[], Figure]
    caption: str
    file_name: str


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
        """Markdown text: one or several paragraphs (subset rendered in HTML, module doc)."""
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
        self._sections.append(_Figure(figure, str(caption), file_name))
        return self

    # ------------------------------------------------------------------------- rendering

    def _render_figures(self, folder: Path) -> dict[str, bytes]:
        pngs = {}
        for section in self._sections:
            if not isinstance(section, _Figure):
                continue
            fig = section.source if isinstance(section.source, Figure) else section.source()
            if not isinstance(fig, Figure):
                raise TypeError(f"figure {section.file_name!r}: builder returned {fig!r}")
            FigureCanvasAgg(fig)
            path = folder / section.file_name
            fig.savefig(path, format="png", dpi=self.dpi)
            pngs[section.file_name] = path.read_bytes()
        return pngs

    def to_markdown(self) -> str:
        """The report as markdown (figures referenced by their PNG file names)."""
        out = [f"# {self.title}", ""]
        figure_no = 0
        for s in self._sections:
            if isinstance(s, _Heading):
                out += ["#" * s.level + " " + s.text, ""]
            elif isinstance(s, _Text):
                out += [s.markdown.strip(), ""]
            elif isinstance(s, _Table):
                if s.caption:
                    out += [f"*{s.caption}*", ""]
                out.append("| " + " | ".join(_md_cell(h) for h in s.header) + " |")
                out.append("|" + "|".join("---" for _ in s.header) + "|")
                out += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in s.rows]
                out.append("")
            elif isinstance(s, _KeyValues):
                if s.caption:
                    out += [f"*{s.caption}*", ""]
                out += [f"- **{_md_cell(k)}:** {_md_cell(v)}" for k, v in s.items]
                out.append("")
            else:
                figure_no += 1
                out += [f"![{_md_cell(s.caption)}]({s.file_name})", "",
                        f"*Figure {figure_no}: {s.caption}*", ""]
        return "\n".join(out)

    def to_html(self, pngs: Mapping[str, bytes] | None = None) -> str:
        """The report as one HTML page; ``pngs`` (file name -> bytes) are embedded if given."""
        esc = html.escape
        body = [f"<h1>{esc(self.title)}</h1>"]
        figure_no = 0
        for s in self._sections:
            if isinstance(s, _Heading):
                body.append(f"<h{s.level}>{_inline_html(s.text)}</h{s.level}>")
            elif isinstance(s, _Text):
                body.append(markdown_to_html(s.markdown))
            elif isinstance(s, _Table):
                cap = f"<caption>{esc(s.caption)}</caption>" if s.caption else ""
                head = "".join(f"<th>{esc(h)}</th>" for h in s.header)
                rows = "".join(
                    "<tr>" + "".join(
                        f'<td class="num">{esc(c)}</td>' if _NUMBER.match(c) else
                        f"<td>{esc(c)}</td>" for c in r
                    ) + "</tr>"
                    for r in s.rows
                )
                body.append(f"<table>{cap}<thead><tr>{head}</tr></thead>"
                            f"<tbody>{rows}</tbody></table>")
            elif isinstance(s, _KeyValues):
                cap = f"<caption>{esc(s.caption)}</caption>" if s.caption else ""
                rows = "".join(
                    f'<tr><th>{esc(k)}</th><td class="num">{esc(v)}</td></tr>'
                    if _NUMBER.match(v) else f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>"
                    for k, v in s.items
                )
                body.append(f'<table class="kv">{cap}<tbody>{rows}</tbody></table>')
            else:
                figure_no += 1
                src = s.file_name
                if pngs is not None and s.file_name in pngs:
                    src = "data:image/png;base64," + base64.b64encode(
                        pngs[s.file_name]).decode("ascii")
                body.append(
                    f'<figure><a href="{esc(s.file_name)}"><img src="{src}" '
                    f'alt="{esc(s.caption)}"></a><figcaption>Figure {figure_no}: '
                    f"{esc(s.caption)}</figcaption></figure>"
                )
        return (
            '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f"<title>{esc(self.title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            + "\n".join(body)
            + "\n</body>\n</html>\n"
        )

    # ------------------------------------------------------------------------- writing

    def write(self, out_dir: str | os.PathLike, summary: Mapping[str, Any]) -> Path:
        """Writes the report folder atomically (module docstring); returns its absolute path.

        Args:
            out_dir: the report folder. If it exists it must be empty or an earlier report
                (contain ``summary.json``); it is replaced only once the new report is complete.
            summary: JSON-able mapping (numpy values allowed, see :func:`json_ready`) written
                to summary.json together with ``"complete": true``.

        Raises:
            ValueError: summary uses a reserved key. TypeError: a summary value has no JSON form.
            FileExistsError: ``out_dir`` is a file or a non-empty folder that is not a report.
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
        _check_replaceable(out_dir)
        parent = out_dir.parent
        parent.mkdir(parents=True, exist_ok=True)
        partial = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-", dir=parent))
        try:
            partial.chmod(0o755)  # mkdtemp makes it private; a report is meant to be shared
            pngs = self._render_figures(partial)
            _write_text(partial / "report.md", self.to_markdown())
            _write_text(partial / "report.html",
                        self.to_html(pngs if self.embed_images else None))
            files = sorted([*pngs, "report.md", "report.html", "summary.json"])
            data.update(complete=True, report_title=self.title, report_files=files)
            # summary.json last: a folder without it is never a finished report.
            _write_text(partial / "summary.json",
                        json.dumps(data, indent=2, allow_nan=False) + "\n")
            _replace_dir(partial, out_dir)
        except BaseException:
            shutil.rmtree(partial, ignore_errors=True)
            raise
        return out_dir


def _write_text(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def _check_replaceable(out_dir: Path) -> None:
    if not (out_dir.exists() or out_dir.is_symlink()):
        return
    if not out_dir.is_dir():
        raise FileExistsError(f"{out_dir} exists and is not a directory")
    if any(out_dir.iterdir()) and not (out_dir / "summary.json").is_file():
        raise FileExistsError(
            f"{out_dir} is a non-empty directory without summary.json (not a report); "
            "refusing to replace it"
        )


def _replace_dir(new: Path, target: Path) -> None:
    """Renames ``new`` to ``target``; an existing ``target`` is removed only afterwards."""
    if not target.exists():
        os.rename(new, target)
        return
    old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
    os.rename(target, old)
    try:
        os.rename(new, target)
    except BaseException:
        os.rename(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)
