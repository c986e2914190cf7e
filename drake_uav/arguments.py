"""Command-line argument checks shared by the ``drake-uav`` sub-commands.

Every option is checked when the command line is parsed, before any work and before the
analysis stack (pydrake) loads; a bad value stops the command with one line
``error: drake-uav <command>: argument --option: ...`` and exit code 2. A new sub-command
declares its options with these types and checks its outputs with
:func:`~drake_uav.reporting.output.check_output_folder` (a report or plot folder) or
:func:`~drake_uav.reporting.output.check_output_file` (one file).

This module uses the standard library only.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["OneLineParser", "real", "integer", "seed", "MAX_SEED"]

MAX_SEED = 2**32 - 1
"""Largest seed: Drake's random generators take 32-bit seeds."""


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors raise ``ValueError`` with one line naming the command
    and the option (the caller prints ``error: ...`` and exits 2) instead of printing the usage.
    Its sub-command parsers are of the same class."""

    def error(self, message: str):
        raise ValueError(f"{self.prog}: {message} (see {self.prog} --help)")


def _bounds_text(above, at_least, below, at_most, unit: str) -> str:
    unit = f" {unit}" if unit else ""
    bounds = ((">", above), (">=", at_least), ("<", below), ("<=", at_most))
    return " and ".join(f"{sign} {value:g}{unit}" if isinstance(value, float) else
                        f"{sign} {value}{unit}" for sign, value in bounds if value is not None)


def real(*, above: float | None = None, at_least: float | None = None,
         below: float | None = None, at_most: float | None = None, unit: str = "",
         why: str = "") -> Callable[[str], float]:
    """An argparse ``type``: a finite float within the given bounds.

    Parameters
    ----------
    above, at_least, below, at_most : strict and inclusive bounds (None: unbounded).
    unit : the unit shown in the message, e.g. ``"m/s"``.
    why : a reason appended to the message, e.g. ``"the RMSE is measured after 2 s"``.
    """
    bounds = _bounds_text(above, at_least, below, at_most, unit)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        inside = math.isfinite(value) and not (
            (above is not None and not value > above)
            or (at_least is not None and not value >= at_least)
            or (below is not None and not value < below)
            or (at_most is not None and not value <= at_most))
        if not inside:
            raise argparse.ArgumentTypeError(
                f"expected a finite number{' ' + bounds if bounds else ''}, got {text!r}"
                + (f" ({why})" if why else ""))
        return value

    parse.__name__ = "number"
    return parse


def integer(*, at_least: int | None = None, at_most: int | None = None,
            why: str = "") -> Callable[[str], int]:
    """An argparse ``type``: an integer within the given inclusive bounds."""
    bounds = _bounds_text(None, at_least, None, at_most, "")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or (at_least is not None and value < at_least) or (
                at_most is not None and value > at_most):
            raise argparse.ArgumentTypeError(
                f"expected an integer{' ' + bounds if bounds else ''}, got {text!r}"
                + (f" ({why})" if why else ""))
        return value

    parse.__name__ = "integer"
    return parse


seed = integer(at_least=0, at_most=MAX_SEED)
"""An argparse ``type``: a random seed, 0 .. 2**32 - 1."""
