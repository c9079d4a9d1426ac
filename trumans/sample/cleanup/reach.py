"""Reach cleanup of sampled episodes: the acting arm brought onto its hand target (the arm analogue
of ``trumans.sample.cleanup.foot``).

The generator is asked for the wrist at a hand goal (``M_goal``) but its arm ends 0.4-0.6 m short
of a door handle. After each episode, for every frame with a reach weight ``w`` in (0, 1] and a
wrist target ``P`` (both from the plan's hand phases: ``reach_schedule``, filled in by
``trumans.sample.controller.Controller``), over the new frames only (the context stays as committed):

1. the wrist's goal is ``D = W + w (P - W)`` (``W``: the network's wrist), so the correction fades
   in and out with ``w`` and frames with ``w = 0`` keep the network's arm exactly;
2. when ``D`` is farther from the shoulder than the arm reaches (upper arm + forearm), the upper
   body (``spine1`` and everything above it) turns rigidly about the pelvis joint in the plane of
   pelvis, shoulder and ``D`` by the least angle that brings the shoulder within reach (closed
   form, law of cosines), never tilting the trunk (pelvis -> neck) beyond ``max_tilt`` from
   vertical (nor further, when the network's trunk is tilted more already) and at most
   ``max_lean`` (a bound on twists; the tilt limit is the one that acts: being absolute, it does
   not let the lean jump at a seam when the next episode continues the leaned context): a lean
   toward the target, bone lengths unchanged;
3. the arm is re-solved with two-bone IK (``trumans.sample.cleanup.common.arm_ik``):
   the shoulder stays, the wrist goes to ``D`` (clamped to the arm's reach: a target still out of
   reach after the lean is approached along the shoulder-target line on a straight arm), the
   elbow stays in the plane of the network's own bend, and the hand (index1) turns with the
   forearm (the least rotation from the old to the new forearm direction) and then, by the
   fraction ``w`` of its angle, into line with the forearm (a hand reaching for a handle points
   along the arm; the network's hand is often folded back 150-170 degrees), so every bone keeps
   its length.

The generator outputs joint positions, not rotations; like the foot cleanup this works on joint
positions only (rotations for export are fitted afterwards, ``trumans.ik.fit``).

Schedule (``reach_schedule``): an approach phase (pick_up, put_down, reach, the first part of
open / close) ramps ``w`` from 0 to 1 over its last ``ramp_in`` seconds with the target at its
hand goal, so the wrist is on the goal at the phase's last frame (the grasp: the frame
``trumans.sample.carry.plan_interactions`` picks as the closest); the moving part of open / close keeps
``w = 1`` with the target on the handle's path (``Phase.info['hand_path']``, eased in and out);
after the contact ends (the release) ``w`` falls back to 0 over ``ramp_out`` seconds with the
target held where the contact ended. All ramps are smoothsteps (zero slope at both ends).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.rotations import rodrigues, unit
from trumans.skeleton import JOINT_INDEX, SUBTREE

from trumans.easing import smoothstep
from trumans.sample.cleanup.common import ARMS, arm_ik, episode_joints

__all__ = ["ReachCleanupConfig", "reach_schedule", "release_weights", "lean_angle", "tilt_limit", "clean_reach"]

PELVIS, SPINE1, NECK = JOINT_INDEX["pelvis"], JOINT_INDEX["spine1"], JOINT_INDEX["neck"]


@dataclass(frozen=True)
class ReachCleanupConfig:
    """enabled: run the reach cleanup; ramp_in / ramp_out: seconds over which the correction fades
    in before a grasp / out after a release (the schedule: ``reach_schedule``, ``release_weights``,
    which the controller applies to the plan's hand phases); max_lean: the largest turn of the upper
    body toward an out-of-reach target, rad; max_tilt: the lean stops where the trunk (pelvis ->
    neck) is this far from vertical, rad (50 degrees: the door's first grasp, ~0.75 m from where the
    plan stands the body, needs it); tilt_steps: grid steps of the search for that stop (``tilt_limit``)."""

    enabled: bool = True
    ramp_in: float = 0.8
    ramp_out: float = 0.6
    max_lean: float = float(np.radians(60.0))
    max_tilt: float = float(np.radians(50.0))
    tilt_steps: int = 64

    def __post_init__(self) -> None:
        if self.tilt_steps < 1:
            raise ValueError(f"tilt_steps must be >= 1, got {self.tilt_steps}")
        if not (self.ramp_in > 0 and self.ramp_out > 0):
            raise ValueError(f"ramp_in and ramp_out must be > 0 s, got {self.ramp_in}, {self.ramp_out}")
        if not (0 <= self.max_lean <= np.pi / 2 and 0 <= self.max_tilt <= np.pi / 2):
            raise ValueError(f"max_lean and max_tilt must be in [0, pi/2] rad, got {self.max_lean}, {self.max_tilt}")


def reach_schedule(phase, u: np.ndarray, fps: float, config: ReachCleanupConfig = ReachCleanupConfig()
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Weights (n,) and wrist targets (n, 3) world m of a hand phase (``controller.Phase`` with a
    ``hand_goal``) at its frames ``u`` (n,) (0 = the phase's first frame); see the module doc."""
    u = np.asarray(u, dtype=np.float64)
    path = phase.info.get("hand_path")
    if path is not None:  # the moving part of open / close: on the handle's path, eased (starts and stops at rest)
        path = np.asarray(path, dtype=np.float64)
        s = smoothstep((u + 1) / phase.frames) * (len(path) - 1)
        i = np.clip(np.floor(s).astype(int), 0, len(path) - 2)
        a = (s - i)[:, None]
        return np.ones(len(u)), (1 - a) * path[i] + a * path[i + 1]
    to_end = phase.frames - 1 - u  # frames until the grasp (the phase's last frame)
    ramp = max(config.ramp_in * fps, 1.0)
    return smoothstep(1.0 - to_end / ramp), np.broadcast_to(np.asarray(phase.hand_goal, np.float64), (len(u), 3)).copy()


def release_weights(since: np.ndarray, fps: float, config: ReachCleanupConfig = ReachCleanupConfig()) -> np.ndarray:
    """Weights (n,) at ``since`` (n,) frames after the last contact frame (>= 1): 1 -> 0 over ``ramp_out``."""
    return 1.0 - smoothstep(np.asarray(since, dtype=np.float64) / (config.ramp_out * fps + 1.0))


def lean_angle(pivot: np.ndarray, shoulder: np.ndarray, target: np.ndarray, reach: float, max_lean: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(angle (...,) rad, axis (..., 3)) of the least rotation about ``pivot`` that brings
    ``shoulder`` within ``reach`` of ``target`` (all (..., 3) m), capped at ``max_lean``; angle 0
    where it is within reach already. With a = |shoulder - pivot|, b = |target - pivot| and phi the
    angle between them, the distance after a turn by theta is sqrt(a^2 + b^2 - 2ab cos(phi - theta))."""
    s, d = shoulder - pivot, target - pivot
    a, b = np.linalg.norm(s, axis=-1), np.linalg.norm(d, axis=-1)
    axis = np.cross(s, d)
    phi = np.arctan2(np.linalg.norm(axis, axis=-1), (s * d).sum(-1))
    c = (a * a + b * b - reach * reach) / np.maximum(2 * a * b, 1e-12)
    theta = phi - np.arccos(np.clip(c, -1.0, 1.0))
    far = np.linalg.norm(target - shoulder, axis=-1) > reach
    return np.where(far, np.clip(theta, 0.0, max_lean), 0.0), unit(axis)


def tilt_limit(trunk: np.ndarray, axis: np.ndarray, theta: np.ndarray, max_tilt: float, n: int = 64) -> np.ndarray:
    """The largest angle (...,) in [0, theta] by which ``trunk`` (..., 3) turns about unit ``axis``
    (..., 3) without tilting beyond ``max_tilt`` rad from vertical (or beyond its own tilt, when
    that is larger): the first crossing on a grid of ``n`` steps, linearly interpolated."""
    v = trunk / np.maximum(np.linalg.norm(trunk, axis=-1, keepdims=True), 1e-12)
    kv = (axis * v).sum(-1, keepdims=True)
    a = theta[..., None] * np.linspace(0.0, 1.0, n + 1)  # (..., n + 1)
    # z of v turned by a about the axis (Rodrigues): v_z cos a + (k x v)_z sin a + k_z (k.v)(1 - cos a)
    z = v[..., 2:3] * np.cos(a) + np.cross(axis, v)[..., 2:3] * np.sin(a) + axis[..., 2:3] * kv * (1 - np.cos(a))
    floor = np.minimum(np.cos(max_tilt), v[..., 2:3]) - 1e-12  # the least allowed z
    bad = z < floor
    first = np.where(bad.any(-1), bad.argmax(-1), n + 1)  # first grid step beyond the limit
    i = np.clip(first - 1, 0, n)
    j = np.clip(first, 0, n)
    zi, zj = np.take_along_axis(z, i[..., None], -1)[..., 0], np.take_along_axis(z, j[..., None], -1)[..., 0]
    frac = np.clip((zi - floor[..., 0]) / np.maximum(zi - zj, 1e-12), 0.0, 1.0)
    return np.where(first > n, theta, theta * (i + frac) / n)


def clean_reach(joints: np.ndarray, lengths: np.ndarray, target: np.ndarray, weight: np.ndarray, fixed: int = 0,
                config: ReachCleanupConfig = ReachCleanupConfig()) -> np.ndarray:
    """joints (B, T, 24, 3) world m on bone ``lengths`` (24,); target (B, T, 2, 3) wrist targets of
    the (left, right) arm (any value where the weight is 0); weight (B, T, 2) in [0, 1] -> cleaned
    copy (module doc). Frames < ``fixed`` (the context) are kept."""
    J = episode_joints(joints, fixed)
    B, T = J.shape[:2]
    target, weight = np.asarray(target, dtype=np.float64), np.asarray(weight, dtype=np.float64)
    if target.shape != (B, T, 2, 3) or weight.shape != (B, T, 2):
        raise ValueError(f"need target (B, T, 2, 3) and weight (B, T, 2) for joints {J.shape}, got "
                         f"{target.shape}, {weight.shape}")
    if not (np.isfinite(weight).all() and (weight >= 0).all() and (weight <= 1).all()):
        raise ValueError(f"reach weights must be finite and in [0, 1], got range "
                         f"[{np.nanmin(weight)}, {np.nanmax(weight)}]")
    active = weight > 0
    active[:, :fixed] = False
    if not np.isfinite(target[active]).all():
        raise ValueError("a reach target with a weight > 0 is not finite (NaN / inf); give a finite wrist target "
                         "or weight 0 there")
    upper = SUBTREE[SPINE1]
    for side, (sh, el, wr, ix) in enumerate(ARMS):
        act = active[..., side]
        if not act.any():
            continue
        w = np.where(act, weight[..., side], 0.0)[..., None]
        goal = J[:, :, wr] + w * (np.where(act[..., None], target[:, :, side], J[:, :, wr]) - J[:, :, wr])
        l1, l2 = float(lengths[el]), float(lengths[wr])
        # 2. lean the upper body toward a goal beyond the arm's reach
        theta, axis = lean_angle(J[:, :, PELVIS], J[:, :, sh], goal, l1 + l2 - 1e-3, config.max_lean)
        theta = tilt_limit(J[:, :, NECK] - J[:, :, PELVIS], axis, np.where(act, theta, 0.0), config.max_tilt,
                           config.tilt_steps)
        R = rodrigues(axis, theta)  # (B, T, 3, 3); identity where theta = 0
        O = J[:, :, PELVIS][:, :, None]
        turned = O + np.einsum("btij,btnj->btni", R, J[:, :, upper] - O)
        J[:, :, upper] = np.where((theta > 0)[..., None, None], turned, J[:, :, upper])
        # 3. two-bone IK of the arm, the elbow in the plane of the network's bend, the hand turning with the forearm
        new_el, new_wr, hand = arm_ik(J, (sh, el, wr, ix), goal, lengths)
        fore = new_wr - new_el
        cross = np.cross(hand, fore)
        angle = np.arctan2(np.linalg.norm(cross, axis=-1), (hand * fore).sum(-1))
        new_ix = new_wr + np.einsum("btij,btj->bti", rodrigues(cross, w[..., 0] * angle), hand)
        m = act[..., None]
        J[:, :, el] = np.where(m, new_el, J[:, :, el])
        J[:, :, wr] = np.where(m, new_wr, J[:, :, wr])
        J[:, :, ix] = np.where(m, new_ix, J[:, :, ix])
    return J.astype(np.asarray(joints).dtype)
