"""Declared sensor specs (TOML): channel -> noise std with its unit; errors name the file."""

import math

import pytest

from drake_uav.vehicles.loading import load_sensor_spec


def _write(tmp_path, text):
    path = tmp_path / "sensors.toml"
    path.write_text(text)
    return path


def test_units_are_converted_to_the_channels_own(tmp_path):
    path = _write(tmp_path, """
[noise_std]
imu_ax = { std = 5, unit = "mg" }
imu_q = { std = 0.35, unit = "deg/s" }
vane_beta = { std = 0.6, unit = "deg" }
pitot_airspeed = { std = 1.8, unit = "km/h" }
pitot_qbar = { std = 0.1, unit = "hPa" }
gps_vd = { std = 0.1, unit = "m/s" }
""")
    spec = load_sensor_spec(path)
    assert spec == pytest.approx({"imu_ax": 5 * 9.80665e-3, "imu_q": math.radians(0.35),
                                  "vane_beta": math.radians(0.6), "pitot_airspeed": 0.5,
                                  "pitot_qbar": 10.0, "gps_vd": 0.1})


@pytest.mark.parametrize("text, words", [
    ("[noise_std]\nimu_bx = { std = 1, unit = \"g\" }", ["noise_std.imu_bx", "unknown channel"]),
    ("[noise_std]\nimu_ax = { std = 1, unit = \"deg\" }", ["noise_std.imu_ax", "'deg'", "mg"]),
    ("[noise_std]\nimu_ax = { std = -1, unit = \"g\" }", ["noise_std.imu_ax", "std"]),
    ("[noise_std]\nimu_ax = { std = \"1\", unit = \"g\" }", ["noise_std.imu_ax", "std"]),
    ("[noise_std]\nimu_ax = 0.05", ["noise_std.imu_ax", "unit"]),
    ("[noise_std]\nimu_ax = { std = 1 }", ["noise_std.imu_ax", "unit"]),
    ("imu_ax = 0.05", ["[noise_std]", "imu_ax"]),
    ("[noise_std\nimu_ax = 1", ["not valid TOML"]),
])
def test_bad_specs_name_the_file_and_the_entry(tmp_path, text, words):
    path = _write(tmp_path, text)
    with pytest.raises(ValueError) as err:
        load_sensor_spec(path)
    message = str(err.value)
    assert str(path) in message
    for word in words:
        assert word in message, message


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ValueError, match="absent.toml"):
        load_sensor_spec(tmp_path / "absent.toml")
