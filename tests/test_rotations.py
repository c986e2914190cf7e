import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.symbolic import Evaluate, Variable

from drake_uav.model import rotations as rot

angles = st.tuples(
    st.floats(-np.pi + 1e-3, np.pi - 1e-3),
    st.floats(-np.pi / 2 + 1e-2, np.pi / 2 - 1e-2),
    st.floats(-np.pi + 1e-3, np.pi - 1e-3),
)


@settings(max_examples=60, deadline=None)
@given(angles)
def test_euler_quat_rotmat_round_trips(rpy):
    rpy = np.array(rpy)
    q = rot.euler_to_quat(rpy)
    R = rot.quat_to_rotmat(q)
    np.testing.assert_allclose(R, rot.euler_to_rotmat(rpy), atol=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rot.quat_to_euler(q), rpy, atol=1e-9)
    np.testing.assert_allclose(rot.rotmat_to_euler(R), rpy, atol=1e-9)
    q_back = rot.rotmat_to_quat(R)
    np.testing.assert_allclose(q_back * np.sign(q_back[0] * q[0]), q, atol=1e-12)


def test_quat_to_euler_on_a_batch_of_samples():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[0] = [np.sqrt(0.5), 0.0, np.sqrt(0.5) * (1 + 1e-15), 0.0]  # gimbal lock, round-off
    batch = rot.quat_to_euler(q.T)
    assert batch.shape == (3, 50)
    np.testing.assert_allclose(batch.T, [rot.quat_to_euler(row) for row in q], atol=1e-14)


def test_matches_drake_roll_pitch_yaw_convention():
    rpy = np.array([0.3, -0.2, 1.1])
    R_drake = RotationMatrix(RollPitchYaw(rpy)).matrix()
    np.testing.assert_allclose(rot.euler_to_rotmat(rpy), R_drake, atol=1e-14)


def test_seed_s0_dcm_is_transpose_of_body_to_ned():
    """Vaiopoulos 2017, eq. 2.2 (with the corrected (3,1) element) maps NED to body."""
    phi, theta, psi = 0.4, 0.25, -0.8
    c, s = np.cos, np.sin
    R_nb = np.array(
        [
            [c(theta) * c(psi), c(theta) * s(psi), -s(theta)],
            [s(phi) * s(theta) * c(psi) - c(phi) * s(psi),
             s(phi) * s(theta) * s(psi) + c(phi) * c(psi), s(phi) * c(theta)],
            [c(phi) * s(theta) * c(psi) + s(phi) * s(psi),
             c(phi) * s(theta) * s(psi) - s(phi) * c(psi), c(phi) * c(theta)],
        ]
    )
    np.testing.assert_allclose(rot.euler_to_rotmat([phi, theta, psi]).T, R_nb, atol=1e-14)


def test_hamilton_product_composes_rotations():
    q1 = rot.euler_to_quat([0.1, 0.2, 0.3])
    q2 = rot.euler_to_quat([-0.4, 0.5, 2.0])
    R12 = rot.quat_to_rotmat(rot.quat_multiply(q1, q2))
    np.testing.assert_allclose(R12, rot.quat_to_rotmat(q1) @ rot.quat_to_rotmat(q2), atol=1e-14)
    ident = rot.quat_multiply(q1, rot.quat_conjugate(q1))
    np.testing.assert_allclose(ident, [1, 0, 0, 0], atol=1e-15)


def test_quat_derivative_matches_euler_rates():
    rpy = np.array([0.2, 0.1, -0.5])
    omega = np.array([0.3, -0.2, 0.4])
    q = rot.euler_to_quat(rpy)
    dt = 1e-6
    q_next = q + dt * rot.quat_derivative(q, omega)
    rpy_rate = (rot.quat_to_euler(q_next) - rpy) / dt
    np.testing.assert_allclose(rpy_rate, rot.euler_rates(rpy, omega), rtol=1e-5)


def test_stabilization_restores_unit_norm():
    q = 1.1 * rot.euler_to_quat([0.1, 0.2, 0.3])
    dq = rot.quat_derivative(q, np.zeros(3), stabilization=1.0)
    assert np.dot(q, dq) < 0.0  # the norm decreases toward one


def test_autodiff_gradients_are_exact():
    rpy_ad = InitializeAutoDiff(np.array([0.2, -0.3, 0.7]))[:, 0]
    q_ad = rot.euler_to_quat(rpy_ad)
    back = rot.quat_to_euler(q_ad)
    assert isinstance(back[0], AutoDiffXd)
    np.testing.assert_allclose(ExtractValue(back)[:, 0], [0.2, -0.3, 0.7], atol=1e-12)
    np.testing.assert_allclose(ExtractGradient(back), np.eye(3), atol=1e-12)
    R_ad = rot.quat_to_rotmat(q_ad)
    q_back = rot.rotmat_to_quat(R_ad)
    np.testing.assert_allclose(ExtractGradient(q_back), ExtractGradient(q_ad), atol=1e-12)


def test_symbolic_expressions_evaluate_to_float_results():
    v = [Variable(n) for n in ("r", "p", "y")]
    env = {v[0]: 0.3, v[1]: -0.1, v[2]: 0.9}
    q_sym = rot.euler_to_quat(np.array(v, dtype=object))
    R_sym = rot.quat_to_rotmat(q_sym)
    expected = rot.euler_to_rotmat([0.3, -0.1, 0.9])
    np.testing.assert_allclose(Evaluate(R_sym, env), expected, atol=1e-14)
    q_back = rot.rotmat_to_quat(R_sym)
    np.testing.assert_allclose(Evaluate(q_back, env)[:, 0], rot.euler_to_quat([0.3, -0.1, 0.9]),
                               atol=1e-12)
    euler_sym = rot.quat_to_euler(q_sym)
    np.testing.assert_allclose(Evaluate(euler_sym, env)[:, 0], [0.3, -0.1, 0.9], atol=1e-12)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rotmat_to_quat_handles_half_turns(axis):
    rpy = np.zeros(3)
    rpy[axis] = np.pi if axis != 1 else np.pi / 2 - 1e-9
    R = rot.euler_to_rotmat(rpy)
    np.testing.assert_allclose(rot.quat_to_rotmat(rot.rotmat_to_quat(R)), R, atol=1e-9)


def test_unit_quat_rotation_normalises_and_rotates_both_ways():
    q = np.array([0.9, -0.2, 0.35, 0.1]) * 1.7  # not unit: the rotation of q / |q|
    rows = rot.unit_quat_rotation(q.tolist())
    R = rot.quat_to_rotmat(q / np.linalg.norm(q))
    np.testing.assert_allclose(np.array(rows), R, atol=1e-15)
    v = [1.0, -2.0, 0.5]
    np.testing.assert_allclose(rot.rotate(rows, v), R @ v, atol=1e-14)
    np.testing.assert_allclose(rot.rotate_back(rows, v), R.T @ v, atol=1e-14)
