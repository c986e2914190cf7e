"""The manoeuvre design: which input separates two rivals, its signals and its command file."""

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import drake_uav
from drake_uav.diagrams.manoeuvre_design import (
    COMMAND_CSV,
    FIXED_WING_CHANNELS,
    InputChannel,
    Rivals,
    column_correlation,
    decisive_f,
    design_manoeuvre,
    distinguishing_energy,
    expected_f,
    propose_manoeuvre,
    read_command_csv,
    rival_share,
    write_command_csv,
)
from drake_uav.identification.pipeline import identify
from drake_uav.io.flight_log import FlightLog
from drake_uav.reporting.identification_report import write_report
from drake_uav.systems.excitation import REFERENCES, SURFACES, Turn, excitation_controls
from drake_uav.testing.manoeuvre_cases import fly_next
from drake_uav.vehicles.fixed_wing import aerosonde

SAMPLE = Path(drake_uav.__file__).parent / "data" / "sample_flight.parquet"
RATE = 50.0
TRIM = {"elevator": -0.02, "aileron": 0.0, "rudder": 0.001, "throttle": 0.45}


CHANNELS = SURFACES + REFERENCES


def _simulate(signals, duration):
    """A plant whose 'samples' are its inputs (surfaces, then the reference offsets): the
    columns below read them directly."""
    t = np.arange(round(duration * RATE)) / RATE
    return excitation_controls(t, np.zeros(len(CHANNELS)), signals, CHANNELS)


def _column(surface):
    return lambda u: u[:, CHANNELS.index(surface)]


# The first rival moves with the elevator and the throttle, the second with the elevator
# only: only the throttle tells them apart.
RIVALS = Rivals("CD", "with_throttle", "elevator_only",
                lambda u: _column("elevator")(u) + 0.5 * _column("throttle")(u),
                _column("elevator"), _column("aileron"))


def _flown():
    """A flight that moved the elevator and the aileron only: the rivals are tied on it."""
    t = np.arange(round(60 * RATE)) / RATE
    u = np.zeros((t.size, 4))
    u[:, 0] = 0.03 * np.sin(2 * np.pi * 0.3 * t)
    u[:, 1] = 0.05 * np.sin(2 * np.pi * 0.7 * t)
    y = 2.0 * RIVALS.first_columns(u) + 0.001 * np.random.default_rng(1).standard_normal(t.size)
    return u, y


def test_design_picks_the_input_that_moves_the_distinguishing_column():
    flown, y = _flown()
    design = design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS,
                              trim=TRIM, duration=41.0, period=20.0)
    assert design.selected == ("throttle",)
    assert design.sensitivity["throttle"] > 0
    assert all(design.sensitivity[c] < 1e-20 for c in ("elevator", "aileron", "rudder"))
    (separation,) = design.separations
    assert separation.correlation_flown == pytest.approx(1.0, abs=1e-9)
    assert separation.correlation_designed < 0.9
    assert separation.f_flown[0] == pytest.approx(1.0, abs=1e-6)
    assert separation.f_designed[0] > 100.0
    assert separation.share_flown[0] == pytest.approx(1.0, abs=1e-9)
    assert max(separation.share_designed) < 0.9 and separation.resolves
    assert set(design.summary()) == {"duration_s", "selected_inputs", "trim", "turn_rate_deg_s",
                                     "sensitivity", "peaks", "separations"}


def test_designed_multisines_are_orthogonal_and_within_their_limits():
    flown, y = _flown()
    design = design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS,
                              trim=TRIM, duration=41.0, period=20.0)
    start, period = design.signals[0].start, design.signals[0].period
    t = start + np.arange(2000) * period / 2000
    x = np.array([s(t) for s in design.signals])
    gram = x @ x.T / t.size
    off = gram - np.diag(np.diag(gram))
    assert np.max(np.abs(off)) < 1e-10 * np.max(np.diag(gram))
    peaks = design.summary()["peaks"]
    for channel in FIXED_WING_CHANNELS:
        share = 1.0 if channel.name in design.selected else 0.5
        assert peaks[channel.name] == pytest.approx(share * channel.limit, rel=1e-3)
    # Only the inputs the flight moved are flown besides the selected one.
    moved = design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS, trim=TRIM,
                             background=("elevator",), duration=41.0, period=20.0)
    assert [c.name for c in moved.channels] == ["elevator", "throttle"]
    assert [s.surface for s in moved.signals] == ["elevator", "throttle"]


