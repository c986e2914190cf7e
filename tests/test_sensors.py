"""Sensor suite: measured-minus-truth statistics, rates, latency, bias walk, seeding."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_uav.model.rotations import euler_to_quat, quat_to_rotmat
from drake_uav.systems.sensors import SensorSuite
from drake_uav.vehicles.sensors import (
    AttitudeParams,
    BaroParams,
    ChannelErrors,
    GpsParams,
    ImuParams,
    PitotParams,
    SensorSuiteParams,
    VaneParams,
)

EULER = np.array([0.2, -0.1, 3.1])  # yaw close to +pi: the measurement wraps
QUAT = euler_to_quat(EULER)
STATE = np.concatenate([[120.0, -40.0, -150.0], QUAT, [24.0, 1.0, 2.0], [0.1, -0.2, 0.05]])
AIR = np.array([25.0, 0.07, -0.03])
FORCE = np.array([0.8, -0.3, -9.5])
RHO = 1.2
GROUP_CHANNELS = {
    ("imu", "accel"): ["imu_ax", "imu_ay", "imu_az"],
    ("imu", "gyro"): ["imu_p", "imu_q", "imu_r"],
    ("gps", "position"): ["gps_pn", "gps_pe", "gps_pd"],
    ("gps", "velocity"): ["gps_vn", "gps_ve", "gps_vd"],
    ("pitot", "dynamic_pressure"): ["pitot_qbar"],
    ("vanes", "angles"): ["vane_alpha", "vane_beta"],
    ("attitude", "angles"): ["att_roll", "att_pitch", "att_yaw"],
    ("baro", "altitude"): ["baro_alt"],
}


def _truth_by_channel() -> dict[str, float]:
    vel = quat_to_rotmat(QUAT) @ STATE[7:10]
    values = [*FORCE, *STATE[10:13], *STATE[0:3], *vel, 0.5 * RHO * AIR[0] ** 2, *AIR[1:],
              *EULER, -STATE[2]]
    names = ["imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r", "gps_pn", "gps_pe",
             "gps_pd", "gps_vn", "gps_ve", "gps_vd", "pitot_qbar", "vane_alpha", "vane_beta",
             "att_roll", "att_pitch", "att_yaw", "baro_alt"]
    return dict(zip(names, values, strict=True))


def _run(params: SensorSuiteParams, duration: float, seed: int = 1):
    """Measurements (rows: samples at the base rate, taken at t = 0, dt, ...) with fixed truth."""
    builder = DiagramBuilder()
    suite = builder.AddSystem(SensorSuite(params))
    for name, value in (("state", STATE), ("air_data", AIR), ("specific_force", FORCE)):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(0), suite.GetInputPort(name))
    dt = 1.0 / params.base_rate_hz
    log = LogVectorOutput(suite.GetOutputPort("measurements"), builder, dt)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(duration)
    data = log.FindLog(context).data()[:, 1:].T  # the row logged at t_(k+1) was taken at t_k
    return dict(zip(suite.channel_names, data.T, strict=True))


def test_table7_defaults():
    p = SensorSuiteParams.seed_table7()
    assert p.imu.accel.noise_std == pytest.approx(0.05)
    assert p.imu.gyro.noise_std == pytest.approx(math.radians(0.35))
    assert p.attitude.angles.noise_std == pytest.approx(math.radians(0.75))
    assert p.vanes.angles.noise_std == pytest.approx(math.radians(0.6))
    assert p.pitot.dynamic_pressure.noise_std == pytest.approx(10.0)
    np.testing.assert_allclose(p.gps.velocity.noise_std, (0.05, 0.05, 0.1))
    assert (p.imu.rate_hz, p.gps.rate_hz, p.pitot.rate_hz, p.vanes.rate_hz) == (100, 20, 100, 100)
    assert SensorSuiteParams.seed_table7("rad/s").imu.gyro.noise_std == pytest.approx(0.35)
    with pytest.raises(ValueError, match="^gyro_noise_unit:"):
        SensorSuiteParams.seed_table7("rpm")


def test_measured_minus_truth_matches_configuration():
    errors = {
        "imu": {"accel": ChannelErrors((0.05, 0.08, 0.1), bias=(0.2, -0.1, 0.05),
                                       scale_factor=0.01),
                "gyro": ChannelErrors(0.004, bias=(0.01, 0.0, -0.02), scale_factor=-0.02)},
        "gps": {"position": ChannelErrors((1.0, 1.0, 2.0), bias=(0.5, 0.0, -1.0)),
                "velocity": ChannelErrors(0.05)},
        "pitot": {"dynamic_pressure": ChannelErrors(10.0, bias=3.0, scale_factor=0.05)},
        "vanes": {"angles": ChannelErrors(0.01, bias=(0.02, -0.01), scale_factor=(0.1, -0.1))},
        "attitude": {"angles": ChannelErrors(0.013, bias=(0.0, 0.01, 0.02))},
        "baro": {"altitude": ChannelErrors(0.5, bias=-2.0, scale_factor=0.002)},
    }
    rates = {"imu": 100.0, "gps": 10.0, "pitot": 50.0, "vanes": 100.0, "attitude": 25.0,
             "baro": 20.0}
    params = SensorSuiteParams(
        imu=ImuParams(rate_hz=rates["imu"], **errors["imu"]),
        gps=GpsParams(rate_hz=rates["gps"], latency=0.0, **errors["gps"]),
        pitot=PitotParams(rate_hz=rates["pitot"], air_density=RHO, **errors["pitot"]),
        vanes=VaneParams(rate_hz=rates["vanes"], **errors["vanes"]),
        attitude=AttitudeParams(rate_hz=rates["attitude"], **errors["attitude"]),
        baro=BaroParams(rate_hz=rates["baro"], **errors["baro"]),
    )
    duration = 200.0
    measured = _run(params, duration)
    truth = _truth_by_channel()
    for sensor, groups in errors.items():
        every = int(100 / rates[sensor])
        for group, err in groups.items():
            names = GROUP_CHANNELS[(sensor, group)]
            arrays = err.arrays(len(names), "test")
            for i, name in enumerate(names):
                series = measured[name]
                # Rate: the held value changes exactly at the sensor's samples.
                changes = np.flatnonzero(np.diff(series) != 0) + 1
                assert changes.size == round(duration * rates[sensor]) - 1, name
                assert np.all(changes % every == 0), name
                samples = series[::every]
                error = samples - (1.0 + arrays["scale_factor"][i]) * truth[name]
                if name == "att_yaw":
                    error = (error + np.pi) % (2 * np.pi) - np.pi
                sigma = arrays["noise_std"][i]
                n = samples.size
                assert abs(error.mean() - arrays["bias"][i]) < 4.5 * sigma / math.sqrt(n), name
                assert abs(error.std() / sigma - 1.0) < 4.5 / math.sqrt(2 * n), name
    # Yaw stays wrapped; pitot airspeed follows the measured dynamic pressure.
    assert np.all(np.abs(measured["att_yaw"]) <= np.pi)
    np.testing.assert_allclose(measured["pitot_airspeed"],
                               np.sqrt(2 * measured["pitot_qbar"] / RHO), rtol=1e-12)


def test_bias_instability_is_a_random_walk():
    walk = 0.02  # [unit / sqrt(s)]
    params = SensorSuiteParams(
        imu=ImuParams(gyro=ChannelErrors(0.0, bias_instability=walk),
                      accel=ChannelErrors(0.0)),
        baro=BaroParams(altitude=ChannelErrors(0.0, bias_instability=walk), rate_hz=20.0),
        gps=None, pitot=None, vanes=None, attitude=None,
    )
    measured = _run(params, 100.0, seed=5)
    truth = _truth_by_channel()
    for name, period in (("imu_p", 0.01), ("imu_q", 0.01), ("baro_alt", 0.05)):
        every = round(period * 100)
        steps = np.diff((measured[name] - truth[name])[::every])
        n = steps.size
        assert abs(steps.std() / (walk * math.sqrt(period)) - 1.0) < 4.5 / math.sqrt(2 * n)
        assert abs(steps.mean()) < 4.5 * walk * math.sqrt(period) / math.sqrt(n)
    np.testing.assert_array_equal(measured["imu_ax"], FORCE[0])


def test_gps_latency_and_rate_with_moving_truth():
    params = SensorSuiteParams(
        gps=GpsParams(position=ChannelErrors(0.0), velocity=ChannelErrors(0.0), rate_hz=5.0,
                      latency=0.3),
        imu=None, pitot=None, vanes=None, attitude=None, baro=None,
    )
    builder = DiagramBuilder()
    suite = builder.AddSystem(SensorSuite(params))
    start = STATE.copy()
    end = STATE.copy()
    end[0] += 2.0 * 10.0  # pN = 120 + 2 t
    ramp = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(
        [0.0, 10.0], np.column_stack([start, end]))))
    builder.Connect(ramp.get_output_port(0), suite.GetInputPort("state"))
    log = LogVectorOutput(suite.GetOutputPort("gps"), builder, 0.01)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(5.0)
    data = log.FindLog(simulator.get_context())
    t, pn = data.sample_times()[1:] - 0.01, data.data()[0, 1:]
    changes = np.flatnonzero(np.diff(pn) != 0) + 1
    np.testing.assert_allclose(t[changes], 0.3 + 0.2 * np.arange(1, changes.size + 1), atol=1e-9)
    # Released at t, the sample was taken at t - latency.
    np.testing.assert_allclose(pn[changes], 120.0 + 2.0 * (t[changes] - 0.3), atol=1e-9)
    assert pn[0] == pytest.approx(120.0)


@pytest.mark.parametrize(
    "params, field",
    [
        (SensorSuiteParams(imu=ImuParams(accel=ChannelErrors(-0.1))), "imu.accel.noise_std"),
        (SensorSuiteParams(gps=GpsParams(rate_hz=200.0)), "gps.rate_hz"),
        (SensorSuiteParams(baro=BaroParams(rate_hz=30.0)), "baro.rate_hz"),
        (SensorSuiteParams(gps=GpsParams(latency=-0.1)), "gps.latency"),
        (SensorSuiteParams(gps=GpsParams(position=ChannelErrors((1.0, 2.0)))),
         "gps.position.noise_std"),
        (SensorSuiteParams(vanes=VaneParams(angles=ChannelErrors(0.1, scale_factor=-1.0))),
         "vanes.angles.scale_factor"),
        (SensorSuiteParams(attitude=AttitudeParams(
            angles=ChannelErrors(0.1, bias_instability=-1.0))),
         "attitude.angles.bias_instability"),
        (SensorSuiteParams(pitot=PitotParams(air_density=0.0)), "pitot.air_density"),
        (SensorSuiteParams(base_rate_hz=0.0), "base_rate_hz"),
    ],
)
def test_bad_parameters_name_the_field(params, field):
    with pytest.raises(ValueError, match=f"^{field}:"):
        SensorSuite(params)


def test_same_seed_same_noise_and_partial_suite():
    params = SensorSuiteParams.seed_table7(air_density=RHO)
    a, b, c = _run(params, 2.0, seed=3), _run(params, 2.0, seed=3), _run(params, 2.0, seed=4)
    assert all(np.array_equal(a[n], b[n]) for n in a)
    assert not np.array_equal(a["imu_p"], c["imu_p"])
    imu_only = SensorSuite(SensorSuiteParams(gps=None, pitot=None, vanes=None, attitude=None,
                                             baro=None))
    names = [imu_only.get_output_port(i).get_name() for i in range(imu_only.num_output_ports())]
    assert names == ["imu", "measurements"]


def test_per_sensor_ports_are_the_parts_of_measurements():
    builder = DiagramBuilder()
    suite = builder.AddSystem(SensorSuite(SensorSuiteParams.seed_table7(air_density=RHO)))
    for name, value in (("state", STATE), ("air_data", AIR), ("specific_force", FORCE)):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.Connect(source.get_output_port(0), suite.GetInputPort(name))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(2))
    simulator.AdvanceTo(1.0)
    suite_context = suite.GetMyContextFromRoot(context)
    measured = dict(zip(suite.channel_names,
                        suite.GetOutputPort("measurements").Eval(suite_context), strict=True))
    prefixes = {"imu": "imu_", "gps": "gps_", "pitot": "pitot_", "vanes": "vane_",
                "attitude": "att_", "baro": "baro_"}
    covered = []
    for sensor, prefix in prefixes.items():
        names = [n for n in suite.channel_names if n.startswith(prefix)]
        np.testing.assert_array_equal(suite.GetOutputPort(sensor).Eval(suite_context),
                                      [measured[n] for n in names])
        covered += names
    assert sorted(covered) == sorted(suite.channel_names)
    truth = _truth_by_channel()
    assert abs(measured["gps_pd"] - truth["gps_pd"]) < 20.0  # a sample, not zeros
