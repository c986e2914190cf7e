"""A declared propeller table: the thrust and torque coefficients against the advance ratio.

A propeller's maker or a wind-tunnel database (the UIUC propeller data site, for one)
gives ``C_T`` and ``C_Q`` (or the power coefficient ``C_P = 2 pi C_Q``) at a few advance
ratios ``J = Va / (n D)``. With the shaft speed logged (an RPM sensor or an ESC's
telemetry), such a table fixes the thrust independently of the drag: the main job then
takes ``T = rho n^2 D^4 C_T(J)`` from it instead of identifying ``C_T0, C_T1`` with C_X
(``drake-uav identify --propeller FILE``).

Two file formats, chosen by the suffix:

* **CSV** (``.csv``): a header row naming the columns ``J``, ``C_T`` and optionally
  ``C_Q`` or ``C_P``, and ``diameter`` [m] (the same value on every row, or on the first
  row only); one row per advance ratio. ``#`` starts a comment line.
* **TOML** (``.toml``): ``diameter = 0.508`` [m] and the arrays ``J``, ``C_T`` and
  optionally ``C_Q`` or ``C_P``, of equal length.

The coefficients are fitted by least squares as the quadratics of
:mod:`drake_uav.model.propeller`, ``C(J) = c0 + c1 J + c2 J^2`` (the form the thrust model
uses everywhere); :attr:`PropellerTable.thrust_fit_rms` says how well the quadratic
follows the table, and the advance ratios of a flight outside the table's range are
reported by the job.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np

from drake_uav.model.propeller import coefficient_polynomial

__all__ = ["PropellerTable", "read_propeller_table", "MIN_TABLE_ROWS"]

MIN_TABLE_ROWS = 3
"""Fewest distinct advance ratios a table needs (three coefficients per quadratic)."""


@dataclasses.dataclass(frozen=True)
class PropellerTable:
    """A propeller's declared coefficients and their quadratic fits.

    Attributes
    ----------
    diameter : float
        Propeller diameter D [m].
    advance_ratio : numpy.ndarray
        The table's advance ratios J [-].
    thrust_coefficient : numpy.ndarray
        C_T at each J [-].
    torque_coefficient : numpy.ndarray or None
        C_Q at each J [-] (from ``C_P / (2 pi)`` for a power column), None when not given.
    source : str
        Where the table came from (the file), for messages and the report.

    Examples
    --------
    >>> import numpy as np
    >>> table = PropellerTable(0.5, np.array([0.0, 0.3, 0.6]),
    ...                        np.array([0.10, 0.08, 0.04]), None, "example")
    >>> np.round(table.thrust_coefficients, 6).tolist()
    [0.1, -0.033333, -0.111111]
    """

    diameter: float
    advance_ratio: np.ndarray
    thrust_coefficient: np.ndarray
    torque_coefficient: np.ndarray | None
    source: str

    def __post_init__(self):
        where = f"{self.source}: "
        if not (math.isfinite(self.diameter) and self.diameter > 0.0):
            raise ValueError(f"{where}field diameter: a positive diameter in metres, "
                             f"got {self.diameter!r}")
        j = np.asarray(self.advance_ratio, dtype=float)
        columns = {"J": j, "C_T": np.asarray(self.thrust_coefficient, dtype=float)}
        if self.torque_coefficient is not None:
            columns["C_Q"] = np.asarray(self.torque_coefficient, dtype=float)
        for name, values in columns.items():
            if values.ndim != 1 or len(values) != len(j):
                raise ValueError(f"{where}field {name}: {values.size} values for {len(j)} "
                                 "advance ratios; give one per J")
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise ValueError(f"{where}field {name}: entry {bad[0] + 1} is not a number")
        if np.any(j < 0.0):
            raise ValueError(f"{where}field J: advance ratios must be >= 0, got "
                             f"{float(j.min()):g}")
        if len(np.unique(j)) < MIN_TABLE_ROWS:
            raise ValueError(f"{where}field J: {len(np.unique(j))} distinct advance ratios; "
                             f"a quadratic C_T(J) needs at least {MIN_TABLE_ROWS}")
        for name, values in columns.items():
            object.__setattr__(self, {"J": "advance_ratio", "C_T": "thrust_coefficient",
                                      "C_Q": "torque_coefficient"}[name], values)

    @property
    def thrust_coefficients(self) -> tuple[float, float, float]:
        """``(C_T0, C_T1, C_T2)`` of the least-squares quadratic through the table [-]."""
        return _quadratic(self.advance_ratio, self.thrust_coefficient)

    @property
    def torque_coefficients(self) -> tuple[float, float, float] | None:
        """``(C_Q0, C_Q1, C_Q2)`` [-], or None without a torque or power column."""
        if self.torque_coefficient is None:
            return None
        return _quadratic(self.advance_ratio, self.torque_coefficient)

    @property
    def thrust_fit_rms(self) -> float:
        """RMS difference [-] between the table's C_T and the fitted quadratic."""
        fitted = coefficient_polynomial(self.advance_ratio, self.thrust_coefficients)
        return float(np.sqrt(np.mean((fitted - self.thrust_coefficient) ** 2)))

    def describe(self) -> str:
        """One line for the report: the file, the diameter and the fitted C_T(J)."""
        c0, c1, c2 = self.thrust_coefficients
        return (f"propeller table {self.source}: D = {self.diameter:.4g} m, C_T(J) = "
                f"{c0:.4g} {c1:+.4g} J {c2:+.4g} J^2 over J {self.advance_ratio.min():.3g}-"
                f"{self.advance_ratio.max():.3g} (fit RMS {self.thrust_fit_rms:.2g})")


