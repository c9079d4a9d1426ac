"""An episode's conditions, defined once for training (``train/data.py``) and sampling (``sample/``).

TRUMANS §4.1-4.4: an episode of L frames is generated in its canonical frame (``episodes``: the
first frame's pelvis floor point and heading); its navigation subgoal is the pelvis floor point
at the last frame (the pelvis x, y entries of ``M_goal``); its scene condition is the local grid
around the subgoal turned to the first frame's heading (§4.3); its action condition is the
window's frame-wise labels with the progress indicator (§4.4; the ablation drops it to 0/1).

In training the subgoal comes from the window itself; a sampler passes the context frames it has
(the first frame at least) and the subgoal it chose (from a path or an object), and gets the same
frame, grid and labels by the same code.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.rotations import yaw_matrix
from .episodes import PELVIS, canonical_frame

__all__ = ["EpisodeCondition", "episode_condition", "subgoal_to_canonical", "subgoal_to_world", "episode_scene_grids"]


@dataclass
class EpisodeCondition:
    """origin: (..., 3) float64 world m, the first frame's pelvis with z = 0; yaw: (...,) float64 rad,
    the first frame's heading; subgoal: (..., 3) float64 world m, a floor point (z = 0); actions:
    (..., L, N_A) float32 labels (None if none were given)."""

    origin: np.ndarray
    yaw: np.ndarray
    subgoal: np.ndarray
    actions: np.ndarray | None = None

    def subgoal_canonical(self) -> np.ndarray:
        """The subgoal in the episode's canonical frame: (..., 3) float64 m."""
        return subgoal_to_canonical(self.subgoal, self.origin, self.yaw)


def episode_condition(joints: np.ndarray, actions: np.ndarray | None = None, *, subgoal: np.ndarray | None = None,
                      progress_indicator: bool = True) -> EpisodeCondition:
    """The conditions of the episode(s) whose frames start with ``joints``.

    joints: (..., L', 24, 3) world m (training: the whole window; sampling: the context frames, at
    least the first); actions: (..., L, N_A) labels of the window (0 off, 1 + progress on); subgoal: (..., 3)
    world m, default the pelvis floor point at the last frame of ``joints`` (z = 0);
    progress_indicator = False turns the labels into plain 0/1 (the paper's ablation).
    """
    origin, yaw = canonical_frame(joints)
    if subgoal is None:
        goal = np.asarray(joints, dtype=np.float64)[..., -1, PELVIS, :].copy()
    else:
        goal = np.array(subgoal, dtype=np.float64)
        if goal.shape != origin.shape:
            raise ValueError(f"subgoal must be {origin.shape} (world m) for joints {np.shape(joints)}, got {goal.shape}")
        if not np.isfinite(goal).all():
            raise ValueError(f"subgoal must be finite, got {goal.tolist()}")
    goal[..., 2] = 0.0
    acts = None
    if actions is not None:
        acts = np.asarray(actions, dtype=np.float32)
        if acts.ndim != np.ndim(joints) - 1 or acts.shape[:-2] != np.shape(joints)[:-3]:
            raise ValueError(f"actions must be (..., L, N_A) with the leading shape of joints {np.shape(joints)[:-3]}, "
                             f"got {acts.shape}")
        if not progress_indicator:
            acts = (acts > 0).astype(np.float32)
    return EpisodeCondition(origin, yaw, goal, acts)


def subgoal_to_canonical(goal: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World -> canonical for points: ``R_z(-yaw) (goal - origin)``. goal, origin: (..., 3) m; yaw: (...,) rad."""
    goal, origin, yaw = _check(goal, origin, yaw)
    return np.einsum("...ji,...j->...i", yaw_matrix(yaw), goal - origin)


def subgoal_to_world(goal: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Canonical -> world for points, the inverse of ``subgoal_to_canonical``: ``R_z(yaw) goal + origin``."""
    goal, origin, yaw = _check(goal, origin, yaw)
    return np.einsum("...ij,...j->...i", yaw_matrix(yaw), goal) + origin


def _check(goal, origin, yaw):
    goal, origin, yaw = (np.asarray(v, dtype=np.float64) for v in (goal, origin, yaw))
    try:
        if goal.shape[-1:] != (3,) or origin.shape[-1:] != (3,):
            raise ValueError
        np.broadcast_shapes(goal.shape[:-1], origin.shape[:-1], yaw.shape)
    except ValueError:
        raise ValueError(f"goal and origin must be (..., 3) and yaw (...,) with matching leading shapes, "
                         f"got {goal.shape}, {origin.shape}, {yaw.shape}") from None
    return goal, origin, yaw


def episode_scene_grids(grids, cond: EpisodeCondition, object_poses: dict[str, np.ndarray] | None = None, *,
                        n: int = 32, extent: tuple[float, float, float] = (1.2, 1.2, 1.2)) -> np.ndarray:
    """The scene condition (TRUMANS §4.3): (B, n, n, n) bool local grids (axes forward, left, up;
    True = occupied) around each episode's subgoal, turned to its first frame's heading.

    grids: a ``trumans.scenes.scene_grids.SceneGrids`` (static occupancy + dynamic objects); cond: B
    episodes (origin (B, 3)); object_poses: name -> (B, 4, 4) world-from-object poses at each
    episode's first frame (objects not given sit at their scene pose)."""
    if np.ndim(cond.yaw) != 1:
        raise ValueError(f"episode_scene_grids takes a flat batch of episodes (yaw (B,)), got yaw {np.shape(cond.yaw)}")
    return grids.query(cond.subgoal, cond.yaw, object_poses, n=n, extent=extent)
