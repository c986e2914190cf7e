"""Load fixed-wing parameters (catalog name or TOML file) and declared sensor specs.

A TOML file may start from a catalog aircraft (``base = "aerosonde"``) and
override any field; tables ``[derivatives]``, ``[propulsion]`` and ``[limits]``
override entries of the corresponding parts::

    base = "aerosonde"
    name = "aerosonde-heavy"
    mass = 15.0

    [derivatives]
    CD_0 = 0.05

A sensor spec file (:func:`load_sensor_spec`) declares the white-noise standard
deviation per sample of logged channels, each with its unit::

    [noise_std]
    imu_ax = { std = 0.05, unit = "m/s^2" }
    imu_p = { std = 0.35, unit = "deg/s" }
    vane_alpha = { std = 0.6, unit = "deg" }
    pitot_airspeed = { std = 0.3, unit = "m/s" }
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

from drake_uav.vehicles.fixed_wing import (
    ControlLimits,
    FixedWingParams,
    Propulsion,
    fixed_wing_catalog,
)
from drake_uav.vehicles.sensors import CHANNEL_LAYOUT

__all__ = ["load_fixed_wing", "load_sensor_spec", "SPEC_UNITS"]

SPEC_UNITS = {
    "m/s^2": {"m/s^2": 1.0, "g": 9.80665, "mg": 9.80665e-3},
    "rad/s": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0},
    "m/s": {"m/s": 1.0, "km/h": 1.0 / 3.6, "kn": 1852.0 / 3600.0},
    "m": {"m": 1.0, "ft": 0.3048},
    "Pa": {"Pa": 1.0, "hPa": 100.0, "mbar": 100.0},
}
"""Units a sensor spec may use, by the channel's own (SI) unit: unit -> factor to SI."""


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
    try:
        return _from_mapping(data, catalog, source=str(path))
    except ValueError as err:  # an invalid value: name the file as well as the field
        message = str(err)
        raise ValueError(message if message.startswith(str(path)) else
                         f"{path}: {message}") from None


def _numbers_only(source: str, where: str, entries: dict) -> None:
    """Raises ValueError naming the entry whose value is not a number (or list of numbers)."""
    for key, value in entries.items():
        items = value if isinstance(value, list) else [value]
        if not items or any(isinstance(v, bool) or not isinstance(v, int | float)
                            for v in items):
            raise ValueError(f"{source}: {where}{key} = {value!r} is not a number")


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
    if "name" in data and not isinstance(data["name"], str):
        raise ValueError(f"{source}: name = {data['name']!r} is not a text")
    _numbers_only(source, "", {k: v for k, v in data.items()
                               if k not in ("name", "derivatives", "propulsion", "limits")})
    for table in ("derivatives", "propulsion", "limits"):
        if table in data:
            if not isinstance(data[table], dict):
                raise ValueError(f"{source}: {table} must be a [{table}] table")
            _numbers_only(source, f"[{table}] ", data[table])
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


def _spec_channels() -> dict[str, str]:
    """Logged sensor channel -> its SI unit (the channels a sensor spec may declare)."""
    channels = {name: unit for *_, names, unit in CHANNEL_LAYOUT for name in names}
    channels["pitot_airspeed"] = "m/s"
    return channels


def load_sensor_spec(path: str | Path) -> dict[str, float]:
    """Declared sensor noise from a TOML file: log channel -> standard deviation [SI].

    The file's ``[noise_std]`` table gives, per logged channel (``imu_ax``,
    ``imu_p``, ``vane_alpha``, ``pitot_airspeed``, ``pitot_qbar``, ...), the
    white-noise standard deviation per sample as ``{ std = value, unit = "..." }``
    (units: :data:`SPEC_UNITS`); the result is in the channel's SI unit. Raises
    ``ValueError`` naming the file and the channel or field at fault.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"sensor spec file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not valid TOML: {err}") from None
    unknown = sorted(set(data) - {"noise_std"})
    if unknown or not isinstance(data.get("noise_std"), dict):
        raise ValueError(f"{path}: expected a [noise_std] table (channel = {{ std = ..., "
                         f"unit = \"...\" }}){f'; unknown key(s) {unknown}' if unknown else ''}")
    channels = _spec_channels()
    return {channel: _spec_std(path, channel, entry, channels)
            for channel, entry in data["noise_std"].items()}


def _spec_std(path: Path, channel: str, entry, channels: dict[str, str]) -> float:
    """One declared standard deviation, converted to the channel's SI unit."""
    where = f"{path}: noise_std.{channel}"
    if channel not in channels:
        raise ValueError(f"{where}: unknown channel; known: {sorted(channels)}")
    if not isinstance(entry, dict) or set(entry) != {"std", "unit"}:
        raise ValueError(f"{where}: expected {{ std = <number>, unit = \"<unit>\" }}, "
                         f"got {entry!r}")
    std, unit = entry["std"], entry["unit"]
    if isinstance(std, bool) or not isinstance(std, int | float) or not (
            math.isfinite(std) and std >= 0):
        raise ValueError(f"{where}: std must be a finite number >= 0, got {std!r}")
    factors = SPEC_UNITS[channels[channel]]
    if unit not in factors:
        raise ValueError(f"{where}: unit {unit!r} does not fit the channel; use one of "
                         f"{sorted(factors)}")
    return float(std) * factors[unit]
