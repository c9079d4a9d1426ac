"""Seam blending between episodes: the new frames continue the context's velocity.

An episode's first generated frame need not continue the last context frames (the model sees
only k context frames and the inpainting is weak), so the joints jump at every seam. The jump is
the first new frame's offset from the constant-velocity extrapolation of the context,
``o = (2 c[-1] - c[-2]) - n[0]``; it is added to the new frames with a weight that falls from 1
to 0 over ``frames`` frames with zero slope at both ends (smoothstep, as in inertialization,
Bollo 2016 "Inertialization: high-performance animation transitions"), so the first new frame
continues the context's velocity and the blend ends without a kink. Only new frames change.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.easing import smoothstep

__all__ = ["SeamConfig", "blend_seam", "seam_weights", "crossfade_weights"]


@dataclass(frozen=True)
class SeamConfig:
    """enabled: blend the seam jump out; frames: new frames over which it is blended (0 = off)."""

    enabled: bool = True
    frames: int = 3

    def __post_init__(self) -> None:
        if self.frames < 0:
            raise ValueError(f"seam frames must be >= 0, got {self.frames}")


def seam_weights(n: int, frames: int) -> np.ndarray:
    """(n,) weight of the seam offset at new frame i: 1 - smoothstep(i / frames), 0 from ``frames`` on."""
    if frames < 0:
        raise ValueError(f"frames must be >= 0, got {frames}")
    if frames == 0:
        return np.zeros(n)
    return 1.0 - smoothstep(np.arange(n) / frames)


def blend_seam(context: np.ndarray, new: np.ndarray, frames: int = 4) -> np.ndarray:
    """context (B, k >= 2, J, 3), new (B, n, J, 3) world m -> new frames with the seam offset
    blended out over ``frames`` frames (see the module doc); ``frames`` = 0 returns a copy."""
    context, new = np.asarray(context), np.asarray(new)
    if context.ndim != 4 or context.shape[1] < 2 or new.ndim != 4 or new.shape[::2] != context.shape[::2] \
            or new.shape[3] != context.shape[3]:
        raise ValueError(f"need context (B, k >= 2, J, 3) and new (B, n, J, 3), got {context.shape}, {new.shape}")
    expected = 2.0 * context[:, -1].astype(np.float64) - context[:, -2]
    offset = expected - new[:, 0]  # (B, J, 3)
    w = seam_weights(new.shape[1], frames)
    return (new + w[None, :, None, None] * offset[:, None]).astype(new.dtype)


def crossfade_weights(D: int) -> np.ndarray:
    """(D,) the later episode's weight on the D frames two overlapping episodes both make
    (``SamplerConfig.overlap``): smoothstep(i / (D + 1)), i = 1..D, rising from near 0 to near 1, so
    the motion leaves the earlier episode with its velocity and joins the later one without a kink."""
    if D < 0:
        raise ValueError(f"D must be >= 0 frames, got {D}")
    return smoothstep(np.arange(1, D + 1) / (D + 1))
