"""Every page the docs point at exists, and every section they name by its title is there:
``[text](page.md)`` links, ``docs/page.md`` mentions and ``page.md, "Section"`` references
in docs/, README.md and CHANGELOG.md."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(ROOT.glob("docs/*.md")) + [ROOT / "README.md", ROOT / "CHANGELOG.md"]
REFERENCE = re.compile(r"\b([a-z_]+\.md)\b(?:[,:]?\s*\(?(?:step \d)?\s*\"([A-Z][^\"]{0,80})\")?")
NOT_PAGES = {"report.md", "pyulog.md", "summary.md"}  # files a command writes
"""File names the docs mention that are not pages of the project (a report's own file)."""


def _page(name: str) -> Path:
    return ROOT / name if name in ("README.md", "CHANGELOG.md") else ROOT / "docs" / name


def _titles(page: Path) -> list[str]:
    """Headings and bold run-in titles (``**Title.**``) of a page, whitespace collapsed."""
    text = page.read_text(encoding="utf-8")
    found = re.findall(r"^#+ (.*)$", text, re.M) + re.findall(r"\*\*([^*]+?)\*\*", text)
    return [" ".join(t.split()).rstrip(".") for t in found]


@pytest.mark.parametrize("source", PAGES, ids=lambda p: p.name)
def test_every_reference_resolves(source):
    text = source.read_text(encoding="utf-8")
    for link in re.findall(r"\]\(([\w./-]+\.md)(?:#[\w-]+)?\)", text):
        assert (source.parent / link).exists(), f"{source.name}: link to {link}"
    for name, section in REFERENCE.findall(text):
        if name in NOT_PAGES:
            continue
        assert _page(name).exists(), f"{source.name}: names {name}, which does not exist"
        if section:
            wanted = " ".join(section.split()).rstrip(".")
            assert any(t.startswith(wanted) for t in _titles(_page(name))), \
                f"{source.name}: {name} has no section {wanted!r}"
