"""Sampling with a given body (`trumans sample --body SEQ.npz[:FRAME]`, trumans.sample.rollout.body_pose)."""
from __future__ import annotations

import numpy as np
import pytest
from helpers import tiny_checkpoint

from trumans.sample.cli import body_frame
from trumans.sample.plan import plan_from_dict
from trumans.sample.rollout import body_pose, sample_plan, stream
from trumans.sample.sampler import EpisodeSampler, SamplerConfig, bone_lengths_of
from trumans.sample.cleanup.support_lift import lowest_foot_height
from trumans.scenes.scene_grids import SceneGrids
from trumans.sequence import Sequence, save_sequence
from trumans.skeleton import JOINT_INDEX, REST_JOINTS, SUBTREE, heading


def _turned(J: np.ndarray, about: int, axis: np.ndarray, angle: float, subtree: list[int]) -> np.ndarray:
    """J with the joints of ``subtree`` turned by ``angle`` about ``axis`` through joint ``about``."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    out = J.copy()
    out[subtree] = (J[subtree] - J[about]) @ R.T + J[about]
    return out


def test_body_pose_is_canonical_on_the_floor_with_its_bones():
    J = REST_JOINTS.astype(np.float64) * 0.9
    c, s = np.cos(2.0), np.sin(2.0)
    world = J @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [3.0, -1.0, 0.3]  # turned, moved, floating
    p = body_pose(world).astype(np.float64)
    np.testing.assert_allclose(p[JOINT_INDEX["pelvis"], :2], 0.0, atol=1e-6)
    assert abs(heading(p)) < 1e-6
    assert lowest_foot_height(p) == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(bone_lengths_of(p), bone_lengths_of(J), atol=1e-6)


def test_body_pose_refuses_frames_that_do_not_stand():
    J = REST_JOINTS.astype(np.float64)
    knee = JOINT_INDEX["left_knee"]
    bent = _turned(J, knee, [0, 1, 0], np.radians(90), SUBTREE[JOINT_INDEX["left_ankle"]])
    with pytest.raises(ValueError, match="left knee"):
        body_pose(bent, "frame 7")
    leaning = _turned(J, JOINT_INDEX["pelvis"], [0, 1, 0], np.radians(45), SUBTREE[JOINT_INDEX["spine1"]])
    with pytest.raises(ValueError, match="trunk"):
        body_pose(leaning)
    nan = J.copy()
    nan[3, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        body_pose(nan)
    with pytest.raises(ValueError, match=r"\(24, 3\)"):
        body_pose(J[:20])


def test_sample_plan_keeps_the_given_body(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    body = REST_JOINTS.astype(np.float64) * 0.85
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "goto", "to": [1.4, 0.6]}]})
    res = sample_plan(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=2)), scene, wm, plan, seed=0,
                      body=body)
    got = bone_lengths_of(res.joints[0].astype(np.float64))
    np.testing.assert_allclose(got, np.broadcast_to(bone_lengths_of(body), got.shape), atol=1e-4)
    gen = stream(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=2)), scene, wm, plan, seed=0, body=body)
    streamed = np.concatenate([next(gen) for _ in range(3)]).astype(np.float64)
    np.testing.assert_allclose(bone_lengths_of(streamed), np.broadcast_to(bone_lengths_of(body), streamed.shape[:2]),
                               atol=1e-4)


def test_body_frame_parses_path_and_frame(tmp_path):
    J = np.broadcast_to(REST_JOINTS, (5, 24, 3)).astype(np.float32).copy()
    J[:, :, 0] += np.arange(5)[:, None]  # frame i at x + i
    path = tmp_path / "me.npz"
    save_sequence(Sequence(joints=J, fps=30.0), path)
    np.testing.assert_allclose(body_frame(str(path))[:, 0], J[0, :, 0])
    np.testing.assert_allclose(body_frame(f"{path}:3")[:, 0], J[3, :, 0])
    with pytest.raises(ValueError, match="out of range"):
        body_frame(f"{path}:9")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        body_frame(str(tmp_path / "missing.npz:2"))
