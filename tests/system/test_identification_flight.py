"""Identification flight: seeding, sensor statistics in flight, wind coupling, bad input."""

import math

import numpy as np
import pytest
from pydrake.systems.primitives import LogVectorOutput

from drake_uav.diagrams.identification_flight import (
    THROTTLE_PEAK,
    build_identification_flight,
    default_excitation,
    fly,
)
from drake_uav.io.flight_log import FlightLog
from drake_uav.model.rotations import quat_to_rotmat
from drake_uav.systems.excitation import Turn
from drake_uav.systems.identifiers import (
    AeroRegressors,
    RecursiveIdentifier,
    RecursiveIdentifierParams,
)
from drake_uav.systems.safety_pilot import SafetyPilot, SafetyPilotGains
from drake_uav.vehicles.fixed_wing import aerosonde
from drake_uav.vehicles.sensors import ChannelErrors, GpsParams, ImuParams, SensorSuiteParams

STEADY = (2.0, -1.5, 0.0)


@pytest.fixture(scope="module")
def flight():
    return build_identification_flight("aerosonde", "moderate", STEADY, "multisine", seed=1,
                                       duration=20.0)


@pytest.fixture(scope="module")
def log(flight):
    return flight.simulate()


def _quats(log: FlightLog) -> np.ndarray:
    q = log.stack(["qw", "qx", "qy", "qz"])
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_same_seed_bit_identical_and_new_seed_new_noise(flight, log):
    again = flight.simulate(seed=1)
    assert again.equals(log)
    other = flight.simulate(seed=2)
    assert not np.array_equal(other["imu_p"] - other["p"], log["imu_p"] - log["p"])
    assert not np.array_equal(other["gust_w"], log["gust_w"])
    # The trim start and the excitation do not depend on the seed.
    np.testing.assert_array_equal(other["cmd_aileron"][:1], log["cmd_aileron"][:1])


def test_log_layout_and_units(log):
    assert len(log) == 2001 and log.time[-1] == pytest.approx(20.0)
    log.require("imu_ax", "gps_vn", "pitot_airspeed", "vane_alpha", "att_yaw", "baro_alt",
                "cmd_elevator", "CX", "Cm", "Fx", "Mz", "wind_n", "gust_w", "alpha", "elevator")
    assert log.is_truth("alpha") and not log.is_truth("vane_alpha")
    assert log.unit("Mz") == "N m" and log.unit("gps_pd") == "m" and log.unit("CZ") == "1"
    assert log.metadata["turbulence"] == "moderate" and log.metadata["seed"] == 1


def test_sensor_errors_in_flight_match_table7(log):
    p = SensorSuiteParams.seed_table7()
    n = len(log)
    pairs = [("imu_q", "q", p.imu.gyro.noise_std), ("imu_az", "az", p.imu.accel.noise_std),
             ("vane_alpha", "alpha", p.vanes.angles.noise_std),
             ("att_pitch", "pitch", p.attitude.angles.noise_std)]
    for measured, true, sigma in pairs:
        error = log[measured] - log[true]
        assert abs(error.mean()) < 4.5 * sigma / math.sqrt(n), measured
        assert abs(error.std() / sigma - 1.0) < 4.5 / math.sqrt(2 * n), measured
    qbar = 0.5 * 1.2682 * log["airspeed"] ** 2
    error = log["pitot_qbar"] - qbar
    assert abs(error.std() / p.pitot.dynamic_pressure.noise_std - 1) < 4.5 / math.sqrt(2 * n)


def test_gps_rate_and_latency_in_flight(log):
    every, lag = 5, 10  # 20 Hz and 0.1 s at 100 Hz
    pn = log["gps_pn"]
    changes = np.flatnonzero(np.diff(pn) != 0) + 1
    assert np.all((changes - lag) % every == 0)
    assert changes.size == (len(log) - 1 - lag) // every + 1
    # Released at t_k, sampled at t_k - 0.1 s: the error to the delayed truth is white noise.
    error = pn[changes] - log["pn"][changes - lag]
    sigma = 1.0
    assert abs(error.mean()) < 4.5 * sigma / math.sqrt(changes.size)
    assert abs(error.std() / sigma - 1) < 4.5 / math.sqrt(2 * changes.size)
    # Against the undelayed truth the error grows by the distance flown in 0.1 s (~2.5 m).
    assert np.abs(pn[changes] - log["pn"][changes]).mean() > 2.0


