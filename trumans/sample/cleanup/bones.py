"""Bone projection: the joints put back on the body's bone lengths after each episode.

The network draws joint positions, not a skeleton, so its bones stretch and shrink from frame to
frame (``raw_bone_length_cv``). From the root down, each joint moves along its bone's direction to
the right distance from its (already moved) parent: the pelvis stays, the bones keep their
directions and get the body's lengths, so the body keeps its proportions over minutes.

The trunk's rigid parts keep their shape too (``rigid_trunk``): a joint with several children (the
pelvis with both hips and spine1, spine3 with the neck and both collars) holds them as one rigid
piece, as a skeleton does - the children's rest offsets at the body's lengths, turned by the
rotation that best fits the network's vectors (Kabsch). Without it the hip width and the collar
spacing swing by centimetres from frame to frame, and a rigid-skeleton export (BVH, GLB) cannot
reproduce the joints.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.ik.fit import kabsch
from trumans.skeleton import NUM_JOINTS, PARENTS, children, rest_offsets

__all__ = ["BoneProjectionConfig", "bone_lengths_of", "project_bones"]


@dataclass(frozen=True)
class BoneProjectionConfig:
    """enabled: project the joints onto the body's bone lengths (off: the network's own bones);
    rigid_trunk: the pelvis-hips-spine1 and spine3-neck-collars pieces keep their rest shape."""

    enabled: bool = True
    rigid_trunk: bool = True


def bone_lengths_of(joints: np.ndarray) -> np.ndarray:
    """joints (..., 24, 3) -> (..., 24) length of each joint's bone to its parent (root 0), m."""
    par = np.asarray(PARENTS)
    d = joints[..., 1:, :] - joints[..., par[1:], :]
    return np.concatenate([np.zeros(joints.shape[:-2] + (1,)), np.linalg.norm(d, axis=-1)], axis=-1)


# joints whose children move as one rigid piece: pelvis (hips, spine1), spine3 (neck, collars)
RIGID_PIECES: dict[int, tuple[int, ...]] = {j: tuple(children(j)) for j in range(NUM_JOINTS) if len(children(j)) > 1}


def rigid_directions(joints: np.ndarray, lengths: np.ndarray) -> dict[int, np.ndarray]:
    """For each joint of ``RIGID_PIECES``: its children's offsets (..., K, 3) m as one rigid piece, the
    rest offsets at bone ``lengths`` (24,) m turned by the rotation that best fits the vectors from
    the joint to its children in ``joints`` (..., 24, 3)."""
    rest = rest_offsets()
    out = {}
    for p, kids in RIGID_PIECES.items():
        k = list(kids)
        a = rest[k] / np.linalg.norm(rest[k], axis=-1, keepdims=True) * np.asarray(lengths)[k, None]  # (K, 3)
        b = np.asarray(joints, np.float64)[..., k, :] - np.asarray(joints, np.float64)[..., p, None, :]
        R = kabsch(np.broadcast_to(a, b.shape), b)  # (..., 3, 3): b ~ R a
        out[p] = np.einsum("...ij,kj->...ki", R, a)
    return out


def project_bones(joints: np.ndarray, lengths: np.ndarray, rigid_trunk: bool = False) -> np.ndarray:
    """Put joints (..., 24, 3) world m on a skeleton with bone ``lengths`` (24,) m: from the root
    down, each joint moves along its bone's direction to the right distance from its (already
    moved) parent; with ``rigid_trunk`` the children of a ``RIGID_PIECES`` joint take their rigid
    piece's offsets (``rigid_directions``). Returns float32."""
    out = np.array(joints, dtype=np.float64, copy=True)
    rigid = rigid_directions(joints, lengths) if rigid_trunk else {}
    for j in range(1, NUM_JOINTS):  # topological order (parents come first)
        p = PARENTS[j]
        if p in rigid:
            out[..., j, :] = out[..., p, :] + rigid[p][..., RIGID_PIECES[p].index(j), :]
            continue
        d = joints[..., j, :] - joints[..., p, :]
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        out[..., j, :] = out[..., p, :] + lengths[j] * d / np.maximum(n, 1e-9)
    return out.astype(np.float32)
