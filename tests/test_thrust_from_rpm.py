"""Thrust from the logged shaft speed: propeller tables, ESC telemetry, noise at the
native rate, and the main job on a log holding only what an autopilot writes.

Flights: the Aerosonde with its motor and propeller (aerosonde_mavsim), seeds below 100,
its shaft speed logged with noise (drake_uav.testing.discovery_cases.shaft_speed_logged).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.identification.pipeline import IdentifyOptions, identify
from drake_uav.identification.propulsion import declared_thrust
from drake_uav.identification.samples.flight_data import gridded_log
from drake_uav.io import FlightLog, read_log
from drake_uav.io.propeller_table import PropellerTable, read_propeller_table
from drake_uav.io.realistic_ardupilot import write_ardupilot_log
from drake_uav.io.realistic_logs import LogProfile
from drake_uav.model.propeller import coefficient_polynomial
from drake_uav.testing.discovery_cases import RPM_NOISE, measured_only, shaft_speed_logged
from drake_uav.vehicles.fixed_wing import Propulsion, aerosonde_mavsim

PARAMS = aerosonde_mavsim()
PROP = PARAMS.propulsion
THRUST = (PROP.C_T0, PROP.C_T1, PROP.C_T2)
TORQUE = (PROP.C_Q0, PROP.C_Q1, PROP.C_Q2)
J = np.linspace(0.0, 0.9, 10)


@functools.cache
def _flight(seed: int = 3, duration: float = 30.0) -> FlightLog:
    """A flight of the Aerosonde with its propeller, ``motor_speed`` logged with noise."""
    return shaft_speed_logged(fly(PARAMS, seed=seed, duration=duration,
                                  excitation="multisine_throttle"), PARAMS, seed)


def _csv(path, thrust=THRUST, torque_column="C_Q", torque=TORQUE, scale=1.0):
    rows = [f"J,C_T,{torque_column},diameter"]
    factor = 2.0 * math.pi if torque_column == "C_P" else 1.0
    for k, j in enumerate(J):
        rows.append(f"{j},{scale * coefficient_polynomial(j, thrust)},"
                    f"{factor * coefficient_polynomial(j, torque)},"
                    + (f"{PROP.diameter}" if k == 0 else ""))
    path.write_text("# a propeller's data\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("torque_column", ["C_Q", "C_P"])
def test_a_csv_table_of_the_propeller_gives_its_coefficients(tmp_path, torque_column):
    table = read_propeller_table(_csv(tmp_path / "prop.csv", torque_column=torque_column))
    assert table.diameter == PROP.diameter
    np.testing.assert_allclose(table.thrust_coefficients, THRUST, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(table.torque_coefficients, TORQUE, rtol=1e-9, atol=1e-12)
    assert table.thrust_fit_rms < 1e-12


def test_a_toml_table_fits_the_least_squares_quadratic(tmp_path):
    """A table that is not a quadratic: the fit is the least-squares one, and its RMS says
    how far the table is from it."""
    c_t = [0.10, 0.095, 0.085, 0.07, 0.05, 0.02]
    j = [0.0, 0.15, 0.3, 0.45, 0.6, 0.75]
    path = tmp_path / "prop.toml"
    path.write_text(f"diameter = 0.3\nJ = {j}\nC_T = {c_t}\n")
    table = read_propeller_table(path)
    expected = np.polyfit(j, c_t, 2)[::-1]
    np.testing.assert_allclose(table.thrust_coefficients, expected, rtol=1e-9)
    residual = np.array(c_t) - coefficient_polynomial(np.array(j), expected)
    assert table.thrust_fit_rms == pytest.approx(np.sqrt(np.mean(residual**2)))
    assert table.torque_coefficients is None
    assert "D = 0.3 m" in table.describe() and "prop.toml" in table.describe()


@pytest.mark.parametrize(("name", "text", "message"), [
    ("p.csv", "J,C_T\n0,0.1\n0.3,0.08\n0.6,0.04\n", "field diameter missing"),
    ("p.csv", "J,C_T,diameter\n0,0.1,0.5\n0.3,x,\n0.6,0.04,\n", "field C_T entry 2: not a number"),
    ("p.csv", "J,C_T,diameter\n0,0.1,0.5\n0.3,0.08,0.4\n0.6,0.04,\n", "field diameter: one value"),
    ("p.csv", "J,C_T,diameter\n0,0.1,0.5\n0.3,0.08,\n", "2 distinct advance ratios"),
    ("p.csv", "J,C_T,diameter\n0,0.1,-0.5\n0.3,0.08,\n0.6,0.04,\n", "field diameter: a positive"),
    ("p.toml", "diameter = 0.5\nJ = [0, 0.3, 0.6]\nC_T = [0.1, 0.08]\n",
     "field C_T: 2 values for 3 advance ratios"),
    ("p.toml", "diameter = 0.5\nJ = [0, 0.3, 0.6]\nC_T = [0.1, 0.08, 0.04]\nC_Q = [1, 1, 1]\n"
     "C_P = [1, 1, 1]\n", "fields C_Q and C_P both given"),
    ("p.toml", "diameter = 0.5\nJ = [-0.1, 0.3, 0.6]\nC_T = [0.1, 0.08, 0.04]\n",
     "field J: advance ratios must be >= 0"),
    ("p.toml", "diameter = 0.5\nJ = 0.3\nC_T = [0.1, 0.08, 0.04]\n", "field J: a list"),
    ("p.toml", "diameter = \n", "not valid TOML"),
    ("p.txt", "J C_T\n", "a .csv or .toml file"),
])
def test_a_bad_table_is_refused_naming_the_file_and_the_field(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as error:
        read_propeller_table(path)
    assert str(error.value).startswith(str(path)) and "\n" not in str(error.value)


def test_the_declared_table_gives_the_flights_thrust_from_the_logged_rpm():
    """The table of the flown propeller gives the true thrust within the shaft speed's and
    the pitot's noise (the multisine throttle moves it by 5.6 N RMS about 0.1 N; the
    error's RMS is 0.63 N); a table with 20 % less C_T gives 20 % less thrust."""
    flight = _flight()
    grid = gridded_log(measured_only(flight), PARAMS)
    table = PropellerTable(PROP.diameter, J, coefficient_polynomial(J, THRUST), None, "t")
    thrust = declared_thrust(grid, PARAMS, table)
    truth = np.array([PROP.thrust_torque(v, d, PARAMS.rho)[0]
                      for v, d in zip(flight["airspeed"], flight["throttle"], strict=True)])
    true = np.interp(grid.log.time, flight.time, truth)
    error = thrust["thrust"] - true  # this aircraft cruises near zero thrust: errors in N
    assert abs(np.mean(error)) < 0.1 and np.sqrt(np.mean(error**2)) < 0.2 * np.std(true)
    assert thrust["thrust_correction_terms"] == ()
    weaker = PropellerTable(PROP.diameter, J, 0.8 * coefficient_polynomial(J, THRUST), None,
                            "t")
    np.testing.assert_allclose(declared_thrust(grid, PARAMS, weaker)["thrust"],
                               0.8 * thrust["thrust"], rtol=1e-9)


