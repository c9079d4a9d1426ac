"""Rotation conversions (trumans.rotations): round trips, numpy vs torch, angles at 0 and pi, bad shapes."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from trumans.rotations import (
    axis_angle_to_matrix, euler_to_matrix, matrix_to_6d, matrix_to_axis_angle, matrix_to_quat,
    quat_to_matrix, sixd_to_matrix, yaw_matrix, rodrigues, unit, fit_yaw,
)


def _random_R(n, seed=0):
    return Rotation.random(n, random_state=seed).as_matrix()


def _special_R():
    """Identity, half turns about the axes and a diagonal, a tiny rotation."""
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    vecs = np.concatenate([np.zeros((1, 3)), axes * np.pi, axes[:1] * 1e-9, axes * (np.pi - 1e-7)])
    return Rotation.from_rotvec(vecs).as_matrix()


@pytest.mark.parametrize("R", [_random_R(64), _special_R()])
def test_6d_round_trip_numpy_and_torch(R):
    r6 = matrix_to_6d(R)
    assert r6.shape == (len(R), 6)
    np.testing.assert_allclose(r6[:, :3], R[:, :, 0])  # first COLUMN, not row
    np.testing.assert_allclose(r6[:, 3:], R[:, :, 1])
    np.testing.assert_allclose(sixd_to_matrix(r6), R, atol=1e-12)
    Rt = torch.as_tensor(R)
    r6t = matrix_to_6d(Rt)
    assert isinstance(r6t, torch.Tensor)
    np.testing.assert_allclose(r6t.numpy(), r6)
    np.testing.assert_allclose(sixd_to_matrix(r6t).numpy(), R, atol=1e-12)


def test_6d_gram_schmidt_projects_noisy_input_to_rotation():
    rng = np.random.default_rng(0)
    r6 = matrix_to_6d(_random_R(32)) + rng.normal(0, 0.05, (32, 6))
    for R in (sixd_to_matrix(r6), sixd_to_matrix(torch.as_tensor(r6)).numpy()):
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_6d_torch_gradients_finite():
    r6 = torch.as_tensor(matrix_to_6d(_random_R(8)), dtype=torch.float64).requires_grad_(True)
    (sixd_to_matrix(r6) ** 3).sum().backward()
    assert torch.isfinite(r6.grad).all() and r6.grad.abs().sum() > 0


@pytest.mark.parametrize("R", [_random_R(64, seed=1), _special_R()])
def test_quat_round_trip(R):
    q = matrix_to_quat(R)
    assert q.shape == (len(R), 4)
    assert (q[:, 3] >= 0).all()  # scalar-last, w >= 0
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-9)


def test_quat_scalar_last_convention():
    q = matrix_to_quat(axis_angle_to_matrix(np.array([0.0, 0.0, np.pi / 2])))
    np.testing.assert_allclose(q, [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(np.array([0, 0, 0, 2.0])), np.eye(3))  # normalised


@pytest.mark.parametrize("R", [_random_R(64, seed=2), _special_R()])
def test_axis_angle_round_trip_numpy_and_torch(R):
    v = matrix_to_axis_angle(R)
    assert v.shape == (len(R), 3)
    assert (np.linalg.norm(v, axis=1) <= np.pi + 1e-9).all()
    np.testing.assert_allclose(axis_angle_to_matrix(v), R, atol=1e-9)
    np.testing.assert_allclose(axis_angle_to_matrix(torch.as_tensor(v)).numpy(), R, atol=1e-9)


def test_axis_angle_analytic_and_zero():
    np.testing.assert_allclose(axis_angle_to_matrix(np.zeros(3)), np.eye(3))
    np.testing.assert_allclose(axis_angle_to_matrix(torch.zeros(5, 3)).numpy(), np.broadcast_to(np.eye(3), (5, 3, 3)))
    Rz = axis_angle_to_matrix(np.array([0.0, 0.0, np.pi]))
    np.testing.assert_allclose(Rz, np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    np.testing.assert_allclose(abs(matrix_to_axis_angle(Rz)), [0, 0, np.pi], atol=1e-9)
    v = torch.tensor([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1]], dtype=torch.float64, requires_grad=True)
    axis_angle_to_matrix(v).sum().backward()
    assert torch.isfinite(v.grad).all()


def test_euler_and_yaw():
    a = 0.7
    Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    np.testing.assert_allclose(euler_to_matrix([a, 0, 0], "xyz"), Rx, atol=1e-12)
    ang = np.array([0.3, -0.5, 1.1])  # intrinsic ZXY = Rz @ Rx @ Ry (the BVH convention)
    expect = (axis_angle_to_matrix(np.array([0, 0, ang[0]])) @ axis_angle_to_matrix(np.array([ang[1], 0, 0]))
              @ axis_angle_to_matrix(np.array([0, ang[2], 0])))
    np.testing.assert_allclose(euler_to_matrix(ang, "zxy"), expect, atol=1e-12)
    np.testing.assert_allclose(yaw_matrix(np.pi / 2) @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-12)
    assert yaw_matrix(np.zeros((4, 2))).shape == (4, 2, 3, 3)


@pytest.mark.parametrize("fn,arg", [
    (matrix_to_6d, np.zeros((2, 3, 4))),
    (matrix_to_6d, torch.zeros(2, 2, 3)),
    (sixd_to_matrix, np.zeros((2, 5))),
    (sixd_to_matrix, torch.zeros(2, 9)),
    (quat_to_matrix, np.zeros((2, 3))),
    (axis_angle_to_matrix, np.zeros((2, 4))),
    (axis_angle_to_matrix, torch.zeros(2, 2)),
])
def test_bad_shapes_raise(fn, arg):
    with pytest.raises(ValueError, match="must be"):
        fn(arg)


def test_rotvec_rodrigues_round_trip():
    v = np.random.default_rng(0).normal(0, 1, (50, 3))
    v *= (np.random.default_rng(1).uniform(0, 3.0, 50) / np.linalg.norm(v, axis=1))[:, None]
    assert np.allclose(matrix_to_axis_angle(axis_angle_to_matrix(v)), v, atol=1e-9)


def test_rotvec_exact_near_half_turn():
    axes = np.random.default_rng(2).normal(size=(20, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    ang = np.pi - np.geomspace(1e-8, 1e-3, 20)
    v = axes * ang[:, None]
    got = matrix_to_axis_angle(Rotation.from_rotvec(v).as_matrix())
    np.testing.assert_allclose(got, v, atol=1e-7)


def test_rodrigues_matches_scipy_numpy_and_torch():
    rng = np.random.default_rng(3)
    axis, angle = rng.normal(size=(30, 3)), rng.uniform(-4, 4, 30)
    ref = Rotation.from_rotvec(axis / np.linalg.norm(axis, axis=1, keepdims=True) * angle[:, None]).as_matrix()
    np.testing.assert_allclose(rodrigues(axis, angle), ref, atol=1e-12)
    got = rodrigues(torch.as_tensor(axis), torch.as_tensor(angle))
    assert isinstance(got, torch.Tensor)
    np.testing.assert_allclose(got.numpy(), ref, atol=1e-12)
    # one axis, many angles; a zero axis is the identity
    np.testing.assert_allclose(rodrigues(np.array([0.0, 0.0, 2.0]), angle[:4]), yaw_matrix(angle[:4]), atol=1e-12)
    np.testing.assert_allclose(rodrigues(np.zeros(3), 1.0), np.eye(3))


def test_unit_vectors():
    v = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(unit(v), [[0.6, 0.8, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(unit(torch.as_tensor(v)).numpy(), unit(v))


def test_fit_yaw_recovers_a_turn_and_weights():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(5, 8, 3))
    a -= a.mean(1, keepdims=True)
    th = rng.uniform(-3, 3, 5)
    b = np.einsum("nij,nkj->nki", yaw_matrix(th), a)
    np.testing.assert_allclose(fit_yaw(a, b), th, atol=1e-12)
    # a zero-weight outlier does not move the fit
    b2 = b.copy()
    b2[:, 0] += 5.0
    w = np.ones((5, 8))
    w[:, 0] = 0.0
    np.testing.assert_allclose(fit_yaw(a, b2, w), th, atol=1e-12)
    with pytest.raises(ValueError, match="a and b"):
        fit_yaw(a, b[:, :4])


def test_least_rotation_turns_a_into_b_about_their_common_normal():
    from trumans.rotations import least_rotation

    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    R = least_rotation(a, b)
    ua, ub = a / np.linalg.norm(a, axis=-1, keepdims=True), b / np.linalg.norm(b, axis=-1, keepdims=True)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, ua), ub, atol=1e-9)
    n = np.cross(ua, ub)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", R, n), n, atol=1e-9)  # the normal stays: least turn
    np.testing.assert_allclose(least_rotation(a, 2 * a), np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-9)
