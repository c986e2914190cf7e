"""CompiledFunction: restricted outputs and the folding of single-use temporaries."""

import math

import numpy as np
import pytest
from pydrake.math import cos, sin, sqrt

from drake_uav.model.compiled import CompiledFunction


def _model(x, u):
    """A small scalar-generic model with shared and single-use subexpressions."""
    r = sqrt(x[0] * x[0] + x[1] * x[1] + 1.0)
    return [r * cos(u[0]), r * sin(u[0]) - x[2] * u[1], x[0] * x[1] / r, (x[2] + u[1]) ** 3]


def test_restricted_outputs_match_the_full_function_and_its_jacobians():
    full = CompiledFunction(_model, (3, 2), wrt={0: None, 1: None})
    part = full.restricted([3, 1])
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, u = rng.normal(size=3), rng.normal(size=2)
        value, jacobian = full.value_and_jacobian(x, u)
        sub_value, sub_jacobian = part.value_and_jacobian(x, u)
        np.testing.assert_array_equal(sub_value, value[[3, 1]])
        np.testing.assert_array_equal(sub_jacobian, jacobian[[3, 1]])
        np.testing.assert_allclose(part.autodiff_jacobians(x, u)[0], value[[3, 1]], rtol=1e-14)
    assert part.operation_count < full.operation_count
    with pytest.raises(ValueError, match="^outputs:"):
        full.restricted([4])
    with pytest.raises(ValueError, match="^outputs:"):
        full.restricted([])


def test_long_chains_of_single_use_temporaries_compile_and_stay_exact():
    def chain(x):
        y = x[0]
        for k in range(400):  # every step used once by the next: folded in bounded pieces
            y = sin(y) + 0.001 * k * x[1]
        return [y, y * x[1]]

    compiled = CompiledFunction(chain, (2,))
    x = [0.3, -1.2]
    y = x[0]
    for k in range(400):
        y = math.sin(y) + 0.001 * k * x[1]
    np.testing.assert_allclose(compiled.value(x), [y, y * x[1]], rtol=1e-13)
    batch = compiled.batch_value(np.tile(x, (20, 1)))
    np.testing.assert_array_equal(batch, np.tile(compiled.value(x), (20, 1)))