def test_wind_truth_and_air_data_are_consistent(log):
    q = _quats(log)
    gust = log.stack(["gust_u", "gust_v", "gust_w"])
    wind = log.stack(["wind_n", "wind_e", "wind_d"])
    # The body gust is the wind less the steady wind, in body axes.
    for k in range(1, len(log), 97):
        R = quat_to_rotmat(q[k] / np.linalg.norm(q[k]))
        np.testing.assert_allclose(R @ gust[k], wind[k] - STEADY, atol=1e-12)
    # The plant's airspeed is the norm of ground velocity minus that wind, in body axes.
    for k in range(0, len(log), 89):
        R = quat_to_rotmat(q[k])
        v = log.stack(["u", "v", "w"])[k] - R.T @ wind[k]
        assert log["airspeed"][k] == pytest.approx(np.linalg.norm(v), rel=1e-12)
    assert 0.5 < np.std(log["gust_w"]) < 3.0
    # A command is stamped with the time it is issued and held until the next one; the
    # truth surfaces are stamped at the end of the interval they were held over.
    np.testing.assert_array_equal(log["cmd_aileron"][:-1], log["aileron"][1:])


def test_actuator_delay_and_disturbance_act_through_the_physics():
    base = fly("aerosonde", None, seed=3, duration=6.0)
    delayed = fly("aerosonde", None, seed=3, duration=6.0, actuator_delay=0.05)
    # The surfaces lag the logged commands by five 10 ms samples (plus the one-sample
    # stamping offset of the truth surfaces, see above).
    np.testing.assert_array_equal(delayed["aileron"][6:], delayed["cmd_aileron"][:-6])
    assert not np.array_equal(base["p"], delayed["p"])
    pushed = fly("aerosonde", None, seed=3, duration=6.0, disturbance=[-20.0, 0, 0, 0, 0, 0])
    # A 20 N drag-like force shows up 1:1 in the accelerometer's truth.
    np.testing.assert_allclose(pushed["ax"][0] - base["ax"][0], -20.0 / 13.5, rtol=1e-9)


def test_the_throttle_multisine_moves_the_throttle_on_its_own():
    """"multisine_throttle": a fourth multisine on the throttle (peak THROTTLE_PEAK) sharing
    no frequency with the surfaces', and the logged throttle command follows it."""
    signals = default_excitation("multisine_throttle", 60.0)
    assert [s.surface for s in signals] == ["elevator", "aileron", "rudder", "throttle"]
    frequencies = [set(np.round(s.frequencies, 9)) for s in signals]
    assert all(not a & b for i, a in enumerate(frequencies) for b in frequencies[i + 1:])
    t = np.arange(1.0, 21.0, 0.001)
    assert np.max(np.abs(signals[3](t))) == pytest.approx(THROTTLE_PEAK, rel=1e-3)
    log = fly("aerosonde", None, excitation="multisine_throttle", seed=3, duration=21.0)
    plain = fly("aerosonde", None, excitation="multisine", seed=3, duration=21.0)
    moved = log["cmd_throttle"] - plain["cmd_throttle"]
    assert np.std(moved) > 0.3 * THROTTLE_PEAK
    assert np.corrcoef(moved, signals[3](log.time))[0, 1] > 0.8  # 0.91: the airspeed hold answers


def test_extend_puts_an_online_identifier_into_the_flight():
    """A RecursiveIdentifier on the plant's truth signals, added through ``extend``,
    recovers the Aerosonde's pitching-moment derivatives in flight."""
    params = aerosonde()
    added = {}

    def extend(builder, ports):
        regressors = builder.AddSystem(AeroRegressors(params, "Cm"))
        for name in ("air_data", "state", "aero_coefficients"):
            builder.Connect(ports[name], regressors.GetInputPort(name))
        builder.Connect(ports["surfaces"], regressors.GetInputPort("controls"))
        identifier = builder.AddSystem(RecursiveIdentifier(RecursiveIdentifierParams(
            names=regressors.names, error_std=(1e-6,) * (len(regressors.names) + 1),
            method="tls")))
        builder.Connect(regressors.GetOutputPort("regressors"),
                        identifier.GetInputPort("regressors"))
        builder.Connect(regressors.GetOutputPort("observation"),
                        identifier.GetInputPort("observation"))
        added["estimate"] = LogVectorOutput(identifier.GetOutputPort("estimate"), builder, 1.0)
        added["names"] = regressors.names

    flight = build_identification_flight(params, "light", duration=20.0, extend=extend)
    log, context = flight.simulate_with_context()
    estimate = added["estimate"].FindLog(context).data()[:, -1]
    truth = np.array([params.derivatives[n] for n in added["names"]])
    np.testing.assert_allclose(estimate, truth, rtol=1e-6, atol=1e-8)
    assert len(log) == 2001


