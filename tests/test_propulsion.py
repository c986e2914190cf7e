"""Propeller equations and thrust identification from simulated flights.

The flights' propulsion differs from the catalog the identification is given (a motor
15 % weaker in voltage, a propeller with 15 % less C_T0 and C_T1), so the catalog thrust
is wrong by 4-17 N; the identified one is compared with the true thrust of the flown
model (truth channels, here only). Flights use seeds below 100.
"""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np
import pytest
from pydrake.symbolic import Variable

from drake_uav.diagrams import fly
from drake_uav.identification import (
    InsufficientExcitationWarning,
    identify_thrust,
    isolate_coefficients,
)
from drake_uav.identification.propulsion import catalog_propeller, thrust_correction_columns
from drake_uav.identification.samples.flight_data import held_commands
from drake_uav.model.fixed_wing import FixedWingModel
from drake_uav.model.isolation import differentiate
from drake_uav.model.propeller import (
    THROTTLE_TERMS,
    advance_ratio,
    propeller_thrust,
    revolutions,
    throttle_thrust_regressors,
    thrust_regressors,
)
from drake_uav.systems.excitation import orthogonal_multisines
from drake_uav.vehicles.fixed_wing import aerosonde, aerosonde_mavsim

DURATION = 60.0
COMMANDS = ("cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle")


def _weak_motor(params):
    """The same aircraft with a motor 15 % weaker (battery voltage or exit speed)."""
    prop = params.propulsion
    if hasattr(prop, "V_max"):
        return dataclasses.replace(params, propulsion=dataclasses.replace(
            prop, V_max=0.85 * prop.V_max))
    return dataclasses.replace(params, propulsion=dataclasses.replace(
        prop, k_motor=prop.k_motor * 0.85**0.5))


def _weak_propeller(params):
    prop = params.propulsion
    return dataclasses.replace(params, propulsion=dataclasses.replace(
        prop, C_T0=0.85 * prop.C_T0, C_T1=0.85 * prop.C_T1))


def _true_thrust(params, airspeed, throttle):
    prop = params.propulsion
    return np.array([prop.thrust_torque(float(v), float(d), params.rho)[0]
                     for v, d in zip(airspeed, throttle, strict=True)])


def _shaft_speed(params, airspeed, throttle) -> float:
    """The propeller speed [rad/s]; the momentum model's disc has none (NaN)."""
    prop = params.propulsion
    if not hasattr(prop, "propeller_speed"):
        return np.nan
    return prop.propeller_speed(float(airspeed), float(throttle), params.rho)


@functools.cache
def _flight(true_name: str, seed: int, throttle_amplitude: float):
    true = {"mavsim": aerosonde_mavsim(), "mavsim_weak_motor": _weak_motor(aerosonde_mavsim()),
            "mavsim_weak_prop": _weak_propeller(aerosonde_mavsim()),
            "aerosonde_weak_motor": _weak_motor(aerosonde())}[true_name]
    excitation = "multisine"
    if throttle_amplitude:
        excitation = orthogonal_multisines(
            ("elevator", "aileron", "rudder", "throttle"), 20.0,
            [np.radians(2.0), np.radians(3.0), np.radians(3.0), throttle_amplitude],
            band=(0.1, 1.5), start=1.0, cycles=(DURATION - 1.0) / 20.0)
    log = fly(true, excitation=excitation, seed=seed, duration=DURATION)
    keep = log.time > 2.0
    controls = held_commands(log.time, log.stack(COMMANDS), log.time)[0][keep]
    data = {
        "time": log.time[keep],
        "specific_force": log.stack(("imu_ax", "imu_ay", "imu_az"))[keep],
        "rates": log.stack(("imu_p", "imu_q", "imu_r"))[keep],
        "air_data": log.stack(("pitot_airspeed", "vane_alpha", "vane_beta"))[keep],
        "controls": controls,
    }
    truth_airspeed, truth_throttle = log["airspeed"][keep], log["throttle"][keep]
    # A shaft-speed sensor: the true propeller speed with 2 rad/s of white noise.
    rng = np.random.default_rng(seed)
    speed = np.array([_shaft_speed(true, v, d)
                      for v, d in zip(truth_airspeed, truth_throttle, strict=True)])
    motor_speed = speed + rng.normal(0.0, 2.0, speed.shape)
    return data, motor_speed, _true_thrust(true, truth_airspeed, truth_throttle), log


