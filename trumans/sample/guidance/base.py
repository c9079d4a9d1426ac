"""The guidance protocol: what a term sees of the predicted clean motion, and what it gives back.

At every guided denoising update the sampler asks the denoiser for the clean episode ``x0`` it
predicts from ``x_t`` and hands it to each configured term as a ``Prediction``; every term returns a
scalar cost (m^2) and the sampler moves ``x_t`` against the gradient of their sum
(``trumans.sample.sampler.EpisodeSampler._guided_sample``). Terms are built once per episode from
``GuidanceInputs`` (the episode's frame, goals and scene); a term with nothing to do in an episode
is not built. Coordinates: ``x0`` holds each sample's episode in its canonical frame (the episode's
first frame: origin on the floor under the pelvis, facing +x; ``trumans.model.episodes``), so a
target given there (a goal) compares with ``features``; ``world_joints`` maps the new frames'
joints to the z-up world (for the scene).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
import torch
from einops import rearrange

from trumans.model.conditions import EpisodeCondition
from trumans.model.episodes import FeatureLayout
from trumans.skeleton import NUM_JOINTS

from trumans.scenes.sdf import SceneSDF

if TYPE_CHECKING:
    from trumans.sample.episode_goal import Goal

__all__ = ["Prediction", "GuidanceTerm", "GuidanceInputs", "canonical_to_world"]


def canonical_to_world(cond: EpisodeCondition) -> tuple[torch.Tensor, torch.Tensor]:
    """The episodes' canonical -> world maps as (rotation (B, 3, 3), origin (B, 3)) float32 for row
    vectors: ``world = canonical @ rotation + origin`` (the rotation is the yaw's transpose)."""
    c, s = np.cos(cond.yaw), np.sin(cond.yaw)
    rotation = torch.as_tensor(np.stack([np.stack([c, s, 0 * c], -1), np.stack([-s, c, 0 * c], -1),
                                         np.stack([0 * c, 0 * c, 1 + 0 * c], -1)], 1), dtype=torch.float32)
    return rotation, torch.as_tensor(cond.origin, dtype=torch.float32)


@dataclass(frozen=True)
class Prediction:
    """The predicted clean episode at one guidance update. x0: (B, L, F) float32 normalised
    features, canonical frame (its gradient is what the guidance follows); mean, std: (F,) the
    normaliser's; k: context frames; rotation (B, 3, 3), origin (B, 3): ``canonical_to_world``."""

    x0: torch.Tensor
    mean: torch.Tensor
    std: torch.Tensor
    k: int
    rotation: torch.Tensor
    origin: torch.Tensor

    def features(self, b: int, frames, columns) -> torch.Tensor:
        """Denormalised features of sample ``b`` at ``frames`` (an index or a LongTensor) and
        ``columns`` (a list of feature columns): positions in m, canonical frame."""
        return self.x0[b, frames, columns] * self.std[columns] + self.mean[columns]

    def world_joints(self) -> torch.Tensor:
        """(B, L - k, 24, 3) float32: the new frames' joint positions, m, z-up world."""
        n = NUM_JOINTS * 3
        pos = self.x0[:, self.k:, :n] * self.std[:n] + self.mean[:n]
        return rearrange(pos, "b l (j c) -> b l j c", c=3) @ self.rotation[:, None] + self.origin[:, None, None]


@dataclass(frozen=True)
class GuidanceInputs:
    """What the terms of one episode are built from. cond: the episode condition (canonical
    frames); goals: one ``Goal`` per sample; layout: the feature layout; L, k: episode and context
    frames; hip_width: m, the body's hip line length (heading term); sdf: the scene's field for the
    penetration term, or None; carried: per sample, goals of the earlier episode whose frame this
    episode makes again (``SamplerConfig.overlap``), ``frame`` counted in this episode (pelvis too);
    device: the sampler's torch device."""

    cond: EpisodeCondition
    goals: tuple[Goal, ...]
    layout: FeatureLayout
    L: int
    k: int
    hip_width: float
    sdf: SceneSDF | None
    carried: tuple[tuple[Goal, ...], ...] = ()  # per sample: the earlier episode's goals due in this one's frames
    device: torch.device | str = "cpu"  # where the sampler's tensors live: the terms build theirs there


class GuidanceTerm(Protocol):
    """One cost of the spatial guidance, built for one episode."""

    def loss(self, prediction: Prediction) -> torch.Tensor:
        """The scalar cost (m^2, summed over the batch) of ``prediction``; differentiable in ``prediction.x0``."""
        ...
