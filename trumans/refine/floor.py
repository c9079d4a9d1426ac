"""Height from the floor (a post-step of the HOI filter, the last one).

Horizontal drift cannot be seen in a sequence without a scene, but height can: the floor is z = 0
(conventions), and a planted foot stands on it. A tracker's constant height offset (a calibration
error of a few centimetres) therefore passes through the network, whose windows are put in a frame
that keeps the tracked height, and feet end up under the floor.

``floor_offset`` reads the offset from the feet's contacts with the importers' rule
(``trumans.importers.joint_maps.floor_height``: the 5th percentile over frames of the lowest foot
joint, ankles and toe bases, minus the toe base's rest height: where the feet touch the floor), on
the *tracked input*, gaps filled and low-passed (Gaussian, ``smooth_frames``) so its jitter does not
pull the percentile down: the filter's own feet stand 1-3 cm off the truth's on some clean-height
clips (its training layout), and reading them moved the whole body by that (real test clips: 26.1 ->
28.2 mm). Only planted feet were tried first (``body_drift.stance_mask``), but a foot at rest is not
always on the floor (lying with the feet on the bed, seated with a heel up: +7 and -4 cm on clean
held-out clips). An offset under ``dead_band_m`` is left alone (read on inputs without an offset:
-0.8 cm on average under the training corruption, 0.0 on clean clips; with a 2-6 cm offset it is
read to 0.07 cm).
``keep_above_floor`` then removes the offset and lifts the body, as one piece, on the frames where
a foot joint would still be under the floor (a smooth envelope of the needed lift, never below it),
so no foot joint ends under z = 0.

Units: metres; joints (T, 24, 3) z-up world.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from trumans.importers.joint_maps import floor_height
from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS

from trumans.refine.tracked import TrackedBody, as_tracked_body

__all__ = ["FloorConfig", "floor_offset", "keep_above_floor"]


@dataclass(frozen=True)
class FloorConfig:
    """enabled: whether the post-step runs (``trumans.refine.post_steps``); dead_band_m: a smaller
    read offset is left alone; max_offset_m: a larger one is the motion's (a clip on stairs or a
    bed), not the tracker's, and is not removed; lift_s: the lift envelope's width (s); smooth_frames:
    the Gaussian low-pass (sigma, frames) of the tracked input before the offset is read."""

    enabled: bool = True
    dead_band_m: float = 0.015
    max_offset_m: float = 0.5
    lift_s: float = 0.2
    smooth_frames: float = 2.0

    def __post_init__(self) -> None:
        if not 0 <= self.dead_band_m <= self.max_offset_m or self.lift_s < 0 or self.smooth_frames < 0:
            raise ValueError(f"floor needs 0 <= dead_band_m <= max_offset_m and lift_s >= 0, got "
                             f"{self.dead_band_m}, {self.max_offset_m}, {self.lift_s}")


def _check(joints: np.ndarray) -> np.ndarray:
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3) or not np.isfinite(J).all():
        raise ValueError(f"joints must be finite (T, {NUM_JOINTS}, 3), got {J.shape}")
    return J


def floor_offset(tracked: np.ndarray | TrackedBody, config: FloorConfig = FloorConfig()) -> float:
    """How far (m) the tracked body stands above (> 0) or under (< 0) the floor z = 0, read from its
    feet: tracked joints (T, 24, 3) m (NaN = missing; or their ``TrackedBody``; gaps filled linearly,
    then low-passed). 0 inside the dead band and beyond ``max_offset_m``."""
    body = as_tracked_body(tracked)
    if not body.seen.any():
        return 0.0
    X = body.filled
    if config.smooth_frames > 0:
        X = gaussian_filter1d(X, config.smooth_frames, axis=0, mode="nearest")
    h = floor_height(X)
    return h if config.dead_band_m <= abs(h) <= config.max_offset_m else 0.0


def keep_above_floor(joints: np.ndarray, fps: float, offset_m: float = 0.0,
                     config: FloorConfig = FloorConfig()) -> np.ndarray:
    """Joints (T, 24, 3) m -> the same moved down by ``offset_m`` (``floor_offset`` of the input) and
    lifted, as one piece, where a
    foot joint (ankles, toe bases) would be under z = 0: the lift is a smooth envelope (a running
    maximum over ``lift_s``, then a Gaussian of a third of it) of the needed lift and never below it."""
    J = _check(joints).copy()
    J[..., 2] -= offset_m
    need = np.maximum(0.0, -J[:, list(FOOT_JOINTS), 2].min(1))  # (T,)
    if need.any():
        width = max(1, int(round(config.lift_s * fps)))
        env = gaussian_filter1d(maximum_filter1d(need, 2 * width + 1, mode="nearest"), width / 3, mode="nearest")
        J[..., 2] += np.maximum(env, need)[:, None]
    return J