def test_correlation_and_expected_f_on_known_columns():
    rng = np.random.default_rng(3)
    base, a = rng.standard_normal((400, 1)), rng.standard_normal(400)
    assert column_correlation(base, a, 2 * a + 1) == pytest.approx(1.0)
    assert column_correlation(base, a, rng.standard_normal(400)) < 0.2
    # Columns orthogonal to each other, to the baseline and to a constant: the
    # non-centrality is theta^2 |first|^2 / sigma^2.
    q = np.linalg.qr(np.column_stack([np.ones(400), base, a, rng.standard_normal(400)]))[0]
    first, second = 3.0 * q[:, 2], q[:, 3]
    f = expected_f([2.0], 0.5, first, second, base)
    assert f == pytest.approx(1 + 4 * 9.0 / 0.25, rel=1e-9)
    assert distinguishing_energy(base, a, a)[0] == pytest.approx(0.0, abs=1e-20)
    # The rival reaches the squared correlation of the two (after the baseline) of the gain.
    assert rival_share([1.0], first, first + second, base) == pytest.approx(0.9, rel=1e-9)


def test_command_csv_round_trips(tmp_path):
    flown, y = _flown()
    design = design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS,
                              trim=TRIM, duration=41.0, period=20.0)
    path = write_command_csv(tmp_path / "next.csv", design, rate_hz=25.0)
    assert path.read_text().startswith("# time [s]")
    table = read_command_csv(path)
    assert list(table) == ["time_s", "elevator_rad", "aileron_rad", "rudder_rad", "throttle_1"]
    assert table["time_s"][-1] == pytest.approx(41.0)
    expected = excitation_controls(table["time_s"], [TRIM[s] for s in SURFACES], design.signals)
    for i, surface in enumerate(SURFACES):
        unit = "1" if surface == "throttle" else "rad"
        np.testing.assert_allclose(table[f"{surface}_{unit}"], expected[:, i], atol=1e-6)


# A force fixed in the NED frame against one fixed in the body: along the body x axis the
# first reads cos(heading) of the second; on a straight flight they are one column.
NED_OR_BODY = Rivals("CD", "ned_fixed", "body_fixed",
                     lambda u: np.cos(_column("heading")(u)) * (1 + 10 * _column("elevator")(u)),
                     lambda u: 1 + 10 * _column("elevator")(u), _column("aileron"))


def test_a_turn_is_kept_where_it_separates_more_pairs_and_written_as_a_heading(tmp_path):
    t = np.arange(round(60 * RATE)) / RATE
    flown = np.zeros((t.size, len(CHANNELS)))
    flown[:, 0] = 0.03 * np.sin(2 * np.pi * 0.3 * t)
    flown[:, 1] = 0.05 * np.sin(2 * np.pi * 0.7 * t)
    y = 2.0 * NED_OR_BODY.first_columns(flown) + 0.001 * np.random.default_rng(2).standard_normal(
        t.size)
    rate = 2 * np.pi / 40.0
    straight = design_manoeuvre(_simulate, [(NED_OR_BODY, y)], flown, FIXED_WING_CHANNELS,
                                trim=TRIM, duration=41.0, period=20.0)
    assert straight.turn is None and not straight.separations[0].resolves
    turning = design_manoeuvre(_simulate, [(NED_OR_BODY, y)], flown, FIXED_WING_CHANNELS,
                               trim=TRIM, duration=41.0, period=20.0, turn_rate=rate)
    assert turning.turn == Turn(rate, 40.0, 1.0)
    assert turning.separations[0].resolves
    assert turning.separations[0].correlation_designed < 0.9
    assert turning.summary()["turn_rate_deg_s"] == pytest.approx(9.0)
    table = read_command_csv(write_command_csv(tmp_path / "next.csv", turning))
    np.testing.assert_allclose(table["heading_rad"], turning.turn(table["time_s"]), atol=1e-5)
    assert table["heading_rad"][-1] == pytest.approx(2 * np.pi, abs=1e-5)
    # The throttle, not the heading, separates the thrust-following rival: no turn.
    flown_4, y_4 = _flown()
    plain = design_manoeuvre(_simulate, [(RIVALS, y_4)], flown_4, FIXED_WING_CHANNELS,
                             trim=TRIM, duration=41.0, period=20.0, turn_rate=rate)
    assert plain.turn is None and plain.separations[0].resolves
    assert "heading" not in [c.name for c in plain.channels]


