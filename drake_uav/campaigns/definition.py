"""What a campaign is: a scenario, its parameters and seeds, expanded into runs.

A campaign runs ``scenario(seed, params) -> metrics`` once per (grid point, seed).
``params`` merges three sources, in this order of precedence (later wins):

* ``fixed``: the same value in every run;
* ``grid``: name -> list of values; every combination is a grid point
  (Cartesian product, in the order the names and values are given);
* ``distributions``: name -> :class:`Distribution`; drawn once per run from a
  generator seeded by (run seed, name), so a run's draw does not depend on which
  worker runs it, on the run order, or on the other parameters.

A run is identified by its key (grid point index, seed); rows of the results are
sorted by that key.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import zlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["Distribution", "Campaign", "RunSpec", "parse_seeds"]

_KINDS = {"uniform": 2, "loguniform": 2, "normal": 2, "choice": 1}


@dataclasses.dataclass(frozen=True)
class Distribution:
    """A scalar parameter drawn per run.

    ``kind`` and ``args``: ``uniform (low, high)``, ``loguniform (low, high)`` (both
    > 0), ``normal (mean, std)`` or ``choice (values,)``.
    """

    kind: str
    args: tuple

    def __post_init__(self):
        if self.kind not in _KINDS:
            raise ValueError(f"Distribution.kind: unknown {self.kind!r} (known: {sorted(_KINDS)})")
        if len(self.args) != _KINDS[self.kind]:
            raise ValueError(f"Distribution.args: {self.kind} takes {_KINDS[self.kind]} "
                             f"argument(s), got {self.args!r}")
        if self.kind == "loguniform" and min(self.args) <= 0.0:
            raise ValueError(f"Distribution.args: loguniform bounds must be > 0, got {self.args}")
        if self.kind == "choice" and not len(self.args[0]):
            raise ValueError("Distribution.args: choice needs at least one value")

    def draw(self, rng: np.random.Generator):
        """One value drawn with ``rng``."""
        if self.kind == "uniform":
            return float(rng.uniform(*self.args))
        if self.kind == "loguniform":
            low, high = self.args
            return float(math.exp(rng.uniform(math.log(low), math.log(high))))
        if self.kind == "normal":
            return float(rng.normal(*self.args))
        values = list(self.args[0])
        return values[int(rng.integers(len(values)))]

    def describe(self) -> list:
        """JSON form: ``[kind, *args]``."""
        return [self.kind, *[list(a) if isinstance(a, tuple | list) else a for a in self.args]]


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One run of a campaign: its key (point, seed) and its parameters."""

    point: int
    seed: int
    params: Mapping[str, Any]

    @property
    def key(self) -> tuple[int, int]:
        return (self.point, self.seed)


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"0:40"`` (start:stop), ``"1,5,9"`` or ``"7"`` -> the seeds."""
    try:
        if ":" in text:
            start, stop = (int(v) for v in text.split(":", 1))
            return tuple(range(start, stop))
        return tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"seeds: expected START:STOP or a comma list of integers, "
                         f"got {text!r}") from None


def _json_value(value):
    if isinstance(value, np.generic):
        return value.item()
    return value


@dataclasses.dataclass(frozen=True)
class Campaign:
    """A scenario, its parameters and seeds (module docstring).

    Args:
        scenario: a function ``(seed: int, params: dict) -> dict`` of metrics
            (bool, int, float or str values), importable by name so that Dask workers
            can load it, or the name of a registered scenario
            (:func:`~drake_uav.campaigns.scenarios.scenario`).
        seeds: the seeds; every grid point runs every seed.
        grid: parameter name -> values (Cartesian product).
        distributions: parameter name -> :class:`Distribution` (or ``[kind, *args]``).
        fixed: parameter name -> value, the same in every run.
        name: a label for reports (default: the scenario's name).
    """

    scenario: Callable[[int, dict], Mapping[str, Any]] | str
    seeds: Sequence[int]
    grid: Mapping[str, Sequence[Any]] = dataclasses.field(default_factory=dict)
    distributions: Mapping[str, Distribution | Sequence] = dataclasses.field(
        default_factory=dict)
    fixed: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    name: str | None = None

    def __post_init__(self):
        seeds = tuple(int(s) for s in self.seeds)
        if not seeds:
            raise ValueError("Campaign.seeds: no seeds")
        if len(set(seeds)) != len(seeds):
            raise ValueError("Campaign.seeds: repeated seeds")
        object.__setattr__(self, "seeds", seeds)
        grid = {str(k): tuple(_json_value(v) for v in values) for k, values in self.grid.items()}
        for k, values in grid.items():
            if not values:
                raise ValueError(f"Campaign.grid[{k!r}]: no values")
        object.__setattr__(self, "grid", grid)
        dists = {str(k): d if isinstance(d, Distribution) else Distribution(d[0], tuple(d[1:]))
                 for k, d in self.distributions.items()}
        object.__setattr__(self, "distributions", dists)
        object.__setattr__(self, "fixed", {str(k): _json_value(v) for k, v in self.fixed.items()})
        if not (isinstance(self.scenario, str) or callable(self.scenario)):
            raise TypeError(f"Campaign.scenario: a function or a scenario name, "
                            f"got {self.scenario!r}")

    @property
    def scenario_name(self) -> str:
        """The scenario's name: its registered name or ``module:qualname``."""
        if isinstance(self.scenario, str):
            return self.scenario
        return f"{self.scenario.__module__}:{self.scenario.__qualname__}"

    @property
    def label(self) -> str:
        return self.name or self.scenario_name

    def points(self) -> list[dict[str, Any]]:
        """The grid points, in order (one empty point without a grid)."""
        names = list(self.grid)
        return [dict(zip(names, combo, strict=True))
                for combo in itertools.product(*(self.grid[n] for n in names))]

    def runs(self) -> list[RunSpec]:
        """Every run, sorted by key (point, seed)."""
        return [RunSpec(point, seed, self.params(grid_point, seed))
                for point, grid_point in enumerate(self.points()) for seed in self.seeds]

    def params(self, grid_point: Mapping[str, Any], seed: int) -> dict[str, Any]:
        """The parameters of the run (``grid_point``, ``seed``)."""
        params = {**self.fixed, **grid_point}
        for name, dist in self.distributions.items():
            rng = np.random.default_rng([seed & 0xFFFFFFFF, zlib.crc32(name.encode())])
            params[name] = dist.draw(rng)
        return params

    def definition(self) -> dict[str, Any]:
        """JSON-ready description without the seeds: what a resumed run must match."""
        return {
            "scenario": self.scenario_name,
            "grid": {k: list(v) for k, v in self.grid.items()},
            "distributions": {k: d.describe() for k, d in self.distributions.items()},
            "fixed": dict(self.fixed),
        }

    def fingerprint(self) -> str:
        """Stable text of :meth:`definition` (sorted keys)."""
        return json.dumps(self.definition(), sort_keys=True)
