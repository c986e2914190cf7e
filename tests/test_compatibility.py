"""Data-compatibility check: calibration errors injected into simulated flights are found
within their uncertainty, clean flights report nothing, the corrected log is compatible.

Flights: straight (the default multisine) for the IMU, GPS and command relations; a flight
with repeated turns (heading swings of about 150 deg) for the airspeed scale factor. The
errors are applied to the measured channels after the flight.
"""

import math

import numpy as np
import pytest

from drake_uav.diagrams import fly
from drake_uav.diagrams.identification_flight import default_excitation
from drake_uav.estimation.compatibility import check_compatibility
from drake_uav.estimation.compatibility_fits import linear_fit, shift_fit
from drake_uav.estimation.signals import Cumulative
from drake_uav.identification.pipeline import measured_command_delay
from drake_uav.io.flight_log import FlightLogError
from drake_uav.systems.excitation import Doublet
from drake_uav.systems.safety_pilot import SafetyPilotGains
from drake_uav.vehicles import load_fixed_wing

PARAMS = load_fixed_wing("aerosonde")
STRAIGHT_SEEDS = (1, 2, 3)
TURNING_SEEDS = (4,)
SIGMAS = 4.0
"""An injected error counts as recovered within this many standard errors."""

GPS = ("gps_pn", "gps_pe", "gps_pd", "gps_vn", "gps_ve", "gps_vd")
COMMANDS = ("cmd_elevator", "cmd_aileron", "cmd_rudder", "cmd_throttle")
KINEMATIC_ERRORS = {
    "gyro_bias_p": 0.01, "gyro_bias_q": 0.01, "gyro_bias_r": 0.01,
    "accelerometer_bias_x": 0.2, "accelerometer_bias_y": 0.2, "accelerometer_bias_z": 0.2,
    "gps_time_skew": 0.2,
}
VANE_OFFSET = math.radians(2.0)
AIR_DATA_ERRORS = {"airspeed_scale_factor": 1.08, "vane_alpha_offset": VANE_OFFSET}


def _delayed(values: np.ndarray, samples: int) -> np.ndarray:
    """``values`` logged ``samples`` samples late (the first value held before)."""
    return np.concatenate([np.repeat(values[:1], samples), values[:-samples]])


def inject(log, airspeed=1.08, alpha_offset=VANE_OFFSET, accel_bias=0.2,
           gyro_bias=0.01, gps_delay=0.2, command_delay=0.0):
    """The calibration errors applied to the measured channels of ``log``."""
    rate = log.sample_rate
    values = {n: _delayed(log[n], int(round(gps_delay * rate))) for n in GPS}
    values["pitot_airspeed"] = log["pitot_airspeed"] * airspeed
    values["pitot_qbar"] = log["pitot_qbar"] * airspeed**2
    values["vane_alpha"] = log["vane_alpha"] + alpha_offset
    values.update({n: log[n] + accel_bias for n in ("imu_ax", "imu_ay", "imu_az")})
    values.update({n: log[n] + gyro_bias for n in ("imu_p", "imu_q", "imu_r")})
    if command_delay:
        values.update({n: _delayed(log[n], int(round(command_delay * rate)))
                       for n in COMMANDS})
    return log.with_measured(values)


