"""Fixed-length windows over a sequence of any length and their overlap blending (the filter works
on windows of ``L`` frames, I'm-HOI §3.1 T = 64).

Windows start every ``L - overlap`` frames; the last one is moved back to end exactly at the last
frame (so it may overlap its predecessor by more). A sequence shorter than ``L`` gets one window
that runs past its end (the caller pads, e.g. with missing frames). Blending: each window's weight
ramps linearly up over the frames it shares with its predecessor and down over those it shares with
its successor, and the result is the weight-normalised sum, so wherever the windows agree the blend
equals them exactly.
"""
from __future__ import annotations

import numpy as np

__all__ = ["window_starts", "window_weights", "blend_windows"]


def window_starts(num_frames: int, length: int, overlap: int) -> np.ndarray:
    """First frames (N,) int64 of windows of ``length`` covering ``num_frames`` frames."""
    if num_frames < 1:
        raise ValueError(f"need at least one frame, got {num_frames}")
    if length < 1 or not 0 <= overlap < length:
        raise ValueError(f"need length >= 1 and 0 <= overlap < length, got length={length}, overlap={overlap}")
    if num_frames <= length:
        return np.zeros(1, dtype=np.int64)
    starts = np.arange(0, num_frames - length, length - overlap, dtype=np.int64)
    return np.append(starts, num_frames - length)


def window_weights(starts: np.ndarray, length: int) -> np.ndarray:
    """Blend weights (N, length) in (0, 1]: linear ramps over each window's overlaps with its
    neighbours (starts sorted ascending)."""
    starts = np.asarray(starts, dtype=np.int64)
    N = len(starts)
    k = np.arange(length, dtype=np.float64)
    w = np.ones((N, length))
    for side in ("in", "out"):
        if N < 2:
            break
        if side == "in":  # overlap with the predecessor: frames [0, prev_end - start)
            ov = np.concatenate([[0], starts[:-1] + length - starts[1:]])
            ramp = (k[None] + 1) / (ov[:, None] + 1)
        else:  # overlap with the successor: frames [next_start - start, length)
            ov = np.concatenate([starts[:-1] + length - starts[1:], [0]])
            ramp = (length - k[None]) / (ov[:, None] + 1)
        w = np.minimum(w, np.where(ov[:, None] > 0, np.minimum(ramp, 1.0), 1.0))
    return w


def blend_windows(pieces: np.ndarray, starts: np.ndarray, num_frames: int) -> np.ndarray:
    """Blend window outputs pieces (N, length, ...) starting at ``starts`` (N,) into (num_frames, ...);
    frames past ``num_frames`` (a padded short sequence) are dropped."""
    pieces = np.asarray(pieces, dtype=np.float64)
    starts = np.asarray(starts, dtype=np.int64)
    N, L = pieces.shape[:2]
    if len(starts) != N:
        raise ValueError(f"{N} pieces but {len(starts)} starts")
    w = window_weights(starts, L)
    idx = starts[:, None] + np.arange(L)[None]  # (N, L)
    keep = idx < num_frames
    if not np.isin(np.arange(num_frames), idx[keep]).all():
        raise ValueError(f"windows starting at {starts.tolist()} (length {L}) do not cover {num_frames} frames")
    acc = np.zeros((num_frames,) + pieces.shape[2:])
    tot = np.zeros(num_frames)
    wb = w.reshape(N, L, *([1] * (pieces.ndim - 2)))
    for i, s in enumerate(starts):  # window by window, in order (a frame's sum adds its windows in order)
        n = max(0, min(L, num_frames - s))
        acc[s:s + n] += pieces[i, :n] * wb[i, :n]
        tot[s:s + n] += w[i, :n]
    return acc / tot.reshape(-1, *([1] * (pieces.ndim - 2)))
