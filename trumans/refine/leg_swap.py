"""Left/right leg swaps read from the whole sequence (before filtering).

Marker-less trackers confuse the two legs for a few frames (the left leg's joints reported where
the right leg is and back), most often when the legs pass each other. A smoother averages the two
legs there, and the filter, which sees each window alone, half follows the swap. Read from the
sequence, a swap is a state: the tracked legs are either as labelled or exchanged, and between two
consecutive frames a leg moves a few centimetres, while an exchange moves each leg joint by the
legs' separation. So each frame gets a state s(t) in {as labelled, swapped} by dynamic programming
(Viterbi over two states): the cost of a path is the squared distance each leg joint travels
between consecutive frames, read with the states' labels, plus ``switch_m``^2 per change of state
(a change must save that much), plus a small ``prior_m``^2 per swapped frame (of two readings that
move the same, the one with fewer swapped frames wins: swaps are the exception), plus, per frame,
``side_weight`` times the squared length by which the reading's left hip lies on the right of its
right hip along the shoulders' left-right axis (the upper body is not swapped; hips and shoulders
never face more than a quarter turn apart). Without that last term a piece of the chain that
starts inside a swap (just after a gap) had no way to tell which labelling is right, and read
the complement of the truth (corpus 38_02 under the tracker model: legs wrong on 23 frames). Only consecutive
frames are compared, on the leg joints seen (with their mirror) in both: across a gap the legs move
too far to tell (in a walk, half a stride puts each leg where the other was), so a gap cuts the
chain and each piece is read on its own. Frames read as swapped get their legs exchanged back.

Not in I'm-HOI; the same reading as the object's flips (``trumans.refine.outliers``), for the body.
Units: metres; joints (T, 24, 3) z-up world.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.skeleton import JOINT_INDEX, NUM_JOINTS, SHOULDERS

from trumans.refine.frame import FRAME_DIM, JOINTS, ROTATIONS

__all__ = ["SwapConfig", "LEFT_LEG", "RIGHT_LEG", "leg_swap_states", "unswap_legs", "unswap_leg_frames"]

LEFT_LEG = tuple(JOINT_INDEX[f"left_{n}"] for n in ("hip", "knee", "ankle", "foot"))
RIGHT_LEG = tuple(JOINT_INDEX[f"right_{n}"] for n in ("hip", "knee", "ankle", "foot"))
_SHOULDERS = SHOULDERS
_SWAP = np.arange(NUM_JOINTS)
_SWAP[list(LEFT_LEG)], _SWAP[list(RIGHT_LEG)] = list(RIGHT_LEG), list(LEFT_LEG)


@dataclass(frozen=True)
class SwapConfig:
    """enabled: whether swaps are read and undone; switch_m: a change of state must save this much
    travel (m, root of the summed squares over the leg joints); prior_m: the cost of one swapped frame
    (m, likewise)."""

    enabled: bool = True
    switch_m: float = 0.10
    prior_m: float = 0.01
    side_weight: float = 1.0

    def __post_init__(self) -> None:
        if not (self.switch_m >= 0 and self.prior_m >= 0 and self.side_weight >= 0):
            raise ValueError(f"swap switch_m, prior_m and side_weight must be >= 0, got {self.switch_m}, "
                             f"{self.prior_m}, {self.side_weight}")


def _side_costs(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T,) each, m^2: how far the left hip of the reading as labelled / swapped lies on the right of
    its right hip along the shoulders' left-right axis (3-D: a body lying on its side has both axes
    vertical), squared (0 where it lies on the left, or where a hip or shoulder is missing)."""
    axis = J[:, _SHOULDERS[0]] - J[:, _SHOULDERS[1]]
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-9)
    proj = ((J[:, LEFT_LEG[0]] - J[:, RIGHT_LEG[0]]) * axis).sum(-1)  # > 0: the hips as labelled agree
    proj = np.nan_to_num(proj, nan=0.0)
    return np.minimum(proj, 0.0) ** 2, np.maximum(proj, 0.0) ** 2