def _smoothed_error(time, thrust, truth) -> np.ndarray:
    """Thrust error [N] through a 1 s smoothing (the sample noise of the airspeed left out)."""
    return differentiate(time, thrust - truth, 1.0, deriv=0)


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def test_propeller_equation_is_the_motor_propellers():
    params = aerosonde_mavsim()
    prop, rho = params.propulsion, params.rho
    airspeed, throttle = 24.0, 0.4
    speed = prop.propeller_speed(airspeed, throttle, rho)
    n_d = revolutions(speed) * prop.diameter
    coefficients = (prop.C_T0, prop.C_T1, prop.C_T2)
    thrust = propeller_thrust(rho, n_d, airspeed, prop.diameter, coefficients)
    assert thrust == prop.thrust_torque(airspeed, throttle, rho)[0]
    # rho n^2 D^4 C_T(J), J = Va / (n D)
    J = advance_ratio(airspeed, speed, prop.diameter)
    n = revolutions(speed)
    c_t = prop.C_T0 + prop.C_T1 * J + prop.C_T2 * J**2
    assert thrust == pytest.approx(rho * n**2 * prop.diameter**4 * c_t, rel=1e-12)
    assert thrust == pytest.approx(np.dot(thrust_regressors(rho, n_d, airspeed, prop.diameter),
                                          coefficients), rel=1e-12)
    nd_var, va_var = Variable("nD"), Variable("Va")
    symbolic = propeller_thrust(rho, nd_var, va_var, prop.diameter, coefficients)
    assert symbolic.Evaluate({nd_var: n_d, va_var: airspeed}) == pytest.approx(thrust,
                                                                                rel=1e-12)
    assert catalog_propeller(aerosonde())[1][1] == 0.0


def test_motor_speed_identifies_the_propeller_of_a_weaker_motor():
    data, motor_speed, truth, _ = _flight("mavsim_weak_motor", 3, 0.1)
    catalog = aerosonde_mavsim()
    model = identify_thrust(catalog, **data, motor_speed=motor_speed)
    assert model.source == "motor_speed" and model.terms[0] == "C_T0"
    assert model.coefficients[0] == pytest.approx(catalog.propulsion.C_T0, rel=0.03)
    airspeed, throttle = data["air_data"][:, 0], data["controls"][:, 3]
    prediction = model.thrust(airspeed, throttle, motor_speed)
    error = _rms(_smoothed_error(data["time"], prediction.thrust, truth))
    catalog_error = _rms(_true_thrust(catalog, airspeed, throttle) - truth)
    assert catalog_error > 10.0
    assert error < 1.5
    assert np.all(prediction.std > 0) and np.all(np.isfinite(prediction.airspeed_slope))


def test_motor_speed_with_a_different_propeller():
    data, motor_speed, truth, _ = _flight("mavsim_weak_prop", 4, 0.1)
    catalog = aerosonde_mavsim()
    model = identify_thrust(catalog, **data, motor_speed=motor_speed)
    airspeed, throttle = data["air_data"][:, 0], data["controls"][:, 3]
    prediction = model.thrust(airspeed, throttle, motor_speed)
    error = _rms(_smoothed_error(data["time"], prediction.thrust, truth))
    catalog_error = _rms(_true_thrust(catalog, airspeed, throttle) - truth)
    # C_T1 stays the catalog's (15 % off): the C_T0 fit takes up most of the difference.
    assert error < 0.6 * catalog_error
    assert model.coefficients[0] < catalog.propulsion.C_T0


@pytest.mark.parametrize("aircraft", ["mavsim_weak_motor", "aerosonde_weak_motor"])
def test_throttle_and_airspeed_thrust_without_motor_speed(aircraft):
    data, _, truth, _ = _flight(aircraft, 5, 0.1)
    catalog = aerosonde_mavsim() if aircraft.startswith("mavsim") else aerosonde()
    model = identify_thrust(catalog, **data)
    assert model.source == "throttle" and model.diagnostics.identifiable
    assert model.terms and set(model.terms) <= {"throttle", "throttle2", "throttle_airspeed"}
    airspeed, throttle = data["air_data"][:, 0], data["controls"][:, 3]
    prediction = model.thrust(airspeed, throttle)
    error = _smoothed_error(data["time"], prediction.thrust, truth)
    catalog_error = _rms(_true_thrust(catalog, airspeed, throttle) - truth)
    assert catalog_error > 10.0
    assert _rms(error) < 2.5
    assert abs(np.mean(error)) < 3.0 * np.median(prediction.std) + 0.5
    assert np.median(prediction.std) < 2.0


def test_the_catalog_is_kept_when_it_is_right():
    data, _, truth, _ = _flight("mavsim", 6, 0.1)
    model = identify_thrust(aerosonde_mavsim(), **data)
    prediction = model.thrust(data["air_data"][:, 0], data["controls"][:, 3])
    assert _rms(_smoothed_error(data["time"], prediction.thrust, truth)) < 0.5