def test_a_declared_table_needs_a_logged_shaft_speed():
    flight = measured_only(_flight())
    log = FlightLog(flight.time, {n: flight[n] for n in flight.names if n != "motor_speed"},
                    units=flight.units)
    table = PropellerTable(PROP.diameter, J, coefficient_polynomial(J, THRUST), None, "p.csv")
    with pytest.raises(ValueError, match="p.csv: a declared propeller table needs the "
                                         "propeller's shaft speed"):
        declared_thrust(gridded_log(log, PARAMS), PARAMS, table)
    with pytest.raises(ValueError, match="needs propulsion='data'"):
        IdentifyOptions(propeller=table, propulsion="catalog")


def _held(flight: FlightLog, rate_hz: float, sigma: float) -> FlightLog:
    """``flight`` with its shaft speed logged at ``rate_hz`` with ``sigma`` [rad/s] more
    noise, held on the 100 Hz log as a reader puts it, the stream's rate in the metadata."""
    step = int(round(100.0 / rate_hz))
    held = np.repeat(np.arange(len(flight) // step + 1), step)[:len(flight)]
    noise = np.random.default_rng(11).normal(0.0, sigma, held[-1] + 1)
    speed = flight["motor_speed"][::step][held] + noise[held]
    return FlightLog(flight.time, {**{n: flight[n] for n in flight.names}, "motor_speed": speed},
                     units=flight.units,
                     metadata={"streams": {"RPM": {"channels": ["motor_speed"],
                                                   "rate_hz": rate_hz}}})


def test_the_shaft_speeds_noise_is_read_from_the_data_at_its_native_rate():
    """A shaft speed logged at 25 Hz: its white noise is read from its own samples
    (RPM_NOISE and 5 rad/s), and given to the thrust fit as white noise on the 50 Hz grid
    of the same density below 12.5 Hz (50 / 25 times its variance); read on the grid, where
    the interpolation hides it, it would be far less. At 10 Hz the flight's own motion
    fills the band: the floor is not read there, and the thrust fit reads it on the grid."""
    flight = measured_only(_flight())
    variance = gridded_log(_held(flight, 25.0, 5.0), PARAMS).noise_variance["motor_speed"]
    assert variance == pytest.approx((RPM_NOISE**2 + 5.0**2) * 50.0 / 25.0, rel=0.15)
    assert "motor_speed" not in gridded_log(_held(flight, 10.0, 5.0), PARAMS).noise_variance


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_job_takes_the_thrust_from_an_arduplane_logs_esc_telemetry(tmp_path):
    """A .bin holding only what ArduPlane writes, the shaft speed in ESC messages at 10 Hz:
    the job takes it as motor_speed and, with the declared table of the flown propeller,
    isolates the coefficients with the true thrust."""
    flight = _flight(seed=5, duration=40.0)
    written = write_ardupilot_log(flight, tmp_path / "f.bin", seed=0, aircraft=PARAMS,
                                  profile=LogProfile(shaft_speed="esc"))
    log = read_log(written.path, deflections=PARAMS.limits.deflections())
    table = read_propeller_table(_csv(tmp_path / "prop.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = identify(log, PARAMS, propeller=table)
    assert "propeller shaft speed from the ESC telemetry (esc_rpm_0)" in run.notes
    assert f"thrust from the {table.describe()}" in run.notes
    truth = np.array([PROP.thrust_torque(v, d, PARAMS.rho)[0]
                      for v, d in zip(flight["airspeed"], flight["throttle"], strict=True)])
    assert np.mean(run.samples.thrust) == pytest.approx(np.mean(truth), abs=0.3)
    assert np.std(run.samples.thrust) == pytest.approx(np.std(truth), rel=0.1)


@pytest.mark.parametrize(("arguments", "message"), [
    (["--propeller", "missing.csv"], "missing.csv: no such file (the --propeller argument)"),
    (["--propeller", "PROP", "--propulsion", "catalog"],
     "--propeller: the table gives the thrust from the logged RPM; it cannot be used with "
     "--propulsion catalog"),
])
def test_the_cli_refuses_a_propeller_table_it_cannot_use(tmp_path, capsys, arguments,
                                                         message):
    from drake_uav.cli import main

    prop = _csv(tmp_path / "prop.csv")
    arguments = [str(prop) if a == "PROP" else str(tmp_path / a) if a.endswith(".csv") else a
                 for a in arguments]
    assert main(["identify", "--out", str(tmp_path / "out"), *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("error: ") and error.endswith(message.split("missing.csv")[-1])


def test_the_motor_current_gives_the_propellers_torque_coefficients():
    """The motor current of the flown motor, ``(V_max dT - KV Omega) / R``, balances the
    propeller's torque: C_Q(J) exactly from the true shaft speed and current, within three
    standard deviations from the logged speed and a current with 0.5 A of noise; a motor
    constant 10 % off scales them by 1.1."""
    from drake_uav.identification.propeller_torque import identify_torque_coefficients

    flight = _flight()
    speed = np.array([PROP.propeller_speed(v, d, PARAMS.rho)
                      for v, d in zip(flight["airspeed"], flight["throttle"], strict=True)])
    current = (PROP.V_max * flight["throttle"] - PROP.KV * speed) / PROP.R_motor
    exact = identify_torque_coefficients(PARAMS, flight["airspeed"], speed, current)
    np.testing.assert_allclose(exact.coefficients, TORQUE, rtol=1e-9)
    noisy = current + np.random.default_rng(2).normal(0.0, 0.5, len(current))
    fit = identify_torque_coefficients(PARAMS, flight["airspeed"], flight["motor_speed"], noisy)
    assert np.all(np.abs(fit.coefficients - TORQUE) < 3.0 * fit.sigma)
    assert fit.rms == pytest.approx(PROP.KQ * 0.5, rel=0.3)
    stronger = dataclasses.replace(PARAMS, propulsion=dataclasses.replace(PROP, KQ=1.1 * PROP.KQ))
    scaled = identify_torque_coefficients(stronger, flight["airspeed"], speed, current)
    np.testing.assert_allclose(scaled.coefficients, 1.1 * np.array(TORQUE), rtol=1e-9)
    with pytest.raises(ValueError, match=r"\(Propulsion\) has no diameter, KQ, i0"):
        identify_torque_coefficients(dataclasses.replace(PARAMS, propulsion=Propulsion()),
                                     flight["airspeed"], speed, current)


def test_the_shaft_speeds_noise_enters_the_thrust_and_the_drag_coefficients_floor():
    """A thrust from the logged shaft speed carries the speed's noise: the samples hold
    d(thrust)/d(speed) and the speed's noise variance, and the C_D noise floor's shaft-speed
    part predicts the C_D error that the logged speed's noise actually makes (the same
    flight isolated with the noise-free speed) within 25 % RMS (this aircraft: about
    0.0007, as large as the rest of the floor with research-grade sensors)."""
    from drake_uav.identification.assessment.noise_floor import held_out_noise_floor
    from drake_uav.identification.discovery.loop import discover
    from drake_uav.identification.samples.aero_samples import SHAFT_SPEED
    from drake_uav.identification.samples.flight_data import isolated_samples
    from drake_uav.testing.discovery_cases import propeller_table

    flight = _flight()
    table = propeller_table(PARAMS)
    true_speed = PROP.propeller_speed(flight["airspeed"], flight["throttle"], PARAMS.rho)
    noiseless = FlightLog(flight.time, {**{n: flight[n] for n in flight.names},
                                        "motor_speed": true_speed}, units=flight.units)
    grids = [gridded_log(measured_only(f), PARAMS) for f in (flight, noiseless)]
    samples, clean = (isolated_samples(g, PARAMS, declared_thrust(g, PARAMS, table))
                      for g in grids)
    assert samples.thrust_speed_slope is not None and SHAFT_SPEED in samples.noise_variance
    assert samples.aligned("Cm").thrust_speed_slope is not None
    caused = samples.coefficients["CD"] - clean.coefficients["CD"]
    floor = held_out_noise_floor(samples, discover(samples, PARAMS), PARAMS)["CD"]
    predicted = floor.parts[SHAFT_SPEED]
    actual = float(np.sqrt(np.mean(caused[-len(caused) // 5:] ** 2)))
    print(f"C_D error from the shaft speed's noise: predicted {predicted:.2e}, made "
          f"{actual:.2e} (RMS)")
    assert predicted == pytest.approx(actual, rel=0.25)


def test_spans_joined_keep_the_shaft_speeds_noise_path():
    """Two airborne spans of an RPM flight joined into one set of samples keep
    d(thrust)/d(speed) beside the speed's noise, so the speed still moves the thrust
    coefficient and C_D of the noise model."""
    from drake_uav.identification.samples.aero_samples import SHAFT_SPEED
    from drake_uav.identification.samples.flight_data import isolated_samples
    from drake_uav.identification.samples.regressor_noise import perturbed, source_variances
    from drake_uav.identification.samples.segments import concatenate_samples
    from drake_uav.testing.discovery_cases import propeller_table

    grid = gridded_log(measured_only(_flight()), PARAMS)
    samples = isolated_samples(grid, PARAMS,
                               declared_thrust(grid, PARAMS, propeller_table(PARAMS)))
    half = len(samples) // 2
    joined = concatenate_samples([samples.subset(slice(0, half - 10)),
                                  samples.subset(slice(half + 10, None))])
    assert len(joined.thrust_speed_slope) == len(joined)
    assert len(joined.moment_view.thrust_speed_slope) == len(joined)
    assert source_variances(joined, "CD")[SHAFT_SPEED] > 0.0
    moved = perturbed(joined, SHAFT_SPEED, 1.0)
    np.testing.assert_allclose(moved.thrust - joined.thrust, joined.thrust_speed_slope)
    assert np.all(joined.observation_sensitivity("CD")[SHAFT_SPEED] != 0.0)
