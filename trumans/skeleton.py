"""The 24-joint skeleton (SMPL-X body joints 0-21 + left/right index1), rest pose and forward kinematics.

Conventions (see DESIGN.md): metres, z up, floor at z = 0. In the rest pose (all local rotations
identity) the body stands upright facing +x, its left side towards +y, feet on the floor.
``offsets[j]`` is joint j's rest position relative to its parent, expressed in the parent's frame.
FK: ``G[j] = G[parent] @ R_local[j]``, ``p[j] = p[parent] + G[parent] @ offsets[j]``; the root's
global rotation is ``R_local[0]`` and its position is the root translation.
"""
from __future__ import annotations

import numpy as np
import torch

__all__ = [
    "JOINT_NAMES",
    "PARENTS",
    "NUM_JOINTS",
    "JOINT_INDEX",
    "REST_JOINTS",
    "rest_offsets",
    "bone_lengths",
    "forward_kinematics",
    "heading",
    "children",
]

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_index1", "right_index1",
)
NUM_JOINTS = len(JOINT_NAMES)
JOINT_INDEX: dict[str, int] = {n: i for i, n in enumerate(JOINT_NAMES)}
# SMPL kinematic tree; each index1 joint hangs off its wrist.
PARENTS: np.ndarray = np.array(
    [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21], dtype=np.int64
)

# Rest joint positions of an average adult in SMPL's frame (x = left, y = up, z = forward), metres.
_SMPL_REST = np.array([
    [-0.0018, -0.2233, 0.0282], [0.0695, -0.3145, 0.0239], [-0.0677, -0.3143, 0.0200],
    [-0.0025, -0.1044, 0.0039], [0.1038, -0.6937, 0.0285], [-0.1060, -0.6981, 0.0266],
    [0.0050, 0.0350, 0.0243], [0.0888, -1.0965, -0.0169], [-0.0910, -1.0944, -0.0210],
    [0.0025, 0.0905, 0.0268], [0.1221, -1.1521, 0.1029], [-0.1189, -1.1527, 0.1065],
    [-0.0153, 0.3051, -0.0115], [0.0757, 0.2136, 0.0111], [-0.0778, 0.2128, 0.0050],
    [0.0021, 0.3913, 0.0395], [0.1988, 0.2425, -0.0115], [-0.1917, 0.2366, -0.0156],
    [0.4507, 0.2249, -0.0327], [-0.4478, 0.2257, -0.0437], [0.7119, 0.2362, -0.0354],
    [-0.7076, 0.2379, -0.0467], [0.8020, 0.2260, -0.0200], [-0.7980, 0.2270, -0.0300],
])
_FOOT_HEIGHT = 0.04  # height of the foot (toe-base) joints above the floor in the rest pose, m


def _rest_joints() -> np.ndarray:
    # SMPL (left, up, forward) -> world (forward, left, up): x_w = z_s, y_w = x_s, z_w = y_s (det +1).
    p = _SMPL_REST[:, [2, 0, 1]].copy()
    # Make the rest pose exactly left/right symmetric about the y = 0 plane.
    left = [i for i, n in enumerate(JOINT_NAMES) if n.startswith("left_")]
    right = [JOINT_INDEX["right_" + JOINT_NAMES[i][5:]] for i in left]
    mid = [i for i in range(NUM_JOINTS) if i not in left and i not in right]
    avg = 0.5 * (p[left] + p[right] * np.array([1.0, -1.0, 1.0]))
    p[left], p[right] = avg, avg * np.array([1.0, -1.0, 1.0])
    p[mid, 1] = 0.0
    p[:, 2] += _FOOT_HEIGHT - p[[10, 11], 2].mean()
    return p


REST_JOINTS: np.ndarray = _rest_joints()  # (24, 3) world rest pose, facing +x, ~1.70 m tall


def children(j: int) -> list[int]:
    """Indices of joint j's children."""
    return [int(c) for c in np.flatnonzero(PARENTS == j)]


