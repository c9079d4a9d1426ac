"""Contact intervals: per-frame contact labels as (joint, object, start, end) intervals, half-open
``[start, end)`` (the runs of ``trumans.intervals``)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from trumans.intervals import runs

__all__ = ["JointContact", "joint_contact_intervals"]


class JointContact(NamedTuple):
    """Joint ``joint`` touches object ``obj`` on frames ``[start, end)``."""

    joint: int
    obj: str
    start: int
    end: int


def joint_contact_intervals(object_index: np.ndarray, names: list[str], max_gap: int = 0,
                            min_len: int = 1) -> list[JointContact]:
    """Contact intervals of every joint with every object: object_index (T, J) int, index into
    ``names`` of the object each joint touches (-1 = none; ``ContactResult.object_index``) ->
    runs per (joint, object) (``runs(.., max_gap, min_len)``), ordered by joint, object index, start."""
    idx = np.asarray(object_index)
    if idx.ndim != 2:
        raise ValueError(f"object_index must be (T, J) int, got shape {idx.shape}")
    if idx.size and idx.max() >= len(names):
        raise ValueError(f"object_index refers to object {int(idx.max())} but names has {len(names)} entries")
    out: list[JointContact] = []
    for j in range(idx.shape[1]):
        for k in np.unique(idx[:, j]):
            if k < 0:
                continue
            out += [JointContact(j, names[k], s, e) for s, e in runs(idx[:, j] == k, max_gap, min_len)]
    return out
