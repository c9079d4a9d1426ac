"""Bone projection: the joints put back on the body's bone lengths after each episode.

The network draws joint positions, not a skeleton, so its bones stretch and shrink from frame to
frame (``raw_bone_length_cv``). From the root down, each joint moves along its bone's direction to
the right distance from its (already moved) parent: the pelvis stays, the bones keep their
directions and get the body's lengths, so the body keeps its proportions over minutes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.skeleton import NUM_JOINTS, PARENTS

__all__ = ["BoneProjectionConfig", "bone_lengths_of", "project_bones"]


@dataclass(frozen=True)
class BoneProjectionConfig:
    """enabled: project the joints onto the body's bone lengths (off: the network's own bones)."""

    enabled: bool = True


def bone_lengths_of(joints: np.ndarray) -> np.ndarray:
    """joints (..., 24, 3) -> (..., 24) length of each joint's bone to its parent (root 0), m."""
    par = np.asarray(PARENTS)
    d = joints[..., 1:, :] - joints[..., par[1:], :]
    return np.concatenate([np.zeros(joints.shape[:-2] + (1,)), np.linalg.norm(d, axis=-1)], axis=-1)


def project_bones(joints: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Put joints (..., 24, 3) world m on a skeleton with bone ``lengths`` (24,) m: from the root
    down, each joint moves along its bone's direction to the right distance from its (already
    moved) parent. Returns float32."""
    out = np.array(joints, dtype=np.float64, copy=True)
    for j in range(1, NUM_JOINTS):  # topological order (parents come first)
        p = PARENTS[j]
        d = joints[..., j, :] - joints[..., p, :]
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        out[..., j, :] = out[..., p, :] + lengths[j] * d / np.maximum(n, 1e-9)
    return out.astype(np.float32)
