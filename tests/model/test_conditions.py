"""Episode conditions: one definition for training and sampling (frame, subgoal, labels, scene grid)."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.scenes.local_grid import local_grids
from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.scene_grids import SceneGrids
from trumans.model.conditions import (episode_condition, episode_scene_grids, subgoal_to_canonical,
                                      subgoal_to_world)
from trumans.model.episodes import FeatureLayout, canonicalize
from trumans.rotations import axis_angle_to_matrix
from trumans.skeleton import forward_kinematics, heading


def _walk(rng, B=4, L=16):
    aa = rng.normal(0, 0.15, (B, L, 24, 3))
    aa[..., 0, :] = 0
    aa[..., 0, 2] = rng.uniform(-np.pi, np.pi, (B, 1))
    root = np.concatenate([rng.uniform(-2, 2, (B, 1, 2)) + np.linspace(0, 1, L)[None, :, None] * rng.normal(0, 1, (B, 1, 2)),
                           np.full((B, L, 1), 0.9)], -1)
    return forward_kinematics(axis_angle_to_matrix(aa), root)[0]


def test_episode_condition_defines_frame_subgoal_and_labels() -> None:
    rng = np.random.default_rng(0)
    joints = _walk(rng)
    labels = rng.uniform(1.0, 2.0, (4, 16, 3)).astype(np.float32) * (rng.random((4, 16, 3)) > 0.5)
    c = episode_condition(joints, labels)
    assert c.origin.shape == (4, 3) and c.yaw.shape == (4,) and c.subgoal.shape == (4, 3)
    assert np.allclose(c.origin[:, :2], joints[:, 0, 0, :2]) and np.all(c.origin[:, 2] == 0)
    assert np.allclose(c.yaw, heading(joints[:, 0]))
    assert np.allclose(c.subgoal[:, :2], joints[:, -1, 0, :2]) and np.all(c.subgoal[:, 2] == 0)
    assert np.array_equal(c.actions, labels)
    # the canonical subgoal is where the canonical features put the last pelvis (x, y) - the M_goal entries
    feats = FeatureLayout().pack(canonicalize(joints, c.origin, c.yaw))
    idx = FeatureLayout().position_index("pelvis", (0, 1))
    assert np.allclose(c.subgoal_canonical()[:, :2], feats[:, -1, idx], atol=1e-5)
    # progress ablation: plain 0/1 labels on the same frames
    ab = episode_condition(joints, labels, progress_indicator=False)
    assert set(np.unique(ab.actions)) <= {0.0, 1.0} and np.array_equal(ab.actions > 0, labels > 0)
    # a sampler passes only the context frames and its own subgoal: same frame, its subgoal (on the floor)
    goal = np.array([[1.0, 2.0, 0.4]] * 4)
    s = episode_condition(joints[:, :2], subgoal=goal)
    assert np.array_equal(s.origin, c.origin) and np.array_equal(s.yaw, c.yaw)
    assert np.allclose(s.subgoal, [[1.0, 2.0, 0.0]] * 4) and s.actions is None
    with pytest.raises(ValueError, match="subgoal must be"):
        episode_condition(joints, subgoal=goal[:2])
    with pytest.raises(ValueError, match="actions must be"):
        episode_condition(joints, labels[:2])  # another batch
    # a sampler: the context frames with the whole window's labels
    s2 = episode_condition(joints[:, :2], labels, subgoal=goal)
    assert np.array_equal(s2.actions, labels)


def test_subgoal_round_trip() -> None:
    rng = np.random.default_rng(1)
    g, o, yaw = rng.normal(0, 3, (5, 3)), rng.normal(0, 3, (5, 3)), rng.uniform(-np.pi, np.pi, 5)
    c = subgoal_to_canonical(g, o, yaw)
    assert np.allclose(subgoal_to_world(c, o, yaw), g)
    assert np.allclose(np.linalg.norm(c, axis=-1), np.linalg.norm(g - o, axis=-1))
    # heading along +x in the canonical frame: a goal 1 m ahead of the body is at (1, 0)
    ahead = o + np.stack([np.cos(yaw), np.sin(yaw), np.zeros(5)], -1)
    assert np.allclose(subgoal_to_canonical(ahead, o, yaw), [[1, 0, 0]] * 5)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        subgoal_to_canonical(g[:, :2], o, yaw)


def test_scene_grids_around_the_subgoal() -> None:
    grid = np.zeros((60, 60, 44), dtype=bool)
    grid[40:50, 10:30, :10] = True
    occ = OccupancyGrid(grid, np.array([-1.5 + 0.025, -1.5 + 0.025, 0.025]), 0.05)
    c = episode_condition(_walk(np.random.default_rng(2), B=3) * np.array([0.3, 0.3, 1.0]))
    out = episode_scene_grids(SceneGrids(occ), c, n=16)
    assert out.shape == (3, 16, 16, 16) and out.dtype == bool
    assert np.array_equal(out, local_grids(occ, c.subgoal, c.yaw, n=16))
