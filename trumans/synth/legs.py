"""Legs of the standing body: the canonical standing state every primitive starts and ends in,
where the feet stand, and the leg IK that keeps planted feet where they are."""
from __future__ import annotations

import numpy as np

from trumans.rotations import yaw_matrix
from trumans.skeleton import ANKLES, HIPS, forward_kinematics
from trumans.ik.limb import limb_reach, set_global_rotation, solve_limb
from .poses import pose

__all__ = ["wrap_angle", "rest_ankle_rel", "stand_height", "foot_places", "solve_legs", "pelvis_height_limit",
           "standing_state"]

_LEGS = ("left_leg", "right_leg")


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap radians to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def rest_ankle_rel(offsets: np.ndarray) -> np.ndarray:
    """(2, 3) left/right ankle positions relative to the pelvis in the rest pose (body frame)."""
    rot = np.tile(np.eye(3), (1, 24, 1, 1))
    P, _ = forward_kinematics(rot, np.zeros((1, 3)), offsets)
    return P[0, list(ANKLES)]


def stand_height(offsets: np.ndarray) -> float:
    """Pelvis height (m) of the canonical standing state: the rest height with the knees softened by
    4 mm (scaled by the leg length) so the legs are not at full extension."""
    leg = min(limb_reach(offsets, "left_leg")[1], limb_reach(offsets, "right_leg")[1])
    return float(offsets[0, 2] - 0.004 * leg / 0.784)


def foot_places(offsets: np.ndarray, pos: np.ndarray, yaw: float) -> np.ndarray:
    """(2, 3) world ankle positions (left, right) of the canonical stance at pelvis xy ``pos`` (2,), ``yaw``."""
    rel = rest_ankle_rel(offsets)
    out = (yaw_matrix(yaw) @ rel.T).T
    out[:, :2] += np.asarray(pos, dtype=np.float64)[:2]
    out[:, 2] = offsets[0, 2] + rel[:, 2]
    return out


def solve_legs(
    rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, ankle_targets: np.ndarray,
    foot_rot: np.ndarray | None = None, pole_dir: np.ndarray | None = None,
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Both legs to world ankle targets (T, 2, 3); ``foot_rot`` (T, 2, 3, 3) sets the ankles' global
    rotations (default: keep them); ``pole_dir`` (T, 3) world knee direction (default: pelvis forward).
    Returns (rot (T, 24, 3, 3), reached (T, 2) bool)."""
    reached = np.ones((rot.shape[0], 2), dtype=bool)
    for i, limb in enumerate(_LEGS):
        pole = None
        if pole_dir is not None:
            P, _ = forward_kinematics(rot, root, offsets)
            pole = P[:, HIPS[i]] + pole_dir
        rot, reached[:, i] = solve_limb(rot, root, offsets, limb, ankle_targets[:, i], pole=pole, mask=mask)
        if foot_rot is not None:
            rot = set_global_rotation(rot, root, offsets, ANKLES[i], foot_rot[:, i])
    return rot, reached


def pelvis_height_limit(rot: np.ndarray, root_xy: np.ndarray, offsets: np.ndarray, ankle_targets: np.ndarray,
                        reach_frac: float = 0.999) -> np.ndarray:
    """Highest pelvis z (T,) (m) at which both legs still reach their ankle targets (T, 2, 3), given
    the local rotations rot (T, 24, 3, 3) (root orientation included) and pelvis xy (T, 2)."""
    T = rot.shape[0]
    P0, _ = forward_kinematics(rot, np.column_stack([root_xy, np.zeros(T)]), offsets)
    h_lim = np.full(T, np.inf)
    for f in range(2):
        reach = limb_reach(offsets, _LEGS[f])[1] * reach_frac
        hip = P0[:, HIPS[f]]
        dh2 = ((ankle_targets[:, f, :2] - hip[:, :2]) ** 2).sum(1)
        h_lim = np.minimum(h_lim, ankle_targets[:, f, 2] + np.sqrt(np.maximum(reach**2 - dh2, 0.0)) - hip[:, 2])
    return h_lim


def standing_state(
    offsets: np.ndarray, pos: np.ndarray, yaw: float, base_pose: str = "stand"
) -> tuple[np.ndarray, np.ndarray]:
    """Canonical standing state: (rot (24, 3, 3), root (3,)) with pelvis xy ``pos`` (2,) at the
    actor's rest height, heading ``yaw`` (rad), upper body ``base_pose``, feet at ``foot_places``."""
    rot = pose(base_pose, offsets)[None].copy()
    rot[0, 0] = yaw_matrix(yaw)
    root = np.array([[pos[0], pos[1], stand_height(offsets)]], dtype=np.float64)
    feet = foot_places(offsets, pos, yaw)[None]
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(yaw), (1, 2, 3, 3)))
    return rot[0], root[0]
