"""Airborne spans: ground, take-off modes, VTOL hover and logging gaps are left out."""

import numpy as np
import pytest

from drake_uav.identification.samples.flight_phases import (
    PhaseSettings,
    mode_timeline,
    usable_spans,
)
from drake_uav.io.flight_log import FlightLog, FlightLogError


def _log(metadata=None, with_baro=True):
    """0-20 s on the ground, 20-30 s take-off roll and climb, 30-200 s flying, then landed."""
    t = np.arange(0.0, 230.0, 0.1)
    airspeed = np.interp(t, [0, 20, 30, 200, 210, 230], [0, 0, 25, 25, 0, 0])
    height = np.interp(t, [0, 24, 40, 200, 208, 230], [0, 0, 100, 100, 0, 0])
    channels = {"pitot_airspeed": airspeed}
    if with_baro:
        channels["baro_alt"] = 350.0 + height  # above mean sea level
    return FlightLog(t, channels, units={"pitot_airspeed": "m/s", "baro_alt": "m"},
                     metadata=metadata or {})


def test_ground_and_landing_are_left_out():
    (start, end), = usable_spans(_log())
    settings = PhaseSettings()
    # Airspeed above 8 m/s from 23.2 s, height above 5 m from 24.8 s (+1 s margin).
    assert start == pytest.approx(24.8 + settings.margin, abs=0.11)
    assert 200.0 < end < 208.0


def test_without_baro_the_airspeed_decides():
    (start, _), = usable_spans(_log(with_baro=False))
    assert start == pytest.approx(23.2 + PhaseSettings().margin, abs=0.11)


def test_take_off_mode_and_vtol_hover_are_left_out():
    modes = [[0.0, "MANUAL"], [20.0, "TAKEOFF"], [50.0, "FBWA"], [120.0, "QHOVER"],
             [140.0, "AUTO"]]
    spans = usable_spans(_log({"flight_modes": modes}))
    assert [round(a) for a, _ in spans] == [51, 141]
    assert round(spans[0][1]) == 119
    vtol = usable_spans(_log({"vtol_state": [[0.0, "mc"], [60.0, "transition"],
                                             [70.0, "fw"], [150.0, "mc"]]}))
    assert [(round(a), round(b)) for a, b in vtol] == [(71, 149)]


def test_logging_gaps_split_the_spans_and_short_pieces_are_dropped():
    spans = usable_spans(_log({"segments": [[0.0, 100.0], [101.0, 105.0], [106.0, 229.9]]}))
    # Segment ends are log ends: no settling margin there.
    assert [(round(a), round(b)) for a, b in spans] == [(26, 100), (106, round(spans[1][1]))]


def test_a_chosen_segment_and_the_reasons_when_nothing_is_left():
    (start, end), = usable_spans(_log(), segment=(60.0, 90.0))
    assert (start, end) == pytest.approx((61.0, 89.0), abs=0.11)
    with pytest.raises(FlightLogError, match="never above 8 m/s"):
        usable_spans(FlightLog(np.arange(100.0), {"pitot_airspeed": np.full(100, 3.0)},
                                 units={"pitot_airspeed": "m/s"}))
    with pytest.raises(FlightLogError, match="inside --segment 0:10"):
        usable_spans(_log(), segment=(0.0, 10.0))


def test_mode_timeline_ends_at_the_log_end():
    log = _log({"flight_modes": [[0.0, "MANUAL"], [50.0, "AUTO"]]})
    assert mode_timeline(log) == [(0.0, 50.0, "MANUAL"), (50.0, pytest.approx(229.9), "AUTO")]
