"""The same flight gives the same findings from every file format.

The bundled flight (150 s, default sensors, light turbulence, propwash drag C_D += 0.1 T_c
put into the physics) is read as Parquet, CSV, an ArduPilot .bin and a PX4 .ulg with its
vanes named, as ``drake-uav identify FILE --vanes ...`` reads them: each must find exactly
``thrust_propwash``, the same list from every file.
"""

from pathlib import Path

import numpy as np
import pytest
from log_writers import dataflash_from_log, ulog_from_log

import drake_uav
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.readers import read_log
from drake_uav.io.streams import FieldSource
from drake_uav.vehicles import aerosonde

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
PARAMS = aerosonde()
VANES = {"bin": ("VANE", "AoA", "SSA", np.radians(1.0)),
         "ulg": ("vane_angles", "alpha", "beta", 1.0)}
"""Where the test writers put the vanes: message, alpha field, beta field, scale to rad."""


def _read(kind: str, log: FlightLog, folder: Path) -> FlightLog:
    if kind == "parquet":
        return read_log(SAMPLE)
    path = folder / f"flight.{kind}"
    if kind == "csv":
        log.save(path)
        return read_log(path)
    (dataflash_from_log if kind == "bin" else ulog_from_log)(log, path)
    message, alpha, beta, scale = VANES[kind]
    vanes = {"vane_alpha": FieldSource(message, alpha, unit="rad", scale=scale),
             "vane_beta": FieldSource(message, beta, unit="rad", scale=scale)}
    return read_log(path, extra=vanes, deflections=PARAMS.limits.deflections())


@pytest.fixture(scope="module")
def findings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("formats")
    log = FlightLog.load(SAMPLE)
    return {kind: list(identify(_read(kind, log, folder), PARAMS, source=kind).findings)
            for kind in ("parquet", "csv", "bin", "ulg")}


def test_every_format_finds_exactly_the_injected_effect(findings):
    assert findings == {kind: ["thrust_propwash"] for kind in findings}