def test_bad_input_raises_a_clear_value_error(tmp_path):
    flown, y = _flown()
    with pytest.raises(ValueError, match="channel: unknown input 'flaps'"):
        InputChannel("flaps", "rad", 0.1)
    with pytest.raises(ValueError, match="channel elevator: limit must be positive"):
        InputChannel("elevator", "rad", -math.radians(2))
    with pytest.raises(ValueError, match="pairs: need at least one pair"):
        design_manoeuvre(_simulate, [], flown, FIXED_WING_CHANNELS, trim=TRIM)
    with pytest.raises(ValueError, match="channels: need at least one channel, each once"):
        design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS[:1] * 2,
                         trim=TRIM)
    with pytest.raises(ValueError, match="duration: 10 s must be at least one period"):
        design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS, trim=TRIM,
                         duration=10)
    with pytest.raises(ValueError, match="second: has 5 rows"):
        column_correlation(np.ones((4, 1)), np.ones(4), np.ones(5))
    with pytest.raises(ValueError, match="trim: no finite trim command for aileron"):
        design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS[:2],
                         trim={"elevator": 0.0}, duration=21.0, period=20.0)
    with pytest.raises(ValueError, match="turn_rate: must be finite and non-zero"):
        design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS, trim=TRIM,
                         duration=41.0, turn_rate=0.0)
    with pytest.raises(ValueError, match="propulsion: 'rpm' unknown"):
        propose_manoeuvre(None, propulsion="rpm")
    (tmp_path / "bad.csv").write_text("t,elevator_rad\n0,1\n")
    with pytest.raises(ValueError, match="no 'time_s' column"):
        read_command_csv(tmp_path / "bad.csv")


