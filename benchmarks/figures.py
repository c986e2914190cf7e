"""Headline figures of the benchmarks in one machine-readable line format.

Every benchmark prints its human-readable report and, for each headline figure, one line

    FIGURE <name> <value> <unit> <higher|lower>

(``higher`` when a larger value is better, e.g. a real-time factor; ``lower`` for a cost).
``benchmarks/compare_revisions.py`` reads these lines and nothing else.
"""

from __future__ import annotations

import math

__all__ = ["figure", "parse_figures"]

PREFIX = "FIGURE"


def figure(name: str, value: float, unit: str, better: str = "higher") -> None:
    """Prints one headline figure line (``name`` without spaces)."""
    if " " in name or better not in ("higher", "lower"):
        raise ValueError(f"name/better: {name!r} must have no spaces, {better!r} must be "
                         "'higher' or 'lower'")
    print(f"{PREFIX} {name} {float(value):.6g} {unit} {better}", flush=True)


def parse_figures(text: str) -> dict[str, tuple[float, str, str]]:
    """``{name: (value, unit, better)}`` of the FIGURE lines in a benchmark's output."""
    figures = {}
    for line in text.splitlines():
        fields = line.split()
        if len(fields) == 5 and fields[0] == PREFIX:
            try:
                value = float(fields[2])
            except ValueError:
                continue
            if math.isfinite(value):
                figures[fields[1]] = (value, fields[3], fields[4])
    return figures
