"""IK targets that keep the joint-contact offset, faded in/out and blended (TRUMANS appendix B.5).

- A1-A2: a joint in contact with a changed object at ``v_m`` gets the target ``l' = l + v`` with
  ``v = v'_m - v_m`` (one offset per contact interval: the mean over the interval).
- A3: around the interval the offset fades linearly, ``w(t) = max(0, 1 - d(t)/W)`` with ``d`` the
  distance in frames to the interval (0 inside). The frames with ``w > 0`` are the joint's *window*.
- A5-A6: where several offsets of one joint overlap (successive contacts), they are blended by
  the norm-weighted mean ``sum |v_it| v_it / sum |v_it|`` with ``v_it = w_i(t) v_i``; at the edges
  of its window a joint hands over to the *drift* the IK gives it where it has no target of its
  own (``handover``).
- A13: with all offsets faded over W, ``|l'_{t+1} - l'_t| <= |l_{t+1} - l_t| + 4/W sum_i |v_i|``;
  ``smooth_ratio`` measures the left side over the right (<= 1 means the bound holds).

Offsets with zero norm (contacts with unchanged objects or the floor) still open a window: the
joint is held at its original position there unless another offset of the same joint is nearby.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trumans.intervals import runs
from trumans.skeleton import NUM_JOINTS

__all__ = [
    "ContactInterval",
    "Tracks",
    "runs",  # re-exported from trumans.contacts.intervals (its home)
    "fade",
    "contact_tracks",
    "handover",
    "blend_tracks",
    "smooth_ratio",
]


@dataclass
class ContactInterval:
    """Joint ``joint`` touches object ``obj`` on frames [start, end). ``offset`` (3,) m is the
    interval's A2 offset v = v'_m - v_m; ``frame_offset`` (end - start, 3) the per-frame ones."""

    joint: int
    obj: str
    start: int
    end: int
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frame_offset: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not (0 <= self.joint < NUM_JOINTS):
            raise ValueError(f"joint must be in [0, 24), got {self.joint}")
        if not (0 <= self.start < self.end):
            raise ValueError(f"need 0 <= start < end, got [{self.start}, {self.end})")
        self.offset = np.asarray(self.offset, dtype=np.float64).reshape(3)


@dataclass
class Tracks:
    """K faded offsets: joint (K,) int; weight (K, T) in [0, 1]; vec (K, 3) m, the un-faded offset,
    or (K, T, 3) when it varies over the frames (a contact point that slides)."""

    joint: np.ndarray
    weight: np.ndarray
    vec: np.ndarray

    def frames(self) -> np.ndarray:
        """(K, T, 3) the un-faded offset of every track at every frame."""
        T = self.weight.shape[1]
        return self.vec if self.vec.ndim == 3 else np.broadcast_to(self.vec[:, None], (len(self.vec), T, 3))

    @staticmethod
    def empty(T: int) -> "Tracks":
        return Tracks(np.zeros(0, np.int64), np.zeros((0, T)), np.zeros((0, 3)))

    def __add__(self, other: "Tracks") -> "Tracks":
        return Tracks(np.concatenate([self.joint, other.joint]), np.concatenate([self.weight, other.weight]),
                      np.concatenate([self.frames(), other.frames()]))

    def strength(self) -> np.ndarray:
        """(T, 24) the largest track weight of each joint (0 = no target: outside every window)."""
        T = self.weight.shape[1]
        out = np.zeros((T, NUM_JOINTS))
        for j in np.unique(self.joint):
            out[:, j] = self.weight[self.joint == j].max(0)
        return out

    def window(self) -> np.ndarray:
        """(T, 24) bool: frames where some track of the joint has weight > 0."""
        return self.strength() > 0


def fade(T: int, start: int, end: int, W: float) -> np.ndarray:
    """(T,) A3 weight of an interval [start, end): 1 inside, 1 - d/W at distance d outside, >= 0."""
    if W <= 0:
        raise ValueError(f"window W must be > 0 frames, got {W}")
    t = np.arange(T)
    d = np.maximum(np.maximum(start - t, t - (end - 1)), 0)
    return np.clip(1.0 - d / W, 0.0, 1.0)


def contact_tracks(intervals: list[ContactInterval], T: int, W: float, smooth: float = 5.0) -> Tracks:
    """One faded track per contact interval (A2-A3). An interval with per-frame offsets keeps
    them (moving-averaged over ``smooth`` frames, so that a contact point jumping between faces
    does not jerk the target) and holds its end values through the fades; otherwise its single
    ``offset`` is used."""
    if not intervals:
        return Tracks.empty(T)
    vec = np.zeros((len(intervals), T, 3))
    for k, iv in enumerate(intervals):
        e = min(iv.end, T)
        if iv.frame_offset is None:
            vec[k] = iv.offset
            continue
        fo = np.asarray(iv.frame_offset, dtype=np.float64).reshape(-1, 3)[: e - iv.start]
        n = int(max(1, round(smooth)))
        if n > 1 and len(fo) > 1:
            pad = np.concatenate([np.repeat(fo[:1], n // 2, 0), fo, np.repeat(fo[-1:], n - 1 - n // 2, 0)])
            c = np.cumsum(np.concatenate([np.zeros((1, 3)), pad]), axis=0)
            fo = (c[n:] - c[:-n]) / n
        vec[k, :iv.start] = fo[0]
        vec[k, iv.start:e] = fo
        vec[k, e:] = fo[-1]
    return Tracks(
        joint=np.array([iv.joint for iv in intervals], np.int64),
        weight=np.stack([fade(T, iv.start, min(iv.end, T), W) for iv in intervals]),
        vec=vec,
    )


def handover(own: np.ndarray, strength: np.ndarray, drift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blend a joint's own offset into the drift the IK gives it outside its window (A5-A6).

    own: (T, 24, 3) blended own offsets; strength: (T, 24) own fade weight s in [0, 1];
    drift: (T, 24, 3) m displacement of each joint in an IK pass where it had no target.
    In each window run of a joint, frames before its first full-contact frame (s = 1) hand over
    to the drift ``d`` at the free frame just before the run, frames after the last one to the
    drift at the free frame just after: ``o + (1 - s) d`` (``o`` already carries the fade s, so
    this runs linearly from the contact offset to ``d``). Where a run touches the clip's
    start or end there is no free frame on that side and ``d`` is the full-contact offset (the
    contact is taken to extend beyond the clip).

    (The paper's norm-weighted mean of ``(1 - s) v`` and ``s d`` halves the offset midway when
    ``v`` and ``d`` agree -- a joint riding on a lowered bed would be lifted off it; the
    complementary blend has no such dip and obeys the same A13 bound, |step| <= (|v| + |d|) / W.)
    Returns (offsets (T, 24, 3), handover drift norm (T, 24) for the A13 slack)."""
    out = own.copy()
    dn = np.zeros(strength.shape)
    T = strength.shape[0]
    for j in np.flatnonzero((strength > 0).any(0)):
        s = strength[:, j]
        for a, b in runs(s > 0):
            full = np.flatnonzero(s[a:b] >= 1.0 - 1e-12) + a
            lo, hi = (full[0], full[-1]) if len(full) else ((a + b) // 2, (a + b) // 2 - 1)
            for sl, edge, near in ((slice(a, lo), a - 1, lo), (slice(hi + 1, b), b, hi)):
                if sl.stop <= sl.start:
                    continue
                # no free frame on this side (the clip starts/ends): keep the full-contact offset
                d = drift[edge, j] if 0 <= edge < T else own[min(max(near, 0), T - 1), j]
                out[sl, j] = own[sl, j] + (1.0 - s[sl, None]) * d
                dn[sl, j] = np.linalg.norm(d)
    return out, dn


def blend_tracks(tracks: Tracks, T: int) -> tuple[np.ndarray, np.ndarray]:
    """A5 norm-weighted blend per joint -> (offsets (T, 24, 3) m, window (T, 24) bool)."""
    num = np.zeros((T, NUM_JOINTS, 3))
    den = np.zeros((T, NUM_JOINTS))
    if len(tracks.joint):
        v = tracks.weight[..., None] * tracks.frames()  # (K, T, 3) v_it
        n = np.linalg.norm(v, axis=-1)  # (K, T) |v_it|
        for k, j in enumerate(tracks.joint):
            num[:, j] += n[k, :, None] * v[k]
            den[:, j] += n[k]
    off = np.where(den[..., None] > 0, num / np.maximum(den, 1e-300)[..., None], 0.0)
    return off, tracks.window() if len(tracks.joint) else np.zeros((T, NUM_JOINTS), bool)


def smooth_ratio(l: np.ndarray, l_new: np.ndarray, tracks: Tracks, W: float, mask: np.ndarray | None = None,
                 extra: np.ndarray | None = None, eps: float = 1e-9) -> np.ndarray:
    """A13 ratio per frame step and joint: |l'_{t+1}-l'_t| / (|l_{t+1}-l_t| + 4/W sum_i |v_i|).

    l, l_new: (T, 24, 3) original and new target trajectories (m); the sum runs over the tracks
    of the joint that are non-zero at t or t+1 (plus ``extra`` (T, 24), e.g. the hand-over drift
    norms, max over t and t+1); mask: (T, 24) joints that have targets (default all). A13 assumes
    each offset constant; for a sliding contact (per-frame offsets) the offset's own change
    |v_{t+1} - v_t| is added to the right side.
    Returns (T-1, 24); 0 where both sides are ~0 or the joint is untargeted at t or t+1."""
    T = l.shape[0]
    num = np.linalg.norm(np.diff(l_new, axis=0), axis=-1)
    base = np.linalg.norm(np.diff(l, axis=0), axis=-1)
    slack = np.zeros((T - 1, NUM_JOINTS))
    fr = tracks.frames()
    for k, j in enumerate(tracks.joint):
        on = (tracks.weight[k, 1:] > 0) | (tracks.weight[k, :-1] > 0)
        n = np.linalg.norm(fr[k], axis=-1)
        # |v_i| of a sliding contact: the larger of its two frames, plus its own change (W/4 |dv|
        # puts a moving offset's step into the same 4/W slack)
        dv = np.linalg.norm(np.diff(fr[k], axis=0), axis=-1)
        slack[:, j] += on * (np.maximum(n[1:], n[:-1]) + W / 4.0 * dv)
    if extra is not None:
        slack += np.maximum(extra[1:], extra[:-1])
    den = base + 4.0 / W * slack
    r = np.where(num <= eps, 0.0, num / np.maximum(den, eps))
    if mask is not None:
        r = np.where(mask[1:] & mask[:-1], r, 0.0)
    return r
