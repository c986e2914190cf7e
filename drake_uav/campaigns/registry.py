"""Scenario registry: names -> scenario functions, and the hook for new ones.

A scenario is a function ``(seed: int, params: dict) -> dict`` of metrics. The
built-in ones (:mod:`drake_uav.campaigns.scenarios`) register themselves here;
other packages join with :func:`register_scenario` (tracking NMPC, fault
scenarios) or are named by ``"package.module:function"`` without registering.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["Scenario", "register_scenario", "scenario", "scenario_names"]

Scenario = Callable[[int, dict], Mapping[str, Any]]

_SCENARIOS: dict[str, Scenario] = {}
_BUILT_IN = ("drake_uav.campaigns.scenarios", "drake_uav.campaigns.realistic_logs",
             "drake_uav.campaigns.discovery_cases", "drake_uav.campaigns.motor_fault")


def register_scenario(name: str, function: Scenario | None = None):
    """Registers ``function`` under ``name``; usable as a decorator
    (``@register_scenario("tracking_nmpc")``). A name may be registered once."""

    def add(f: Scenario) -> Scenario:
        if not callable(f):
            raise TypeError(f"register_scenario({name!r}): not a function: {f!r}")
        if name in _SCENARIOS and _SCENARIOS[name] is not f:
            raise ValueError(f"register_scenario: {name!r} is already registered "
                             f"({_SCENARIOS[name].__module__})")
        _SCENARIOS[name] = f
        return f

    return add if function is None else add(function)


def scenario_names() -> list[str]:
    """Registered names (the built-in scenarios included)."""
    _import_built_in()
    return sorted(_SCENARIOS)


def scenario(name: str | Scenario) -> Scenario:
    """The scenario function of a registered ``name`` or of ``"module:function"``."""
    if callable(name):
        return name
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            target = importlib.import_module(module)
            for part in attr.split("."):
                target = getattr(target, part)
        except (ImportError, AttributeError) as err:
            raise ValueError(f"scenario {name!r}: cannot import it ({err})") from None
        return target
    if name not in _SCENARIOS:
        _import_built_in()
    if name not in _SCENARIOS:
        raise ValueError(f"scenario {name!r}: unknown (registered: {', '.join(sorted(_SCENARIOS))};"
                         f" or give module:function)")
    return _SCENARIOS[name]


def _import_built_in() -> None:
    """Imports the modules of the built-in scenarios (they register themselves)."""
    for module in _BUILT_IN:
        importlib.import_module(module)
