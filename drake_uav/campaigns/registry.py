"""Scenario registry: names -> scenario functions, and the hook for new ones.

A scenario is a function ``(seed: int, params: dict) -> dict`` of metrics. The
built-in ones (:mod:`drake_uav.campaigns.scenarios`) register themselves here;
other packages join with :func:`register_scenario` (tracking NMPC, fault
scenarios) or are named by ``"package.module:function"`` without registering.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["BUILT_IN", "Scenario", "check_scenario", "register_scenario", "scenario",
           "scenario_names"]

Scenario = Callable[[int, dict], Mapping[str, Any]]

_SCENARIOS: dict[str, Scenario] = {}
BUILT_IN = {"main_job": "drake_uav.campaigns.scenarios",
            "air_data_ekf": "drake_uav.campaigns.scenarios",
            "tracking_nmpc": "drake_uav.campaigns.scenarios",
            "realistic_logs": "drake_uav.testing.realistic_logs",
            "discovery": "drake_uav.testing.discovery_cases",
            "logged_force": "drake_uav.testing.logged_force_cases",
            "motor_fault": "drake_uav.campaigns.motor_fault"}
"""Built-in scenario name -> the module that registers it (imported on first use only)."""


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
    """The scenario function of a registered ``name`` or of ``"module:function"``.

    Raises ``ValueError`` for an unknown name, a module that does not import, or an object that
    is not a function of ``(seed, params)``.
    """
    if callable(name):
        return _checked_function(name, repr(name))
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            target = importlib.import_module(module)
            for part in attr.split("."):
                target = getattr(target, part)
        except Exception as err:  # a missing module or name, or a module that fails to load
            raise ValueError(f"scenario {name!r}: cannot import it ({type(err).__name__}: "
                             f"{err})") from None
        return _checked_function(target, repr(name))
    check_scenario(name)
    if name not in _SCENARIOS:
        importlib.import_module(BUILT_IN[name])
    return _SCENARIOS[name]


def check_scenario(name: str | Scenario) -> None:
    """Raises ``ValueError`` unless ``name`` names a scenario (:func:`scenario`); a built-in
    name is checked without importing its module."""
    if isinstance(name, str) and ":" not in name:
        if name not in _SCENARIOS and name not in BUILT_IN:
            known = sorted({*_SCENARIOS, *BUILT_IN})
            raise ValueError(f"scenario {name!r}: unknown (built-in: {', '.join(known)}; or "
                             "give package.module:function)")
        return
    scenario(name)


def _checked_function(target, shown: str) -> Scenario:
    """``target`` if it can be called as ``target(seed, params)``."""
    what = "a function (seed, params) -> dict of metrics"
    if not callable(target):
        raise ValueError(f"scenario {shown}: is a {type(target).__name__}, not {what}")
    try:
        inspect.signature(target).bind(0, {})
    except TypeError:
        raise ValueError(f"scenario {shown}: its arguments do not take (seed, params); "
                         f"a scenario is {what}") from None
    except ValueError:  # no signature to read (some built-in functions): tried when run
        pass
    return target


def _import_built_in() -> None:
    """Imports the modules of the built-in scenarios (they register themselves)."""
    for module in dict.fromkeys(BUILT_IN.values()):
        importlib.import_module(module)