def _quadratic(j: np.ndarray, values: np.ndarray) -> tuple[float, float, float]:
    design = np.column_stack([np.ones_like(j), j, j * j])
    return tuple(float(c) for c in np.linalg.lstsq(design, values, rcond=None)[0])


def read_propeller_table(path: str | Path) -> PropellerTable:
    """Reads a propeller table (module docstring for the formats).

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.toml`` file.

    Returns
    -------
    PropellerTable

    Raises
    ------
    ValueError
        One line naming the file and the field: a missing or unreadable file, an unknown
        suffix, a missing column, a value that is not a number, too few advance ratios.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such propeller table file")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        fields = _csv_fields(path)
    elif suffix == ".toml":
        try:
            fields = tomllib.loads(path.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
            raise ValueError(f"{path}: not valid TOML ({err})") from None
    else:
        raise ValueError(f"{path}: a propeller table is a .csv or .toml file, got "
                         f"{suffix or 'no suffix'!r}")
    for name in ("diameter", "J", "C_T"):
        if name not in fields:
            raise ValueError(f"{path}: field {name} missing (a table needs diameter [m], J "
                             "and C_T; C_Q or C_P optional)")
    if "C_Q" in fields and "C_P" in fields:
        raise ValueError(f"{path}: fields C_Q and C_P both given; give one of them")
    diameter = _number(path, "diameter", fields["diameter"])
    torque = None
    if "C_Q" in fields:
        torque = _numbers(path, "C_Q", fields["C_Q"])
    elif "C_P" in fields:
        torque = _numbers(path, "C_P", fields["C_P"]) / (2.0 * math.pi)
    return PropellerTable(diameter, _numbers(path, "J", fields["J"]),
                          _numbers(path, "C_T", fields["C_T"]), torque, str(path))


def _csv_fields(path: Path) -> dict[str, object]:
    """Column name -> list of cells of a CSV table; ``diameter`` -> its one value."""
    lines = [line for line in path.read_text().splitlines()
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise ValueError(f"{path}: empty propeller table")
    rows = list(csv.reader(lines))
    header = [name.strip() for name in rows[0]]
    columns = {name: [row[k].strip() if k < len(row) else "" for row in rows[1:]]
               for k, name in enumerate(header)}
    if "diameter" in columns:
        given = [cell for cell in columns["diameter"] if cell]
        if len(set(given)) != 1:
            raise ValueError(f"{path}: field diameter: one value [m] (on every row or on the "
                             f"first only), got {sorted(set(given)) or 'none'}")
        columns["diameter"] = given[0]
    return columns


def _number(path: Path, field: str, value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: field {field}: not a number ({value!r})") from None


def _numbers(path: Path, field: str, values) -> np.ndarray:
    if isinstance(values, str | int | float):
        raise ValueError(f"{path}: field {field}: a list of numbers, one per advance ratio")
    return np.array([_number(path, f"{field} entry {k + 1}", v)
                     for k, v in enumerate(values)], dtype=float)
