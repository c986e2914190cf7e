"""`drake-uav identify` on the real autopilot logs: none is a fixed-wing identification
flight, so each must stop with one line naming the file and the reason, and no report."""

from pathlib import Path

import pytest

from drake_uav.cli import main

DATA = Path(__file__).parent / "data"

REASONS = {
    "ardupilot_center_0003.bin": "no IMU messages",
    "ardupilot_pilot_0004.BIN": "no IMU messages",
    "px4_sample.ulg": "not a fixed-wing log (MAV_TYPE 2",
    "px4_sample_px4_events.ulg": "not a fixed-wing log (MAV_TYPE 2",
    "px4_sample_log_small.ulg": "no airspeed",
}


@pytest.mark.parametrize("name", sorted(REASONS))
def test_a_real_log_that_cannot_be_identified_says_why_in_one_line(name, tmp_path, capsys):
    path = DATA / name
    out = tmp_path / "report"
    assert main(["identify", str(path), "--out", str(out)]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith("error:")]
    assert len(errors) == 1 and str(path) in errors[0] and REASONS[name] in errors[0], errors
    assert not out.exists()
