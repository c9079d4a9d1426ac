"""An episode's goal (the ``M_goal`` mask of TRUMANS §4.1): what the controller asks of the next
episode, read by the sampler (inpainting) and by the guidance terms."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Goal"]


@dataclass(frozen=True)
class Goal:
    """An episode goal (M_goal): ``joint`` 'pelvis' with ``point`` (2,) world xy at the last
    frame, or a joint name with ``point`` (3,) world m at episode frame ``frame``."""

    point: tuple[float, ...]
    joint: str = "pelvis"
    frame: int = -1
    guide: bool = True  # the goal guidance term applies (``SamplerConfig.goal_guidance``); else inpainting only
    heading: float | None = None  # world heading (rad) the body should have at the goal (sitting down)
    pelvis_z: tuple[tuple[int, float], ...] = ()  # (episode frame, world pelvis height m): seated frames