def test_the_report_shows_the_manoeuvre_and_holds_its_command_file(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sample's thrust/C_X confounding note
        run = identify(FlightLog.load(SAMPLE), aerosonde(), source="sample",
                       segment=(0.0, 30.0), propulsion="catalog")
    flown, y = _flown()
    design = design_manoeuvre(_simulate, [(RIVALS, y)], flown, FIXED_WING_CHANNELS,
                              trim=TRIM, duration=41.0, period=20.0)
    out = write_report(run, tmp_path / "report", design)
    text = (out / "report.md").read_text()
    assert "## What to fly next" in text
    assert f"`{COMMAND_CSV}`" in text and "throttle" in text
    assert "`with_throttle` against `elevator_only` on CD" in text
    assert "the manoeuvre separates them" in text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["what_to_fly_next"]["manoeuvre"]["command_file"] == COMMAND_CSV
    assert summary["what_to_fly_next"]["manoeuvre"]["selected_inputs"] == ["throttle"]
    assert COMMAND_CSV in summary["report_files"]
    table = read_command_csv(out / COMMAND_CSV)
    assert table["throttle_1"][0] == pytest.approx(TRIM["throttle"], abs=1e-6)
    without = write_report(run, tmp_path / "plain")
    assert "What to fly next" not in (without / "report.md").read_text()
    assert "what_to_fly_next" not in json.loads((without / "summary.json").read_text())


@pytest.mark.slow
def test_the_proposed_manoeuvre_resolves_the_propwash_tie_with_a_known_thrust():
    """A drag that follows the thrust, on research-grade flights (20 % of C_D's variation)
    with the thrust known as from a logged motor speed: among the seeds whose report holds
    a near tie, flying the proposed manoeuvre names `thrust_propwash` alone in >= 80 %."""
    rows = [fly_next(seed, "propwash_drag", propulsion="catalog") for seed in range(10)]
    tied = [r["resolved"] for r in rows if r["resolved"] is not None]
    assert len(tied) >= 5, rows
    assert sum(tied) >= 0.8 * len(tied), rows


@pytest.mark.slow
def test_the_proposed_turn_tells_a_body_force_from_one_fixed_in_ned():
    """A constant tow along the body x axis, tied on C_D with a force fixed in the NED
    frame on a straight flight (research-grade sensors, 20 %, thrust known): the proposed
    manoeuvre is flown in a turn and its flight ends that pair's tie in >= 80 % of the
    flights that had it (measured 10/10 on seeds 0-9; these are seeds 20-29)."""
    rows = [fly_next(seed, "tow_force", propulsion="catalog") for seed in range(20, 30)]
    tied = [r for r in rows if "ned_force" in r["pairs"]]
    assert len(tied) >= 5, rows
    assert all(r["turn"] for r in tied), rows
    assert sum(r["pairs"]["ned_force"] for r in tied) >= 0.8 * len(tied), rows


def test_a_decision_needs_the_expected_f_of_a_powerful_test():
    """80 % power at the 1 % level: (z_0.995 + z_0.8)^2 = 11.7 of non-centrality for one
    column, less per column for more."""
    assert decisive_f(1) == pytest.approx(1 + (2.5758 + 0.8416) ** 2, rel=0.01)
    assert decisive_f(1) > decisive_f(2) > decisive_f(6) > 1.0
    with pytest.raises(ValueError, match="columns: need at least one"):
        decisive_f(0)


def test_a_rival_whose_direction_awaits_a_search_is_not_designed_for():
    """The library's force towards a point has no direction until the data locate the point:
    no columns, so the proposal leaves that pair out instead of failing."""
    from drake_uav.diagrams.manoeuvre_design import _effect_columns

    params = aerosonde()
    assert _effect_columns("force_towards_point", params, "CD") is None
    assert _effect_columns("force_body_x_off_cg", params, "CD") is not None
    assert _effect_columns("p_hat*r_hat", params, "CD") is None


def test_a_pair_is_told_apart_when_the_rival_leaves_the_injected_effects_group():
    """Per aliased pair: the next flight ends the tie of the injected effect and a rival when
    it still points at the injected effect (named, or tied with what is named) and the rival
    is neither named nor tied with it."""
    from types import SimpleNamespace

    from drake_uav.testing.manoeuvre_cases import tied_with, told_apart

    def tie(winner, *others):
        return SimpleNamespace(winner=SimpleNamespace(effect=winner),
                               alternatives=tuple(SimpleNamespace(effect=o) for o in others))

    run = SimpleNamespace(findings=("force_air_velocity",),
                          near_ties=(tie("force_air_velocity", "constant_body_force"),))
    assert tied_with(run, "constant_body_force") == {"force_air_velocity"}
    assert told_apart(run, "constant_body_force", "ned_force")
    assert not told_apart(run, "constant_body_force", "force_air_velocity")
    named_rival = SimpleNamespace(findings=("ned_force",), near_ties=())
    assert not told_apart(named_rival, "constant_body_force", "thrust_propwash")
    alone = SimpleNamespace(findings=("constant_body_force",), near_ties=())
    assert told_apart(alone, "constant_body_force", "ned_force")
