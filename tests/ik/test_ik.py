"""trumans.ik.fit (joint positions -> rotations) and trumans.ik.rescale."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from trumans.ik.fit import fit_error, fit_rotations, kabsch, offsets_from_joints
from trumans.rotations import least_rotation
from trumans.ik.rescale import leg_length, rescale_motion, scale_offsets
from trumans.rotations import axis_angle_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS, PARENTS, bone_lengths, forward_kinematics, rest_offsets

torch.set_num_threads(1)


def _plausible(T, seed=0, scale=0.35):
    """Random poses: modest local rotations, random heading, pelvis near standing height."""
    rng = np.random.default_rng(seed)
    aa = rng.normal(0, scale, (T, NUM_JOINTS, 3))
    R = axis_angle_to_matrix(aa)
    R[:, 0] = yaw_matrix(rng.uniform(-np.pi, np.pi, T)) @ R[:, 0]
    root = np.concatenate([rng.uniform(-3, 3, (T, 2)), rng.uniform(0.6, 1.0, (T, 1))], axis=1)
    return R, root


@pytest.mark.parametrize("given_offsets", [True, False])
def test_fk_ik_fk_round_trip(given_offsets):
    R, root = _plausible(120)
    off = rest_offsets(np.random.default_rng(1).uniform(0.85, 1.15, NUM_JOINTS))
    J, _ = forward_kinematics(R, root, off)
    R2, root2, off2 = fit_rotations(J, off if given_offsets else None, refine_steps=5)
    assert R2.shape == (120, 24, 3, 3) and root2.shape == (120, 3) and off2.shape == (24, 3)
    J2, _ = forward_kinematics(R2, root2, off2)
    assert np.abs(J2 - J).max() < 1e-3
    assert fit_error(J, R2, root2, off2)["max"] < 1e-3
    np.testing.assert_allclose(np.linalg.det(R2), 1.0, atol=1e-9)
    np.testing.assert_allclose(R2 @ np.swapaxes(R2, -1, -2), np.broadcast_to(np.eye(3), R2.shape), atol=1e-9)
    # bone lengths come from the data when offsets are not given
    np.testing.assert_allclose(np.linalg.norm(off2[1:], axis=1), np.linalg.norm(off[1:], axis=1), atol=1e-6)
    # the pelvis, and every bone's swing, are determined by the positions: global bone directions agree
    np.testing.assert_allclose(R2[:, 0], R[:, 0], atol=1e-6)


def test_hinges_come_out_as_hinges():
    """Hip flexion + knee flexion (about +y) and elbow flexion in T-pose (forearm forward, about -z
    on the left): the fitted knee / elbow rotations turn about those hinge axes."""
    T = 40
    a = np.linspace(0.3, 1.6, T)
    R = np.broadcast_to(np.eye(3), (T, NUM_JOINTS, 3, 3)).copy()
    R[:, JOINT_INDEX["left_hip"]] = axis_angle_to_matrix(np.stack([0 * a, -0.5 * a, 0 * a], 1))
    R[:, JOINT_INDEX["left_knee"]] = axis_angle_to_matrix(np.stack([0 * a, a, 0 * a], 1))
    R[:, JOINT_INDEX["left_elbow"]] = axis_angle_to_matrix(np.stack([0 * a, 0 * a, -a], 1))
    root = np.tile([0.0, 0.0, 0.95], (T, 1))
    J, _ = forward_kinematics(R, root)
    R2, _, _ = fit_rotations(J, rest_offsets(), refine_steps=0)
    for name, axis in (("left_knee", [0, 1, 0]), ("left_elbow", [0, 0, -1])):
        rv = Rotation.from_matrix(R2[:, JOINT_INDEX[name]]).as_rotvec()
        ang = np.linalg.norm(rv, axis=1)
        cos = rv @ np.asarray(axis, float) / ang
        assert (cos > np.cos(np.radians(12))).all(), (name, np.degrees(np.arccos(cos.min())))
        np.testing.assert_allclose(ang, a, atol=0.1)


def test_refinement_reduces_error_on_inconsistent_joints():
    R, root = _plausible(30, seed=4)
    J, _ = forward_kinematics(R, root)
    noisy = J + np.random.default_rng(5).normal(0, 0.01, J.shape)
    e0 = fit_error(noisy, *fit_rotations(noisy, rest_offsets(), refine_steps=0))
    e1 = fit_error(noisy, *fit_rotations(noisy, rest_offsets(), refine_steps=30))
    assert e1["mean"] < e0["mean"]
    assert e1["max"] < 0.1


def test_kabsch_and_least_rotation_analytic():
    Rt = Rotation.random(10, random_state=0).as_matrix()
    a = np.random.default_rng(0).normal(size=(10, 5, 3))
    b = np.einsum("tij,tnj->tni", Rt, a)
    np.testing.assert_allclose(kabsch(a, b), Rt, atol=1e-9)
    u = np.array([[1.0, 0, 0], [0, 0, 2.0], [1.0, 0, 0], [0, 0, 0]])
    v = np.array([[0.0, 3.0, 0], [0, 0, 1.0], [-1.0, 0, 0], [1.0, 0, 0]])
    Rb = least_rotation(u, v)
    np.testing.assert_allclose(Rb[0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(Rb[1], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(Rb[2] @ u[2], v[2], atol=1e-12)  # opposite vectors: a half turn
    np.testing.assert_allclose(np.linalg.det(Rb[2]), 1.0)
    np.testing.assert_allclose(Rb[3], np.eye(3))  # zero vector: identity


def test_offsets_from_joints_median_lengths():
    R, root = _plausible(20, seed=2)
    off = rest_offsets(1.2)
    J, _ = forward_kinematics(R, root, off)
    est = offsets_from_joints(J)
    np.testing.assert_allclose(est[1:], off[1:], atol=1e-9)
    eye = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    assert abs(forward_kinematics(eye, est[0], est)[0][[10, 11], 2].min() - 0.04) < 1e-9


def test_fit_rotations_bad_inputs():
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        fit_rotations(np.zeros((5, 22, 3)))
    bad = np.zeros((3, 24, 3))
    bad[1, 4, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        fit_rotations(bad)
    with pytest.raises(ValueError, match="offsets"):
        fit_rotations(np.zeros((3, 24, 3)), offsets=np.zeros((23, 3)))
    with pytest.raises(ValueError, match="no frames"):
        fit_rotations(np.zeros((0, 24, 3)))


def test_retarget_keeps_rotations_and_changes_bones():
    R, root = _plausible(50, seed=7, scale=0.2)
    src = rest_offsets()
    J_src, _ = forward_kinematics(R, root, src)
    root[:, 2] += 0.04 - J_src[:, [7, 8, 10, 11], 2].min(-1)  # put the source on the floor
    J_src, _ = forward_kinematics(R, root, src)
    dst = scale_offsets(src, 1.25)
    R2, root2 = rescale_motion(R, root, src, dst)
    np.testing.assert_array_equal(R2, R)  # rotations copied
    J_dst, _ = forward_kinematics(R2, root2, dst)
    np.testing.assert_allclose(bone_lengths(J_dst), 1.25 * bone_lengths(J_src), atol=1e-9)
    np.testing.assert_allclose(J_dst[:, [7, 8, 10, 11], 2].min(-1), 0.04, atol=1e-9)  # feet on the floor
    np.testing.assert_allclose(root2[:, :2], 1.25 * root[:, :2], atol=1e-9)  # strides scale with the legs
    assert abs(leg_length(dst) / leg_length(src) - 1.25) < 1e-12
    # per-bone scaling: only the named bones change
    s = np.ones(NUM_JOINTS)
    s[JOINT_INDEX["left_elbow"]] = 0.5
    short = scale_offsets(src, s)
    np.testing.assert_allclose(short[JOINT_INDEX["left_elbow"]], 0.5 * src[JOINT_INDEX["left_elbow"]])
    np.testing.assert_allclose(np.delete(short, [0, JOINT_INDEX["left_elbow"]], 0), np.delete(src, [0, JOINT_INDEX["left_elbow"]], 0))
    assert PARENTS[JOINT_INDEX["left_elbow"]] == JOINT_INDEX["left_shoulder"]


def test_retarget_bad_inputs():
    R, root = _plausible(4)
    with pytest.raises(ValueError, match="dst_offsets"):
        rescale_motion(R, root, rest_offsets(), np.zeros((23, 3)))
    with pytest.raises(ValueError, match="root"):
        rescale_motion(R, root[:2], rest_offsets(), rest_offsets())
    with pytest.raises(ValueError, match="scale"):
        scale_offsets(rest_offsets(), -1.0)
