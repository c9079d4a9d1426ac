"""Frame-wise multi-hot action labels with the progress indicator (TRUMANS §4.3).

Label convention (docs/conventions.md): ``(T, N_A)`` float; 0 where an action is off, ``1 + progress``
while it runs, progress going linearly 0 -> 1 from the action's first to its last frame.
The vocabulary is a list of names stored with data and checkpoints; order is never assumed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .intervals import run_bounds

# The action vocabulary of the embedded dataset (``trumans data synth``, and BVH/FBX imports labelled from
# the motion: ``trumans.importers.labels``); saved with the data, so never assume its order elsewhere.
SYNTH_ACTIONS: tuple[str, ...] = (
    "stand", "walk", "turn", "sit_down", "sit", "stand_up", "lie_down", "lie", "get_up",
    "reach", "grasp", "pick_up", "carry", "put_down", "drink", "phone_call", "type", "use_mouse",
    "open_door", "close_door", "open_drawer", "close_drawer", "push", "pull",
)

__all__ = ["ActionInterval", "labels_from_intervals", "intervals_from_labels", "remap_labels"]


@dataclass(frozen=True)
class ActionInterval:
    """Action ``name`` running on frames ``[start, end)`` (half-open, like every interval in trumans)."""

    name: str
    start: int
    end: int


def labels_from_intervals(intervals: list[ActionInterval], vocab: list[str], num_frames: int) -> np.ndarray:
    """Intervals -> (T, N_A) float32 labels with progress. Unknown names raise ValueError."""
    lab = np.zeros((num_frames, len(vocab)), dtype=np.float32)
    index = {n: i for i, n in enumerate(vocab)}
    for iv in intervals:
        if iv.name not in index:
            raise ValueError(f"unknown action {iv.name!r}; the vocabulary is {list(vocab)}")
        s, e = max(iv.start, 0), min(iv.end, num_frames)
        if e <= s:
            continue
        n = iv.end - 1 - iv.start  # progress 0 -> 1 from the first to the last frame
        t = np.arange(s, e)
        prog = (t - iv.start) / n if n > 0 else np.ones(len(t))
        lab[s:e, index[iv.name]] = 1.0 + prog.astype(np.float32)
    return lab


def intervals_from_labels(labels: np.ndarray, vocab: list[str]) -> list[ActionInterval]:
    """Inverse of ``labels_from_intervals`` for non-touching runs: (T, N_A) -> intervals (sorted by start)."""
    labels = np.asarray(labels)
    if labels.ndim != 2 or labels.shape[1] != len(vocab):
        raise ValueError(f"labels must be (T, {len(vocab)}), got {labels.shape}")
    out = []
    on = labels > 0
    for a in range(labels.shape[1]):
        starts, ends = run_bounds(on[:, a])  # half-open runs; ActionInterval's end is inclusive
        out += [ActionInterval(vocab[a], int(s), int(e)) for s, e in zip(starts, ends)]
    return sorted(out, key=lambda iv: (iv.start, iv.name))


def remap_labels(labels: np.ndarray, names: list[str], vocab: list[str]) -> np.ndarray:
    """Reorder label columns named ``names`` into vocabulary ``vocab`` (missing columns are 0).
    Raises ValueError for a name that ``vocab`` lacks."""
    missing = [n for n in names if n not in vocab]
    if missing:
        raise ValueError(f"actions {missing} are not in the vocabulary {list(vocab)}")
    out = np.zeros((labels.shape[0], len(vocab)), dtype=np.float32)
    for i, n in enumerate(names):
        out[:, vocab.index(n)] = labels[:, i]
    return out
