"""The tracked input's body as the input guards read it, computed once per clip.

The gate (``gate.py``), the bone lengths (``bones.py``, through ``gate.noise_level``) and the floor
(``floor.py``) all read the tracked joints with their gaps filled, and the first two the residual
of a local cubic fit; ``TrackedBody`` holds them so that one clip's post-steps fill and fit once
(``post_steps.RefinedClip.tracked_body``; the pipeline hands over the gaps it already filled for the
network's condition). Units: metres; joints (T, 24, 3) z-up world.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.ndimage import median_filter
from scipy.signal import savgol_filter

from trumans.skeleton import NUM_JOINTS

from trumans.refine.frame import fill_missing_joints

__all__ = ["TrackedBody", "cubic_residual", "as_tracked_body", "column_median"]


def cubic_residual(filled: np.ndarray) -> np.ndarray:
    """|x - SG(7, 3)(x)| per frame and joint (T, 24) m of gap-filled joints (T, 24, 3) (the residual
    of a 7-frame cubic Savitzky-Golay fit, ``gate``'s jitter measure; T < 7: 0)."""
    if len(filled) < 7:
        return np.zeros(filled.shape[:2])
    return np.linalg.norm(filled - savgol_filter(filled, 7, 3, axis=0, mode="interp"), axis=-1)


@dataclass(frozen=True)
class TrackedBody:
    """joints: (T, 24, 3) float64 m, NaN = missing; filled: the same with each coordinate's gaps
    filled linearly in time, ends held (``frame.fill_missing_joints``); seen: (T, 24) bool, the
    joint observed; residual: (T, 24) m, ``cubic_residual`` of ``filled``."""

    joints: np.ndarray
    filled: np.ndarray
    seen: np.ndarray
    residual: np.ndarray
    _running: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def read(cls, tracked: np.ndarray, filled: np.ndarray | None = None) -> TrackedBody:
        """From tracked joints (T, 24, 3) m (NaN = missing); ``filled``: the same joints with their gaps
        already filled by ``fill_missing`` (default: filled here)."""
        J = np.asarray(tracked, dtype=np.float64)
        if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"joints must be (T, {NUM_JOINTS}, 3), got {J.shape}")
        if filled is None:
            F = fill_missing_joints(J)
        else:
            F = np.asarray(filled, dtype=np.float64)
            if F.shape != J.shape or not np.isfinite(F).all():
                raise ValueError(f"filled joints must be finite and shaped like the tracked {J.shape}, got {F.shape}")
        return cls(J, F, np.isfinite(J).all(-1), cubic_residual(F))

    @cached_property
    def residual_median(self) -> np.ndarray:
        """(24,) m each joint's median ``residual`` over its observed frames (NaN for a joint never
        observed): ``np.nanmedian`` of the residual with unobserved frames NaN, by one sort (nanmedian
        goes column by column when there are NaNs); read by the gate and the bone lengths alike."""
        return column_median(self.residual, self.seen)


    def running_median(self, window: int) -> np.ndarray:
        """(T, 24) m the running median of ``residual`` over ``window`` frames (mirrored ends), a missing
        frame counting as its joint's ``residual_median`` (0 for a joint never observed); computed once
        per window length (the gate and the residual's gap fill read the same one)."""
        if window not in self._running:
            med = self.residual_median if self.seen.any() else np.zeros(NUM_JOINTS)
            rm = np.where(self.seen, self.residual, np.nan_to_num(med)[None])
            # one joint at a time: scipy's 1-D median filter is several times faster than its n-D one, same values
            self._running[window] = np.stack([median_filter(rm[:, j], size=window, mode="mirror")
                                              for j in range(rm.shape[1])], axis=1) if rm.size else rm
        return self._running[window]


def column_median(values: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """(T, J) values, (T, J) bool -> (J,) median of each column's ``seen`` entries (the mean of the two
    middle ones for an even count; NaN for none), as ``np.nanmedian(np.where(seen, values, nan), 0)``."""
    v = np.sort(np.where(seen, values, np.inf), axis=0)
    k = seen.sum(0)
    cols = np.arange(v.shape[1])
    lo, hi = v[np.maximum(k - 1, 0) // 2, cols], v[k // 2 - (k == 0), cols]
    return np.where(k > 0, np.where(k % 2 == 1, lo, (lo + hi) / 2), np.nan)


def as_tracked_body(tracked: np.ndarray | TrackedBody) -> TrackedBody:
    """``tracked`` itself if it is a ``TrackedBody``, else ``TrackedBody.read(tracked)``."""
    return tracked if isinstance(tracked, TrackedBody) else TrackedBody.read(tracked)