def rest_offsets(scale: float | np.ndarray = 1.0) -> np.ndarray:
    """Rest offsets (24, 3) float64 in metres: root's entry is its rest position; ``scale``
    multiplies every bone (scalar or (24,) per bone)."""
    off = REST_JOINTS.copy()
    off[1:] -= REST_JOINTS[PARENTS[1:]]
    scale = np.asarray(scale, dtype=np.float64)
    if scale.ndim == 0:
        scale = np.full(NUM_JOINTS, float(scale))
    if scale.shape != (NUM_JOINTS,):
        raise ValueError(f"scale must be a scalar or (24,), got {scale.shape}")
    off[1:] *= scale[1:, None]
    off[0, 2] = _FOOT_HEIGHT + (REST_JOINTS[0, 2] - _FOOT_HEIGHT) * scale[[1, 4, 7, 10]].mean()
    return off


def bone_lengths(joints: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """joints (..., 24, 3) -> (..., 23) lengths of the bones to joints 1..23 (metres)."""
    if joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (..., 24, 3), got {tuple(joints.shape)}")
    d = joints[..., 1:, :] - joints[..., PARENTS[1:], :]
    if isinstance(d, torch.Tensor):
        return d.norm(dim=-1)
    return np.linalg.norm(d, axis=-1)


def forward_kinematics(
    rot: np.ndarray | torch.Tensor,
    root_pos: np.ndarray | torch.Tensor,
    offsets: np.ndarray | torch.Tensor | None = None,
) -> tuple[np.ndarray | torch.Tensor, np.ndarray | torch.Tensor]:
    """Batched FK.

    rot: (..., 24, 3, 3) local rotation matrices; root_pos: (..., 3) world pelvis position (m);
    offsets: (24, 3) or (..., 24, 3) rest offsets in metres (default: ``rest_offsets()``).
    Returns ``(joints (..., 24, 3), global_rot (..., 24, 3, 3))``; torch in -> torch out
    (differentiable), numpy in -> numpy out.
    """
    if rot.shape[-3:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"rot must be (..., 24, 3, 3), got {tuple(rot.shape)}")
    if root_pos.shape[-1] != 3 or tuple(root_pos.shape[:-1]) != tuple(rot.shape[:-3]):
        raise ValueError(f"root_pos must be {tuple(rot.shape[:-3]) + (3,)}, got {tuple(root_pos.shape)}")
    is_torch = isinstance(rot, torch.Tensor)
    if offsets is None:
        offsets = rest_offsets()
    if is_torch:
        offsets = torch.as_tensor(offsets, dtype=rot.dtype, device=rot.device)
        off = offsets.expand(*rot.shape[:-3], NUM_JOINTS, 3)
    else:
        off = np.broadcast_to(np.asarray(offsets, dtype=rot.dtype), (*rot.shape[:-3], NUM_JOINTS, 3))
    G: list = [rot[..., 0, :, :]]
    P: list = [root_pos]
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        G.append(G[p] @ rot[..., j, :, :])
        P.append(P[p] + (G[p] @ off[..., j, :, None])[..., 0])
    if is_torch:
        return torch.stack(P, dim=-2), torch.stack(G, dim=-3)
    return np.stack(P, axis=-2), np.stack(G, axis=-3)


def heading(joints: np.ndarray) -> np.ndarray:
    """Yaw (radians, atan2 from +x) of the body's forward direction: joints (..., 24, 3) -> (...,).

    Forward is perpendicular to the hip line in the ground plane, pointing where the toes point:
    ``forward = (left_hip - right_hip) x z``.
    """
    joints = np.asarray(joints)
    if joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (..., 24, 3), got {joints.shape}")
    hip = joints[..., 1, :] - joints[..., 2, :]
    fwd_x, fwd_y = hip[..., 1], -hip[..., 0]  # (hx, hy, hz) x (0, 0, 1) = (hy, -hx, 0)
    return np.arctan2(fwd_y, fwd_x)
