"""The main job end to end: undeclared effects put into the physics are found by name,
the equation error falls, the reconstruction improves; clean data gives no discovery."""

import json
import subprocess
import sys

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.discovery.result import NO_EFFECT_MESSAGE
from drake_uav.identification.pipeline import identify
from drake_uav.vehicles import aerosonde
from drake_uav.vehicles.sensors import (
    ChannelErrors,
    ImuParams,
    PitotParams,
    SensorSuiteParams,
    VaneParams,
)

PARAMS = aerosonde()
# A research-grade air-data boom and IMU, so that the effects, not the sensor noise,
# dominate the equation error of the coefficient they act on.
QUIET = SensorSuiteParams(
    imu=ImuParams(accel=ChannelErrors(0.02), gyro=ChannelErrors(np.radians(0.1))),
    vanes=VaneParams(angles=ChannelErrors(np.radians(0.1))),
    pitot=PitotParams(dynamic_pressure=ChannelErrors(2.0), air_density=PARAMS.rho),
)
OUTPUTS = ("airspeed", "alpha", "beta", "p", "q", "r")

# name: (flight options, expected effect, coefficient it acts on, outputs it moves)
CASES = {
    "stall onset": (dict(disturbance=lambda c: (-60.0 * c.alpha**3, 0, 0, 0, 0, 0)),
                    "stall_onset", "CL", ("alpha",)),
    "propwash drag": (dict(disturbance=lambda c: (0, 0.08 * c.thrust_coefficient, 0, 0, 0, 0)),
                      "thrust_propwash", "CD", ("airspeed",)),
    "servo delay": (dict(actuator_delay=0.08), "actuator_time_delay", "Cm", ("q",)),
    "rate coupling": (dict(disturbance=lambda c: (
        0, 0, 0, 0, 40.0 * (PARAMS.b * c.p / (2 * c.airspeed)) * (PARAMS.b * c.r / (
            2 * c.airspeed)), 0)), "rate_coupling", "Cm", ("q",)),
    "elevator rolling moment": (dict(disturbance=lambda c: (0, 0, 0, 0.02 * c.elevator, 0, 0)),
                                "control_cross_coupling", "Cl", ("p",)),
}


# The default run flies the first case; `-m slow` flies the others.
@pytest.mark.parametrize("case", [pytest.param(c, marks=() if i == 0 else pytest.mark.slow)
                                  for i, c in enumerate(CASES)])
def test_an_undeclared_effect_is_named_and_removed(case):
    options, expected, coefficient, outputs = CASES[case]
    log = fly(PARAMS, turbulence="light", sensors=QUIET, seed=5, duration=120.0, **options)
    run = identify(log, PARAMS)
    found = [f.name for f in run.discovery.found]
    assert found and found[0] == expected, found
    before, after = run.discovery.rms_change()[coefficient]
    assert after <= 0.5 * before, (before, after)
    mae_before = dict(zip(OUTPUTS, run.reconstruction_before.mae, strict=True))
    mae_after = dict(zip(OUTPUTS, run.reconstruction_after.mae, strict=True))
    for name in outputs:
        assert mae_after[name] < mae_before[name], (name, mae_before[name], mae_after[name])


@pytest.mark.slow
def test_an_effect_outside_the_library_is_traced_to_its_signals():
    """Yawing moment growing with alpha * beta: no named effect has it; the fallback names
    the two signals and identifies the coefficient."""
    log = fly(PARAMS, turbulence="light", sensors=QUIET, seed=5, duration=120.0,
              disturbance=lambda c: (0, 0, 0, 0, 0, 10.0 * c.alpha * c.beta))
    run = identify(log, PARAMS)
    found = run.discovery.found
    assert [f.name for f in found] == ["data_driven:alpha*beta"]
    assert "alpha x beta" in found[0].explanation
    value, sigma = found[0].parameters["Cn:alpha*beta"]
    assert abs(value - 10.0) < max(3 * sigma, 0.5)
    before, after = run.discovery.rms_change()["Cn"]
    assert after < 0.8 * before  # the rest of the Cn residual is gyro-derivative noise
    r = OUTPUTS.index("r")
    assert run.reconstruction_after.mae[r] < run.reconstruction_before.mae[r]


@pytest.mark.parametrize("flights, allowed", [
    pytest.param(2, 0, id="2 flights"),
    pytest.param(40, 2, id="40 flights", marks=pytest.mark.slow),
])
def test_clean_flights_give_no_discovery(flights, allowed):
    """The first ``flights`` seeds, the Table 7 sensors of Vaiopoulos 2017, light turbulence,
    no effect in the physics: at most ``allowed`` false discoveries (5 %)."""
    discoveries = []
    for seed in range(flights):
        log = fly(PARAMS, turbulence="light", seed=100 + seed, duration=60.0)
        result = identify(log, PARAMS).discovery
        if result.message != NO_EFFECT_MESSAGE:
            discoveries.append((seed, result.message))
    assert len(discoveries) <= allowed, discoveries


def test_command_line_without_arguments_runs_on_the_bundled_flight(tmp_path):
    out = tmp_path / "report"
    done = subprocess.run([sys.executable, "-m", "drake_uav.cli", "identify", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "report:" in done.stdout and "->" in done.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True
    assert [e["name"] for e in summary["effects"]] == ["thrust_propwash"]
    rms = summary["equation_error_rms_holdout"]["CD"]
    assert rms["after"] < rms["before"]
    assert (out / "report.html").read_text().count("<img") >= 4
