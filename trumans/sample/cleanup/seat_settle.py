"""Seat settle: a seated pelvis is put on its seat, whatever the guidance left (the safety issue's
"seated pelvis within 5 cm of its seat on every seated frame").

The seat guidance term pulls the predicted pelvis of every seated frame (a ``sit`` phase) to
``seat height + sit offset`` (``trumans.sample.guidance.seat``), but a pull is soft: at the first
frames of a sit phase, with the descent still finishing, the default sampler left the demo's pelvis
5.3 cm above its seat. This step is the hard constraint: on every seated new frame whose pelvis is
more than ``tolerance`` m from its target height, the whole body moves vertically by the excess
(so the pelvis ends ``tolerance`` from the target), and the move fades out over ``blend`` frames on
either side into the unseated frames of the episode (smoothstep, no step in the descent). The feet
may go under the floor by that much; the foot cleanup after it lifts them and re-solves the legs
from the moved hips (``foot.py``), as a person lowers the pelvis onto a chair with the feet
planted. The committed context frames stay as they are.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.easing import smoothstep
from trumans.skeleton import JOINT_INDEX

from trumans.sample.cleanup.common import episode_joints

__all__ = ["SeatSettleConfig", "settle_on_seat"]

PELVIS = JOINT_INDEX["pelvis"]


@dataclass(frozen=True)
class SeatSettleConfig:
    """enabled: put a seated pelvis on its seat; tolerance: m the pelvis may stay from its target
    height; blend: frames over which the move fades into the unseated neighbours."""

    enabled: bool = True
    tolerance: float = 0.02
    blend: int = 3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.tolerance) and self.tolerance >= 0):
            raise ValueError(f"seat tolerance must be a finite number >= 0 m, got {self.tolerance}")
        if self.blend < 0:
            raise ValueError(f"seat blend must be >= 0 frames, got {self.blend}")


def settle_on_seat(joints: np.ndarray, target_z: np.ndarray, fixed: int,
                   config: SeatSettleConfig = SeatSettleConfig()) -> np.ndarray:
    """joints (B, T, 24, 3) world m; target_z (B, T) the seated pelvis height, m (NaN on frames
    that are not seated); fixed: leading context frames kept -> joints with every seated new frame's
    pelvis within ``config.tolerance`` of its target height (module doc)."""
    J = episode_joints(joints, fixed)
    target = np.asarray(target_z, dtype=np.float64)
    if target.shape != J.shape[:2]:
        raise ValueError(f"target_z must be (B, T) = {J.shape[:2]}, got {target.shape}")
    seated = np.isfinite(target)
    seated[:, :fixed] = False
    if not seated.any():
        return J
    miss = np.where(seated, target - J[..., PELVIS, 2], 0.0)  # (B, T) m, + = the pelvis is too low
    move = np.sign(miss) * np.maximum(np.abs(miss) - config.tolerance, 0.0)
    T = J.shape[1]
    t = np.arange(T)
    for b in range(J.shape[0]):
        frames = np.flatnonzero(seated[b])
        if not frames.size or config.blend == 0:
            continue
        # unseated frames take the nearest seated frame's move, faded by their distance from it
        dist = np.abs(t[:, None] - frames[None])  # (T, n)
        near = frames[np.argmin(dist, axis=1)]
        fade = 1.0 - smoothstep(dist.min(axis=1) / (config.blend + 1))
        move[b] = np.where(seated[b], move[b], move[b, near] * fade)
    move[:, :fixed] = 0.0
    J[..., 2] += move[..., None]
    return J
