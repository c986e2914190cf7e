"""A console progress bar for campaigns: runs done, errors, elapsed time, estimate left."""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["ProgressBar"]


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600:d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class ProgressBar:
    """``[#####.....] 12/40 runs, 1 error, 0:00:35 elapsed, 0:01:10 left``.

    On a terminal the line is redrawn in place; elsewhere (a CI log) a line is
    printed at every tenth of the runs, so logs stay short.

    Args:
        total: runs to do in this session.
        done: runs already on disk (shown in the label, not counted in the rate).
        stream: where to write (default ``sys.stderr``); ``None`` disables output.
    """

    def __init__(self, total: int, done: int = 0, stream: TextIO | None = sys.stderr,
                 width: int = 30):
        self.total, self.skipped, self.stream, self.width = total, done, stream, width
        self.count = self.errors = 0
        self._start = time.perf_counter()
        self._tty = bool(stream is not None and getattr(stream, "isatty", lambda: False)())
        self._last_tenth = -1
        if stream is not None and done:
            print(f"resuming: {done} run(s) already done, {total} to go", file=stream,
                  flush=True)

    def line(self) -> str:
        filled = self.width * self.count // self.total if self.total else self.width
        elapsed = time.perf_counter() - self._start
        left = (elapsed / self.count * (self.total - self.count)) if self.count else float("nan")
        errors = f", {self.errors} error{'s' if self.errors != 1 else ''}" if self.errors else ""
        eta = _clock(left) if self.count else "?"
        return (f"[{'#' * filled}{'.' * (self.width - filled)}] {self.count}/{self.total} runs"
                f"{errors}, {_clock(elapsed)} elapsed, {eta} left")

    def update(self, error: bool = False) -> None:
        """One more run finished (``error``: it failed)."""
        self.count += 1
        self.errors += bool(error)
        if self.stream is None:
            return
        if self._tty:
            print("\r" + self.line(), end="", file=self.stream, flush=True)
            return
        tenth = 10 * self.count // max(self.total, 1)
        if tenth != self._last_tenth:
            self._last_tenth = tenth
            print(self.line(), file=self.stream, flush=True)

    def close(self) -> None:
        if self.stream is not None and self._tty:
            print(file=self.stream, flush=True)