def test_constant_throttle_is_confounded_and_falls_back_to_the_catalog():
    data, _, _, _ = _flight("mavsim_weak_motor", 7, 0.0)
    with pytest.warns(InsufficientExcitationWarning, match="confounded"):
        model = identify_thrust(aerosonde_mavsim(), **data)
    assert model.source == "catalog" and not model.diagnostics.identifiable
    # The one throttle term a constant throttle leaves is a constant force: a tow and a
    # thrust error are one column.
    assert model.diagnostics.correlation > 0.999
    prediction = model.thrust(data["air_data"][:, 0], data["controls"][:, 3])
    assert np.all(prediction.std == 0.0)


def test_isolation_takes_the_identified_thrust_and_its_slope():
    data, _, truth, log = _flight("aerosonde_weak_motor", 5, 0.1)
    catalog = aerosonde()
    with warnings.catch_warnings():
        warnings.simplefilter("error", InsufficientExcitationWarning)
        model = identify_thrust(catalog, **data)
    prediction = model.thrust(data["air_data"][:, 0], data["controls"][:, 3])
    args = (catalog, data["time"], data["specific_force"], data["rates"], data["air_data"],
            data["controls"])
    identified = isolate_coefficients(*args, thrust=prediction.thrust,
                                      thrust_airspeed_slope=prediction.airspeed_slope)
    default = isolate_coefficients(*args)
    assert identified.thrust_airspeed_slope is not None
    assert identified.moment_view.thrust_airspeed_slope is not None
    keep = log.time > 2.0
    true_cx = differentiate(data["time"], log["CX"][keep], 0.2, deriv=0)
    alpha = identified.condition.alpha

    def cx_error(samples):
        cx = samples.coefficients["CL"] * np.sin(alpha) - samples.coefficients["CD"] * np.cos(
            alpha)
        return _rms(cx - true_cx)

    assert cx_error(identified) < 0.3 * cx_error(default)


def test_the_discovery_columns_are_what_a_thrust_change_does_to_the_measured_drag():
    """``thrust_correction_columns``: a thrust in the isolation larger by theta times each
    term moves the measured C_D by theta times that term's column (the discovery can give
    back to the thrust what its correction took)."""
    data, _, _, _ = _flight("aerosonde_weak_motor", 5, 0.1)
    catalog = aerosonde()
    args = (catalog, data["time"], data["specific_force"], data["rates"], data["air_data"],
            data["controls"])
    airspeed, throttle = data["air_data"][:, 0], data["controls"][:, 3]
    thrust = FixedWingModel(catalog).thrust(airspeed, throttle)[0]
    slope = np.zeros_like(thrust)
    base = isolate_coefficients(*args, thrust=thrust, thrust_airspeed_slope=slope,
                                thrust_correction_terms=THROTTLE_TERMS)
    columns = thrust_correction_columns(base)
    assert list(columns) == [f"thrust:{t}" for t in THROTTLE_TERMS]
    theta = (3.0, -2.0, 0.05)  # N, N, N s/m
    change = sum(t * r for t, r in zip(theta, throttle_thrust_regressors(throttle, airspeed),
                                       strict=True))
    moved = isolate_coefficients(*args, thrust=thrust + change, thrust_airspeed_slope=slope)
    predicted = sum(t * c for t, c in zip(theta, columns.values(), strict=True))
    drag_change = moved.coefficients["CD"] - base.coefficients["CD"]
    scale = np.abs(drag_change).max()
    assert scale > 1e-3
    np.testing.assert_allclose(drag_change, predicted, atol=2e-3 * scale)
    assert thrust_correction_columns(isolate_coefficients(*args)) == {}


def test_bad_input_names_the_array():
    data, motor_speed, _, _ = _flight("mavsim", 6, 0.1)
    with pytest.raises(ValueError, match="controls must have shape"):
        identify_thrust(aerosonde_mavsim(), **{**data, "controls": data["controls"][:, :3]})
    with pytest.raises(ValueError, match="motor_speed is not finite at sample 4"):
        bad = np.full(len(data["time"]), 500.0)
        bad[4] = np.nan
        identify_thrust(aerosonde_mavsim(), **data, motor_speed=bad)
    model = identify_thrust(aerosonde_mavsim(), **data, motor_speed=motor_speed)
    assert model.source == "motor_speed"
    with pytest.raises(ValueError, match="pass the logged motor speed"):
        model.thrust(data["air_data"][:, 0], data["controls"][:, 3])
