"""Arm push-out of hands left in the scene (trumans.sample.cleanup.arm_pushout)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.scenes.occupancy import OccupancyGrid
from trumans.sample.cleanup.arm_pushout import ArmPushConfig, arm_push, push_arms_out
from trumans.sample.guidance.penetration import SceneSDF
from trumans.sample.sampler import bone_lengths_of
from trumans.sample.cleanup.scene_pushout import push_radii

from trumans.skeleton import JOINT_INDEX

from helpers import standing_body

L_ARM = [JOINT_INDEX[f"left_{n}"] for n in ("elbow", "wrist", "index1")]
WRIST, INDEX = JOINT_INDEX["left_wrist"], JOINT_INDEX["left_index1"]


def _wall(y0: float = 0.70, y1: float = 0.78) -> SceneSDF:
    """Floor (z < 0) plus an 8 cm wall y in [y0, y1] across the grid, 2 cm voxels, as a field."""
    origin = np.array([-0.59, -0.19, -0.09])
    c = origin[:, None] + 0.02 * np.arange(100)[None]
    x, y, z = np.meshgrid(*c, indexing="ij")
    return SceneSDF(OccupancyGrid((z < 0) | ((y > y0) & (y < y1)), origin, 0.02))


def _depth(sdf: SceneSDF, J: np.ndarray) -> np.ndarray:
    """(..., 24) depth of each joint's core (push radii, no margin) inside the scene, m."""
    return np.maximum(push_radii() - sdf(torch.as_tensor(J, dtype=torch.float32)).numpy(), 0.0)


def test_a_hand_through_a_thin_wall_comes_back_on_the_body_side_with_bones_kept():
    """T-pose, left arm along +y: the wrist is just inside the wall, the index1 past its middle,
    where the field's gradient points on through (+y). The push brings the hand back (-y)."""
    sdf, k, T = _wall(0.70, 0.84), 2, 14
    J = standing_body(T)
    assert _depth(sdf, J)[0, :, INDEX].min() > 0.03
    _, g = sdf.value_and_gradient(torch.as_tensor(J[0, 0, INDEX], dtype=torch.float32)[None])
    assert g[0, 1] > 0.5  # the gradient would push the index1 through the wall
    out = push_arms_out(J, bone_lengths_of(J[0, 0]), sdf, fixed=k)
    np.testing.assert_array_equal(out[:, :k], J[:, :k])  # the context stays
    settled = slice(k + ArmPushConfig().spread, T)  # after the fade-in
    assert _depth(sdf, out)[0, settled].max() < 0.01
    assert (out[0, settled, INDEX, 1] < 0.70).all() and (out[0, settled, WRIST, 1] < 0.70).all()
    np.testing.assert_allclose(bone_lengths_of(out), bone_lengths_of(J), atol=1e-6)
    others = [j for j in range(24) if j not in L_ARM]
    np.testing.assert_array_equal(out[:, :, others], J[:, :, others])  # the shoulder and the rest stay


def test_a_brief_touch_is_eased_in_and_out():
    sdf, T = _wall(0.84, 0.92), 20  # the rest pose's index1 (y = 0.80) is clear of this wall
    J = standing_body(T)
    J[0, 10, INDEX, 1] += 0.08  # one frame's hand 8 cm further: into the wall
    assert _depth(sdf, J)[0, 10, INDEX] > 0.04 and _depth(sdf, J)[0, [9, 11]].max() == 0
    out = push_arms_out(J, bone_lengths_of(J[0, 0]), sdf)
    assert _depth(sdf, out)[0, 10].max() < 0.01
    moved = np.linalg.norm(out[0, :, WRIST] - J[0, :, WRIST], axis=-1)
    assert moved[10] > 0.03 and 0 < moved[8] < moved[9] < moved[10] and moved[10] > moved[11] > moved[12] > 0
    assert moved[:4].max() == 0 and moved[17:].max() == 0  # only within twice the spread
    assert np.abs(np.diff(moved)).max() < 0.6 * moved[10]  # no single-frame pop


def test_a_clear_body_and_kept_frames_are_left_exactly():
    sdf, T = _wall(), 8
    J = standing_body(T)
    clear = J.copy()
    clear[..., 1] -= 0.3  # the whole body 30 cm back from the wall
    assert not arm_push(clear, sdf).any()
    np.testing.assert_array_equal(push_arms_out(clear, bone_lengths_of(J[0, 0]), sdf), clear)
    keep = np.zeros((1, T, 2), bool)
    keep[0, :, 0] = True  # the left arm is in a hand phase of the plan: the reach cleanup's
    np.testing.assert_array_equal(push_arms_out(J, bone_lengths_of(J[0, 0]), sdf, keep=keep), J)


def test_a_shoulder_in_the_scene_is_left_to_the_body_push_out():
    sdf = _wall(0.10, 0.60)  # the left shoulder (y = 0.195) inside a thick wall
    J = standing_body(4)
    assert _depth(sdf, J)[0, 0, JOINT_INDEX["left_shoulder"]] > 0
    assert not arm_push(J, sdf)[..., 0, :].any()


def test_bad_input_raises():
    sdf, J = _wall(), standing_body(6)
    lengths = bone_lengths_of(J[0, 0])
    with pytest.raises(ValueError, match="joints must be"):
        push_arms_out(J[0], lengths, sdf)
    with pytest.raises(ValueError, match="fixed"):
        push_arms_out(J, lengths, sdf, fixed=7)
    with pytest.raises(ValueError, match="keep must be"):
        push_arms_out(J, lengths, sdf, keep=np.zeros((1, 6), bool))
    with pytest.raises(ValueError, match="spread"):
        ArmPushConfig(spread=0)
    with pytest.raises(ValueError, match="margin"):
        ArmPushConfig(margin=float("nan"))


def test_batch_members_are_pushed_independently():
    sdf, k = _wall(0.70, 0.84), 2
    J = standing_body(10)
    clear = J.copy()
    clear[..., 1] -= 0.3
    lengths = bone_lengths_of(J[0, 0])
    both = push_arms_out(np.concatenate([J, clear]), lengths, sdf, fixed=k)
    np.testing.assert_allclose(both[:1], push_arms_out(J, lengths, sdf, fixed=k), atol=1e-9)
    np.testing.assert_array_equal(both[1:], clear)
