"""Hand conventions and the arm placement shared by every hand primitive (``trumans.synth.hands``).

Conventions owned here:

- **Hand contact point** ("palm point") = the midpoint of the wrist and the index1 joint
  (``palm_points``). At a grasp the palm point is placed ``PALM_GAP`` (1.5 cm) outside the object's
  surface at its ``grasp_point``, along the outward surface direction (``-grasp_axis``).
- **Hand frame**: the wrist's global rotation. In the rest pose (a T-pose, palms down) the palm
  normal is ``G_wrist @ -z`` and the finger axis ``G_wrist @ (+y)`` for the left hand,
  ``G_wrist @ (-y)`` for the right hand (as in ``trumans.contacts.rule``); ``hand_frame`` builds it.
- **Hand transform** ``H`` (4, 4) = [G_wrist | p_wrist]. A held object's world pose is
  ``H @ hold.offset`` where ``hold.offset`` = ``inv(H_grasp) @ object_pose_grasp`` is fixed at the
  grasp frame, so the object moves rigidly with the hand.
- **Primitives overlay a base motion**: each takes the body's own motion ``base`` (e.g.
  ``locomotion.stand`` / ``posture.sit`` / ``locomotion.walk``) and returns a copy with the arm(s)
  re-targeted by analytic limb IK (``place_arm``), the torso leaning where the hand needs it
  (``hands.lean``), action intervals, the object's (T, 4, 4) world pose track on every frame of the
  motion, and grasp flags keyed by the WRIST joint index (20 left, 21 right). Phase timing is in
  ``hands.timing``. Targets the arm cannot reach raise ``OutOfReach`` (a ValueError).
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from trumans.actions import ActionInterval
from trumans.rotations import unit, yaw_matrix
from trumans.skeleton import ELBOWS, SHOULDERS, WRISTS, forward_kinematics
from trumans.skeleton import INDEX1 as INDEX1S
from trumans.ik.limb import limb_reach, set_global_rotation, solve_limb
from ..motion import Motion, yaw_of
from ..poses import ease

__all__ = [
    "Side", "WRIST", "INDEX1", "SHOULDER", "ELBOW", "SIGN", "PALM_GAP", "REACH_FRAC", "PLAN_FRAC", "OutOfReach",
    "palm_points", "hand_transform", "hand_frame", "heading_frame", "actor_scale", "slerp_track", "place_arm",
    "wrist_targets", "wrist_to_palm", "base_arrays", "base_palm", "is_seated", "finish_motion", "require_reached",
    "reach_path", "reach_hold_retract", "hand_world",
]

Side = Literal["left", "right"]
# Joint of each side (trumans.skeleton's (left, right) groups, keyed by side).
WRIST: dict[str, int] = dict(zip(("left", "right"), WRISTS))
INDEX1: dict[str, int] = dict(zip(("left", "right"), INDEX1S))
SHOULDER: dict[str, int] = dict(zip(("left", "right"), SHOULDERS))
ELBOW: dict[str, int] = dict(zip(("left", "right"), ELBOWS))
SIGN: dict[str, float] = {"left": 1.0, "right": -1.0}  # +1: the body's left (+y in the heading frame)
PALM_GAP = 0.015  # m, palm point outside the surface at a grasp (about the palm's half thickness)
REACH_FRAC = 0.97  # fraction of the arm's full extension a target may ask for (then soft saturation)
PLAN_FRAC = 0.95  # fraction used when planning leans / stances (slack for sway and gait)
UP = np.array([0.0, 0.0, 1.0])
# Natural elbow direction from the shoulder in the heading frame (forward, left, up), per side.
ELBOW_DIR = {"left": np.array([-0.35, 0.7, -1.0]), "right": np.array([-0.35, -0.7, -1.0])}


class OutOfReach(ValueError):
    """The hand cannot reach the target from the given base motion (walk closer, then retry)."""


# ----------------------------------------------------------------------------- geometry helpers


def to_h(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    H = np.zeros(R.shape[:-2] + (4, 4))
    H[..., :3, :3], H[..., :3, 3], H[..., 3, 3] = R, p, 1.0
    return H


def inv_h(H: np.ndarray) -> np.ndarray:
    Rt = np.swapaxes(H[..., :3, :3], -1, -2)
    return to_h(Rt, -(Rt @ H[..., :3, 3:])[..., 0])


def apply_h(H: np.ndarray, p) -> np.ndarray:
    return (H[..., :3, :3] @ np.asarray(p, dtype=np.float64)[..., None])[..., 0] + H[..., :3, 3]


def check_side(side: str) -> None:
    if side not in WRIST:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")


def check_pose(pose: np.ndarray, what: str) -> np.ndarray:
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (4, 4):
        raise ValueError(f"{what} must be a (4, 4) world-from-object pose, got {pose.shape}")
    return pose


def palm_points(joints: np.ndarray) -> np.ndarray:
    """Hand contact points: joints (T, 24, 3) m -> (T, 2, 3) left/right midpoint of wrist and index1."""
    joints = np.asarray(joints)
    return 0.5 * (joints[..., [WRIST["left"], WRIST["right"]], :] + joints[..., [INDEX1["left"], INDEX1["right"]], :])


def hand_transform(m: Motion, side: Side) -> np.ndarray:
    """(T, 4, 4) world transform of the ``side`` wrist (global rotation, position in m)."""
    check_side(side)
    P, G = forward_kinematics(m.rot, m.root, m.offsets)
    return to_h(G[:, WRIST[side]], P[:, WRIST[side]])


def hand_frame(normal: np.ndarray, fingers: np.ndarray, side: Side) -> np.ndarray:
    """Wrist global rotation (..., 3, 3) whose palm faces ``normal`` (..., 3) with the fingers along
    ``fingers`` (..., 3) (orthogonalised against the normal); world vectors."""
    check_side(side)
    n = unit(np.asarray(normal, dtype=np.float64))
    f = np.asarray(fingers, dtype=np.float64)
    f = unit(f - (f * n).sum(-1, keepdims=True) * n)
    z = -n
    y = SIGN[side] * f
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def heading_frame(m: Motion) -> np.ndarray:
    """(T, 4, 4) body heading frame: origin at the pelvis, x forward (root yaw), z up."""
    R0 = m.rot[:, 0]
    yaw = yaw_of(R0)
    return to_h(yaw_matrix(yaw), m.root)


def actor_scale(offsets: np.ndarray) -> float:
    return float(limb_reach(offsets, "right_arm")[1] / 0.52)


def wrist_targets(palm: np.ndarray, R: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    """Wrist positions (..., 3) that put the palm point at ``palm`` with wrist rotation ``R``."""
    return palm - 0.5 * (R @ offsets[INDEX1[side]])


def wrist_to_palm(wrist: np.ndarray, R: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    return wrist + 0.5 * (R @ offsets[INDEX1[side]])


def slerp_track(A: np.ndarray, B: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-frame interpolation A -> B of rotation tracks A, B (T, 3, 3) by w (T,) that is continuous
    in time: where the relative rotation passes ~180 deg (its shortest axis flips between frames)
    the other way round is taken, so the blend never jumps."""
    rel = Rotation.from_matrix(np.swapaxes(A, -1, -2) @ B).as_rotvec()
    th = np.linalg.norm(rel, axis=-1)
    u = rel / np.maximum(th, 1e-12)[:, None]
    big = th > 2.5
    s = np.ones(len(th))
    both = big[1:] & big[:-1]
    s[1:][both] = np.sign((u[1:] * u[:-1]).sum(-1))[both] + (np.sign((u[1:] * u[:-1]).sum(-1))[both] == 0)
    c = np.cumprod(s)
    start = np.where(big & ~np.r_[False, both], np.arange(len(th)), 0)
    start = np.maximum.accumulate(start)
    prev = np.where(start > 0, c[np.maximum(start - 1, 0)], 1.0)
    parity = np.where(big, c * prev, 1.0)
    eff = np.where((parity > 0)[:, None], rel, -u * (2 * np.pi - th)[:, None])
    return A @ Rotation.from_rotvec(np.asarray(w, dtype=np.float64)[:, None] * eff).as_matrix()


