"""A term fixed at a known value instead of fitted (Design.with_fixed): its part and the
noise it carries move to the measured side, so the compensated fit of the other terms stays
unbiased."""

import dataclasses

import numpy as np
import pytest

from drake_uav.identification.discovery.coefficient_design import Design
from drake_uav.identification.statistics.errors_in_variables import PropagatedNoise

THETA = np.array([0.3, 2.0, -1.5])  # constant, x1, x2


def _design(n: int, noise_std: float, seed: int) -> Design:
    """z = THETA . [1, x1, x2]; one source s enters both x1 (gain 1) and x2 (gain 0.8)."""
    rng = np.random.default_rng(seed)
    x1, x2 = rng.normal(size=n), rng.normal(size=n)
    s = noise_std * rng.normal(size=n)
    X = np.column_stack([np.ones(n), x1 + s, x2 + 0.8 * s])
    z = THETA @ np.vstack([np.ones(n), x1, x2])
    J = np.column_stack([np.zeros(n), np.ones(n), 0.8 * np.ones(n)])
    return Design(["c", "x1", "x2"], X, z, PropagatedNoise(3, {"s": J}, {}, {"s": noise_std**2}))


def test_noise_free_the_other_terms_come_out_exactly():
    design = _design(500, 0.0, seed=1)
    reduced = design.with_fixed({"x2": THETA[2]})
    assert reduced.names == ["c", "x1"]
    np.testing.assert_allclose(reduced.solve(), THETA[:2], atol=1e-12)
    assert design.with_fixed({"unknown": 1.0}) is design


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_the_noise_the_fixed_term_carries_is_compensated(seed):
    design = _design(200_000, 0.5, seed)
    reduced = design.with_fixed({"x2": THETA[2]})
    # d z'/d s = -THETA_2 * 0.8: the fixed column's noise now sits in the measured side.
    np.testing.assert_allclose(reduced.noise.observation["s"], -THETA[2] * 0.8)
    estimate = reduced.solve()
    print(f"seed {seed}: x1 {estimate[1]:.4f} (true {THETA[1]})")
    assert estimate == pytest.approx(THETA[:2], abs=0.02)
    # Without the moved noise the same fit is biased by -THETA_2 * 0.8 * var = 0.3.
    blind = dataclasses.replace(reduced, noise=dataclasses.replace(reduced.noise,
                                                                   observation={}))
    assert blind.solve()[1] - THETA[1] == pytest.approx(0.3, abs=0.02)
