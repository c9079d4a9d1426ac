"""What the cleanup steps share: the checked float64 copy of an episode, the smoothstep ramp, the
arms and their two-bone IK, the push-out radii. Steps import these from here, never from each other.

Joints are ``(B, T, 24, 3)`` world m, z up; ``fixed`` is the number of leading context frames that
a step keeps as committed.
"""
from __future__ import annotations

import numpy as np

from trumans.contacts.rule import JOINT_CORE_RADIUS, JOINT_RADIUS
from trumans.ik.limb import two_bone_positions
from trumans.rotations import least_rotation
from trumans.skeleton import JOINT_INDEX, SEAT

__all__ = ["episode_joints", "ARMS", "arm_ik", "push_radii"]

# (shoulder, elbow, wrist, index1) per arm; side 0 = left, 1 = right
ARMS = tuple(tuple(JOINT_INDEX[f"{side}_{n}"] for n in ("shoulder", "elbow", "wrist", "index1"))
             for side in ("left", "right"))


def episode_joints(joints: np.ndarray, fixed: int) -> np.ndarray:
    """A float64 copy of an episode's joints (B, T, 24, 3), checked with its ``fixed`` context
    frames (0 <= fixed <= T): the common input of the sampling-time cleanups."""
    J = np.array(joints, dtype=np.float64, copy=True)
    if J.ndim != 4 or J.shape[2:] != (24, 3):
        raise ValueError(f"joints must be (B, T, 24, 3), got {J.shape}")
    if not 0 <= fixed <= J.shape[1]:
        raise ValueError(f"fixed must be in [0, {J.shape[1]}] frames, got {fixed}")
    return J


def arm_ik(J: np.ndarray, arm: tuple[int, int, int, int], goal: np.ndarray, lengths: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two-bone IK of one arm (``ARMS[side]``) of joints J (..., 24, 3) world m with the wrist to
    ``goal`` (..., 3): the shoulder stays, the elbow in the plane of the network's bend
    (``trumans.ik.limb.two_bone_positions``), bone ``lengths`` (24,) m kept. Returns (elbow, wrist,
    hand): the new elbow and wrist (..., 3) and the wrist -> index1 vector turned with the forearm
    (the least rotation from the old to the new forearm direction)."""
    sh, el, wr, ix = arm
    new_el, new_wr = two_bone_positions(J[..., sh, :], J[..., el, :], goal, float(lengths[el]), float(lengths[wr]))
    turn = least_rotation(J[..., wr, :] - J[..., el, :], new_wr - new_el)
    return new_el, new_wr, np.einsum("...ij,...j->...i", turn, J[..., ix, :] - J[..., wr, :])


def push_radii(margin: float = 0.0) -> np.ndarray:
    """(24,) m: how close each joint may come to the scene in the push-outs: the contact radius
    for the seat joints (pelvis, hips: the training data rests their skin on seats), the core
    radius elsewhere (``trumans.contacts.rule``), plus ``margin``."""
    r = JOINT_CORE_RADIUS.copy()
    r[list(SEAT)] = JOINT_RADIUS[list(SEAT)]
    return r + margin