# ----------------------------------------------------------------------------- arm placement


def place_arm(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side, palm: np.ndarray,
              R_hand: np.ndarray, w: np.ndarray, elbow_dir: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Blend the ``side`` arm from its pose in ``rot`` towards a hand with palm point ``palm``
    (T, 3) world m and wrist rotation ``R_hand`` (T, 3, 3), by weight ``w`` (T,) in [0, 1] (eased by
    the caller). ``elbow_dir`` (3,) or (T, 3): elbow direction from the shoulder in the heading frame.
    Returns (rot (T, 24, 3, 3), reached (T,) bool) — frames with w = 0 are unchanged."""
    T = rot.shape[0]
    w = np.clip(np.asarray(w, dtype=np.float64), 0.0, 1.0)
    mask = w > 1e-9
    if not mask.any():
        return rot.copy(), np.ones(T, dtype=bool)
    P, G = forward_kinematics(rot, root, offsets)
    wr, ix = WRIST[side], INDEX1[side]
    palm0 = 0.5 * (P[:, wr] + P[:, ix])
    Rw = slerp_track(G[:, wr], np.broadcast_to(R_hand, (T, 3, 3)), w)
    target = palm0 + w[:, None] * (np.asarray(palm) - palm0)
    wrist_t = wrist_targets(target, Rw, offsets, side)
    # Soft saturation of the shoulder-wrist distance above REACH_FRAC of full extension: near a
    # straight arm the elbow angle changes fast with distance, so targets beyond are pulled in
    # smoothly (C1) to at most REACH_FRAC + 0.02, and reported as not reached (> 1 mm moved).
    sh_p = P[:, SHOULDER[side]]
    v = wrist_t - sh_p
    dist = np.linalg.norm(v, axis=-1)
    R_full = limb_reach(offsets, f"{side}_arm")[1]
    a, b = REACH_FRAC * R_full, 0.02 * R_full
    sat = np.where(dist > a, a + b * np.tanh((dist - a) / b), dist)
    wrist_s = sh_p + v * (sat / np.maximum(dist, 1e-9))[:, None]
    close = np.linalg.norm(wrist_s - wrist_t, axis=-1) < 1e-3
    yaw = yaw_of(rot[:, 0])
    ed = np.broadcast_to(ELBOW_DIR[side] if elbow_dir is None else np.asarray(elbow_dir, float), (T, 3))
    nat = (yaw_matrix(yaw) @ unit(ed)[..., None])[..., 0]
    sh = P[:, SHOULDER[side]]
    cur = unit(P[:, ELBOW[side]] - sh)
    pole = sh + 0.5 * unit((1 - w)[:, None] * cur + w[:, None] * nat)
    out = set_global_rotation(rot, root, offsets, wr, np.where(mask[:, None, None], Rw, G[:, wr]))
    out, reached = solve_limb(out, root, offsets, f"{side}_arm", wrist_s, pole=pole, mask=mask)
    out[~mask] = rot[~mask]
    return out, reached & (close | ~mask)


def base_arrays(base: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not isinstance(base, Motion):
        raise ValueError(f"base must be a trumans.synth.motion.Motion, got {type(base).__name__}")
    return base.rot.copy(), base.root.copy(), np.asarray(base.offsets, dtype=np.float64)


def is_seated(base: Motion) -> bool:
    """A body is seated when its pelvis is well below the standing height (knees bent ~90 deg)."""
    return bool(base.root[0, 2] < 0.8 * base.offsets[0, 2])


def finish_motion(base: Motion, rot: np.ndarray, root: np.ndarray, actions: list[ActionInterval],
                  objects: dict[str, np.ndarray], grasp: dict[int, np.ndarray]) -> Motion:
    """The primitive's result: ``base`` with the new rotations / root, its foot contacts, and the
    primitive's action intervals, object tracks (name -> (T, 4, 4)) and grasp flags (wrist -> (T,))."""
    return Motion(rot=rot, root=root, offsets=base.offsets, fps=base.fps, foot_contact=base.foot_contact.copy(),
                  actions=actions, objects=objects, grasp=grasp)


def require_reached(reached: np.ndarray, frames: np.ndarray, what: str) -> None:
    bad = frames & ~reached
    if bad.any():
        raise OutOfReach(f"{what}: the hand does not reach its target on {int(bad.sum())} frames "
                         f"(first {int(np.flatnonzero(bad)[0])}); stand closer to the object")


def reach_path(palm0: np.ndarray, palm1: np.ndarray, out: np.ndarray, s: np.ndarray,
               clear: float = 0.08) -> np.ndarray:
    """Palm path (T, 3) from palm0 (T, 3) at s = 0 to palm1 (3,) at s = 1, bowed out along ``out``
    (the outward surface direction at the target) so that the hand arrives from outside."""
    e = ease(s)[:, None]
    return palm0 * (1 - e) + palm1 * e + (clear * 4.0 * e * (1 - e)) * out


def hand_world(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    P, G = forward_kinematics(rot, root, offsets)
    return to_h(G[:, WRIST[side]], P[:, WRIST[side]])


def base_palm(base: Motion, side: Side) -> np.ndarray:
    """(T, 3) the base motion's own palm point of ``side``."""
    return palm_points(base.joints())[:, 0 if side == "left" else 1]


def reach_hold_retract(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side, palm_base: np.ndarray,
                       held: np.ndarray, R_hand: np.ndarray, grip: int, release: int,
                       reach: tuple[np.ndarray, np.ndarray], retract: tuple[np.ndarray, np.ndarray], ramp: float,
                       what: str) -> tuple[np.ndarray, np.ndarray]:
    """The ``side`` arm reaches from its base palm track ``palm_base`` (T, 3) to the palm point
    ``reach[0]`` (3,) by frame ``grip``, arriving from outside along ``reach[1]`` (3,) (``reach_path``),
    follows the palm track ``held`` (T, 3) world m on the hold frames grip..release, and retracts
    from ``retract[0]`` to the base track by the last frame, leaving along ``retract[1]``; wrist
    rotations ``R_hand`` (T, 3, 3). The arm's weight rises ``ramp`` times faster than the path
    progress (eased), so the wrist is turned early. Returns (rot (T, 24, 3, 3), hold (T,) bool);
    raises OutOfReach when the hand misses a hold frame."""
    T = len(palm_base)
    t = np.arange(T)
    s_in = t / max(grip, 1)
    s_out = (T - 1 - t) / max(T - 1 - release, 1)
    path = np.where((t <= grip)[:, None], reach_path(palm_base, reach[0], reach[1], s_in),
                    reach_path(palm_base, retract[0], retract[1], s_out))
    hold = (t >= grip) & (t <= release)
    path[hold] = held[hold]
    w = np.where(hold, 1.0, ease(np.clip(np.minimum(s_in, s_out) * ramp, 0, 1)))
    rot, reached = place_arm(rot, root, offsets, side, path, R_hand, w)
    require_reached(reached, hold, what)
    return rot, hold
