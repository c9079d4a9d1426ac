"""Scene-penetration term of the sampler's guidance: the scene's signed distance field
(``trumans.sample.scene_sdf.SceneSDF``) sampled at the predicted joints.

The term for joints x (.., 24, 3) world m is sum_j relu(r_j - sdf(x_j))^2 with the body's core
radius r_j (``trumans.contacts.rule.JOINT_CORE_RADIUS``): a joint closer to a surface than its body
is thick is pushed out along the field's gradient (as the collision term of scene-aware sampling,
e.g. the penetration guidance of Huang et al. 2023 "Diffusion-based generation, optimization, and
planning in 3D scenes", Eq. 10). The field excludes the floor: that is the foot cleanup's job
(``trumans.sample.cleanup.foot``).
"""
from __future__ import annotations

import torch

from trumans.contacts.rule import JOINT_CORE_RADIUS

from trumans.sample.scene_sdf import SceneSDF

__all__ = ["penetration_loss"]


def penetration_loss(sdf: SceneSDF, joints: torch.Tensor) -> torch.Tensor:
    """joints (..., 24, 3) world m -> scalar sum_j relu(r_j - sdf(x_j))^2, m^2 (module doc)."""
    r = torch.as_tensor(JOINT_CORE_RADIUS, dtype=joints.dtype, device=joints.device)
    return (torch.relu(r - sdf(joints)) ** 2).sum()
