"""The main job's settings: one checked IdentifyOptions, the keyword form kept as a shortcut."""

import pytest

from drake_uav.identification import IdentifyOptions, identify
from drake_uav.identification.samples.flight_phases import PhaseSettings
from drake_uav.model.coefficients import COEFFICIENTS


def test_the_defaults_are_the_command_line_ones():
    options = IdentifyOptions()
    assert (options.rate_hz, options.air_data, options.propulsion, options.seed) == (
        50.0, "auto", "data", 0)
    assert options.coefficients == COEFFICIENTS
    assert options.rule is None and options.segment is None
    assert options.phases == PhaseSettings()


@pytest.mark.parametrize(("field", "value", "message"), [
    ("rate_hz", 0.0, "rate_hz: a positive rate"),
    ("rate_hz", float("nan"), "rate_hz: a positive rate"),
    ("reset_interval", -1.0, "reset_interval: a positive time"),
    ("air_data", "pitot", "air_data: unknown mode 'pitot'"),
    ("propulsion", "motor", "propulsion: 'catalog' or 'data'"),
    ("seed", 1.5, "seed: an integer"),
    ("coefficients", ("CL", "Cx"), "unknown coefficient 'Cx'"),
    ("coefficients", "CL", "coefficients: expected a non-empty sequence"),
    ("sensor_noise_std", {"imu_ax": -0.1}, "sensor_noise_std: imu_ax"),
    ("imu_position", (0.1, 0.0), "imu_position: need three finite numbers"),
])
def test_a_bad_value_is_refused_naming_the_field(field, value, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("'", "'")):
        IdentifyOptions(**{field: value})


def test_replace_checks_again_and_names_an_unknown_option():
    options = IdentifyOptions(coefficients=["CL", "CD"])
    assert options.coefficients == ("CL", "CD")
    assert options.replace(seed=3).seed == 3
    with pytest.raises(ValueError, match="propulsion"):
        options.replace(propulsion="none")
    with pytest.raises(ValueError, match="unknown option ratehz"):
        options.replace(ratehz=10.0)


def test_identify_refuses_an_unknown_option_before_reading_the_log():
    with pytest.raises(ValueError, match="unknown option segments"):
        identify(None, None, segments=(0.0, 10.0))
    with pytest.raises(ValueError, match="air_data: unknown mode"):
        identify(None, None, IdentifyOptions(), air_data="wind")