def _turning(seed: int, duration: float = 180.0):
    """A flight with repeated 25 s turns each way (heading hold off)."""
    turns = tuple(Doublet("aileron", math.radians(8.0), 25.0, 2.0 + 50.0 * i)
                  for i in range(int((duration - 2.0) // 50.0)))
    flight = fly("aerosonde", turbulence="light", seed=seed, duration=duration,
                 excitation=default_excitation("multisine", duration) + turns,
                 pilot_gains=SafetyPilotGains(heading=0.0))
    return flight.select(flight.measured_names)


@pytest.fixture(scope="module")
def straight():
    flights = {}
    for seed in STRAIGHT_SEEDS:
        flight = fly("aerosonde", turbulence="light", seed=seed, duration=40.0)
        flights[seed] = flight.select(flight.measured_names)
    return flights


@pytest.fixture(scope="module")
def turning():
    return {seed: _turning(seed) for seed in TURNING_SEEDS}


def _assert_recovered(result, truth: dict) -> None:
    """Each error within SIGMAS standard errors; corrected wherever it stands out of its
    tolerance by more than five standard errors (a sure detection)."""
    for name, value in truth.items():
        effect = result[name]
        assert abs(effect.estimate - value) <= SIGMAS * effect.sigma, (effect.line(), value)
        if abs(value - effect.nominal) > effect.tolerance + 5.0 * effect.sigma:
            assert effect.applied, effect.line()


def test_clean_flights_report_nothing_significant(straight, turning):
    for log in [*straight.values(), *turning.values()]:
        result = check_compatibility(log, PARAMS)
        assert result.significant == (), [e.line() for e in result.significant]
        assert result.corrected(log) is log


def test_imu_and_gps_errors_recovered_within_their_uncertainty(straight):
    for log in straight.values():
        result = check_compatibility(inject(log), PARAMS)
        _assert_recovered(result, KINEMATIC_ERRORS)


def test_air_data_errors_recovered_within_their_uncertainty(turning):
    for log in turning.values():
        result = check_compatibility(inject(log), PARAMS)
        _assert_recovered(result, {**KINEMATIC_ERRORS, **AIR_DATA_ERRORS})
        assert not result["vane_beta_offset"].significant


def test_corrected_log_is_compatible_and_says_what_was_corrected(straight):
    log = inject(straight[STRAIGHT_SEEDS[0]])
    result = check_compatibility(log, PARAMS)
    corrected = result.corrected(log)
    names = [c["name"] for c in corrected.metadata["compatibility_corrections"]]
    assert set(names) == {e.name for e in result.applied}
    assert corrected.duration < log.duration  # the GPS read 0.2 s later
    assert check_compatibility(corrected, PARAMS).significant == ()


def test_straight_flight_leaves_the_airspeed_scale_factor_unobservable(straight):
    result = check_compatibility(inject(straight[STRAIGHT_SEEDS[0]]), PARAMS)
    effect = result["airspeed_scale_factor"]
    assert not effect.observable and not effect.applied
    assert "heading spread" in effect.note


def test_command_skews_a_servo_delay_is_reported_a_logging_skew_corrected(straight):
    """A servo delay is left to the model, which takes its measured value
    (``measured_command_delay``); a logging skew is corrected and is no delay."""
    log = straight[STRAIGHT_SEEDS[0]]
    logging = check_compatibility(inject(log, command_delay=0.3), PARAMS)
    late = logging["command_time_skew"]
    assert abs(late.estimate + 0.3) <= SIGMAS * late.sigma and late.applied
    early = log.with_measured({n: np.concatenate([log[n][8:], np.repeat(log[n][-1:], 8)])
                               for n in COMMANDS})
    delayed = check_compatibility(early, PARAMS)
    servo = delayed["command_time_skew"]
    assert abs(servo.estimate - 0.08) <= SIGMAS * servo.sigma
    assert servo.significant and not servo.applied
    assert measured_command_delay(delayed) == servo.estimate
    assert measured_command_delay(logging) is None
    assert measured_command_delay(check_compatibility(log, PARAMS)) is None


AIR_DATA = ("pitot_airspeed", "pitot_qbar", "vane_alpha", "vane_beta")


@pytest.mark.parametrize("seed", STRAIGHT_SEEDS)
def test_an_air_data_skew_of_two_samples_is_found_to_a_few_milliseconds(straight, seed):
    """Within half the 10 ms tolerance and SIGMAS standard errors, clean and with 25 ms
    late air data (the specific force and the commands that move it are timed against
    the vanes; without the commands the estimate carried about +15 ms)."""
    log = straight[seed]
    clean = check_compatibility(log, PARAMS)["air_data_time_skew"]
    assert abs(clean.estimate) < min(0.005, SIGMAS * clean.sigma), clean.line()
    assert not clean.significant
    t = log.time
    late = log.with_measured({n: np.interp(t - 0.025, t, log[n]) for n in AIR_DATA})
    skew = check_compatibility(late, PARAMS)["air_data_time_skew"]
    assert abs(skew.estimate - 0.025) < min(0.005, SIGMAS * skew.sigma), skew.line()
    assert skew.applied


def test_a_servo_delay_is_not_taken_for_an_air_data_skew():
    """The surfaces 60 ms behind their commands: the command skew says so, and the air
    data, timed against the commands read that much earlier, show no skew."""
    for seed in STRAIGHT_SEEDS[:2]:
        flight = fly("aerosonde", turbulence="light", seed=seed, duration=40.0,
                     actuator_delay=0.06)
        result = check_compatibility(flight.select(flight.measured_names), PARAMS)
        assert abs(result["command_time_skew"].estimate - 0.06) < 0.003
        skew = result["air_data_time_skew"]
        assert abs(skew.estimate) < min(0.005, SIGMAS * skew.sigma), skew.line()
        assert not skew.significant


def test_skews_of_seconds_between_channel_groups_are_found(straight):
    log = straight[STRAIGHT_SEEDS[1]]
    gps = check_compatibility(inject(log, gps_delay=4.3), PARAMS)["gps_time_skew"]
    assert abs(gps.estimate - 4.3) <= SIGMAS * gps.sigma and gps.applied
    late = log.with_measured({n: _delayed(log[n], 230)
                              for n in ("att_roll", "att_pitch", "att_yaw")})
    attitude = check_compatibility(late, PARAMS)["attitude_time_skew"]
    assert abs(attitude.estimate - 2.3) <= SIGMAS * attitude.sigma and attitude.applied


def test_reads_only_measured_channels(straight):
    flight = fly("aerosonde", turbulence="light", seed=STRAIGHT_SEEDS[0], duration=40.0)
    with_truth = check_compatibility(flight, PARAMS)
    measured = check_compatibility(straight[STRAIGHT_SEEDS[0]], PARAMS)
    assert with_truth.summary() == measured.summary()


def test_missing_channels(straight):
    log = straight[STRAIGHT_SEEDS[0]]
    with pytest.raises(FlightLogError, match="att_yaw"):
        check_compatibility(log.select([n for n in log.measured_names if n != "att_yaw"]),
                            PARAMS)
    no_gps = check_compatibility(log.select([n for n in log.measured_names
                                             if not n.startswith("gps")]), PARAMS)
    assert any("no GPS velocity" in note for note in no_gps.notes)
    assert "gps_time_skew" not in {e.name for e in no_gps.effects}


def test_channels_held_constant_leave_notes_not_errors(straight):
    log = straight[STRAIGHT_SEEDS[0]]
    lateral = ("imu_ay", "imu_p", "imu_r", "vane_beta", "att_roll", "cmd_aileron",
               "cmd_rudder")
    held = log.with_measured({**{n: 0.0 * log[n] for n in lateral},
                              "att_yaw": 0.0 * log["att_yaw"] + log["att_yaw"][0]})
    result = check_compatibility(held, PARAMS)
    assert result.significant == ()
    assert not result["vane_beta_scale_factor"].observable


def test_shift_fit_finds_a_sub_sample_delay_with_an_honest_error():
    rng = np.random.default_rng(5)
    time = np.arange(0.0, 60.0, 0.01)
    drive = np.convolve(rng.normal(size=time.size), np.ones(20) / 20, mode="same")
    integral = Cumulative(time, drive)
    start = time[100:-300:10]
    end = start + 0.5
    measured = Cumulative(time, np.interp(time - 0.0234, time, drive))
    change = measured.between(start, end)[:, 0] + rng.normal(0.0, 0.01, start.size)

    def design(tau):
        return integral.between(start, end, tau), change, 0.5 * (start + end)

    fit = shift_fit(design, ["gain"], 0.0, 0.01, 5, 3.0)
    assert abs(fit.value("skew") - 0.0234) <= 3.0 * fit.sigma("skew") < 0.003
    assert abs(fit.value("gain") - 1.0) <= 3.0 * fit.sigma("gain")


def test_block_errors_match_ordinary_ones_on_white_noise():
    rng = np.random.default_rng(6)
    errors = []
    for _ in range(200):
        y = 1.0 + rng.normal(size=400)
        fit = linear_fit(np.ones((400, 1)), y, ["mean"], np.arange(400.0), 20.0)
        errors.append((fit.value("mean") - 1.0) / fit.sigma("mean"))
    assert 0.85 < np.std(errors) < 1.25


@pytest.mark.slow
@pytest.mark.parametrize("seed", [10, 11, 12, 13, 14, 15])
def test_air_data_errors_recovered_on_more_seeds(seed):
    log = _turning(seed)
    assert check_compatibility(log, PARAMS).significant == ()
    _assert_recovered(check_compatibility(inject(log), PARAMS),
                      {**KINEMATIC_ERRORS, **AIR_DATA_ERRORS})