def test_safety_pilot_damps_with_the_gyro_it_is_given():
    pilot = SafetyPilot(SafetyPilotGains(), 0.0, 100.0, 0.0, 25.0, 0.01)
    context = pilot.CreateDefaultContext()
    state = np.array([0, 0, -100.0, 1, 0, 0, 0, 25, 0, 0, 0.1, 0.2, 0.3])
    pilot.GetInputPort("state").FixValue(context, state)
    pilot.GetInputPort("air_data").FixValue(context, [25.0, 0.0, 0.0])

    def correction():
        return pilot.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()

    gains = pilot.gains
    true_rates = correction()  # no imu connected: the true rates
    assert true_rates[2] == pytest.approx(gains.yaw_rate * 0.3)
    pilot.GetInputPort("imu").FixValue(context, [0, 0, -9.81, -0.4, 0.5, -0.6])
    gyro = correction()
    assert gyro[2] == pytest.approx(gains.yaw_rate * -0.6)
    assert gyro[1] - true_rates[1] == pytest.approx(-gains.roll_rate * (-0.4 - 0.1))
    assert gyro[0] - true_rates[0] == pytest.approx(gains.pitch_rate * (0.5 - 0.2))
    # The flight wires the suite's IMU to it.
    flight = build_identification_flight(duration=5.0)
    assert flight.pilot.GetInputPort("imu").HasValue(
        flight.pilot.GetMyContextFromRoot(flight.diagram.CreateDefaultContext()))


def test_flight_stays_near_trim(log):
    assert np.abs(np.degrees(log["roll"])).max() < 30.0
    assert np.abs(log["airspeed"] - 25.0).max() < 6.0
    assert np.abs(-log["pd"] - 100.0).max() < 30.0


def test_log_round_trip(log, tmp_path):
    assert FlightLog.load(log.save(tmp_path / "flight.parquet")).equals(log)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"turbulence": "extreme"}, "level"),
        ({"sensors": SensorSuiteParams(imu=ImuParams(gyro=ChannelErrors(-0.01)))},
         "imu.gyro.noise_std"),
        ({"sensors": SensorSuiteParams(gps=GpsParams(rate_hz=400.0))}, "gps.rate_hz"),
        ({"excitation": "sweep"}, "excitation"),
        ({"duration": -1.0}, "duration"),
        ({"excitation": "multisine"}, "duration"),  # too short for the default multisine
        ({"seed": -3}, "seed"),
        ({"turbulence": None, "steady_wind": (1.0, 2.0)}, "steady_wind"),
    ],
)
def test_bad_input_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=f"^{field}:"):
        fly(**{"duration": 1.0, **kwargs})


def test_a_turn_of_the_heading_reference_is_flown_by_the_safety_pilot():
    """A Turn is a reference signal: the heading hold banks the aircraft to follow it (one
    circle in a minute at 25 m/s needs about 15 deg of bank), the airspeed hold keeps the
    speed; without the safety pilot nothing would fly it, and the flight says so."""
    rate = 2 * math.pi / 60.0
    log = fly("aerosonde", turbulence=None, excitation=(Turn(rate, 59.0, 1.0),),
              duration=60.0)
    yaw = np.unwrap(log["yaw"])
    assert math.degrees(yaw[-1] - yaw[0]) > 300.0
    bank = math.degrees(math.atan(25.0 * rate / 9.81))
    assert math.degrees(np.max(np.abs(log["roll"]))) < bank + 3.0
    assert np.ptp(log["airspeed"]) < 0.5
    straight = fly("aerosonde", turbulence=None, excitation="none", duration=10.0)
    assert abs(np.unwrap(straight["yaw"])[-1] - straight["yaw"][0]) < 0.01
    with pytest.raises(ValueError, match="excitation: a signal on a reference .heading."):
        build_identification_flight(excitation=(Turn(rate, 10.0),), stabilize=False)
