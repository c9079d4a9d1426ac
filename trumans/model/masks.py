"""Inpainting masks over episode features (TRUMANS §4.1): ``M_trans`` and ``M_goal``.

A mask is ``(L, F)`` or ``(B, L, F)`` bool over the episode's features (``trumans.model.episodes.FeatureLayout``);
``True`` marks a *given* entry: it enters the denoiser clean (never noised), is excluded from the
loss, and is overwritten with its given value at every sampling step.

- ``M_trans``: the first ``k`` frames, every feature (continuation from the previous episode).
- ``M_goal``: the pelvis x, y at the last frame (navigation subgoal), or one hand joint's 3D
  position at a chosen frame (interaction subgoal).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from .episodes import PELVIS, FeatureLayout
from trumans.skeleton import JOINT_INDEX

__all__ = ["transition_mask", "pelvis_goal_mask", "joint_goal_mask", "MaskSampler", "HAND_JOINTS"]

HAND_JOINTS: tuple[int, ...] = (JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"])


def transition_mask(length: int, layout: FeatureLayout, k: int) -> torch.Tensor:
    """M_trans: (L, F) bool, True on every feature of frames 0..k-1."""
    if not 0 <= k <= length:
        raise ValueError(f"k must be in [0, L={length}], got {k}")
    m = torch.zeros(length, layout.dim, dtype=torch.bool)
    m[:k] = True
    return m


def pelvis_goal_mask(length: int, layout: FeatureLayout) -> torch.Tensor:
    """M_goal for navigation: (L, F) bool, True on the pelvis x, y of the last frame."""
    m = torch.zeros(length, layout.dim, dtype=torch.bool)
    m[length - 1, layout.position_index(PELVIS, (0, 1))] = True
    return m


def joint_goal_mask(length: int, layout: FeatureLayout, joint: int | str, frame: int) -> torch.Tensor:
    """M_goal for interaction: (L, F) bool, True on ``joint``'s 3D position at ``frame``."""
    if not -length <= frame < length:
        raise ValueError(f"frame must be in [-{length}, {length}), got {frame}")
    m = torch.zeros(length, layout.dim, dtype=torch.bool)
    m[frame, layout.position_index(joint)] = True
    return m


@dataclass(frozen=True)
class MaskSampler:
    """Random training masks: M_trans with probability ``p_trans``; then pelvis-xy goal with
    ``p_goal_pelvis``, else a hand-joint 3D goal (left/right wrist, frame in [k, L)) with
    ``p_goal_hand``, else no goal."""

    length: int
    layout: FeatureLayout
    k: int = 2
    p_trans: float = 0.9
    p_goal_pelvis: float = 0.6
    p_goal_hand: float = 0.2

    def __post_init__(self) -> None:
        for name in ("p_trans", "p_goal_pelvis", "p_goal_hand"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1], got {p}")
        if self.p_goal_pelvis + self.p_goal_hand > 1.0 + 1e-9:
            raise ValueError("p_goal_pelvis + p_goal_hand must be <= 1")
        if not 0 <= self.k < self.length:
            raise ValueError(f"k must be in [0, L), got k={self.k}, L={self.length}")

    def __call__(self, batch: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """(B, L, F) bool masks, vectorised over the batch."""
        L, F = self.length, self.layout.dim
        u = torch.rand(batch, 2, generator=generator)
        trans = u[:, 0] < self.p_trans
        pelvis = u[:, 1] < self.p_goal_pelvis
        hand = (u[:, 1] >= self.p_goal_pelvis) & (u[:, 1] < self.p_goal_pelvis + self.p_goal_hand)
        m = transition_mask(L, self.layout, self.k)[None] & trans[:, None, None]
        m = m | (pelvis_goal_mask(L, self.layout)[None] & pelvis[:, None, None])
        which = torch.randint(0, len(HAND_JOINTS), (batch,), generator=generator)
        frame = torch.randint(self.k, L, (batch,), generator=generator)
        hand_cols = torch.tensor([self.layout.position_index(j) for j in HAND_JOINTS])  # (hands, 3)
        cols = hand_cols[which]  # (B, 3) position features of the chosen hand
        hand_m = torch.zeros(batch, L, F, dtype=torch.bool)
        b = torch.arange(batch)[:, None].expand(-1, 3)
        hand_m[b, frame[:, None].expand(-1, 3), cols] = True
        return m | (hand_m & hand[:, None, None])
