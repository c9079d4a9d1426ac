"""Retarget motion between skeletons that share our 24-joint topology but differ in bone lengths.

Local rotations are copied unchanged; the root trajectory is scaled by the leg-length ratio
(so strides match the new legs), and each frame is shifted vertically so that the lowest foot is as
high above the floor as it was on the source skeleton (feet stay on the floor, jumps stay jumps).
"""
from __future__ import annotations

import numpy as np

from trumans.skeleton import ANKLES, FOOT_JOINTS, KNEES, NUM_JOINTS, forward_kinematics

__all__ = ["rescale_motion", "scale_offsets", "leg_length"]

_LEG = [*KNEES, *ANKLES]  # the thigh and shin bones end at these joints
_FEET = list(FOOT_JOINTS)


def _check_offsets(off: np.ndarray, name: str) -> np.ndarray:
    off = np.asarray(off, dtype=np.float64)
    if off.shape != (NUM_JOINTS, 3):
        raise ValueError(f"{name} must be (24, 3) rest offsets, got {off.shape}")
    if not np.isfinite(off).all():
        raise ValueError(f"{name} contains NaN or inf")
    return off


def leg_length(offsets: np.ndarray) -> float:
    """Mean thigh + shin length (m) of rest ``offsets (24, 3)``."""
    off = _check_offsets(offsets, "offsets")
    return float(np.linalg.norm(off[_LEG], axis=-1).sum() / 2)


def scale_offsets(offsets: np.ndarray, scale: float | np.ndarray) -> np.ndarray:
    """Offsets (24, 3) with every bone scaled by ``scale`` (scalar or (24,) per joint's bone; entry
    0 is ignored). The root entry (rest pelvis position) is moved vertically so that the rest pose's
    feet stay at the same height above the floor."""
    off = _check_offsets(offsets, "offsets")
    s = np.asarray(scale, dtype=np.float64)
    if s.ndim == 0:
        s = np.full(NUM_JOINTS, float(s))
    if s.shape != (NUM_JOINTS,):
        raise ValueError(f"scale must be a scalar or (24,), got {s.shape}")
    if not (np.isfinite(s).all() and (s[1:] > 0).all()):
        raise ValueError(f"scale must be positive and finite, got {s}")
    out = off.copy()
    out[1:] *= s[1:, None]
    eye = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    old = forward_kinematics(eye, off[0], off)[0][_FEET, 2].min()
    new = forward_kinematics(eye, off[0], out)[0][_FEET, 2].min()
    out[0, 2] += old - new
    return out


def rescale_motion(
    rot: np.ndarray,
    root: np.ndarray,
    src_offsets: np.ndarray,
    dst_offsets: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Move a motion from the ``src_offsets`` skeleton to the ``dst_offsets`` one.

    rot: (T, 24, 3, 3) local rotations (copied); root: (T, 3) pelvis positions, m, z-up;
    offsets: (24, 3) rest offsets (m). Returns ``(rot (T, 24, 3, 3), root (T, 3))``: the root's
    horizontal and vertical motion scaled by dst/src leg length, then per frame lifted or lowered so
    the lowest foot joint keeps its source height."""
    rot = np.asarray(rot, dtype=np.float64)
    root = np.asarray(root, dtype=np.float64)
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"rot must be (T, 24, 3, 3), got {rot.shape}")
    if root.shape != (rot.shape[0], 3):
        raise ValueError(f"root must be ({rot.shape[0]}, 3), got {root.shape}")
    src = _check_offsets(src_offsets, "src_offsets")
    dst = _check_offsets(dst_offsets, "dst_offsets")
    ls, ld = leg_length(src), leg_length(dst)
    if ls <= 0 or ld <= 0:
        raise ValueError(f"leg lengths must be positive (src {ls:.3f} m, dst {ld:.3f} m)")
    ratio = ld / ls
    new_root = root * ratio
    if len(rot):
        Js, _ = forward_kinematics(rot, root, src)
        Jd, _ = forward_kinematics(rot, new_root, dst)
        new_root[:, 2] += Js[:, _FEET, 2].min(-1) - Jd[:, _FEET, 2].min(-1)
    return rot.copy(), new_root

