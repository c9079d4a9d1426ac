"""Easing curves shared by the jobs' blends and fades."""
from __future__ import annotations

import numpy as np

__all__ = ["smoothstep"]


def smoothstep(x: np.ndarray) -> np.ndarray:
    """3x^2 - 2x^3 of x clipped to [0, 1] (any shape; float64): 0 and 1 with zero slope at both ends."""
    s = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)
