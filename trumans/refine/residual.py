"""Keep the tracked input's low frequencies: the filter's output plus the low-passed residual
(a post-step of the HOI filter; our addition, not I'm-HOI's).

The network's estimate is good where the tracked input is bad in the short term (jitter, spikes,
bursts, gaps: high frequencies) and poor where the input is good in the long term: its own error
is slow (a pose a little off for a second, a limb held a few cm away). A smoother of the input has
the opposite profile. So the output takes the high frequencies from the filter and the low ones
from the input: with r = tracked - filtered per joint and coordinate,

    out = filtered + G_sigma(r),

r's gaps (missing and frozen entries) filled linearly in time first, so a gap is filled with the
filter's shape bent to meet the tracked frames on either side; G a Gaussian of ``sigma_frames``.
The smoothing runs on the difference, not on the motion, so the detail the filter drew stays.

A planted foot must not take the input's low-passed jitter along (it would slide by centimetres a
second and hide the stance from the foot lock after it): with ``hold_feet``, on the stances of the
filter's own feet (``body_drift.stance_mask``) each foot joint's added residual is its mean over the
stance, faded in and out over ``fade_s`` (``foot_lock.stance_corrections``).

First of the post-steps: the steps after it read the body it returns. Chosen on corpus train clips
(docs/refine.md): sigma 2-4 frames give the same errors within 0.3 mm; a running median before the
Gaussian (against spikes) did not help. Units: metres; joints (T, 24, 3) z-up world; frames at the
filter's rate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.refine.body_drift import DriftConfig, stance_mask
from trumans.refine.foot_lock import stance_corrections
from trumans.refine.frame import fill_missing_joints
from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS

__all__ = ["ResidualConfig", "keep_low_frequencies"]


@dataclass(frozen=True)
class ResidualConfig:
    """enabled: whether the post-step runs; sigma_frames: the Gaussian's std (frames at the filter's
    rate); hold_feet: planted foot joints keep one residual per stance, faded over ``fade_s``
    seconds; stance: how stances are found (the body-drift fit's detection; only the detection is read)."""

    enabled: bool = True
    sigma_frames: float = 3.0
    hold_feet: bool = True
    fade_s: float = 0.2
    stance: DriftConfig = DriftConfig()

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma_frames) and self.sigma_frames > 0):
            raise ValueError(f"residual sigma_frames must be > 0, got {self.sigma_frames}")
        if not (np.isfinite(self.fade_s) and self.fade_s >= 0):
            raise ValueError(f"residual fade_s must be >= 0, got {self.fade_s}")
        if not self.stance.enabled:
            raise ValueError("residual stance is the stance detection only: its enabled must stay true")


def keep_low_frequencies(filtered: np.ndarray, tracked: np.ndarray, fps: float,
                         config: ResidualConfig = ResidualConfig()) -> np.ndarray:
    """filtered (T, 24, 3) m (finite), tracked (T, 24, 3) m (NaN = missing) at ``fps`` -> filtered +
    G(tracked - filtered), planted feet held (module docstring): (T, 24, 3) float64. A joint never
    tracked keeps the filter's."""
    F, X = np.asarray(filtered, np.float64), np.asarray(tracked, np.float64)
    if F.ndim != 3 or F.shape[1:] != (NUM_JOINTS, 3) or X.shape != F.shape:
        raise ValueError(f"filtered and tracked joints must both be (T, {NUM_JOINTS}, 3), got {F.shape} and {X.shape}")
    if not np.isfinite(F).all():
        raise ValueError("the filtered joints must be finite")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    r = fill_missing_joints(X - F)
    r = np.where(np.isfinite(r), r, 0.0)  # a joint never tracked: nothing to keep
    low = gaussian_filter1d(r, config.sigma_frames, axis=0, mode="nearest")
    if config.hold_feet and len(F) >= 2:
        planted = stance_mask(F, fps, config.stance)
        if planted.any():
            low[:, FOOT_JOINTS] += stance_corrections(low, planted, config.fade_s * fps)
    return F + low
