"""Physically impossible input: each class of it stops with one line naming the file, the
channel and the likely cause, or is repaired with a warning the console shows, or (an
estimate the flight does not observe) is withheld and said.

Logs: the bundled sample flight (straight, vanes, 150 s) with one channel spoilt, and
simulated flights of their own seeds (a straight one, one with a 150 deg turn and a
steady wind).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from drake_uav.cli import main
from drake_uav.diagrams import fly
from drake_uav.diagrams.identification_flight import default_excitation
from drake_uav.estimation import estimate_air_data
from drake_uav.estimation.channel_checks import (
    ImplausibleChannelError,
    check_channels,
    max_airspeed,
)
from drake_uav.estimation.compatibility import check_compatibility
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.io.readers import read_log
from drake_uav.systems.excitation import Doublet
from drake_uav.systems.safety_pilot import SafetyPilotGains
from drake_uav.vehicles import aerosonde

SAMPLE = Path(__file__).parents[1] / "drake_uav" / "data" / "sample_flight.parquet"
FLOW_ANGLE_MAE_DEG = 0.75
"""Bound on the mean absolute alpha and beta error of the estimate without vanes (the
bound of tests/test_air_data_smoother.py)."""


@pytest.fixture(scope="module")
def sample() -> FlightLog:
    return read_log(SAMPLE)


def _saved(log: FlightLog, tmp_path: Path, name: str, **channels) -> Path:
    return log.with_measured(channels).save(tmp_path / f"{name}.parquet")


def _identify(path: Path, out: Path, capsys, *options: str) -> tuple[int, list[str], list[str]]:
    code = main(["identify", str(path), "--out", str(out), *options])
    captured = capsys.readouterr()
    return code, captured.out.splitlines(), captured.err.splitlines()


def _stops_with(path: Path, tmp_path: Path, capsys, line: str) -> None:
    """The CLI stops (exit 2) with exactly ``line`` as its one error and writes nothing."""
    out = tmp_path / "report"
    code, _, err = _identify(path, out, capsys)
    errors = [e for e in err if e.startswith("error:")]
    assert code == 2 and errors == [line], err
    assert not out.exists()


def _measured_without_vanes(log: FlightLog, **replace) -> FlightLog:
    names = [n for n in log.measured_names if not n.startswith("vane_")]
    return FlightLog(log.time, {n: replace.get(n, log[n]) for n in names}, {},
                     {n: log.unit(n) for n in names})


def _turning_flight(seed: int, duration: float = 60.0) -> FlightLog:
    """A 25 s turn each way (a heading swing of about 150 deg) in a steady wind."""
    return fly("aerosonde", turbulence="light", seed=seed, duration=duration,
               steady_wind=(4.0, -3.0, 0.0),
               excitation=default_excitation("multisine", duration)
               + (Doublet("aileron", math.radians(8.0), 25.0, 2.0),),
               pilot_gains=SafetyPilotGains(heading=0.0))


def test_a_vane_logged_in_degrees_as_radians_stops_naming_the_cause(sample, tmp_path,
                                                                      capsys):
    path = _saved(sample, tmp_path, "degrees", vane_alpha=sample["vane_alpha"] * 57.3,
                  vane_beta=sample["vane_beta"] * 57.3)
    _stops_with(path, tmp_path, capsys,
                f"error: {path}: vane_alpha looks like degrees: 0.236 to 8.74 rad in flight, "
                "14948 of 15001 samples outside +-1.571 rad (a flow angle beyond +-90 deg); "
                "fix the unit or the channel of the log")


def test_an_absurd_airspeed_stops_naming_the_channel_and_the_gps_speed(sample, tmp_path,
                                                                       capsys):
    # The Aerosonde's power-on vertical dive with half its least drag coefficient: its
    # propeller has stopped pulling there, the drag equals the weight.
    params = aerosonde()
    top = max_airspeed(params)
    assert params.propulsion.thrust_torque(top, 1.0, params.rho)[0] < 0.0
    least_drag = params.derivatives["CD_0"] - params.derivatives["CD_alpha"] ** 2 / (
        4.0 * params.derivatives["CD_alpha2"])
    assert 0.25 * params.rho * top**2 * params.S * least_drag == pytest.approx(
        params.mass * params.gravity, rel=1e-3)
    # A pitot in cm/s: beyond the aircraft, within what a logger can hold.
    path = _saved(sample, tmp_path, "pitot",
                  pitot_airspeed=np.asarray(sample["pitot_airspeed"]) * 100.0)
    _stops_with(path, tmp_path, capsys,
                f"error: {path}: pitot_airspeed is not physical (a wrong unit, a wrong "
                "channel or a failed sensor): 2.35e+03 to 2.65e+03 m/s in flight, 15001 of "
                "15001 samples outside 0 to 131.8 m/s (the aircraft's power-on vertical "
                "dive); the GPS ground speed is 25.4 m/s; fix the unit or the channel of the "
                "log")
    # 1e6 m/s is beyond any sensor: the reader stops first, naming the channel too.
    path = _saved(sample, tmp_path, "pitot_1e6", pitot_airspeed=np.full(len(sample), 1e6))
    _stops_with(path, tmp_path, capsys,
                f"error: {path}: channel pitot_airspeed holds 1e+06 m/s at t = 0 s (sample 0; "
                "15001 such sample(s)), beyond any sensor's range (|value| > 10000 m/s): "
                "corrupt data")
    # The redundant channel: a GPS velocity in cm/s implies a wind no aircraft flies in.
    path = _saved(sample, tmp_path, "gps", **{n: sample[n] * 100.0
                                              for n in ("gps_vn", "gps_ve", "gps_vd")})
    _stops_with(path, tmp_path, capsys,
                f"error: {path}: pitot_airspeed disagrees with the GPS ground speed: median "
                "25 m/s against 2.54e+03 m/s, a wind of 2.51e+03 m/s, faster than the "
                "aircraft can fly (132 m/s); check the unit and channel of the airspeed and "
                "of the GPS velocity")


def test_an_airspeed_spike_is_drawn_over_with_a_warning_and_the_finding_kept(
        sample, tmp_path, capsys):
    airspeed = sample["pitot_airspeed"].copy()
    airspeed[len(airspeed) // 2] = 400.0
    path = _saved(sample, tmp_path, "spike", pitot_airspeed=airspeed)
    out = tmp_path / "report"
    # C_D only, for speed: the sample's effect lies in it.
    code, lines, _ = _identify(path, out, capsys, "--coefficients", "CD")
    warning = ("pitot_airspeed: 1 sample(s) outside 0 to 131.8 m/s (the aircraft's power-on "
               "vertical dive) removed as glitches at 75.00 s; drawn as a straight line between "
               "their neighbours")
    assert code == 0 and f"warning: {warning}" in lines, lines
    summary = json.loads((out / "summary.json").read_text())
    assert summary["data"]["warnings"] == [warning]
    assert summary["findings"] == ["thrust_propwash"]  # the clean sample's finding
    assert f"- **Warning:** {warning}" in (out / "report.md").read_text()
    # A spike inside the range: a jump no aircraft makes in a sample interval.
    airspeed[len(airspeed) // 2] = 125.0
    checked = check_channels(sample.with_measured({"pitot_airspeed": airspeed}), aerosonde())
    assert checked.notes == ("pitot_airspeed: 1 isolated spike(s), a jump faster than the "
                             "aircraft accelerates (17 g), removed at 75.00 s; drawn as a "
                             "straight line between their neighbours",)
    assert np.abs(checked.log["pitot_airspeed"] - sample["pitot_airspeed"]).max() < 0.5
    assert check_channels(sample, aerosonde()).notes == ()  # the clean flight: none


def test_a_wind_the_flight_does_not_observe_is_withheld_and_said(sample):
    straight = fly("aerosonde", turbulence="light", seed=171, duration=40.0)
    # A heading 20 deg off: on a straight track it moves the estimated wind by metres per
    # second, and the estimate cannot tell; it must not report that wind.
    biased = _measured_without_vanes(straight,
                                     att_yaw=straight["att_yaw"] + math.radians(20.0))
    estimate = estimate_air_data(biased, aerosonde())
    assert estimate.wind_observable == (False,)
    assert np.isnan(estimate.wind_ned).all() and np.isnan(estimate.wind_std).all()
    assert len(estimate.notes) == 1 and estimate.notes[0].startswith("wind not estimated over")
    keep = estimate.valid & (estimate.time >= estimate.segments[0][0] + 5.0)
    for name in ("alpha", "beta"):  # the air-relative velocity stays right
        error = np.degrees(np.abs(getattr(estimate, name) - straight[name])[keep].mean())
        assert error < FLOW_ANGLE_MAE_DEG, (name, error)
    # With a turn the wind is observed, and estimated.
    turning = _turning_flight(seed=172)
    estimate = estimate_air_data(_measured_without_vanes(turning), aerosonde())
    assert estimate.wind_observable == (True,) and estimate.notes == ()
    keep = estimate.valid & (estimate.time >= estimate.segments[0][0] + 5.0)
    assert np.abs(estimate.wind_ned[keep, :2].mean(axis=0) - (4.0, -3.0)).max() < 1.0
    # The main job on the straight sample flight without vanes says so, and still finds
    # the sample's effect (on C_D, the one coefficient it lies in, for speed).
    run = identify(sample, aerosonde(), air_data="estimate", source=str(SAMPLE),
                   coefficients=("CD",))
    assert [w.split(":")[0] for w in run.warnings] == ["span 0.0-150.0 s"]
    assert "wind not estimated over 0.0-150.0 s" in run.warnings[0]
    assert run.findings == ("thrust_propwash",)
    assert any(n.startswith("wind (segment 0): not observable")
               for n in run.compatibility.notes)


def test_a_calibration_far_outside_its_tolerance_stops(sample, tmp_path, capsys):
    # An airspeed in knots on a turning flight: the scale factor is observable.
    flight = _turning_flight(seed=173)
    clean = flight.select(flight.measured_names)
    check_compatibility(clean, aerosonde())  # a clean flight passes
    knots = clean.with_measured({"pitot_airspeed": clean["pitot_airspeed"] / 0.514444,
                                 "pitot_qbar": clean["pitot_qbar"] / 0.514444**2})
    with pytest.raises(ImplausibleChannelError,
                       match=r"^pitot_airspeed: airspeed_scale_factor 1\.9\d* \+- 0\.0\d+, far "
                             r"outside 0\.667 to 1\.5 \(.*\): likely knots logged as m/s;"):
        check_compatibility(knots, aerosonde())
    # A vane in degrees: its scale factor (18 in the case) stops the check itself
    # instead of "no significant calibration error".
    degrees = sample.with_measured({"vane_alpha": sample["vane_alpha"] * 57.3})
    with pytest.raises(ImplausibleChannelError,
                       match=r"^vane_alpha: vane_alpha_scale_factor 12\.\d+ \+- 1\.\d+, far "
                             r"outside 0\.5 to 2 "):
        check_compatibility(degrees, aerosonde())
    # A vane zeroed 30 deg off, through the command line: the file is named.
    path = _saved(sample, tmp_path, "offset",
                  vane_alpha=sample["vane_alpha"] + math.radians(30.0))
    _stops_with(path, tmp_path, capsys,
                f"error: {path}: vane_alpha: vane_alpha_offset 30.23 +- 0.28 deg, far outside "
                "-10 to 10 deg (a vane's mounting and the upwash offset it by under 10 deg): "
                "likely a wrong zero or a wrong channel, not a calibration; fix the log's "
                "unit or channel")
