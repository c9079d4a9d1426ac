"""Scene-penetration term of the sampler's guidance: the scene's signed distance field
(``trumans.scenes.sdf.SceneSDF``) sampled at the predicted joints.

The term for joints x (.., 24, 3) world m is sum_j relu(r_j - sdf(x_j))^2 with the body's core
radius r_j (``trumans.contacts.rule.JOINT_CORE_RADIUS``): a joint closer to a surface than its body
is thick is pushed out along the field's gradient (as the collision term of scene-aware sampling,
e.g. the penetration guidance of Huang et al. 2023 "Diffusion-based generation, optimization, and
planning in 3D scenes", Eq. 10). The field excludes the floor: that is the foot cleanup's job
(``trumans.sample.cleanup.foot``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from trumans.contacts.rule import JOINT_CORE_RADIUS

from trumans.sample.guidance.base import GuidanceInputs, Prediction
from trumans.scenes.sdf import SceneSDF

__all__ = ["penetration_loss", "PenetrationTermConfig", "PenetrationTerm"]


@dataclass(frozen=True)
class PenetrationTermConfig:
    """enabled: push the predicted joints out of the scene (needs the scene); weight: this term
    against the goal's position term."""

    enabled: bool = True
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.weight) and self.weight >= 0):
            raise ValueError(f"penetration weight must be a finite number >= 0, got {self.weight}")


def penetration_loss(sdf: SceneSDF, joints: torch.Tensor) -> torch.Tensor:
    """joints (..., 24, 3) world m -> scalar sum_j relu(r_j - sdf(x_j))^2, m^2 (module doc)."""
    r = torch.as_tensor(JOINT_CORE_RADIUS, dtype=joints.dtype, device=joints.device)
    return (torch.relu(r - sdf(joints)) ** 2).sum()


class PenetrationTerm:
    """weight x ``penetration_loss`` of the new frames' predicted world joints."""

    def __init__(self, sdf: SceneSDF, weight: float) -> None:
        self.sdf, self.weight = sdf, weight

    @classmethod
    def build(cls, config: PenetrationTermConfig, inputs: GuidanceInputs) -> PenetrationTerm | None:
        """The term in ``inputs.sdf``, or None without a scene."""
        return None if inputs.sdf is None else cls(inputs.sdf, config.weight)

    def loss(self, prediction: Prediction) -> torch.Tensor:
        return self.weight * penetration_loss(self.sdf, prediction.world_joints())
