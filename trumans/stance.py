"""Foot stances: the frames a foot (or a foot joint) is planted, from its speed and height.

The one stance detector of the project: the generator's foot cleanup (``trumans.sample.cleanup.foot``,
per foot, speed and height with hysteresis) and the HOI filter's body-drift fit and foot lock
(``trumans.refine.body_drift``, per foot joint, speed only, a shortest stance) are two settings of
``planted``. A contact starts where the foot is low and slow (``enter_*``) and ends only where it is
high or fast (``exit_*``); between the two thresholds the last decided state holds (hysteresis), so
a foot hovering at a threshold does not flicker.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import label

__all__ = ["planted"]


def _drop_short_runs(mask: np.ndarray, min_frames: float) -> np.ndarray:
    """(N, T) bool -> the same with runs of True shorter than ``min_frames`` frames cleared."""
    runs, _ = label(mask, structure=[[0, 0, 0], [1, 1, 1], [0, 0, 0]])  # runs along time, per row
    length = np.bincount(runs.ravel())
    return mask & (length[runs] >= min_frames)


def planted(speed: np.ndarray, height: np.ndarray | None = None, *, enter_speed: float,
            exit_speed: float | None = None, enter_height: float = np.inf, exit_height: float = np.inf,
            min_frames: float = 0.0, initial: np.ndarray | bool = False) -> np.ndarray:
    """(..., T, K) bool: foot k planted at frame t.

    speed: (..., T, K) m/s; height: (..., T, K) m above the foot's resting height (None: speed
    only); enter_speed / enter_height: a contact starts where speed < enter_speed and height <
    enter_height; exit_speed (default enter_speed) / exit_height: it ends where speed > exit_speed
    or height > exit_height; in between, the last decided state holds. initial: (..., K) bool, the
    state before frame 0. min_frames: planted runs shorter than this many frames are dropped."""
    speed = np.asarray(speed, dtype=np.float64)
    exit_speed = enter_speed if exit_speed is None else exit_speed
    if not (0 <= enter_speed <= exit_speed and enter_height <= exit_height):
        raise ValueError(f"need 0 <= enter_speed <= exit_speed and enter_height <= exit_height, got "
                         f"{enter_speed}, {exit_speed}, {enter_height}, {exit_height}")
    if speed.ndim < 2:
        raise ValueError(f"speed must be (..., T, K), got shape {speed.shape}")
    h = np.full(speed.shape, -np.inf) if height is None else np.asarray(height, dtype=np.float64)
    if h.shape != speed.shape:
        raise ValueError(f"height {h.shape} and speed {speed.shape} must have one shape (..., T, K)")
    *lead, T, K = speed.shape
    v = np.moveaxis(speed, -2, -1).reshape(-1, T)  # (N, T), N = prod(lead) * K
    hh = np.moveaxis(h, -2, -1).reshape(-1, T)
    init = np.broadcast_to(np.asarray(initial, dtype=bool), (*lead, K)).reshape(-1)
    enter = (hh < enter_height) & (v < enter_speed)
    leave = (hh > exit_height) | (v > exit_speed)
    idx = np.where(enter | leave, np.arange(T)[None], -1)
    last = np.maximum.accumulate(idx, axis=1)  # the last decisive frame at or before t
    state = np.take_along_axis(enter, np.maximum(last, 0), axis=1)
    out = np.where(last >= 0, state, init[:, None])
    if min_frames > 0:
        out = _drop_short_runs(out, min_frames)
    return np.moveaxis(out.reshape(*lead, K, T), -1, -2)
