"""Attach the pinned pelvis: the first cleanup step, on the network's own output.

A pelvis goal pins the pelvis x, y at the episode's last frame (``M_goal``, inpainted), which
need not be where the generated body is: a model that lags leaves that pelvis torn from the hips,
and the frame becomes the next episode's context. So the last frame's pelvis x, y is put back on
the body, keeping the previous frame's offset from the hip midpoint (the goal error is then
measured on the body, not on the pin).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.skeleton import HIPS, JOINT_INDEX

__all__ = ["AttachPelvisConfig", "attach_pinned_pelvis"]

PELVIS = JOINT_INDEX["pelvis"]


@dataclass(frozen=True)
class AttachPelvisConfig:
    """enabled: put a pinned pelvis back on the body (off: keep the inpainted pin)."""

    enabled: bool = True


def attach_pinned_pelvis(joints: np.ndarray, pinned: np.ndarray) -> np.ndarray:
    """joints (B, L, 24, 3) world m, L >= 2; pinned (B,) bool: samples whose pelvis x, y was pinned
    at the last frame -> copy with those samples' last-frame pelvis x, y at the previous frame's
    offset from the hip midpoint (module doc)."""
    out = np.array(joints, copy=True)
    pinned = np.asarray(pinned, dtype=bool)
    if out.ndim != 4 or out.shape[1] < 2 or out.shape[2:] != (24, 3) or pinned.shape != out.shape[:1]:
        raise ValueError(f"need joints (B, L >= 2, 24, 3) and pinned (B,), got {out.shape} and {pinned.shape}")
    for b in np.flatnonzero(pinned):
        mid = out[b][:, list(HIPS)].mean(axis=1)  # (L, 3)
        out[b, -1, PELVIS, :2] = mid[-1, :2] + out[b, -2, PELVIS, :2] - mid[-2, :2]
    return out
