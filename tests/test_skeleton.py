"""The 24-joint skeleton: FK numpy vs torch, rest pose, bone lengths, heading, symmetry."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from trumans.rotations import axis_angle_to_matrix, yaw_matrix
from trumans.skeleton import (
    JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS, REST_JOINTS, bone_lengths, children, forward_kinematics,
    heading, rest_offsets,
)


def _random_pose(T, seed=0, scale=0.5):
    rng = np.random.default_rng(seed)
    R = Rotation.from_rotvec(rng.normal(0, scale, (T * NUM_JOINTS, 3))).as_matrix().reshape(T, NUM_JOINTS, 3, 3)
    return R, rng.normal(0, 1, (T, 3))


def test_tree_and_names():
    assert NUM_JOINTS == 24 and len(JOINT_NAMES) == 24 and PARENTS[0] == -1
    assert all(PARENTS[j] < j for j in range(1, NUM_JOINTS))  # parents precede children
    assert PARENTS[JOINT_INDEX["left_index1"]] == JOINT_INDEX["left_wrist"]
    assert children(JOINT_INDEX["pelvis"]) == [1, 2, 3]
    assert children(JOINT_INDEX["spine3"]) == [12, 13, 14]


def test_fk_numpy_matches_torch_and_is_differentiable():
    R, root = _random_pose(16)
    off = rest_offsets(1.1)
    J, G = forward_kinematics(R, root, off)
    Rt = torch.as_tensor(R).requires_grad_(True)
    Jt, Gt = forward_kinematics(Rt, torch.as_tensor(root), off)
    np.testing.assert_allclose(Jt.detach().numpy(), J, atol=1e-12)
    np.testing.assert_allclose(Gt.detach().numpy(), G, atol=1e-12)
    Jt.sum().backward()
    assert torch.isfinite(Rt.grad).all()
    np.testing.assert_allclose(J[:, 0], root)  # root joint sits at the root translation


def test_fk_identity_gives_rest_pose():
    eye = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    J, G = forward_kinematics(eye, REST_JOINTS[0])
    np.testing.assert_allclose(J, REST_JOINTS, atol=1e-12)
    np.testing.assert_allclose(G, np.broadcast_to(np.eye(3), G.shape))


def test_rest_pose_height_and_floor():
    head = REST_JOINTS[JOINT_INDEX["head"], 2]
    assert 1.5 < head < 1.65  # head joint of a ~1.70 m adult
    feet = REST_JOINTS[[JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"]], 2]
    np.testing.assert_allclose(feet, 0.04)  # on the floor (joint 4 cm above it)
    assert REST_JOINTS[:, 2].min() >= 0.0
    assert 0.85 < REST_JOINTS[0, 2] < 1.05
    # facing +x: toes ahead of the ankles, left side towards +y
    for s in ("left", "right"):
        assert REST_JOINTS[JOINT_INDEX[f"{s}_foot"], 0] > REST_JOINTS[JOINT_INDEX[f"{s}_ankle"], 0] + 0.05
    assert REST_JOINTS[JOINT_INDEX["left_wrist"], 1] > 0.5 > -0.5 > REST_JOINTS[JOINT_INDEX["right_wrist"], 1]


def test_rest_pose_symmetric():
    for j, n in enumerate(JOINT_NAMES):
        if n.startswith("left_"):
            k = JOINT_INDEX["right_" + n[5:]]
            np.testing.assert_allclose(REST_JOINTS[k], REST_JOINTS[j] * [1, -1, 1], atol=1e-12)
        elif not n.startswith("right_"):
            assert REST_JOINTS[j, 1] == 0.0


def test_bone_lengths_preserved_under_rotations():
    off = rest_offsets()
    R, root = _random_pose(32, seed=3, scale=1.0)
    J, _ = forward_kinematics(R, root, off)
    L = bone_lengths(J)
    assert L.shape == (32, 23)
    np.testing.assert_allclose(L, np.broadcast_to(np.linalg.norm(off[1:], axis=1), L.shape), atol=1e-12)
    Lt = bone_lengths(torch.as_tensor(J))
    np.testing.assert_allclose(Lt.numpy(), L)


def test_rest_offsets_scale():
    base, big = rest_offsets(), rest_offsets(1.2)
    np.testing.assert_allclose(big[1:], base[1:] * 1.2)
    eye = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    J, _ = forward_kinematics(eye, big[0], big)
    np.testing.assert_allclose(J[[10, 11], 2], 0.04, atol=1e-9)  # still standing on the floor
    per_bone = rest_offsets(np.linspace(0.9, 1.1, NUM_JOINTS))
    assert per_bone.shape == (24, 3)
    with pytest.raises(ValueError, match="scale"):
        rest_offsets(np.ones(5))


def test_heading_rest_and_yawed():
    assert abs(heading(REST_JOINTS)) < 1e-9
    yaws = np.array([0.3, -1.2, 2.5, np.pi / 2])
    eye = np.broadcast_to(np.eye(3), (4, NUM_JOINTS, 3, 3)).copy()
    eye[:, 0] = yaw_matrix(yaws)
    J, _ = forward_kinematics(eye, np.zeros((4, 3)))
    np.testing.assert_allclose(heading(J), yaws, atol=1e-9)
    # leaning forward (pitch about +y) does not change the heading
    lean = eye.copy()
    lean[:, 0] = yaw_matrix(yaws) @ axis_angle_to_matrix(np.array([0.0, 0.4, 0.0]))
    J2, _ = forward_kinematics(lean, np.zeros((4, 3)))
    np.testing.assert_allclose(heading(J2), yaws, atol=1e-9)


@pytest.mark.parametrize("rot,root", [
    (np.zeros((2, 23, 3, 3)), np.zeros((2, 3))),
    (np.zeros((2, 24, 3, 3)), np.zeros((3, 3))),
])
def test_fk_bad_shapes(rot, root):
    with pytest.raises(ValueError, match="must be"):
        forward_kinematics(rot, root)
    with pytest.raises(ValueError, match="24, 3"):
        bone_lengths(np.zeros((5, 22, 3)))


def test_depth_subtree_and_groups():
    from trumans.skeleton import DEPTH, FEET, HINGE_AXES, LIMB_CHAINS, SUBTREE, TORSO, WRISTS

    assert DEPTH[0] == 0 and all(DEPTH[j] == DEPTH[PARENTS[j]] + 1 for j in range(1, NUM_JOINTS))
    assert SUBTREE[0].tolist() == list(range(NUM_JOINTS))
    for j in range(NUM_JOINTS):  # a joint's subtree = itself + its children's subtrees
        kids = [SUBTREE[c] for c in children(j)]
        assert sorted([j, *np.concatenate(kids).tolist()] if kids else [j]) == SUBTREE[j].tolist()
    assert [JOINT_NAMES[j] for j in FEET] == ["left_foot", "right_foot"]
    assert [JOINT_NAMES[j] for j in WRISTS] == ["left_wrist", "right_wrist"]
    assert 0 in TORSO and JOINT_INDEX["head"] in TORSO
    # every limb is a parent -> child chain whose middle joint is a hinge
    for a, b, c in LIMB_CHAINS.values():
        assert PARENTS[b] == a and PARENTS[c] == b and b in HINGE_AXES
    assert len(HINGE_AXES) == 4


def test_hinge_axes_bend_limbs_the_anatomical_way():
    from trumans.skeleton import HINGE_AXES, LIMB_CHAINS

    off = rest_offsets()
    rot = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    for name, (a, b, c) in LIMB_CHAINS.items():
        r = rot.copy()
        r[b] = axis_angle_to_matrix(HINGE_AXES[b] * 0.5)
        P, _ = forward_kinematics(r, np.zeros(3), off)
        move = P[c] - forward_kinematics(rot, np.zeros(3), off)[0][c]
        if name.endswith("leg"):
            assert move[0] < -0.05  # the shin swings backwards
        else:
            assert move[0] > 0.05  # the forearm swings forwards


def test_global_to_local_and_offsets_invert_fk():
    from trumans.skeleton import bone_offsets, global_to_local, offsets_from_joints, offsets_from_pose, rest_root

    R, root = _random_pose(6, seed=3)
    off = rest_offsets(1.1)
    P, G = forward_kinematics(R, root, off)
    np.testing.assert_allclose(global_to_local(G), R, atol=1e-12)
    per_frame = bone_offsets(P, G)
    np.testing.assert_allclose(per_frame[:, 1:], np.broadcast_to(off[1:], (6, 23, 3)), atol=1e-12)
    est = offsets_from_pose(P, G)
    np.testing.assert_allclose(est[1:], off[1:], atol=1e-12)
    np.testing.assert_allclose(est[0], rest_root(off))
    # the rest root puts the rest pose's lowest foot at the canonical foot height
    rest, _ = forward_kinematics(np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy(), est[0], est)
    assert abs(rest[[10, 11], 2].min() - REST_JOINTS[[10, 11], 2].min()) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(offsets_from_joints(P)[1:], axis=-1), np.linalg.norm(off[1:], axis=-1))
    with pytest.raises(ValueError, match="global_rot"):
        bone_offsets(P, G[:, :5])
