"""Planted feet held still (a post-step of the HOI filter, after the body-drift fit).

The filter's feet keep a little of the tracker's jitter and wander through a stance: summed over a
stance, a refined foot slides centimetres where the real one stays put, which an animator sees at
once. Each stance of a foot joint (``body_drift.stance_mask``: ankles and feet, each on its own, so
a heel can lift while the toes stay) is pinned to one point, the joint's mean over the stance; the
correction is faded in and out over ``fade_s`` outside the stance so nothing jumps. The leg follows
by two-bone IK in position space with the hip fixed (thigh and shin keep their lengths in every
frame, the knee stays in its bend plane), the toe joint keeps its distance to the ankle (with
``toe_first``: one distance for the clip, the median of the filter's, and a held toe is placed
first, the ankle going on the sphere of that distance around it - else the toe, hung from the
ankle at each frame's own length, moved with the filter's toe bone: 4-5 mm off its target on a
third of the held frames, half of the planted feet's remaining skate under the tracker model), and the
local rotations of hip, knee and ankle turn by the same minimal rotations as their bones, so the
joints and the rotations stay as consistent as the filter left them. Everything above the hips, the
object and the IMU are untouched.

Not in I'm-HOI (its filter sees one window and has no contact term); foot contact clean-up is the
standard last step of motion-capture pipelines. Measured in the README's filter section.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.ik.limb import two_bone_positions
from trumans.rotations import least_rotation, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import FOOT_JOINTS, LEG_CHAINS, NUM_JOINTS, PARENTS

from trumans.refine.body_drift import DriftConfig, stance_mask
from trumans.refine.frame import FRAME_DIM, JOINTS, ROTATIONS

__all__ = ["LockConfig", "lock_feet", "stance_corrections"]

assert all(PARENTS[hip] == 0 for hip, *_ in LEG_CHAINS), "the legs' hips hang from the root (_turn_leg_rotations)"



@dataclass(frozen=True)
class LockConfig:
    """fade_s: seconds over which a stance's correction fades in before it and out after it;
    stance: how stances are found (the body-drift fit's detection). Chosen on 40 val clips (fade 0.1
    / 0.2 s, speed 0.2 / 0.25 / 0.3 m/s, shortest stance 0.1 / 0.17 s): skate 4.3 -> 1.6 cm per planted
    foot joint, mpjpe unchanged (18.79 -> 18.80 mm); faster thresholds lock more and cost mpjpe.
    enabled: whether the post-step runs (``trumans.refine.post_steps``). toe_first: a held toe base is
    placed first, at the clip's one toe-bone length (module doc); 14 corpus train clips, skate of the
    output's feet: the training corruption 3.3 -> 1.7 cm/s, jitter 2.8 -> 1.3, the tracker model 3.9
    -> 2.9; limbs within 0.1 mm. hold_s: with 0, each stance's foot joint is pinned to its mean; above
    0, to its own Gaussian low-pass of std ``hold_s`` within the stance (``stance_corrections``), so a
    long stance (standing, sitting, lying) follows the foot's slow roll and shift instead of one point,
    while a walking stance (well under ``hold_s``) is still all but pinned. The mean was chosen on
    procedural feet, which do not roll; on the corpus's 68 held-out real clips it cost 8-10 % of the
    limb error (docs/refine.md, "The foot lock on real feet"). vertical: the lock moves the height
    too (False: the horizontal slide only)."""

    enabled: bool = True
    fade_s: float = 0.2
    stance: DriftConfig = DriftConfig()
    toe_first: bool = True
    hold_s: float = 1.0
    vertical: bool = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.fade_s) and self.fade_s >= 0):
            raise ValueError(f"lock fade_s must be >= 0, got {self.fade_s}")
        if not (np.isfinite(self.hold_s) and self.hold_s >= 0):
            raise ValueError(f"lock hold_s must be >= 0 s, got {self.hold_s}")
        if not self.stance.enabled:
            raise ValueError("lock stance is the stance detection only: its enabled must stay true (switch the "
                             "foot lock off with the lock's own enabled, the drift fit with body_drift.enabled)")


def stance_corrections(J: np.ndarray, planted: np.ndarray, fade: float, smooth: float = 0.0) -> np.ndarray:
    """(T, 4, 3): per foot joint of FOOT_JOINTS, the move that puts it on its stance's mean (``smooth``
    = 0) or, with ``smooth`` > 0, on its own Gaussian low-pass of std ``smooth`` frames within the
    stance (edges held), faded linearly to 0 over ``fade`` frames on either side of the stance (outside
    a stance the target is the stance's value at its nearer end; where fades of neighbouring stances
    overlap, the one with the larger weight wins; on a tie the earlier one). Vectorised over frames:
    a frame's weight comes from the stance it is in or, outside, the nearer of the stances before and
    after it (farther ones are farther still)."""
    T = len(J)
    out = np.zeros((T, len(FOOT_JOINTS), 3))
    t = np.arange(T)
    for k, j in enumerate(FOOT_JOINTS):
        edge = np.diff(np.r_[0, planted[:, k].astype(np.int8), 0])
        a, b = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1) - 1  # stances [a, b]
        if not len(a):
            continue
        if smooth > 0:  # each stance's own low-pass: the foot follows its slow roll, not its jitter
            path = J[:, j].copy()
            for s0, s1 in zip(a, b):  # a Gaussian-weighted mean over the stance's own frames
                n = s1 - s0 + 1  # the kernel cut at the stance's length: the rest would weigh zeros only
                w = gaussian_filter1d(np.c_[J[s0:s1 + 1, j], np.ones(n)], smooth, axis=0, mode="constant",
                                      radius=min(int(4.0 * smooth + 0.5), n - 1))
                path[s0:s1 + 1] = w[:, :3] / w[:, 3:]
        else:
            csum = np.concatenate([np.zeros((1, 3)), np.cumsum(J[:, j], axis=0)])
            mean = (csum[b + 1] - csum[a]) / (b - a + 1)[:, None]  # (n, 3) each stance's mean
        prev = np.searchsorted(a, t, side="right") - 1  # the last stance starting at or before t
        nxt = np.minimum(prev + 1, len(a) - 1)
        d_prev = np.where(prev >= 0, t - b[np.maximum(prev, 0)], np.inf)  # <= 0 inside that stance
        d_next = np.where(prev + 1 < len(a), a[nxt] - t, np.inf)
        use_prev = d_prev <= d_next
        which = np.where(use_prev, np.maximum(prev, 0), nxt)
        d = np.minimum(d_prev, d_next)
        w = np.clip(1.0 - d / max(fade, 1e-9), 0.0, 1.0) if fade > 0 else (d <= 0) * 1.0
        if smooth > 0:  # inside a stance its own frame; outside, the stance's nearer end
            target = path[np.where(d_prev <= 0, t, np.where(use_prev, b[which], a[which]))]
        else:
            target = mean[which]
        out[:, k] = w[:, None] * (target - J[:, j])
    return out


def lock_feet(frames: np.ndarray, fps: float, config: LockConfig = LockConfig()) -> np.ndarray:
    """frames: (T, 235) the filter's output at ``fps`` (finite joints and rotations) -> (T, 235) a
    copy whose planted foot joints stay at one point per stance, the legs following (module doc)."""
    f = np.array(frames, dtype=np.float64, copy=True)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    T = len(f)
    J = f[:, JOINTS].reshape(T, NUM_JOINTS, 3).copy()  # a copy: f's joints are overwritten below
    if T < 2 or not np.isfinite(J).all():
        return f.astype(frames.dtype)
    planted = stance_mask(J, fps, config.stance)
    if not planted.any():
        return f.astype(frames.dtype)
    delta = stance_corrections(J, planted, config.fade_s * fps, config.hold_s * fps)
    if not config.vertical:
        delta[..., 2] = 0.0
    new = J.copy()
    for side, (hip, knee, ankle, toe) in enumerate(LEG_CHAINS):
        d_ankle, d_toe = delta[:, side], delta[:, 2 + side]  # FOOT_JOINTS: left/right ankle, left/right foot
        touched = (np.abs(d_ankle).sum(-1) > 0) | (np.abs(d_toe).sum(-1) > 0)
        if not touched.any():
            continue
        t = np.flatnonzero(touched)
        toe_len = np.linalg.norm(J[t, toe] - J[t, ankle], axis=-1)
        if config.toe_first:  # one length for the clip: the filter's varies from frame to frame
            toe_len = np.full(len(t), float(np.median(np.linalg.norm(J[:, toe] - J[:, ankle], axis=-1))))
        ankle_goal = J[t, ankle] + d_ankle[t]
        if config.toe_first:  # a held toe puts the ankle on the sphere of the toe bone around it
            toe_goal = J[t, toe] + d_toe[t]
            held = np.abs(d_toe[t]).sum(-1) > 0
            away = ankle_goal - toe_goal
            on_sphere = toe_goal + toe_len[:, None] * away / np.maximum(np.linalg.norm(away, axis=-1), 1e-12)[:, None]
            ankle_goal = np.where(held[:, None], on_sphere, ankle_goal)
        new[t, knee], new[t, ankle] = two_bone_positions(
            J[t, hip], J[t, knee], ankle_goal, np.linalg.norm(J[t, knee] - J[t, hip], axis=-1),
            np.linalg.norm(J[t, ankle] - J[t, knee], axis=-1), reach_margin=(1e-6, 1e-6))
        aim = J[t, toe] + d_toe[t] - new[t, ankle]
        new[t, toe] = new[t, ankle] + toe_len[:, None] * aim / np.maximum(np.linalg.norm(aim, axis=-1), 1e-12)[:, None]
    f[:, JOINTS] = new.reshape(T, -1)
    rot = f[:, ROTATIONS].reshape(T, NUM_JOINTS, 6)
    if np.isfinite(rot).all():
        f[:, ROTATIONS] = _turn_leg_rotations(rot, J, new).reshape(T, -1)
    return f.astype(frames.dtype)


def _turn_leg_rotations(rot6: np.ndarray, old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Local rotations (T, 24, 6) whose hip, knee and ankle turn so that each one's bone (to its
    child: knee, ankle, toe), which the turns above it have already carried along, lands on the new
    joints' direction by the minimal world rotation; every other local rotation, and the legs' on
    frames where no joint of the leg moved, is kept as it came. Only the root and the legs of those
    frames are converted to matrices (the hips hang from the root)."""
    out = np.array(rot6, dtype=np.float64, copy=True)
    for hip, knee, ankle, toe in LEG_CHAINS:
        chain = [hip, knee, ankle, toe]
        t = np.flatnonzero((new[:, chain] != old[:, chain]).any(axis=(1, 2)))  # the frames this leg moved in
        if not len(t):
            continue
        root = sixd_to_matrix(out[t, 0])  # (n, 3, 3): the root's local rotation is its global one
        L = sixd_to_matrix(out[t][:, [hip, knee, ankle]])  # (n, 3, 3, 3) local
        G = {hip: root @ L[:, 0]}  # global orientations down the chain
        G[knee] = G[hip] @ L[:, 1]
        G[ankle] = G[knee] @ L[:, 2]
        acc = np.broadcast_to(np.eye(3), root.shape)  # world turn the joints above have applied
        parent_new = root
        for j, child in ((hip, knee), (knee, ankle), (ankle, toe)):
            cur = np.einsum("tij,tj->ti", acc, old[t, child] - old[t, j])
            acc = least_rotation(cur, new[t, child] - new[t, j]) @ acc
            G_new = acc @ G[j]
            out[t, j] = matrix_to_6d(np.swapaxes(parent_new, -1, -2) @ G_new)
            parent_new = G_new
    return out
