"""The 24-joint skeleton (SMPL-X body joints 0-21 + left/right index1), rest pose and forward kinematics.

Conventions (see docs/conventions.md): metres, z up, floor at z = 0. In the rest pose (all local rotations
identity) the body stands upright facing +x, its left side towards +y, feet on the floor.
``offsets[j]`` is joint j's rest position relative to its parent, expressed in the parent's frame.
FK: ``G[j] = G[parent] @ R_local[j]``, ``p[j] = p[parent] + G[parent] @ offsets[j]``; the root's
global rotation is ``R_local[0]`` and its position is the root translation.
"""
from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # torch is imported by whoever passes tensors; ``import trumans`` stays light
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
    "HIPS", "KNEES", "ANKLES", "FEET", "SHOULDERS", "ELBOWS", "WRISTS", "INDEX1", "FOOT_JOINTS", "FOOT_REST_HEIGHT",
    "HAND_JOINTS", "LEG_CHAINS", "SEAT", "SPINE", "TORSO",
    "LIMB_CHAINS",
    "HINGE_AXES",
    "DEPTH",
    "SUBTREE",
    "global_to_local",
    "bone_offsets",
    "offsets_from_pose",
    "offsets_from_joints",
    "rest_root",
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


def _idx(*names: str) -> tuple[int, ...]:
    return tuple(JOINT_INDEX[n] for n in names)


