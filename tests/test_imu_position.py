"""The accelerometers moved to the centre of gravity from the IMU position the log records.

The flights carry an IMU 20 cm ahead of the centre of gravity, 5 cm left and 10 cm below
(:mod:`drake_uav.testing.imu_offset`; Aerosonde, default sensors, light turbulence,
120 s): its accelerometers read ``w_dot x r + w x (w x r)`` more. Without that position
the job took it for an air-data time skew of 14-18 ms and found an accelerometer lever
arm and an unsteady alpha-dot on tuning flights 100-103; with it, nothing on the same
four (rates over more flights: ``benchmarks/bench_imu_position.py``). The seeds below
were run once.
"""

import warnings

import numpy as np
import pytest
from log_writers import dataflash_from_log, ulog_from_log

from drake_uav.cli import main
from drake_uav.diagrams import fly
from drake_uav.estimation.imu_position import accelerometers_at_cg, logged_imu_position
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog, FlightLogError
from drake_uav.io.readers import read_log
from drake_uav.model.isolation import lever_arm_specific_force
from drake_uav.testing.discovery_cases import measured_only
from drake_uav.testing.imu_offset import OFFSET as IMU_OFFSET
from drake_uav.testing.imu_offset import imu_away_from_cg
from drake_uav.vehicles import aerosonde

PARAMS = aerosonde()
OFFSET = np.array(IMU_OFFSET)
"""[m] body axes FRD."""
ACCELEROMETERS = ("imu_ax", "imu_ay", "imu_az")
ARDUPILOT = {"INS_POS1_X": 0.2, "INS_POS1_Y": -0.05, "INS_POS1_Z": 0.1}
PX4 = {"EKF2_IMU_POS_X": 0.2, "EKF2_IMU_POS_Y": -0.05, "EKF2_IMU_POS_Z": 0.1}


def _offset_imu(flight: FlightLog) -> FlightLog:
    return imu_away_from_cg(flight, OFFSET)


@pytest.fixture(scope="module")
def flight() -> FlightLog:
    return fly(PARAMS, "light", seed=0, duration=120.0)


def test_the_reading_per_metre_is_the_rigid_body_acceleration_of_the_point():
    w, w_dot = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -0.5])
    np.testing.assert_allclose(OFFSET @ lever_arm_specific_force(w_dot, w),
                               np.cross(w_dot, OFFSET) + np.cross(w, np.cross(w, OFFSET)))


def test_the_accelerometers_are_moved_back_to_the_centre_of_gravity(flight):
    """From the logged gyros, differentiated over the isolation's 0.2 s window: over that
    window (the band the isolation keeps) within 10 mm/s^2 RMS of the accelerometers at the
    centre of gravity (a fifth of their own noise) and within a tenth of the offset's
    reading on every axis; the roll acceleration above that band is left."""
    offset = _offset_imu(flight)
    moved = accelerometers_at_cg(offset, OFFSET)
    window = np.ones(21) / 21

    def band(values):
        return np.convolve(values, window, mode="valid")

    for c in ACCELEROMETERS:
        reading = np.sqrt(np.mean(band(offset[c] - flight[c]) ** 2))
        error = np.sqrt(np.mean(band(moved[c] - flight[c]) ** 2))
        assert error < min(0.01, reading / 10), (c, error, reading)


def test_a_bad_position_is_refused_by_name(flight):
    with pytest.raises(FlightLogError, match="imu_position"):
        accelerometers_at_cg(flight, (0.1, 0.0))
    with pytest.raises(FlightLogError, match="imu_position"):
        accelerometers_at_cg(flight, (0.1, np.nan, 0.0))
    with pytest.raises(FlightLogError, match="imu_position"):
        identify(flight, PARAMS, imu_position=(0.0, 0.0))


@pytest.mark.parametrize("kind, parameters, source", [
    ("bin", ARDUPILOT, "INS_POS1_X/Y/Z"), ("ulg", PX4, "EKF2_IMU_POS_X/Y/Z")])
def test_the_readers_take_the_position_from_the_autopilot_parameters(flight, tmp_path, kind,
                                                                     parameters, source):
    short = flight.slice(0.0, 20.0)
    write = dataflash_from_log if kind == "bin" else ulog_from_log
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with_position = read_log(write(short, tmp_path / f"a.{kind}", parameters=parameters))
        without = read_log(write(short, tmp_path / f"b.{kind}"))
    position = logged_imu_position(with_position)
    np.testing.assert_allclose(position.position, OFFSET, atol=1e-6)
    assert position.source == source
    assert logged_imu_position(without) is None


def _identified(log: FlightLog, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify(log, PARAMS, seed=0, **options)


def test_with_the_logged_position_an_offset_imu_finds_nothing(flight, tmp_path):
    """The same .bin flight with and without INS_POS1_*: without, the offset shows up as
    findings (here an accelerometer lever arm; on tuning seeds 100-103 an air-data skew,
    the lever arm and an unsteady alpha-dot)."""
    log = _offset_imu(flight)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        recorded = read_log(dataflash_from_log(log, tmp_path / "a.bin", parameters=ARDUPILOT))
        unrecorded = read_log(dataflash_from_log(log, tmp_path / "b.bin"))
    run = _identified(recorded)
    assert list(run.findings) == []
    assert run.notes[0] == ("accelerometers moved to the centre of gravity from the IMU "
                            "position (0.2, -0.05, 0.1) m (INS_POS1_X/Y/Z)")
    assert _identified(unrecorded).findings


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_a_given_position_finds_nothing_on_more_seeds(seed):
    log = measured_only(_offset_imu(fly(PARAMS, "light", seed=seed, duration=120.0)))
    assert list(_identified(log, imu_position=OFFSET).findings) == []


def test_the_command_line_takes_the_position_and_refuses_a_bad_one(tmp_path, capsys):
    log = tmp_path / "flight.csv"
    log.write_text("time\n0\n")
    assert main(["identify", str(log), "--imu-position", "0.2,0"]) == 2
    assert "--imu-position: give X,Y,Z in metres" in capsys.readouterr().err
