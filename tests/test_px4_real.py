"""PX4 ULog reader on real logs and on synthetic logs of the cases they lack.

Real logs (tests/data/, from PX4/pyulog's tests, BSD-3-Clause, LICENSE-pyulog.md):
``px4_sample_log_small.ulg`` a PX4 1.11 standard VTOL on the ground (6.5 s),
``px4_sample.ulg`` a quadrotor moved by hand (69 s), ``px4_sample_px4_events.ulg``
a PX4 1.15 simulated quadrotor (no ``actuator_controls``).
"""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from drake_uav.io.flight_log import FlightLogError
from drake_uav.io.px4 import read_px4, read_px4_metadata
from drake_uav.io.readers import read_log
from drake_uav.model.rotations import euler_to_quat

try:
    from drake_uav.io.writers import ULogWriter
except ImportError:  # the writers' earlier home
    from log_writers import ULogWriter

DATA = Path(__file__).parent / "data"
VTOL, QUAD, QUAD_115 = (DATA / name for name in (
    "px4_sample_log_small.ulg", "px4_sample.ulg", "px4_sample_px4_events.ulg"))
FULL = math.radians(25.0)  # deflection at a demand of 1
SURFACES = ("cmd_elevator", "cmd_aileron", "cmd_rudder")


def _read(path, **options):
    """(log, warning messages) of reading ``path``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_log(path, **options)
    return log, [str(w.message) for w in caught]


# ------------------------------------------------------------------ real logs
def test_vtol_ground_log_reads_the_fixed_wing_group_with_plausible_values():
    log, messages = _read(VTOL)
    meta = log.metadata
    assert meta["vehicle_type"] == {"mav_type": 22, "name": "VTOL standard (fixed rotors)"}
    assert meta["firmware"].startswith("PX4 v1.11.2")
    assert meta["flight_modes"] == [[pytest.approx(20.220673), "MANUAL"]]
    assert [state for _, state in meta["vtol_state"]] == ["mc"]
    assert meta["imu_rate_hz"] == pytest.approx(200, rel=0.05)
    assert len(meta["parameters"]) == 980 and meta["parameters"]["MAV_TYPE"] == 22
    # Surfaces from actuator_controls_1: its roll demand is -0.33..-0.18, the
    # multicopter group's -0.07..-0.02.
    assert meta["actuators"]["message"] == "actuator_controls_1"
    assert -0.33 * FULL < log["cmd_aileron"].min() and log["cmd_aileron"].max() < -0.17 * FULL
    for name in SURFACES:
        assert np.abs(log[name]).max() <= FULL, name
    assert 0 <= log["cmd_throttle"].min() and log["cmd_throttle"].max() <= 1
    force = np.linalg.norm(log.stack(["imu_ax", "imu_ay", "imu_az"]), axis=1)
    assert np.median(force) == pytest.approx(9.81, abs=0.3)  # at rest
    # Airspeed negative on the ground: every sample invalid, the stream dropped.
    assert "pitot_airspeed" not in log and "airspeed" in meta["dropped_streams"]
    # 1 Hz optional topics dropped with a warning naming the file.
    for topic in ("differential_pressure", "wind_estimate"):
        assert any(str(VTOL) in m and f"'{topic}' dropped: sparse" in m for m in messages)
    # xy_valid = 0 throughout: no horizontal position, the height kept.
    assert "gps_pn" not in log and "gps_vn" not in log
    assert np.abs(log["gps_pd"]).max() < 1.5
    # Commands invalid once disarmed (vehicle_status at 25.83 s): the log ends there.
    # actuator_controls_1 (404 Hz) is logged faster than the IMU (205 Hz): its samples
    # are the time base, from the first one inside the IMU's data.
    assert meta["time_base"] == "actuator_controls_1"
    assert log.time[0] == pytest.approx(20.327, abs=1e-3)
    assert log.time[-1] < 25.83 and log.duration > 5.3


def test_vtol_metadata_without_the_streams():
    meta = read_px4_metadata(VTOL)
    assert meta["vehicle_type"]["mav_type"] == 22 and meta["vtol_state"][0][1] == "mc"
    assert meta["actuators"]["message"] == "actuator_controls_1"
    assert meta["parameters"] == read_log(VTOL).metadata["parameters"]
    # The IMU position parameters as PX4 1.11 writes them (this airframe: at the origin).
    assert meta["imu_position"] == {"position": [0.0, 0.0, 0.0],
                                    "source": "EKF2_IMU_POS_X/Y/Z"}


def test_vtol_ground_log_options_fail_clearly():
    with pytest.raises(FlightLogError, match=r"px4_sample_log_small\.ulg: actuator outputs of "
                                             r"a VTOL without PWM_MAIN_FUNCn"):
        read_log(VTOL, actuators="outputs")
    # Instance 1: sensor_accel / sensor_gyro multi-id 1, logged at 1 Hz here.
    with pytest.warns(UserWarning, match=r"IMU \(sensor_accel multi-id 1\) logged at 1 Hz, "
                                         r"below 100 Hz"):
        with pytest.raises(FlightLogError, match=r"stream 'sensor_accel'"):
            read_log(VTOL, instance=1)
    log = read_log(VTOL, instance=1, max_gap=1.5)
    assert log.metadata["imu_rate_hz"] == pytest.approx(1.0, rel=0.02)
    assert log.metadata["streams"]["sensor_gyro"]["channels"] == ["imu_p", "imu_q", "imu_r"]
    with pytest.raises(FlightLogError, match=r"no IMU of instance 5: multi-ids of "
                                             r"sensor_combined \[0\], sensor_accel \[0, 1, 2\]"):
        read_log(VTOL, instance=5)


def test_quadrotor_log_reads_for_replay_without_zero_positions():
    log, messages = _read(QUAD)
    meta = log.metadata
    assert meta["vehicle_type"]["mav_type"] == 2
    assert meta["firmware"] == "PX4 (fd483321)"
    assert "vtol_state" not in meta
    assert len(meta["parameter_changes"]) == 6 and "COM_AUTOS_PAR" in meta["parameters"]
    assert meta["actuators"]["message"] is None  # no surfaces on a multicopter
    assert not any(name.startswith("cmd_") for name in log.names)
    # xy_valid = 0 in every sample: the logged zeros are not positions.
    assert "gps_pn" not in log and "gps_pe" not in log and "gps_vn" not in log
    assert any("'vehicle_local_position.xy' dropped" in m for m in messages)
    assert "gps_pd" in log and log.duration > 68


def test_px4_115_log_reads_without_actuator_controls_and_motors_are_not_surfaces():
    for actuators in (None, "outputs"):
        log, _ = _read(QUAD_115, actuators=actuators)
        assert not set(SURFACES) & set(log.names)
    meta = log.metadata
    assert meta["vehicle_type"]["mav_type"] == 2
    assert meta["firmware"].startswith("PX4 v1.15.0")
    assert [mode for _, mode in meta["flight_modes"]] == [
        "AUTO_LOITER", "AUTO_TAKEOFF", "AUTO_LOITER", "AUTO_RTL", "AUTO_LOITER"]
    assert meta["parameters"]["PWM_MAIN_FUNC1"] == 101
    assert meta["imu_rate_hz"] == pytest.approx(250, rel=0.01)


# ------------------------------------------------------------- synthetic logs
def _us(t0, rate, n):
    return np.round((t0 + np.arange(n) / rate) * 1e6).astype(np.uint64)


def _last_stamp(t, stamps):
    """Stamp [s] of the last sample at or before each time ``t`` [s] (previous-sample hold)."""
    index = np.searchsorted(stamps, t, side="right") - 1
    return np.asarray(stamps)[np.clip(index, 0, len(stamps) - 1)]


class _Log:
    """A 4 s synthetic ULog: sensor_combined 200 Hz and vehicle_attitude 50 Hz, plus
    whatever a test adds (:meth:`topic`); times from 1 s."""

    def __init__(self, **parameters):
        self.w = ULogWriter(start_us=500_000)
        for name, value in parameters.items():
            self.w.parameter(name, value)
        n = 801
        self.topic("sensor_combined", "float[3] gyro_rad;float[3] accelerometer_m_s2", 200,
                   gyro_rad=np.zeros((n, 3)), accelerometer_m_s2=np.tile([0, 0, -9.81], (n, 1)))
        self.topic("vehicle_attitude", "float[4] q", 50,
                   q=np.tile(euler_to_quat(np.array([0.0, 0.05, 1.0])), (201, 1)))

    def topic(self, name, fields, rate, **columns):
        """Adds topic ``name``: as many rows as given, at ``rate`` [Hz] from 1 s."""
        self.w.format(name, f"uint64_t timestamp;{fields}")
        n = len(next(iter(columns.values())))
        self.w.data(name, self.w.subscribe(name), timestamp=_us(1.0, rate, n), **columns)

    def save(self, path):
        return self.w.save(path)


def _controls(log, group, roll, n=201):
    control = np.zeros((n, 8))
    control[:, 0], control[:, 1], control[:, 3] = roll, 0.2, 0.6
    log.topic(group, "float[8] control", 50, control=control)


def test_sparse_optional_topics_dropped_and_invalid_samples_are_holes(tmp_path):
    log = _Log(MAV_TYPE=1)
    _controls(log, "actuator_controls_0", 0.1)
    k = np.arange(81)
    speed = 20.0 + 0.1 * k
    speed[40:43] = -0.5  # three negative samples (0.15 s) inside
    log.topic("airspeed", "float indicated_airspeed_m_s;float true_airspeed_m_s", 20,
              indicated_airspeed_m_s=speed, true_airspeed_m_s=speed)
    log.topic("differential_pressure", "float differential_pressure_pa", 1,
              differential_pressure_pa=np.full(5, 240.0))
    log.topic("wind", "float windspeed_north;float windspeed_east", 1,
              windspeed_north=np.ones(5), windspeed_east=np.ones(5))
    k = np.arange(41)
    log.topic("vehicle_local_position", "float x;float y;float z;float vx;float vy;float vz;"
              "bool xy_valid;bool z_valid;bool v_xy_valid;bool v_z_valid", 10,
              x=np.zeros(41), y=np.zeros(41), z=-50.0 - k, vx=np.zeros(41), vy=np.zeros(41),
              vz=np.full(41, -10.0), xy_valid=np.zeros(41), z_valid=np.ones(41),
              v_xy_valid=np.zeros(41), v_z_valid=np.ones(41))
    path = log.save(tmp_path / "sparse.ulg")
    flight, messages = _read(path)
    meta = flight.metadata
    assert meta["dropped_streams"] == ["vehicle_local_position.xy",
                                       "vehicle_local_position.v_xy", "differential_pressure",
                                       "wind"]
    for topic in ("differential_pressure", "wind"):
        assert any(m.startswith(f"{path}: optional stream '{topic}' dropped: sparse: logged "
                                "at 1 Hz") for m in messages)
    assert "gps_pn" not in flight and "gps_vn" not in flight
    # held: logged slower than 0.45 of the time base
    s = _last_stamp(flight.time, _us(1.0, 10, 41) / 1e6)
    np.testing.assert_allclose(flight["gps_pd"], -50 - 10 * (s - 1.0), atol=1e-4)
    # The pitot of a plane is required: its negative samples are a hole between segments.
    assert meta["streams"]["airspeed"]["invalid"] == 3
    np.testing.assert_allclose(meta["segments"], [[1.0, 2.95], [3.15, 5.0]])
    assert flight["pitot_airspeed"].min() >= 20.0
    assert meta["actuators"]["message"] == "actuator_controls_0"
    assert meta["vehicle_type"] == {"mav_type": 1, "name": "fixed wing"}


def test_vtol_reads_the_fixed_wing_group_and_its_state_timeline(tmp_path):
    log = _Log(MAV_TYPE=22)
    _controls(log, "actuator_controls_0", 0.9)  # hover rotors' roll demand
    _controls(log, "actuator_controls_1", -0.2)  # fixed-wing group
    log.topic("vehicle_status", "uint8_t nav_state;uint8_t arming_state", 1,
              nav_state=[2, 2, 3, 3, 18], arming_state=np.full(5, 2))
    log.topic("vtol_vehicle_status", "uint8_t vehicle_vtol_state", 1,
              vehicle_vtol_state=[3, 1, 4, 4, 2])
    flight = read_px4(log.save(tmp_path / "vtol.ulg"))
    np.testing.assert_allclose(flight["cmd_aileron"], np.float32(-0.2) * FULL, rtol=1e-7)
    np.testing.assert_allclose(flight["cmd_elevator"], -np.float32(0.2) * FULL, rtol=1e-7)
    meta = flight.metadata
    assert meta["actuators"]["selected"] == "fixed-wing control group of a VTOL"
    assert meta["flight_modes"] == [[1.0, "POSCTL"], [3.0, "AUTO_MISSION"], [5.0, "AUTO_LAND"]]
    assert meta["vtol_state"] == [[1.0, "mc"], [2.0, "transition"], [3.0, "fw"],
                                  [5.0, "transition"]]
    only_mc = _Log(MAV_TYPE=22)
    _controls(only_mc, "actuator_controls_0", 0.9)
    with pytest.raises(FlightLogError, match=r"only_mc\.ulg: VTOL log \(MAV_TYPE 22\) without "
                                             r"actuator_controls_1"):
        read_px4(only_mc.save(tmp_path / "only_mc.ulg"))


def _allocated_vtol(tmp_path, pusher=True):
    """A PX4 1.14-style VTOL: servos 0/1 left/right aileron, 2 elevator, 3 rudder;
    rotors 0-3 up, rotor 4 forward (CA_ROTOR4_AX = 1) unless ``pusher`` is False."""
    log = _Log(MAV_TYPE=22, CA_SV_CS_COUNT=4, CA_SV_CS0_TYPE=1, CA_SV_CS1_TYPE=2,
               CA_SV_CS2_TYPE=3, CA_SV_CS3_TYPE=4, CA_ROTOR_COUNT=5,
               CA_ROTOR4_AX=1.0 if pusher else 0.0)
    servos = np.full((201, 8), np.nan)
    servos[:, :4] = [-0.3, 0.3, 0.5, -0.1]
    log.topic("actuator_servos", "float[8] control", 50, control=servos)
    motors = np.full((201, 12), np.nan)
    motors[:, :5] = [0.5, 0.5, 0.5, 0.5, 0.7]
    motors[:10, :5] = np.nan  # not driven before arming
    log.topic("actuator_motors", "float[12] control", 50, control=motors)
    return log.save(tmp_path / "vtol114.ulg")


def test_allocated_servos_and_pusher_motor_of_px4_114(tmp_path):
    flight = read_px4(_allocated_vtol(tmp_path))
    np.testing.assert_allclose(flight["cmd_aileron"], np.float32(0.3) * FULL, rtol=1e-7)
    np.testing.assert_allclose(flight["cmd_elevator"], -np.float32(0.5) * FULL, rtol=1e-7)
    np.testing.assert_allclose(flight["cmd_rudder"], np.float32(0.1) * FULL, rtol=1e-7)
    np.testing.assert_allclose(flight["cmd_throttle"], 0.7, rtol=1e-7)  # motor 4 only
    assert flight.time[0] == pytest.approx(1.2)  # motors not driven before
    assert flight.metadata["streams"]["actuator_motors"]["invalid"] == 10
    limit = math.radians(20.0)  # the aircraft's aileron limit: a servo at +-1
    flight = read_px4(_allocated_vtol(tmp_path), deflections={"aileron": limit})
    np.testing.assert_allclose(flight["cmd_aileron"], np.float32(0.3) * limit, rtol=1e-7)
    np.testing.assert_allclose(flight["cmd_elevator"], -np.float32(0.5) * FULL, rtol=1e-7)
    with pytest.raises(FlightLogError, match=r"vtol114\.ulg: VTOL log without a forward "
                                             r"\(fixed-wing\) motor: no CA_ROTORn_AX = 1"):
        read_px4(_allocated_vtol(tmp_path, pusher=False))


def test_servos_without_surface_types_are_refused(tmp_path):
    log = _Log(MAV_TYPE=1, CA_SV_CS_COUNT=2)
    log.topic("actuator_servos", "float[8] control", 50, control=np.zeros((201, 8)))
    with pytest.raises(FlightLogError, match=r"untyped\.ulg: no servo of servos \[0, 1\] "
                                             r"moves a control axis \(CA_SV_CSn_TYPE"):
        read_px4(log.save(tmp_path / "untyped.ulg"))


def test_outputs_through_pwm_functions_and_limits(tmp_path):
    log = _Log(MAV_TYPE=1, PWM_MAIN_FUNC1=201, PWM_MAIN_FUNC2=202, PWM_MAIN_FUNC3=101,
               CA_SV_CS_COUNT=2, CA_SV_CS0_TYPE=15, CA_SV_CS1_TYPE=3, CA_ROTOR_COUNT=1,
               PWM_MAIN_REV=2, **{f"PWM_MAIN_{key}{n}": value for n in (1, 2, 3)
                                  for key, value in (("MIN", 1100), ("MAX", 1900))},
               PWM_MAIN_DIS1=1500, PWM_MAIN_DIS2=1500, PWM_MAIN_DIS3=1000)
    out = np.zeros((201, 16))
    out[:, :3] = [1600, 1300, 1500]
    out[:20, :3] = 0  # outputs not driven at first
    out[100, 0] = 2100  # one sample beyond PWM_MAIN_MAX1
    out[150:, 0] = 1500  # at the disarmed value, but armed: a valid centred aileron
    log.topic("actuator_outputs", "uint32_t noutputs;float[16] output", 50, output=out)
    log.topic("vehicle_status", "uint8_t nav_state;uint8_t arming_state", 1,
              nav_state=np.zeros(5), arming_state=np.full(5, 2))
    flight = read_px4(log.save(tmp_path / "outputs.ulg"), actuators="outputs")
    np.testing.assert_allclose(flight.metadata["segments"], [[1.4, 2.98], [3.02, 5.0]])
    early = flight.time < 3.0
    np.testing.assert_allclose(flight["cmd_aileron"][early], 0.25 * FULL)
    np.testing.assert_allclose(flight["cmd_aileron"][flight.time >= 4.0], 0.0)
    np.testing.assert_allclose(flight["cmd_elevator"], -0.5 * FULL)  # output 2 reversed
    np.testing.assert_allclose(flight["cmd_throttle"], 0.5)
    assert flight.metadata["streams"]["actuator_outputs"]["invalid"] == 21
    assert flight.metadata["actuators"]["sources"]["actuator_outputs"][
        "pwm_min_max_disarmed"]["output[0]"] == [1100.0, 1900.0, 1500.0]