def leg_swap_states(joints: np.ndarray, config: SwapConfig = SwapConfig()) -> np.ndarray:
    """Tracked joints (T, 24, 3) m (NaN = missing) -> (T,) bool, True where the legs are read as
    swapped (the Viterbi path described in the module docstring)."""
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, {NUM_JOINTS}, 3), got {J.shape}")
    T = len(J)
    legs = list(LEFT_LEG + RIGHT_LEG)
    X, Xs = J[:, legs], J[:, _SWAP[legs]]  # (T, 8, 3): the readings as labelled / swapped
    ok = np.isfinite(X).all(-1) & np.isfinite(Xs).all(-1)  # (T, 8): a joint and its mirror observed
    states = np.zeros(T, bool)
    if T < 2:
        return states
    both = ok[1:] & ok[:-1]  # (T-1, 8): compared between consecutive frames only
    A = (np.nan_to_num(X), np.nan_to_num(Xs))
    step = np.empty((T - 1, 2, 2))  # travel (summed squares, m^2) from reading a at t-1 to reading b at t
    for a in range(2):
        for b in range(2):
            step[:, a, b] = (((A[b][1:] - A[a][:-1]) ** 2).sum(-1) * both).sum(-1)
    linked = both.any(-1)  # a frame pair without a joint seen in both cuts the chain: no travel, no switch cost
    sw, pr = config.switch_m ** 2, config.prior_m ** 2
    # two states: a loop over the frames on Python floats (numpy's per-call overhead on 2 x 2 arrays
    # was most of the cost); c0, c1: the best cost of a path ending as labelled / swapped
    u0, u1 = _side_costs(J)
    u0, u1 = (config.side_weight * u0).tolist(), (config.side_weight * u1).tolist()
    c0, c1 = u0[0], pr + u1[0]
    back0, back1 = bytearray(T), bytearray(T)  # per frame, the best predecessor of each state (ties: as labelled)
    steps = zip(step[:, 0, 0].tolist(), step[:, 0, 1].tolist(), step[:, 1, 0].tolist(), step[:, 1, 1].tolist(),
                (sw * linked).tolist(), u0[1:], u1[1:])
    for t, (s00, s01, s10, s11, k, v0, v1) in enumerate(steps, start=1):
        t00, t10, t01, t11 = c0 + s00, c1 + s10 + k, c0 + s01 + k, c1 + s11  # from -> to
        back0[t], back1[t] = t00 > t10, t01 > t11
        c0, c1 = min(t00, t10) + v0, min(t01, t11) + pr + v1
    path = np.empty(T, np.int8)
    p = path[-1] = 0 if c0 <= c1 else 1
    for t in range(T - 1, 0, -1):
        p = path[t - 1] = (back1 if p else back0)[t]
    states = path.astype(bool) & ok.any(-1)  # a frame without an observed leg joint keeps its labels
    return states


def unswap_legs(joints: np.ndarray, config: SwapConfig = SwapConfig()) -> np.ndarray:
    """Tracked joints (T, 24, 3) m -> the same with the legs exchanged back on the frames
    ``leg_swap_states`` reads as swapped."""
    J = np.asarray(joints, dtype=np.float64)
    s = leg_swap_states(J, config)
    out = J.copy()
    out[s] = J[s][:, _SWAP]
    return out


def unswap_leg_frames(frames: np.ndarray, config: SwapConfig = SwapConfig()) -> np.ndarray:
    """Frame vectors (T, 235) (``trumans.refine.frame``) -> a copy whose frames ``leg_swap_states``
    reads as swapped get the legs' joint positions and local rotations exchanged back."""
    f = np.array(frames, dtype=np.float32, copy=True)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    s = leg_swap_states(f[:, JOINTS].reshape(len(f), NUM_JOINTS, 3), config)
    if s.any():
        cols = lambda j, width, start: [start + width * j + k for k in range(width)]
        src = np.concatenate([cols(j, w, o) for w, o in ((3, JOINTS.start), (6, ROTATIONS.start)) for j in _SWAP])
        dst = np.concatenate([cols(j, w, o) for w, o in ((3, JOINTS.start), (6, ROTATIONS.start)) for j in range(NUM_JOINTS)])
        f[np.ix_(s, dst)] = f[np.ix_(s, src)]
    return f
