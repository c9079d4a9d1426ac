"""Goal term of the sampler's guidance (OmniControl, Xie et al. 2024, "spatial guidance").

An inpainted goal (2 of L x F entries) is followed only weakly, so the guidance pulls the predicted
body onto it: for a pelvis goal the hip midpoint's x, y at the last frame onto the subgoal and, with
a goal heading (sitting down), the hip line (left minus right hip, ``hip_width`` long) onto the
heading's left direction, weighted ``heading_weight`` against the position; for a hand goal that
joint's 3D position at its frame. Costs are squared distances in metres in the episode's canonical
frame. Goals with ``guide=False`` are inpainted only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from trumans.model.conditions import subgoal_to_canonical

from trumans.sample.guidance.base import GuidanceInputs, Prediction

__all__ = ["GoalTermConfig", "GoalTerm"]


@dataclass(frozen=True)
class GoalTermConfig:
    """enabled: pull the body onto its episode goal; heading_weight: the hip-line (heading) term
    against the position term (6: with the default schedule's 6 guided updates, 3 left a body lying
    90-150 deg off its bed's lie direction; docs/results.md, "Sampling speed")."""

    enabled: bool = True
    heading_weight: float = 6.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.heading_weight) and self.heading_weight >= 0):
            raise ValueError(f"heading_weight must be a finite number >= 0, got {self.heading_weight}")


class GoalTerm:
    """sum over samples and targets of |W x0[frame, columns] - target|^2 (module doc)."""

    def __init__(self, targets: list[tuple[int, int, list[int], torch.Tensor, torch.Tensor]]) -> None:
        self.targets = targets  # (sample, frame, feature columns, W, target)

    @classmethod
    def build(cls, config: GoalTermConfig, inputs: GuidanceInputs) -> GoalTerm | None:
        """The term for ``inputs``' guided goals (and the earlier episode's ``carried`` ones, at
        their frames), or None when none is guided."""
        lay, L, cond = inputs.layout, inputs.L, inputs.cond
        hips = lay.position_index("left_hip", (0, 1)) + lay.position_index("right_hip", (0, 1))
        mean_w = torch.tensor([[0.5, 0, 0.5, 0], [0, 0.5, 0, 0.5]])
        diff_w = torch.tensor([[1.0, 0, -1.0, 0], [0, 1.0, 0, -1.0]])
        targets = []

        def add(b: int, g, frame: int, local: np.ndarray) -> None:
            """Targets of goal g of sample b at episode ``frame``, its point in canonical metres."""
            local = torch.as_tensor(local, dtype=torch.float32)
            if g.joint != "pelvis":
                targets.append((b, frame, lay.position_index(g.joint), torch.eye(3), local))
                return
            targets.append((b, frame, hips, mean_w, local[:2]))
            if g.heading is not None:
                h = g.heading - float(cond.yaw[b])  # canonical heading
                left = torch.tensor([-np.sin(h), np.cos(h)], dtype=torch.float32) * inputs.hip_width
                targets.append((b, frame, hips, config.heading_weight * diff_w, config.heading_weight * left))

        def canonical(b: int, point) -> np.ndarray:
            p = np.zeros(3)
            p[:len(point)] = point
            return subgoal_to_canonical(p, cond.origin[b], cond.yaw[b])

        for b, g in enumerate(inputs.goals):
            if not g.guide:
                continue
            if g.joint == "pelvis":  # the episode's subgoal, at its last frame
                add(b, g, L - 1, cond.subgoal_canonical()[b, :2])
            else:
                add(b, g, g.frame % L, canonical(b, g.point))
        for b, goals in enumerate(inputs.carried):  # the earlier episode's goals on the frames made again
            for g in goals:
                if g.guide:
                    add(b, g, g.frame % L, canonical(b, g.point))
        dev = inputs.device
        return cls([(b, f, cols, W.to(dev), t.to(dev)) for b, f, cols, W, t in targets]) if targets else None

    def loss(self, prediction: Prediction) -> torch.Tensor:
        loss = prediction.x0.new_zeros(())
        for b, f, cols, W, target in self.targets:
            loss = loss + ((W @ prediction.features(b, f, cols) - target) ** 2).sum()
        return loss
