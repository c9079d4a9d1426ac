"""Per-frame contact-predictor labels of a labelled sequence (training and evaluation).

- hand contact: the hand's wrist or index1 joint is in contact (``Sequence.contacts``: the
  TRUMANS rule, any object including static ones and the floor);
- interaction class (``CLASSES``): the dof of a dynamic scene object that moves within
  ``dilate_s`` of the frame (slide | hinge | free), else "none";
- ``moving_intervals``: the [start, end) frame ranges in which an object moves (its ground-truth
  interactions), gaps up to ``max_gap`` frames bridged.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d

from trumans.sequence import Sequence

from trumans.intervals import runs
from trumans.track.predictor import CLASSES, HAND_JOINTS, HANDS

__all__ = ["hand_labels", "object_moving", "moving_intervals", "sequence_labels"]

_MOVE_EPS = 1e-4  # m (or rotation-matrix entry) per frame: below this an object is at rest


def hand_labels(contacts: np.ndarray) -> np.ndarray:
    """(T, 24) bool per-joint contacts -> (T, 2) bool (left, right) hand contacts."""
    c = np.asarray(contacts, dtype=bool)
    if c.ndim != 2 or c.shape[1] != 24:
        raise ValueError(f"contacts must be (T, 24) bool, got {c.shape}")
    return np.stack([c[:, list(HAND_JOINTS[h])].any(axis=1) for h in HANDS], axis=1)


def object_moving(pose: np.ndarray) -> np.ndarray:
    """(T, 4, 4) poses -> (T,) bool: the pose changes between frame t and t + 1."""
    p = np.asarray(pose, dtype=np.float64)
    if len(p) < 2:
        return np.zeros(len(p), bool)
    step = np.abs(np.diff(p, axis=0)).reshape(len(p) - 1, -1).max(1)
    return np.r_[step > _MOVE_EPS, False]


def moving_intervals(pose: np.ndarray, max_gap: int = 15) -> np.ndarray:
    """(N, 2) half-open frame ranges in which the object moves (gaps <= max_gap frames bridged)."""
    r = np.asarray(runs(object_moving(pose), max_gap=max_gap), dtype=np.int64).reshape(-1, 2)
    r[:, 1] = np.minimum(r[:, 1] + 1, len(pose))  # the pose reached at the last step's end
    return r


def sequence_labels(seq: Sequence, dofs: dict[str, str], dilate_s: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """hands (T, 2) bool and classes (T,) int64 into CLASSES (module doc). dofs: object name ->
    dof in the sequence's scene."""
    if seq.contacts is None:
        raise ValueError("the sequence has no per-joint contacts; contact labels need a labelled sequence")
    hands = hand_labels(seq.contacts)
    classes = np.zeros(seq.num_frames, np.int64)
    size = 2 * int(round(dilate_s * seq.fps)) + 1
    for name, track in seq.objects.items():
        dof = dofs.get(name, "static")
        if dof not in CLASSES or dof == "none":
            continue
        moving = maximum_filter1d(object_moving(track.pose).astype(np.uint8), size=size) > 0
        classes[moving] = CLASSES.index(dof)
    return hands, classes
