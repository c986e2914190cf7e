"""Load fixed-wing parameters by catalog name or from a TOML file.

A TOML file may start from a catalog aircraft (``base = "aerosonde"``) and
override any field; tables ``[derivatives]``, ``[propulsion]`` and ``[limits]``
override entries of the corresponding parts::

    base = "aerosonde"
    name = "aerosonde-heavy"
    mass = 15.0

    [derivatives]
    CD_0 = 0.05
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

from drake_uav.vehicles.fixed_wing import (
    ControlLimits,
    FixedWingParams,
    Propulsion,
    fixed_wing_catalog,
)

__all__ = ["load_fixed_wing"]


def load_fixed_wing(name_or_path: str | Path) -> FixedWingParams:
    """Catalog aircraft by name, or parameters from a ``.toml`` file.

    Raises ``ValueError`` naming the unknown aircraft, the unknown field or the
    invalid value.
    """
    catalog = fixed_wing_catalog()
    text = str(name_or_path)
    if text in catalog:
        return catalog[text]
    path = Path(text)
    if path.suffix != ".toml":
        raise ValueError(
            f"unknown aircraft '{text}': use one of {sorted(catalog)} or a params .toml file")
    if not path.is_file():
        raise ValueError(f"aircraft parameter file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: not valid TOML: {err}") from None
    return _from_mapping(data, catalog, source=str(path))


def _from_mapping(data: dict, catalog: dict[str, FixedWingParams], source: str):
    data = dict(data)
    base_name = data.pop("base", None)
    if base_name is not None and base_name not in catalog:
        raise ValueError(f"{source}: base '{base_name}' is not in the catalog {sorted(catalog)}")
    base = catalog.get(base_name)
    fields = {f.name for f in dataclasses.fields(FixedWingParams)}
    unknown = sorted(set(data) - fields)
    if unknown:
        raise ValueError(f"{source}: unknown field(s) {unknown}; known: {sorted(fields)}")
    parts = {
        "propulsion": base.propulsion if base else Propulsion(),
        "limits": base.limits if base else ControlLimits(),
    }
    for key, default in parts.items():
        if key in data:
            try:
                data[key] = dataclasses.replace(default, **data[key])
            except TypeError as err:
                raise ValueError(f"{source}: [{key}] {err}") from None
    if base is not None:
        if "derivatives" in data:
            data["derivatives"] = {**base.derivatives, **data["derivatives"]}
        return dataclasses.replace(base, **data)
    missing = sorted(
        f.name for f in dataclasses.fields(FixedWingParams)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        and f.name not in data
    )
    if missing:
        raise ValueError(f"{source}: missing field(s) {missing} (or give base = \"<catalog>\")")
    return FixedWingParams(**data)
