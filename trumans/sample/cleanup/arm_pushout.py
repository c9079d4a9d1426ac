"""Arm push-out: a hand still in the scene after the body push-out is moved out by arm IK.

The body push-out (``trumans.sample.cleanup.scene_pushout``) moves the whole body by one slow, smooth offset; a
hand that swings into a table while walking past it, or into a wall when a drink starts facing
it, is in by more than the trunk may move (the default room's demo left a hand 6 cm in a wall).
After the body push-out, for each arm and new frame:

1. the push ``p_t``: for the wrist and the index1, back along the line from the shoulder to the
   joint to where that line first comes within ``r_j + margin`` of the scene (``r_j``: the core
   radius, as the body push-out's; the field of ``trumans.sample.guidance.penetration``), the longer of
   the two; 0 for a joint that is not in, or whose shoulder is. Not along the field's gradient:
   a hand through a thin wall or table top is past its middle, where the gradient points on;
2. an envelope in time, so that the arm eases in and out: the push of largest norm within
   ``spread`` frames of each frame, then a Gaussian of sigma ``spread / 2`` cut at ``spread`` (an
   isolated push keeps ~95 % of its size; frames farther than ``2 spread`` stay), faded in over
   ``spread`` frames after the context (whose frames stay: no jump at the seam);
3. the wrist goes to ``W + p``; elbow and wrist are re-solved by two-bone IK
   (``trumans.sample.cleanup.common.arm_ik``: shoulder fixed, the elbow in the plane of the network's bend, bone
   lengths kept) and the hand (index1) turns with the forearm.

Repeated ``iters`` times (the hand may still touch after the first). Frames with a reach weight
> 0 (the plan's hand phases, ``trumans.sample.cleanup.reach``: the hand is meant to touch a handle) are
left to the reach cleanup, which runs after this. Works on joint positions, like the other
cleanups (rotations for export are fitted afterwards).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import gaussian_filter1d

from trumans.easing import smoothstep
from trumans.sample.cleanup.common import ARMS, arm_ik, episode_joints, push_radii
from trumans.scenes.sdf import SceneSDF

__all__ = ["ArmPushConfig", "arm_push", "push_arms_out"]


@dataclass(frozen=True)
class ArmPushConfig:
    """enabled: run the arm push-out (it needs the scene); margin: m added to the core radii (as
    the body push-out's); spread: frames over which a push eases in and out; iters: push-and-solve
    rounds; samples: points along the shoulder-to-joint line searched for where it enters (step 1)."""

    enabled: bool = True
    margin: float = 0.01
    spread: int = 3
    iters: int = 2
    samples: int = 64

    def __post_init__(self) -> None:
        if not (np.isfinite(self.margin) and self.margin >= 0):
            raise ValueError(f"margin must be a finite number >= 0 m, got {self.margin}")
        if self.spread < 1 or self.iters < 1 or self.samples < 2:
            raise ValueError(f"spread and iters must be >= 1 and samples >= 2, got {self.spread}, {self.iters}, "
                             f"{self.samples}")


def arm_push(joints: np.ndarray, sdf: SceneSDF, margin: float = 0.01, samples: int = 64) -> np.ndarray:
    """joints (B, T, 24, 3) world m -> (B, T, 2, 3) the wrist push of each (left, right) arm, m
    (step 1 of the module doc): for the wrist and the index1, the way back along the line from
    the shoulder to the joint, to the last of ``samples`` points before the line first comes
    within the joint's radius of the scene; the longer of the two; 0 for a joint that is not
    itself within its radius or whose shoulder is. Back toward the shoulder
    rather than along the field's gradient: a hand through a thin wall or table top is past the
    middle, where the gradient points on through."""
    r = push_radii(margin)
    J = np.asarray(joints, dtype=np.float64)
    hands = np.array([[a[2], a[3]] for a in ARMS])  # (2 arms, wrist / index1)
    sh = J[:, :, [a[0] for a in ARMS]][:, :, :, None]  # (B, T, 2, 1, 3)
    x = J[:, :, hands]  # (B, T, 2, 2, 3)
    s = np.linspace(0.0, 1.0, samples)
    q = sh[..., None, :] + s[:, None] * (x - sh)[..., None, :]  # (B, T, 2, 2, S, 3)
    d = sdf(torch.as_tensor(q, dtype=torch.float32)).numpy().astype(np.float64)
    inside = d < r[hands][..., None]  # (B, T, 2, 2, S)
    first = np.where(inside.any(-1), inside.argmax(-1), samples)  # first sample within the radius
    back = np.take_along_axis(q, np.clip(first - 1, 0, samples - 1)[..., None, None], -2)[..., 0, :]
    # only a joint that is itself in, and not when the shoulder is (the body push-out's job)
    push = np.where((inside[..., -1] & (first > 0))[..., None], back - x, 0.0)
    longer = np.linalg.norm(push, axis=-1).argmax(-1)  # (B, T, 2)
    return np.take_along_axis(push, longer[..., None, None], -2)[..., 0, :]


def _envelope(push: np.ndarray, fixed: int, spread: int) -> np.ndarray:
    """push (B, T, 2, 3) -> the eased push (step 2): largest-norm push within ``spread`` frames,
    Gaussian-smoothed, faded in after frame ``fixed - 1`` (0 there and before)."""
    B, T = push.shape[:2]
    pad = np.pad(push, ((0, 0), (spread, spread), (0, 0), (0, 0)))
    win = sliding_window_view(pad, 2 * spread + 1, axis=1)  # (B, T, 2, 3, W)
    pick = np.linalg.norm(win, axis=3).argmax(-1)  # (B, T, 2)
    peak = np.take_along_axis(win, pick[:, :, :, None, None], -1)[..., 0]
    smooth = gaussian_filter1d(peak, spread / 2.0, axis=1, mode="constant", truncate=2.0)  # within 2 * spread
    return smooth * smoothstep((np.arange(T) - (fixed - 1)) / spread)[None, :, None, None]


def push_arms_out(joints: np.ndarray, lengths: np.ndarray, sdf: SceneSDF, fixed: int = 0,
                  keep: np.ndarray | None = None, config: ArmPushConfig = ArmPushConfig()) -> np.ndarray:
    """joints (B, T, 24, 3) world m on bone ``lengths`` (24,) -> copy with the hands moved out of the
    scene by arm IK (module doc). Frames < ``fixed`` (the context) are kept; keep (B, T, 2) bool:
    frames of an arm left as they are (the plan's hand phases)."""
    J = episode_joints(joints, fixed)
    B, T = J.shape[:2]
    if keep is not None and np.shape(keep) != (B, T, 2):
        raise ValueError(f"keep must be (B, T, 2) = {(B, T, 2)}, got {np.shape(keep)}")
    free = np.ones((B, T, 2), bool) if keep is None else ~np.asarray(keep, bool)
    free[:, :fixed] = False
    for _ in range(config.iters):
        push = np.where(free[..., None], arm_push(J, sdf, config.margin, config.samples), 0.0)
        if not push.any():
            break
        push = np.where(free[..., None], _envelope(push, fixed, config.spread), 0.0)
        for side, arm in enumerate(ARMS):
            act = (np.linalg.norm(push[:, :, side], axis=-1) > 1e-6)[..., None]
            if not act.any():
                continue
            _, el, wr, ix = arm
            new_el, new_wr, hand = arm_ik(J, arm, J[:, :, wr] + push[:, :, side], lengths)
            J[:, :, el] = np.where(act, new_el, J[:, :, el])
            J[:, :, wr] = np.where(act, new_wr, J[:, :, wr])
            J[:, :, ix] = np.where(act, new_wr + hand, J[:, :, ix])
    return J.astype(np.asarray(joints).dtype)
