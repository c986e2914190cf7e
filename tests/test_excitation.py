"""Excitation signals: shapes, Schroeder/optimised phases, orthogonality, the held source."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from drake_uav.systems.excitation import (
    REFERENCES,
    SURFACES,
    Doublet,
    ExcitationSource,
    Multisine,
    ThreeTwoOneOne,
    Turn,
    doublet,
    excitation_controls,
    low_peak_factor_phases,
    multisine,
    orthogonal_multisines,
    relative_peak_factor,
    schroeder_phases,
    three_two_one_one,
)

DT = 1e-3


def test_doublet_and_3211_shapes():
    t = np.arange(0.0, 12.0, DT)
    d = doublet(t, 0.1, 0.5, start=1.0)
    assert np.all(d[(t >= 1.0) & (t < 1.5)] == 0.1)
    assert np.all(d[(t >= 1.5) & (t < 2.0)] == -0.1)
    assert np.all(d[(t < 1.0) | (t >= 2.0)] == 0.0)
    assert np.sum(d) * DT == pytest.approx(0.0, abs=1e-9)
    x = three_two_one_one(t, 0.05, 0.4, start=2.0)
    # Sign changes at 3, 2, 1, 1 unit widths, then zero.
    edges = 2.0 + 0.4 * np.cumsum([0, 3, 2, 1, 1])
    for (a, b), sign in zip(zip(edges[:-1], edges[1:], strict=True), (1, -1, 1, -1), strict=True):
        inside = (t >= a + DT) & (t < b - DT)
        assert np.all(x[inside] == sign * 0.05)
    assert np.all(x[t >= edges[-1] + DT] == 0.0)
    # Net area: (3 - 2 + 1 - 1) units.
    assert np.sum(x) * DT == pytest.approx(0.05 * 0.4, abs=2e-4)
    assert ThreeTwoOneOne("elevator", 0.05, 0.4, 2.0).end == pytest.approx(edges[-1])


def test_schroeder_phases_formula_and_peak_factor():
    m = 12
    phases = schroeder_phases(np.ones(m))
    k = np.arange(1, m + 1)
    np.testing.assert_allclose(phases, -np.pi * k * (k - 1) / m, atol=1e-12)
    t = np.arange(0.0, 10.0, DT)
    harmonics = np.arange(1, m + 1)
    zero = relative_peak_factor(multisine(t, 10.0, harmonics, np.ones(m), np.zeros(m)))
    schroeder = relative_peak_factor(multisine(t, 10.0, harmonics, np.ones(m), phases))
    assert zero > 2.0 and schroeder < 1.3


def test_optimised_phases_lower_peak_factor_keep_spectrum_and_start_at_zero():
    period, harmonics = 20.0, np.arange(2, 42, 2)
    amplitudes = np.linspace(1.0, 0.5, harmonics.size)
    t = np.arange(0.0, period, 0.005)
    schroeder = multisine(t, period, harmonics, amplitudes, schroeder_phases(amplitudes))
    phases = low_peak_factor_phases(harmonics, amplitudes)
    x = multisine(t, period, harmonics, amplitudes, phases)
    assert relative_peak_factor(x) < min(1.15, relative_peak_factor(schroeder))
    # Amplitude spectrum unchanged, no energy elsewhere.
    spectrum = np.abs(np.fft.rfft(x)) * 2 / t.size
    np.testing.assert_allclose(spectrum[harmonics], amplitudes, rtol=1e-9)
    others = np.delete(spectrum, harmonics)
    assert others.max() < 1e-9
    # Starts at zero, rising.
    assert abs(x[0]) < 1e-9 and x[1] > 0


def test_orthogonal_multisines():
    signals = orthogonal_multisines(["elevator", "aileron", "rudder"], 15.0,
                                    np.radians([3.0, 4.0, 2.0]), band=(0.2, 2.0), start=1.0)
    sets = [set(s.harmonics) for s in signals]
    assert not (sets[0] & sets[1] or sets[0] & sets[2] or sets[1] & sets[2])
    all_k = sorted(sets[0] | sets[1] | sets[2])
    assert all_k == list(range(3, 31))  # 0.2 Hz * 15 s .. 2.0 Hz * 15 s
    t = np.arange(1.0, 16.0, DT)
    X = np.array([s(t) for s in signals])
    gram = X @ X.T * DT
    off = gram - np.diag(np.diag(gram))
    assert np.abs(off).max() < 1e-9 * np.diag(gram).max()
    np.testing.assert_allclose(np.abs(X).max(axis=1), np.radians([3.0, 4.0, 2.0]), rtol=1e-3)
    for s in signals:
        assert relative_peak_factor(s(t)) < 1.3
        assert abs(s(np.array([1.0]))[0]) < 1e-8
        assert s(np.array([0.99, 16.0])).tolist() == [0.0, 0.0]


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: Doublet("flap", 0.1, 1.0).validate(), "surface"),
        (lambda: Doublet("elevator", 0.1, 0.0).validate(), "width"),
        (lambda: ThreeTwoOneOne("rudder", np.nan, 0.3).validate(), "amplitude"),
        (lambda: Multisine("aileron", 10.0, (1, 1), (1.0, 1.0), (0.0, 0.0)).validate(),
         "harmonics"),
        (lambda: Multisine("aileron", 10.0, (1, 2), (1.0, -1.0), (0.0, 0.0)).validate(),
         "amplitudes"),
        (lambda: orthogonal_multisines(["elevator", "aileron"], 5.0, 0.1, (0.1, 0.3)), "band"),
        (lambda: orthogonal_multisines(["elevator", "wing"], 5.0, 0.1, (0.1, 2.0)), "surface"),
        (lambda: ExcitationSource([0.0, 0.0, 0.0], ()), "trim_controls"),
        (lambda: ExcitationSource(np.zeros(4), (), sample_period=-0.01), "sample_period"),
        (lambda: Turn(0.0, 10.0).validate(), "rate"),
        (lambda: Turn(0.1, -1.0).validate(), "duration"),
        (lambda: excitation_controls([0.0], np.zeros(4), (Turn(0.1, 5.0),)), "surface"),
    ],
)
def test_bad_inputs_name_the_field(make, field):
    with pytest.raises(ValueError, match=f"^{field}:"):
        make()


def test_source_holds_trim_plus_signals():
    trim = np.array([-0.1, 0.0, 0.0, 0.4])
    signals = (Doublet("elevator", 0.05, 0.25, start=0.1),
               *orthogonal_multisines(["aileron", "rudder"], 4.0, 0.03, (0.25, 3.0)))
    source = ExcitationSource(trim, signals, sample_period=0.02)
    builder = DiagramBuilder()
    builder.AddSystem(source)
    log = LogVectorOutput(source.GetOutputPort("controls"), builder, 0.01)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(5.0)
    data = log.FindLog(simulator.get_context())
    t, u = data.sample_times(), data.data().T
    expected_now = excitation_controls(t, trim, signals)
    # Held: at t the output is the value sampled at the last multiple of 0.02 s before t.
    k = np.ceil(np.round(t / 0.02, 9)) - 1
    held = excitation_controls(np.maximum(k, 0) * 0.02, trim, signals)
    np.testing.assert_allclose(u[1:], held[1:], atol=1e-15)
    np.testing.assert_allclose(u[0], expected_now[0], atol=1e-15)
    assert np.all(u[:, 3] == 0.4)
    assert np.abs(u[:, 1] - trim[1]).max() > 0.02


def test_a_turn_moves_the_heading_reference_and_holds_where_it_ends():
    turn = Turn(0.1, duration=20.0, start=2.0).validate()
    t = np.array([0.0, 2.0, 12.0, 22.0, 30.0])
    np.testing.assert_allclose(turn(t), [0.0, 0.0, 1.0, 2.0, 2.0])
    assert turn.end == 22.0 and turn.surface == "heading"
    offsets = excitation_controls(t, np.zeros(len(REFERENCES)), (turn,), REFERENCES)
    np.testing.assert_allclose(offsets[:, REFERENCES.index("heading")], turn(t))
    assert not np.any(offsets[:, [REFERENCES.index(r) for r in REFERENCES if r != "heading"]])
    both = excitation_controls(t, np.zeros(8), (turn, Doublet("elevator", 0.1, 1.0)),
                               SURFACES + REFERENCES)
    np.testing.assert_allclose(both[:, len(SURFACES) + REFERENCES.index("heading")], turn(t))
