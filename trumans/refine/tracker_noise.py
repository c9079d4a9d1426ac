"""An independent body-tracker error model, for evaluating the filter on errors it was not trained on.

Written apart from the training corruption (``trumans.refine.corrupt``), after what marker-less
and inertial body trackers get wrong (issue 36's outside test). Every kind is on its own switch
(``TrackerConfig.kinds``), so each can be measured alone; every draw comes from the caller's
``numpy.random.Generator``.

In the order they are applied (``TRACKER_KINDS``):

- ``drift``: a random walk of the whole body (3D Gaussian steps, ``walk_m_per_sqrt_s`` per axis per
  square-root second, the vertical at ``walk_vertical`` of that);
- ``height``: a constant vertical offset per clip, ``height_m`` (lo, hi) in magnitude, either sign;
- ``jitter``: white per-joint noise of ``jitter_m`` per axis, the extremities (wrists, index1,
  ankles, toe bases) at ``extremity_jitter`` of that;
- ``burst``: runs of ``burst_frames`` where the noise is ``burst_m`` per axis (motion blur, a
  lost and re-found track);
- ``swap``: the left and right legs (hip to toe base) exchanged for ``swap_frames`` frames;
- ``freeze``: silent freezes: a limb (an arm from the elbow or a leg from the knee) or the whole
  body repeats its last output for ``freeze_frames`` frames, with no missing flag;
- ``dropout``: runs of missing frames (NaN) of ``dropout_frames``.

Probabilities are per frame (a run starts there). Units: metres, seconds.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from trumans.skeleton import JOINT_INDEX, NUM_JOINTS

__all__ = ["TRACKER_KINDS", "TrackerConfig", "tracker_corrupt"]

TRACKER_KINDS: tuple[str, ...] = ("drift", "height", "jitter", "burst", "swap", "freeze", "dropout")
_LIMBS = tuple(tuple(JOINT_INDEX[f"{s}_{n}"] for n in names) for s in ("left", "right")
               for names in (("elbow", "wrist", "index1"), ("knee", "ankle", "foot")))
_EXTREMITIES = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("wrist", "index1", "ankle", "foot")]
_LEGS = [[JOINT_INDEX[f"{s}_{n}"] for n in ("hip", "knee", "ankle", "foot")] for s in ("left", "right")]


@dataclass(frozen=True)
class TrackerConfig:
    """The kinds that are on (``TRACKER_KINDS``) and their magnitudes (m, frames, per-frame
    probabilities). ``only(kind)``: one kind alone."""

    kinds: tuple[str, ...] = TRACKER_KINDS
    walk_m_per_sqrt_s: float = 0.01
    walk_vertical: float = 0.3
    height_m: tuple[float, float] = (0.02, 0.06)
    p_freeze: float = 0.006
    freeze_frames: tuple[int, int] = (3, 15)
    p_swap: float = 0.004
    swap_frames: tuple[int, int] = (3, 12)
    jitter_m: float = 0.012
    extremity_jitter: float = 1.5
    p_dropout: float = 0.006
    dropout_frames: tuple[int, int] = (2, 15)
    p_burst: float = 0.004
    burst_frames: tuple[int, int] = (3, 10)
    burst_m: float = 0.04

    def __post_init__(self) -> None:
        bad = sorted(set(self.kinds) - set(TRACKER_KINDS))
        if bad or not self.kinds:
            raise ValueError(f"tracker kinds must be a non-empty subset of {TRACKER_KINDS}, got {self.kinds}")
        for name in ("walk_m_per_sqrt_s", "walk_vertical", "jitter_m", "extremity_jitter", "burst_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"tracker {name} must be finite and >= 0, got {v}")
        for name in ("p_freeze", "p_swap", "p_dropout", "p_burst"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"tracker {name} is a probability, got {getattr(self, name)}")
        lo, hi = self.height_m
        if not 0 <= lo <= hi:
            raise ValueError(f"tracker height_m must be (lo, hi) with 0 <= lo <= hi, got {self.height_m}")
        for name in ("freeze_frames", "swap_frames", "dropout_frames", "burst_frames"):
            a, b = getattr(self, name)
            if not 1 <= a <= b:
                raise ValueError(f"tracker {name} must be (min, max) frames with 1 <= min <= max, got {(a, b)}")

    def only(self, kind: str) -> "TrackerConfig":
        """The same magnitudes with one kind on."""
        return replace(self, kinds=(kind,))


def _runs(rng: np.random.Generator, B: int, T: int, p: float, frames: tuple[int, int]) -> list[list[tuple[int, int]]]:
    """Per clip, [start, end) runs that start with probability p per frame and last frames[0..1]."""
    out = []
    for _ in range(B):
        starts = np.flatnonzero(rng.random(T) < p)
        lens = rng.integers(frames[0], frames[1] + 1, len(starts))
        out.append([(int(s), int(min(T, s + n))) for s, n in zip(starts, lens)])
    return out


def tracker_corrupt(joints: np.ndarray, fps: float, rng: np.random.Generator,
                    config: TrackerConfig = TrackerConfig()) -> np.ndarray:
    """Clean joints (B, T, 24, 3) m at ``fps`` -> tracked-like joints (B, T, 24, 3) float32, NaN =
    missing (dropouts only), by the kinds of ``config`` applied in the order of ``TRACKER_KINDS``: the
    tracker's output is the drifted body with its noise, and swaps, freezes (a repeat of that output,
    bit for bit) and dropouts act on the output."""
    X = np.array(joints, dtype=np.float64, copy=True)
    if X.ndim != 4 or X.shape[2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (B, T, {NUM_JOINTS}, 3), got {X.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    B, T = X.shape[:2]
    c, on = config, set(config.kinds)
    if "drift" in on:
        steps = rng.normal(0.0, c.walk_m_per_sqrt_s / np.sqrt(fps), (B, T, 3)) * np.array([1.0, 1.0, c.walk_vertical])
        walk = np.cumsum(steps, axis=1)
        X += (walk - walk[:, :1])[:, :, None]
    if "height" in on:
        h = rng.uniform(*c.height_m, B) * rng.choice([-1.0, 1.0], B)
        X[..., 2] += h[:, None, None]
    if "jitter" in on:
        scale = np.ones(NUM_JOINTS)
        scale[_EXTREMITIES] = c.extremity_jitter
        X += rng.normal(0.0, c.jitter_m, X.shape) * scale[None, None, :, None]
    if "burst" in on:
        for b, runs in enumerate(_runs(rng, B, T, c.p_burst, c.burst_frames)):
            for s, e in runs:
                X[b, s:e] += rng.normal(0.0, c.burst_m, (e - s, NUM_JOINTS, 3))
    if "swap" in on:
        for b, runs in enumerate(_runs(rng, B, T, c.p_swap, c.swap_frames)):
            for s, e in runs:
                Xb = X[b]
                Xb[s:e, _LEGS[0] + _LEGS[1]] = Xb[s:e, _LEGS[1] + _LEGS[0]]
    if "freeze" in on:
        for b, runs in enumerate(_runs(rng, B, T, c.p_freeze, c.freeze_frames)):
            for s, e in runs:
                if s == 0:
                    continue
                which = rng.integers(0, len(_LIMBS) + 1)  # a limb, or (the last draw) the whole body
                cols = list(range(NUM_JOINTS)) if which == len(_LIMBS) else list(_LIMBS[which])
                Xb = X[b]  # a view: one advanced index, so the result keeps (frames, joints, 3)
                Xb[s:e, cols] = Xb[s - 1, cols]
    if "dropout" in on:
        for b, runs in enumerate(_runs(rng, B, T, c.p_dropout, c.dropout_frames)):
            for s, e in runs:
                X[b, s:e] = np.nan
    return X.astype(np.float32)