# Joint groups; paired groups are (left, right).
HIPS: tuple[int, int] = _idx("left_hip", "right_hip")
KNEES: tuple[int, int] = _idx("left_knee", "right_knee")
ANKLES: tuple[int, int] = _idx("left_ankle", "right_ankle")
FEET: tuple[int, int] = _idx("left_foot", "right_foot")  # toe-base joints
SHOULDERS: tuple[int, int] = _idx("left_shoulder", "right_shoulder")
ELBOWS: tuple[int, int] = _idx("left_elbow", "right_elbow")
WRISTS: tuple[int, int] = _idx("left_wrist", "right_wrist")
INDEX1: tuple[int, int] = _idx("left_index1", "right_index1")  # index-finger base, one per hand
FOOT_JOINTS: tuple[int, ...] = (*ANKLES, *FEET)  # what stands on the floor: left/right ankle, left/right toe base
# Resting heights (m) above the floor of FOOT_JOINTS on a standing body: ankle 0.08, toe base 0.04.
FOOT_REST_HEIGHT: np.ndarray = np.array([0.08, 0.08, 0.04, 0.04])
HAND_JOINTS: tuple[int, ...] = (*WRISTS, *INDEX1)  # left/right wrist, left/right index1
# Each leg's chain (hip, knee, ankle, toe base), left then right.
LEG_CHAINS: tuple[tuple[int, int, int, int], ...] = tuple(
    _idx(f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_foot") for s in ("left", "right"))
SEAT: tuple[int, ...] = _idx("pelvis", "left_hip", "right_hip")  # what rests on a seat
SPINE: tuple[int, ...] = _idx("spine1", "spine2", "spine3")
# The rigid trunk: pelvis, hips, spine, neck, head, collars and shoulders.
TORSO: tuple[int, ...] = _idx("pelvis", "left_hip", "right_hip", "spine1", "spine2", "spine3", "neck", "head",
                              "left_collar", "right_collar", "left_shoulder", "right_shoulder")
# Two-bone limbs: name -> (upper, middle (the hinge), end) joints.
LIMB_CHAINS: dict[str, tuple[int, int, int]] = {
    "left_arm": _idx("left_shoulder", "left_elbow", "left_wrist"),
    "right_arm": _idx("right_shoulder", "right_elbow", "right_wrist"),
    "left_leg": _idx("left_hip", "left_knee", "left_ankle"),
    "right_leg": _idx("right_hip", "right_knee", "right_ankle"),
}
# Flexion axis of each hinge joint (knee, elbow), in its own frame, which is also its parent's
# (rest) frame, since turning about the axis leaves it fixed: a positive turn bends the limb the
# anatomical way. Rest pose faces +x, left +y, z up: knees flex about +y (shin backwards); in the
# T-pose rest the elbows flex about -z (left, arm along +y) / +z (right), forearm forwards (+x).
HINGE_AXES: dict[int, np.ndarray] = {
    JOINT_INDEX["left_knee"]: np.array([0.0, 1.0, 0.0]),
    JOINT_INDEX["right_knee"]: np.array([0.0, 1.0, 0.0]),
    JOINT_INDEX["left_elbow"]: np.array([0.0, 0.0, -1.0]),
    JOINT_INDEX["right_elbow"]: np.array([0.0, 0.0, 1.0]),
}
for _axis in HINGE_AXES.values():
    _axis.flags.writeable = False


def children(j: int) -> list[int]:
    """Indices of joint j's children."""
    return [int(c) for c in np.flatnonzero(PARENTS == j)]


def _depth(j: int) -> int:
    d = 0
    while PARENTS[j] >= 0:
        j, d = int(PARENTS[j]), d + 1
    return d


def _subtree(j: int) -> np.ndarray:
    out, todo = [j], [j]
    while todo:
        kids = children(todo.pop())
        out += kids
        todo += kids
    return np.array(sorted(out), dtype=np.int64)


DEPTH: np.ndarray = np.array([_depth(j) for j in range(NUM_JOINTS)])  # bones to the root: pelvis 0 ... index1 8
SUBTREE: tuple[np.ndarray, ...] = tuple(_subtree(j) for j in range(NUM_JOINTS))  # joint j and its descendants, sorted


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


def _is_tensor(x) -> bool:
    """Whether ``x`` is a torch tensor (without importing torch: a tensor exists only once torch is)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


def bone_lengths(joints: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """joints (..., 24, 3) -> (..., 23) lengths of the bones to joints 1..23 (metres)."""
    if joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (..., 24, 3), got {tuple(joints.shape)}")
    d = joints[..., 1:, :] - joints[..., PARENTS[1:], :]
    if _is_tensor(d):
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
    is_torch = _is_tensor(rot)
    if offsets is None:
        offsets = rest_offsets()
    torch = sys.modules.get("torch")
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


def global_to_local(global_rot: np.ndarray) -> np.ndarray:
    """(..., 24, 3, 3) global joint rotations -> local ones: ``R_local[j] = G[parent]^T G[j]``
    (the root's is its global rotation)."""
    G = np.asarray(global_rot)
    if G.shape[-3:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"global_rot must be (..., 24, 3, 3), got {G.shape}")
    L = G.copy()
    L[..., 1:, :, :] = np.swapaxes(G[..., PARENTS[1:], :, :], -1, -2) @ G[..., 1:, :, :]
    return L


def bone_offsets(joints: np.ndarray, global_rot: np.ndarray) -> np.ndarray:
    """Per-frame bones in their parent's frame, ``G[parent]^T (p[j] - p[parent])``: joints
    (..., 24, 3) m with their global rotations (..., 24, 3, 3) -> (..., 24, 3) m (root entry 0).
    For a pose made by FK these are exactly the offsets it was made with."""
    P, G = np.asarray(joints, dtype=np.float64), np.asarray(global_rot, dtype=np.float64)
    if P.shape[-2:] != (NUM_JOINTS, 3) or G.shape != P.shape[:-1] + (3, 3):
        raise ValueError(f"joints must be (..., 24, 3) and global_rot (..., 24, 3, 3), got {P.shape} and {G.shape}")
    off = np.zeros_like(P)
    off[..., 1:, :] = np.einsum("...jik,...ji->...jk", G[..., PARENTS[1:], :, :], P[..., 1:, :] - P[..., PARENTS[1:], :])
    return off


def rest_root(offsets: np.ndarray) -> np.ndarray:
    """Rest root position (3,) for bone ``offsets (24, 3)``: under the rest pelvis in x, y = 0, and
    high enough that the rest pose's lowest foot joint is at the canonical rest foot height."""
    off = np.asarray(offsets, dtype=np.float64)
    rest, _ = forward_kinematics(np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy(), np.zeros(3), off)
    foot_h = REST_JOINTS[list(FEET), 2].min()
    return np.array([REST_JOINTS[0, 0], 0.0, foot_h - rest[list(FEET), 2].min()])


def offsets_from_pose(joints: np.ndarray, global_rot: np.ndarray) -> np.ndarray:
    """Rest offsets (24, 3) m of a posed clip: each bone in its parent's frame
    (``bone_offsets``) averaged over frames; the root entry is ``rest_root``.
    joints: (T, 24, 3) m; global_rot: (T, 24, 3, 3)."""
    P = np.asarray(joints, dtype=np.float64)
    if P.ndim != 3 or len(P) == 0:
        raise ValueError(f"joints must be (T, 24, 3) with T >= 1, got {P.shape}")
    off = bone_offsets(P, global_rot).mean(0)
    off[0] = rest_root(off)
    return off


def offsets_from_joints(joints: np.ndarray) -> np.ndarray:
    """Rest offsets (24, 3) for a clip of joint positions only: median bone lengths of ``joints
    (T, 24, 3)`` (m) along the rest directions of ``rest_offsets()``; root entry ``rest_root``."""
    P = np.asarray(joints, np.float64)
    if P.ndim != 3 or P.shape[1:] != (NUM_JOINTS, 3) or len(P) == 0:
        raise ValueError(f"joints must be (T, 24, 3) with T >= 1, got {P.shape}")
    L = np.median(np.linalg.norm(P[:, 1:] - P[:, PARENTS[1:]], axis=-1), axis=0)
    base = rest_offsets()
    off = np.zeros((NUM_JOINTS, 3))
    off[1:] = base[1:] / np.linalg.norm(base[1:], axis=-1, keepdims=True) * L[:, None]
    off[0] = rest_root(off)
    return off


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
