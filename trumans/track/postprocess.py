"""From per-frame contact probabilities to contact intervals (iReplica §4.2 and supp. §10).

Threshold the probabilities, fill gaps of at most ``max_gap_s`` (0.5 s in the paper) between two
active stretches of a hand, then cut the timeline into *segments* in which the set of hands in
contact is constant: when one hand lets go while the other holds on, a two-handed interaction is
split into a two-handed and a one-handed one (hands swapping are treated the same way).
Intervals are half-open frame ranges ``[start, end)`` (``trumans.contacts.intervals.runs``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.intervals import runs

__all__ = ["PostprocessConfig", "ContactSegment", "fill_gaps", "contact_mask", "contact_segments"]


@dataclass(frozen=True)
class PostprocessConfig:
    """threshold: probability at which a hand is in contact; max_gap_s: gaps between active
    stretches up to this long (s) are filled; min_len_s: active stretches shorter than this (s,
    after filling) are dropped as false positives (0 keeps all)."""

    threshold: float = 0.5
    max_gap_s: float = 0.5
    min_len_s: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.threshold < 1.0:
            raise ValueError(f"threshold must be in (0, 1), got {self.threshold}")
        if not self.max_gap_s >= 0:
            raise ValueError(f"max_gap_s must be >= 0 seconds, got {self.max_gap_s}")
        if not self.min_len_s >= 0:
            raise ValueError(f"min_len_s must be >= 0 seconds, got {self.min_len_s}")


@dataclass(frozen=True)
class ContactSegment:
    """Frames [start, end) during which exactly the hands ``hands`` ((left, right) bools, at least
    one True) are in contact; ``interval``: index of the union contact interval (any hand in
    contact, no break) the segment belongs to, so consecutive segments of one interaction share it."""

    start: int
    end: int
    hands: tuple[bool, bool]
    interval: int

    @property
    def two_handed(self) -> bool:
        return all(self.hands)


def _check_mask(mask: np.ndarray, ndim: int) -> np.ndarray:
    m = np.asarray(mask)
    if m.ndim != ndim:
        raise ValueError(f"mask must have {ndim} dimension(s), got shape {m.shape}")
    if m.dtype != bool:
        raise ValueError(f"mask must be boolean, got dtype {m.dtype}; threshold probabilities first")
    return m


def _paint(ranges: list[tuple[int, int]], T: int) -> np.ndarray:
    """Half-open [start, end) ranges -> (T,) bool, True inside any range."""
    r = np.asarray(ranges, dtype=np.int64).reshape(-1, 2)
    d = np.zeros(T + 1, np.int64)
    np.add.at(d, r[:, 0], 1)
    np.add.at(d, r[:, 1], -1)
    return np.cumsum(d[:-1]) > 0


def fill_gaps(mask: np.ndarray, max_gap: int) -> np.ndarray:
    """(T,) bool -> (T,) bool with every False gap of at most ``max_gap`` frames that lies between
    two True frames set True (gaps at the ends are kept)."""
    m = _check_mask(mask, 1)
    return _paint(runs(m, max_gap=max_gap), len(m))


def contact_mask(prob: np.ndarray, fps: float, config: PostprocessConfig = PostprocessConfig()) -> np.ndarray:
    """prob: (T, H) contact probabilities per hand -> (T, H) bool after threshold, gap filling
    (gaps <= ``max_gap_s``) and dropping stretches shorter than ``min_len_s``."""
    p = np.asarray(prob, dtype=np.float64)
    if p.ndim != 2:
        raise ValueError(f"prob must be (T, hands), got shape {p.shape}")
    if not (np.isfinite(p).all() and (p >= 0).all() and (p <= 1).all()):
        raise ValueError("prob must hold probabilities in [0, 1] (apply a sigmoid to logits)")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    max_gap = int(np.floor(config.max_gap_s * fps + 1e-9))
    min_len = max(1, int(np.ceil(config.min_len_s * fps - 1e-9)))
    cols = [_paint(runs(p[:, h] >= config.threshold, max_gap=max_gap, min_len=min_len), len(p))
            for h in range(p.shape[1])]  # per hand (2), not per frame
    return np.stack(cols, axis=1) if cols else np.zeros(p.shape, bool)


def contact_segments(mask: np.ndarray) -> list[ContactSegment]:
    """mask: (T, 2) bool (left, right) -> segments of constant, non-empty hand set, in time order."""
    m = _check_mask(mask, 2)
    if m.shape[1] != 2:
        raise ValueError(f"mask must be (T, 2) for the left and right hand, got {m.shape}")
    code = m[:, 0].astype(np.int64) + 2 * m[:, 1].astype(np.int64)  # 0 none, 1 L, 2 R, 3 both
    change = np.flatnonzero(np.diff(np.concatenate([[0], code, [0]])) != 0)  # run boundaries
    starts, ends = change[:-1], change[1:]
    codes = code[starts] if len(starts) else np.zeros(0, np.int64)
    union_starts = np.asarray([s for s, _ in runs(code > 0)], dtype=np.int64)
    interval_of = np.searchsorted(union_starts, starts, side="right") - 1
    return [ContactSegment(int(s), int(e), (bool(c & 1), bool(c & 2)), int(i))
            for s, e, c, i in zip(starts, ends, codes, interval_of) if c > 0]
