"""Runs of True in per-frame masks: the one interval convention, half-open ``[start, end)``.

Used for contact intervals (augmentation, metrics, the tracker) and action labels alike.
``run_bounds`` gives the raw runs as arrays; ``runs`` closes short gaps and drops short runs.
"""
from __future__ import annotations

import numpy as np

__all__ = ["run_bounds", "runs"]


def run_bounds(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Maximal runs of True in a (T,) mask -> (starts (n,), ends (n,)) int64, run k = frames
    ``[starts[k], ends[k])``."""
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 1:
        raise ValueError(f"mask must be (T,) bool, got shape {m.shape}")
    d = np.diff(np.concatenate([[0], m.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def runs(mask: np.ndarray, max_gap: int = 0, min_len: int = 1) -> list[tuple[int, int]]:
    """Maximal runs ``[start, end)`` of True in a (T,) mask; gaps of at most ``max_gap`` frames
    between runs are closed (merging them), then runs shorter than ``min_len`` frames dropped."""
    if max_gap < 0 or min_len < 1:
        raise ValueError(f"need max_gap >= 0 and min_len >= 1, got max_gap={max_gap}, min_len={min_len}")
    starts, ends = run_bounds(mask)
    out: list[tuple[int, int]] = []
    for s, e in zip(starts, ends):
        if out and s - out[-1][1] <= max_gap:
            out[-1] = (out[-1][0], int(e))
        else:
            out.append((int(s), int(e)))
    return [(s, e) for s, e in out if e - s >= min_len]
