"""Seated pelvis height targets for the sampler's guidance (``Goal.pelvis_z``).

The generator alone leaves a seated pelvis ~14 cm off its seat. The plan knows the seat: a
``sit`` phase carries ``info['seat_height']`` (``trumans.sample.controller.compile_plan``), so every new
frame of an episode in a sit phase gets the target pelvis height ``seat height + offset``, the
offset being the pelvis height above the seat surface of this body in the training data
(``trumans.body.sit_offset``). The seat term of the sampler's guidance pulls the predicted pelvis
onto it (``SeatTerm``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from trumans.model.episodes import PELVIS

from trumans.sample.guidance.base import GuidanceInputs, Prediction

__all__ = ["seated_heights", "SEATED_KINDS", "SeatTermConfig", "SeatTerm"]

SEATED_KINDS = ("sit",)  # phase kinds whose frames are seated (sit_down / stand_up move the pelvis)


@dataclass(frozen=True)
class SeatTermConfig:
    """enabled: pull a seated pelvis to its seat's height; weight: this term (per frame) against
    the goal's position term; seated_kinds: the phase kinds whose frames are seated."""

    enabled: bool = True
    weight: float = 1.0
    seated_kinds: tuple[str, ...] = SEATED_KINDS

    def __post_init__(self) -> None:
        if not (np.isfinite(self.weight) and self.weight >= 0):
            raise ValueError(f"seat weight must be a finite number >= 0, got {self.weight}")


def seated_heights(phase_of: np.ndarray, phases: list, offset: float, k: int,
                   kinds: tuple[str, ...] = SEATED_KINDS) -> tuple[tuple[int, float], ...]:
    """phase_of: (L,) phase index per episode frame (-1 = none); phases: the compiled phases;
    offset: pelvis height above the seat, m; k: context frames (not targeted); kinds: the seated
    phase kinds -> ((frame, pelvis height m), ...) for the seated new frames."""
    out = []
    for f in np.flatnonzero(np.asarray(phase_of)[k:] >= 0) + k:
        p = phases[int(phase_of[f])]
        if p.kind in kinds and "seat_height" in p.info:
            out.append((int(f), float(p.info["seat_height"]) + offset))
    return tuple(out)


class SeatTerm:
    """sum over samples and seated frames of weight^2 (z_pelvis - target)^2, m^2 (canonical z = world z)."""

    def __init__(self, targets: list[tuple[int, torch.Tensor, list[int], torch.Tensor, torch.Tensor]]) -> None:
        self.targets = targets  # (sample, frames, the pelvis z column, W, target)

    @classmethod
    def build(cls, config: SeatTermConfig, inputs: GuidanceInputs) -> SeatTerm | None:
        """The term for the goals' seated frames (``Goal.pelvis_z``), or None without any."""
        col = inputs.layout.position_index(PELVIS, (2,))
        targets = []
        for b, g in enumerate(inputs.goals):
            if g.pelvis_z:
                frames = torch.as_tensor([f % inputs.L for f, _ in g.pelvis_z], dtype=torch.long, device=inputs.device)
                z = torch.as_tensor([h for _, h in g.pelvis_z], dtype=torch.float32, device=inputs.device)
                targets.append((b, frames, col, config.weight * torch.eye(len(z), device=inputs.device), config.weight * z))
        return cls(targets) if targets else None

    def loss(self, prediction: Prediction) -> torch.Tensor:
        loss = prediction.x0.new_zeros(())
        for b, frames, col, W, target in self.targets:
            loss = loss + ((W @ prediction.features(b, frames, col) - target) ** 2).sum()
        return loss
