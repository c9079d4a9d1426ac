"""Objects at rest: one pose per rest, pooled over the whole rest (a post-step of the HOI filter).

An object moves only while a hand drives it and otherwise stays where it is (iReplica §4.3). A
window of the filter (~2 s) cannot tell a tracker's slow drift (knots every second or so) from a
slow move, but over a whole rest the drift averages out. So, on the filtered sequence at the
filter's rate:

- detection (``rest_mask``): the filtered object's speed, smoothed over ``smooth_s``, with
  hysteresis: a frame moves when it lies in a run above ``lo_m_s`` that reaches ``hi_m_s``; moving
  runs are padded by ``pad_s``; rests shorter than ``min_rest_s`` count as moving;
- pooling (``pool_rest``): each rest's translation becomes the mean of the tracked translations
  observed in it, and its rotation the chordal mean of the tracked rotations observed in it that lie
  within ``max_rot_deg`` of the filtered rotations' mean (flips left out; that mean itself where
  fewer than 3 remain). Tracked rather than filtered rotations: the filter leans on the object IMU,
  whose constant bias (~3°) no pooling removes. The moving frames keep their filtered motion, shifted by the translation
  change interpolated linearly between the neighbouring rests (held at the ends), so the path stays
  continuous.

Not in I'm-HOI (whose filter sees one window); measured in the README's filter section.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation, label, uniform_filter1d
from scipy.spatial.transform import Rotation

from trumans.contacts.intervals import runs
from trumans.rotations import matrix_to_6d, sixd_to_matrix

from .frame import FRAME_DIM, OBJ_R, OBJ_T

__all__ = ["RestConfig", "rest_mask", "pool_rest"]


@dataclass(frozen=True)
class RestConfig:
    """Speeds in m/s, durations in s (module doc). The defaults are the best of a grid on the
    dataset's val split (lo 0.1-0.2, hi 0.25-0.4, smooth 0.15-0.5 s, pad 0-0.2 s; README)."""

    lo_m_s: float = 0.2
    hi_m_s: float = 0.25
    smooth_s: float = 0.3
    pad_s: float = 0.0
    min_rest_s: float = 0.33
    max_rot_deg: float = 45.0

    def __post_init__(self) -> None:
        if not 0 < self.lo_m_s <= self.hi_m_s:
            raise ValueError(f"need 0 < lo_m_s <= hi_m_s, got {self.lo_m_s}, {self.hi_m_s}")
        if not 0 < self.max_rot_deg <= 180:
            raise ValueError(f"max_rot_deg must be in (0, 180], got {self.max_rot_deg}")
        if min(self.smooth_s, self.pad_s, self.min_rest_s) < 0:
            raise ValueError(f"smooth_s, pad_s and min_rest_s must be >= 0, got {self.smooth_s}, {self.pad_s}, "
                             f"{self.min_rest_s}")


def rest_mask(obj_t: np.ndarray, fps: float, config: RestConfig = RestConfig()) -> np.ndarray:
    """obj_t: (T, 3) filtered object translations (m, finite) at ``fps`` -> (T,) bool, True where
    the object is at rest (module doc)."""
    p = np.asarray(obj_t, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
        raise ValueError(f"object translations must be (T, 3) with T >= 2, got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("object translations must be finite (fill or drop missing frames first)")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    v = np.gradient(p, axis=0) * fps
    k = max(1, int(round(config.smooth_s * fps)))
    speed = np.linalg.norm(uniform_filter1d(v, k, axis=0, mode="nearest"), axis=-1)
    lab, _ = label(speed > config.lo_m_s)
    fast = np.unique(lab[speed > config.hi_m_s])
    moving = np.isin(lab, fast[fast > 0])
    pad = int(round(config.pad_s * fps))
    if pad and moving.any():
        moving = binary_dilation(moving, iterations=pad)
    rest = np.zeros(len(p), dtype=bool)
    for a, b in runs(~moving, min_len=max(1, int(np.ceil(config.min_rest_s * fps)))):
        rest[a:b] = True
    return rest


def _rest_rotation(filtered6: np.ndarray, tracked6: np.ndarray, max_deg: float) -> np.ndarray:
    """One rest's rotation (6,) from its filtered (N, 6) and tracked (N, 6, NaN = missing)
    rotations: the chordal mean (scipy's ``Rotation.mean``) of the tracked ones within ``max_deg``
    of the filtered ones' mean, else that mean."""
    ref = Rotation.from_matrix(sixd_to_matrix(filtered6)).mean()
    seen = tracked6[np.isfinite(tracked6).all(-1)]
    if len(seen) >= 3:
        rots = Rotation.from_matrix(sixd_to_matrix(seen))
        near = (rots * ref.inv()).magnitude() <= np.radians(max_deg)
        if near.sum() >= 3:
            ref = rots[near].mean()
    return matrix_to_6d(ref.as_matrix())


def pool_rest(filtered: np.ndarray, tracked: np.ndarray, fps: float,
              config: RestConfig = RestConfig()) -> np.ndarray:
    """filtered: (T, 235) the filter's output, tracked: (T, 235) its input on the same frames (NaN =
    missing) -> (T, 235) a copy with one object pose per rest (module doc). Rests with fewer than 3
    observed tracked translations are left as filtered; so is a sequence without an observed object."""
    out = np.array(filtered, dtype=np.float64, copy=True)
    tr = np.asarray(tracked, dtype=np.float64)
    if out.ndim != 2 or out.shape[1] != FRAME_DIM or tr.shape != out.shape:
        raise ValueError(f"filtered and tracked must both be (T, {FRAME_DIM}), got {out.shape} and {tr.shape}")
    if len(out) < 2 or not np.isfinite(out[:, OBJ_T]).all() or not np.isfinite(tr[:, OBJ_T]).any():
        return out.astype(filtered.dtype)
    seen = np.isfinite(tr[:, OBJ_T]).all(-1)
    offset = np.full((len(out), 3), np.nan)
    for a, b in runs(rest_mask(out[:, OBJ_T], fps, config)):
        ok = seen[a:b]
        if ok.sum() < 3:
            continue
        offset[a:b] = tr[a:b, OBJ_T][ok].mean(0) - out[a:b, OBJ_T]
        out[a:b, OBJ_R] = _rest_rotation(out[a:b, OBJ_R], tr[a:b, OBJ_R], config.max_rot_deg)[None]
    have = np.isfinite(offset[:, 0])
    if have.any():
        t = np.arange(len(out))
        out[:, OBJ_T] += np.stack([np.interp(t, t[have], offset[have, i]) for i in range(3)], -1)
    return out.astype(filtered.dtype)
