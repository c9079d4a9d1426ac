"""Procedural hand interactions with small objects: reach + grasp, pick up / carry / put down,
drink, phone call. Desk work (type, use_mouse) is in ``hands_desk``, articulated and pushable
furniture (doors, drawers, push / pull) in ``hands_furniture``.

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
  re-targeted by analytic limb IK, the torso leaning where the hand needs it (feet stay where the
  base puts them, by leg IK), action intervals, the object's (T, 4, 4) world pose track on every
  frame of the motion, and grasp flags keyed by the WRIST joint index (20 left, 21 right). The phase
  durations are drawn from ``rng``, lengthened so that the palm's mean speed stays under
  ``HAND_SPEED`` (and the torso's lean is as slow), and fitted to the base's length: spare frames go
  to the primitive's steady phase (holding, sipping, typing, ...), a shortage compresses every
  phase (``nominal_frames`` gives a natural base length; a base under half the need is an error).
  Rotationally symmetric upright objects (bottle, cup, vase) are grasped on the side facing the
  reaching shoulder: their ``grasp_point`` turned about the object's vertical axis. The arm is back
  at its base pose on the base's last frame unless the object is still held, in which case it is at
  the carry pose (``carry_pose``), a deterministic function of the body state, so consecutive
  primitives join without a jump. Targets the arm cannot reach raise ``OutOfReach`` (a ValueError).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import yaw_matrix
from trumans.skeleton import JOINT_INDEX, forward_kinematics
from trumans.ik.limb import limb_reach, set_global_rotation, solve_limb
from .locomotion import pelvis_height_limit, solve_legs
from .motion import Motion
from .poses import ease, slerp_rot

__all__ = [
    "Side",
    "WRIST",
    "INDEX1",
    "PALM_GAP",
    "OutOfReach",
    "Hold",
    "palm_points",
    "hand_transform",
    "hand_frame",
    "heading_frame",
    "hand_for",
    "slerp_track",
    "carry_pose",
    "grasp_target",
    "choose_lean",
    "lean_travel",
    "place_arm",
    "HAND_SPEED",
    "nominal_frames",
    "reach_grasp",
    "pick_up",
    "carry",
    "put_down",
    "drink",
    "phone_call",
]

Side = Literal["left", "right"]
WRIST: dict[str, int] = {"left": JOINT_INDEX["left_wrist"], "right": JOINT_INDEX["right_wrist"]}
INDEX1: dict[str, int] = {"left": JOINT_INDEX["left_index1"], "right": JOINT_INDEX["right_index1"]}
SHOULDER: dict[str, int] = {"left": JOINT_INDEX["left_shoulder"], "right": JOINT_INDEX["right_shoulder"]}
ELBOW: dict[str, int] = {"left": JOINT_INDEX["left_elbow"], "right": JOINT_INDEX["right_elbow"]}
SIGN: dict[str, float] = {"left": 1.0, "right": -1.0}  # +1: the body's left (+y in the heading frame)
PALM_GAP = 0.015  # m, palm point outside the surface at a grasp (about the palm's half thickness)
REACH_FRAC = 0.97  # fraction of the arm's full extension a target may ask for (then soft saturation)
PLAN_FRAC = 0.95  # fraction used when planning leans / stances (slack for sway and gait)
_UP = np.array([0.0, 0.0, 1.0])
# Natural elbow direction from the shoulder in the heading frame (forward, left, up), per side.
_ELBOW_DIR = {"left": np.array([-0.35, 0.7, -1.0]), "right": np.array([-0.35, -0.7, -1.0])}

# Nominal phase durations (s): (low, high) per phase name.
_PHASES: dict[str, dict[str, tuple[float, float]]] = {
    "reach_grasp": {"reach": (1.0, 1.4), "grasp": (0.8, 1.6), "release": (0.9, 1.2)},
    "pick_up": {"reach": (1.0, 1.4), "grasp": (0.25, 0.4), "pick_up": (0.9, 1.3), "carry": (0.3, 0.8)},
    "put_down": {"put_down": (0.9, 1.3), "release": (0.2, 0.35), "retract": (0.8, 1.1)},
    "drink": {"raise": (1.1, 1.5), "sip": (1.2, 2.5), "lower": (1.0, 1.4)},
    "phone_call": {"raise": (1.2, 1.6), "talk": (2.0, 5.0), "lower": (1.1, 1.5)},
}


class OutOfReach(ValueError):
    """The hand cannot reach the target from the given base motion (walk closer, then retry)."""


@dataclass
class Hold:
    """An object held in one hand. ``offset`` (4, 4): hand-from-object transform (object pose =
    hand transform @ offset); ``carry`` (3,) palm point and ``carry_rot`` (3, 3) wrist rotation
    while carried, both in the heading frame (``heading_frame``) of the body; ``name`` the object."""

    name: str
    side: Side
    offset: np.ndarray
    carry: np.ndarray
    carry_rot: np.ndarray


# ----------------------------------------------------------------------------- geometry helpers


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _rodrigues(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit axes (T, 3), angles (T,) -> (T, 3, 3)."""
    axis = _unit(np.asarray(axis, dtype=np.float64))
    K = np.zeros(axis.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -axis[..., 2], axis[..., 1], -axis[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _to_h(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    H = np.zeros(R.shape[:-2] + (4, 4))
    H[..., :3, :3], H[..., :3, 3], H[..., 3, 3] = R, p, 1.0
    return H


def _inv_h(H: np.ndarray) -> np.ndarray:
    Rt = np.swapaxes(H[..., :3, :3], -1, -2)
    return _to_h(Rt, -(Rt @ H[..., :3, 3:])[..., 0])


def _apply(H: np.ndarray, p) -> np.ndarray:
    return (H[..., :3, :3] @ np.asarray(p, dtype=np.float64)[..., None])[..., 0] + H[..., :3, 3]


def _check_side(side: str) -> None:
    if side not in WRIST:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")


def _check_pose(pose: np.ndarray, what: str) -> np.ndarray:
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
    _check_side(side)
    P, G = forward_kinematics(m.rot, m.root, m.offsets)
    return _to_h(G[:, WRIST[side]], P[:, WRIST[side]])


def hand_frame(normal: np.ndarray, fingers: np.ndarray, side: Side) -> np.ndarray:
    """Wrist global rotation (..., 3, 3) whose palm faces ``normal`` (..., 3) with the fingers along
    ``fingers`` (..., 3) (orthogonalised against the normal); world vectors."""
    _check_side(side)
    n = _unit(np.asarray(normal, dtype=np.float64))
    f = np.asarray(fingers, dtype=np.float64)
    f = _unit(f - (f * n).sum(-1, keepdims=True) * n)
    z = -n
    y = SIGN[side] * f
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def heading_frame(m: Motion) -> np.ndarray:
    """(T, 4, 4) body heading frame: origin at the pelvis, x forward (root yaw), z up."""
    R0 = m.rot[:, 0]
    yaw = np.arctan2(R0[:, 1, 0], R0[:, 0, 0])
    return _to_h(yaw_matrix(yaw), m.root)


def _actor_scale(offsets: np.ndarray) -> float:
    return float(limb_reach(offsets, "right_arm")[1] / 0.52)


def carry_pose(m: Motion, hold: Hold) -> tuple[np.ndarray, np.ndarray]:
    """World palm-point targets (T, 3) and wrist rotations (T, 3, 3) of a carried object over ``m``."""
    F = heading_frame(m)
    return _apply(F, hold.carry), F[:, :3, :3] @ hold.carry_rot


def _object_height(obj: SceneObject) -> float:
    return float(obj.mesh.bounds[1, 2])


# ----------------------------------------------------------------------------- timing


def nominal_frames(kind: str, rng: np.random.Generator, fps: float = 30.0) -> int:
    """A natural length (frames) of a base motion for primitive ``kind`` (one of the keys of the
    phase table: reach_grasp, pick_up, put_down, drink, phone_call, type, use_mouse, open_door,
    close_door, open_drawer, close_drawer)."""
    from .hands_desk import _PHASES as DESK
    from .hands_furniture import _PHASES as FURN

    table = {**_PHASES, **DESK, **FURN}
    if kind not in table:
        raise ValueError(f"unknown primitive {kind!r}; choose one of {sorted(table)}")
    # 25 % slack: reaches far away take longer than the nominal phases (see ``_phases``).
    return int(round(1.25 * sum(rng.uniform(*v) for v in table[kind].values()) * fps)) + 1


# The phase that absorbs spare frames of the base, per primitive.
FLEX: dict[str, str] = {"reach_grasp": "grasp", "pick_up": "carry", "put_down": "release", "drink": "sip",
                        "phone_call": "talk", "type": "work", "use_mouse": "work", "open_door": "move",
                        "close_door": "move", "open_drawer": "move", "close_drawer": "move"}
HAND_SPEED = 0.65  # m/s, mean palm speed of a reach (eased: peak ~1.9x, 1.2 m/s)


def _phases(kind: str, T: int, rng: np.random.Generator, fps: float,
            table: dict[str, dict[str, tuple[float, float]]] | None = None,
            moves: dict[str, float] | None = None) -> dict[str, tuple[int, int]]:
    """Phase name -> (first frame, last frame) covering 0..T-1. Durations are drawn from the
    nominal table, raised so that each phase in ``moves`` (phase -> palm path length, m) keeps the
    mean hand speed under ``HAND_SPEED``; spare frames go to the FLEX phase, a shortage compresses
    every phase (at most 2x, else ValueError)."""
    spec = (table or _PHASES)[kind]
    names = list(spec)
    dur = np.array([rng.uniform(*v) for v in spec.values()])
    for k, dist in (moves or {}).items():
        i = names.index(k)
        dur[i] = max(dur[i], 0.25 + float(dist) / HAND_SPEED)
    need = dur.sum() * fps
    if T - 1 < 0.5 * need or T - 1 < 2 * len(spec):
        raise ValueError(f"{kind}: the base motion has {T} frames, too short for its phases "
                         f"(about {int(need) + 1} frames natural, at least {int(0.5 * need) + 1}); "
                         f"make the base with nominal_frames({kind!r}, rng, fps) frames or more")
    if T - 1 > need:
        dur[names.index(FLEX[kind])] += (T - 1 - need) / fps
    edges = np.round(np.concatenate([[0.0], np.cumsum(dur)]) / dur.sum() * (T - 1)).astype(int)
    return {k: (int(edges[i]), int(edges[i + 1])) for i, k in enumerate(names)}


def _ramp(T: int, a: int, b: int) -> np.ndarray:
    """(T,) eased 0 -> 1 from frame a to frame b (0 before, 1 after)."""
    t = np.arange(T, dtype=np.float64)
    return ease((t - a) / max(b - a, 1))


# ----------------------------------------------------------------------------- torso lean


def _lean_pose(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, pitch: np.ndarray, drop: np.ndarray,
               seated: bool) -> tuple[np.ndarray, np.ndarray]:
    """Forward lean ``pitch`` (T,) rad (hip hinge 55 %, spine 45 %) and pelvis drop ``drop`` (T,) m;
    feet kept where the input puts them (leg IK). Seated bodies keep the pelvis on the seat."""
    rot, root = rot.copy(), root.copy()
    if not (np.any(pitch) or np.any(drop)):
        return rot, root
    P, G = forward_kinematics(rot, root, offsets)
    ank = P[:, [JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"]]]
    frot = G[:, [JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"]]]
    yaw = np.arctan2(rot[:, 0, 1, 0], rot[:, 0, 0, 0])
    fwd = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], -1)
    left = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], -1)
    rot[:, 0] = _rodrigues(left, 0.55 * pitch) @ rot[:, 0]
    ey = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (len(pitch), 3))
    for j, f in ((JOINT_INDEX["spine1"], 0.25), (JOINT_INDEX["spine2"], 0.2)):
        rot[:, j] = _rodrigues(ey, f * pitch) @ rot[:, j]
    if not seated:
        root[:, :2] -= (0.12 * np.sin(0.55 * pitch))[:, None] * fwd[:, :2]  # hips back to balance
        root[:, 2] -= drop
        h_lim = pelvis_height_limit(rot, root[:, :2], offsets, ank)
        root[:, 2] = np.minimum(root[:, 2], h_lim - 0.001)
    rot, _ = solve_legs(rot, root, offsets, ank, foot_rot=frot, pole_dir=fwd)
    return rot, root


def _lean_candidates(seated: bool, scale: float, max_pitch: float = np.inf,
                     max_drop: float = np.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pitch (K,), drop (K,), cost (K,)) candidate leans (pitch <= max_pitch rad, drop <= max_drop m),
    cheapest first."""
    pitch = np.radians(np.linspace(0.0, 55.0 if seated else 75.0, 12 if seated else 11))
    drops = np.array([0.0]) if seated else scale * np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    pp, dd = np.meshgrid(pitch, drops, indexing="ij")
    pp, dd = pp.ravel(), dd.ravel()
    cost = pp / np.radians(60.0) + 1.5 * dd / 0.4  # a squat costs more than a lean
    keep = (pp <= max_pitch + 1e-9) & (dd <= max_drop + 1e-9)
    pp, dd, cost = pp[keep], dd[keep], cost[keep]
    o = np.argsort(cost, kind="stable")
    return pp[o], dd[o], cost[o]


def _wrist_targets(palm: np.ndarray, R: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    """Wrist positions (..., 3) that put the palm point at ``palm`` with wrist rotation ``R``."""
    return palm - 0.5 * (R @ offsets[INDEX1[side]])


def choose_lean(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, side: Side, wrists: np.ndarray,
                seated: bool, max_pitch: float = np.inf, max_drop: float = np.inf,
                clear=None) -> tuple[float, float]:
    """Cheapest (pitch rad, drop m) lean of the body state rot1 (24, 3, 3), root1 (3,) from which
    the ``side`` shoulder reaches every wrist target in ``wrists`` (M, 3) (leans limited to
    ``max_pitch`` rad / ``max_drop`` m; ``clear``: optional test joints (K, 24, 3) -> (K,) bool that
    a leaned body must pass, e.g. keeping clear of the object). Raises OutOfReach."""
    pitch, drop, _ = _lean_candidates(seated, _actor_scale(offsets), max_pitch, max_drop)
    K = len(pitch)
    rot, root = _lean_pose(np.repeat(rot1[None], K, 0), np.repeat(root1[None], K, 0), offsets, pitch, drop, seated)
    P, _ = forward_kinematics(rot, root, offsets)
    lo, hi = limb_reach(offsets, f"{side}_arm")
    d = np.linalg.norm(np.asarray(wrists)[None] - P[:, SHOULDER[side]][:, None], axis=-1)  # (K, M)
    ok = ((d <= PLAN_FRAC * hi) & (d >= 1.15 * lo)).all(axis=1)
    if clear is not None:
        ok &= clear(P)
    if not ok.any():
        raise OutOfReach(f"the {side} hand cannot reach {np.round(wrists, 3).tolist()} from the pelvis at "
                         f"{np.round(root1, 3).tolist()} even leaning (nearest shoulder distance "
                         f"{d.max(axis=1).min():.2f} m, arm reach {PLAN_FRAC * hi:.2f} m): stand closer")
    k = int(np.flatnonzero(ok)[0])
    return float(pitch[k]), float(drop[k])


def lean_travel(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, pitch: float, drop: float,
                seated: bool) -> float:
    """Largest joint displacement (m) that a lean (pitch rad, drop m) causes on the state rot1
    (24, 3, 3), root1 (3,) — the lean's own path length, used to time the phase it happens in."""
    if pitch == 0.0 and drop == 0.0:
        return 0.0
    rot, root = _lean_pose(np.stack([rot1, rot1]), np.stack([root1, root1]), offsets, np.array([0.0, pitch]),
                           np.array([0.0, drop]), seated)
    P, _ = forward_kinematics(rot, root, offsets)
    return float(np.linalg.norm(P[1] - P[0], axis=-1).max())


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
    wrist_t = _wrist_targets(target, Rw, offsets, side)
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
    yaw = np.arctan2(rot[:, 0, 1, 0], rot[:, 0, 0, 0])
    ed = np.broadcast_to(_ELBOW_DIR[side] if elbow_dir is None else np.asarray(elbow_dir, float), (T, 3))
    nat = (yaw_matrix(yaw) @ _unit(ed)[..., None])[..., 0]
    sh = P[:, SHOULDER[side]]
    cur = _unit(P[:, ELBOW[side]] - sh)
    pole = sh + 0.5 * _unit((1 - w)[:, None] * cur + w[:, None] * nat)
    out = set_global_rotation(rot, root, offsets, wr, np.where(mask[:, None, None], Rw, G[:, wr]))
    out, reached = solve_limb(out, root, offsets, f"{side}_arm", wrist_s, pole=pole, mask=mask)
    out[~mask] = rot[~mask]
    return out, reached & (close | ~mask)


def _base_arrays(base: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not isinstance(base, Motion):
        raise ValueError(f"base must be a trumans.synth.motion.Motion, got {type(base).__name__}")
    return base.rot.copy(), base.root.copy(), np.asarray(base.offsets, dtype=np.float64)


def _is_seated(base: Motion) -> bool:
    """A body is seated when its pelvis is well below the standing height (knees bent ~90 deg)."""
    return bool(base.root[0, 2] < 0.8 * base.offsets[0, 2])


def _finish(base: Motion, rot: np.ndarray, root: np.ndarray, actions: list[ActionInterval],
            objects: dict[str, np.ndarray], grasp: dict[int, np.ndarray]) -> Motion:
    return Motion(rot=rot, root=root, offsets=base.offsets, fps=base.fps, foot_contact=base.foot_contact.copy(),
                  actions=actions, objects=objects, grasp=grasp)


def _require(reached: np.ndarray, frames: np.ndarray, what: str) -> None:
    bad = frames & ~reached
    if bad.any():
        raise OutOfReach(f"{what}: the hand does not reach its target on {int(bad.sum())} frames "
                         f"(first {int(np.flatnonzero(bad)[0])}); stand closer to the object")


# ----------------------------------------------------------------------------- grasp planning


def grasp_target(obj: SceneObject, pose: np.ndarray, shoulder: np.ndarray,
                 side: Side) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where and how the ``side`` hand grasps ``obj`` at world ``pose`` (4, 4), seen from a shoulder
    at ``shoulder`` (3,): (surface point (3,), palm point (3,),
    wrist rotation (3, 3)). Upright revolved objects (grasp_axis horizontal) are grasped on the side
    facing the shoulder (turned 35 deg towards the body's midline, thumb up); top grasps come from
    above with the fingers along the object axis closest to the reach direction."""
    if "grasp_point" not in obj.meta or "grasp_axis" not in obj.meta:
        raise ValueError(f"object {obj.name!r} ({obj.category}) has no grasp_point / grasp_axis meta")
    gp = np.asarray(obj.meta["grasp_point"], dtype=np.float64)
    ga = _unit(np.asarray(obj.meta["grasp_axis"], dtype=np.float64))
    R = pose[:3, :3]
    upright = R[2, 2] > np.cos(np.radians(10))
    reach = shoulder - _apply(pose, [0.0, 0.0, gp[2]])
    reach_h = _unit(np.array([reach[0], reach[1], 0.0]))
    if abs(ga[2]) < 0.3 and upright and np.hypot(gp[0], gp[1]) > 1e-4 and obj.category in ("bottle", "cup", "vase"):
        # Revolved around local z: grasp the side turned towards the shoulder, rotated towards the midline.
        turn = np.radians(35.0) * (1.0 if side == "right" else -1.0)
        out = yaw_matrix(turn) @ reach_h  # outward surface direction (from the axis to the palm)
        r = np.hypot(gp[0], gp[1])
        axis_pt = _apply(pose, [0.0, 0.0, gp[2]])
        surf = axis_pt + r * out
        n = -out
        fingers = np.cross(n, _UP) if side == "right" else np.cross(_UP, n)
        return surf, surf + PALM_GAP * out, hand_frame(n, fingers, side)  # thumb up
    surf = _apply(pose, gp)
    n = R @ ga
    cand = np.concatenate([R[:, :2].T, -R[:, :2].T])  # object's local +-x, +-y in world
    d = -reach_h
    cand = cand - (cand @ n)[:, None] * n
    fingers = cand[np.argmax(_unit(cand) @ d)]
    return surf, surf - PALM_GAP * n, hand_frame(n, fingers, side)


def _reach_path(palm0: np.ndarray, palm1: np.ndarray, out: np.ndarray, s: np.ndarray,
                clear: float = 0.08) -> np.ndarray:
    """Palm path (T, 3) from palm0 (T, 3) at s = 0 to palm1 (3,) at s = 1, bowed out along ``out``
    (the outward surface direction at the target) so that the hand arrives from outside."""
    e = ease(s)[:, None]
    return palm0 * (1 - e) + palm1 * e + (clear * 4.0 * e * (1 - e)) * out


def _hand_world(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    P, G = forward_kinematics(rot, root, offsets)
    return _to_h(G[:, WRIST[side]], P[:, WRIST[side]])


def _default_carry(offsets: np.ndarray, side: Side, rng: np.random.Generator, seated: bool) -> np.ndarray:
    """Carry palm point in the heading frame (m): in front of the hip, higher when seated (above the thighs)."""
    s = _actor_scale(offsets)
    return s * np.array([0.30 + rng.uniform(-0.02, 0.03), SIGN[side] * (0.17 + rng.uniform(-0.02, 0.02)),
                         (0.28 if seated else 0.10) + rng.uniform(-0.03, 0.03)])


def hand_for(base: Motion, point: np.ndarray, frame: int = 0) -> Side:
    """The hand on the side of the body where world ``point`` (3,) lies at ``frame`` of ``base``."""
    rel = _inv_h(heading_frame(base)[frame]) @ np.r_[np.asarray(point, dtype=np.float64)[:3], 1.0]
    return "left" if rel[1] > 0 else "right"


# ----------------------------------------------------------------------------- primitives


def _base_palm(base: Motion, side: Side) -> np.ndarray:
    """(T, 3) the base motion's own palm point of ``side``."""
    return palm_points(base.joints())[:, 0 if side == "left" else 1]


def _grasp_phase(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, frame: int):
    """Lean + grasp target of ``obj`` for the body at base frame ``frame``."""
    rot, root, off = _base_arrays(base)
    P, _ = forward_kinematics(rot[frame:frame + 1], root[frame:frame + 1], off)
    surf, palm, Rh = grasp_target(obj, pose, P[0, SHOULDER[side]], side)
    pitch, drop = choose_lean(rot[frame], root[frame], off, side, _wrist_targets(palm, Rh, off, side)[None],
                              _is_seated(base))
    return surf, palm, Rh, pitch, drop


def reach_grasp(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, rng: np.random.Generator) -> Motion:
    """Reach for ``obj`` (at world ``pose`` (4, 4)), hold it without lifting, let go and return.

    base: the body's own motion (T frames, e.g. ``locomotion.stand``; see ``nominal_frames``).
    Labels 'reach' (to the grasp frame) and 'grasp' (grasp frame to release). The object does not
    move (its constant pose is returned in ``objects[obj.name]``); grasp flags on the wrist."""
    _check_side(side)
    pose = _check_pose(pose, "pose")
    T = base.num_frames
    surf, palm, Rh, pitch, drop = _grasp_phase(base, obj, pose, side, 0)
    pb = _base_palm(base, side)
    lt = lean_travel(base.rot[0], base.root[0], base.offsets, pitch, drop, _is_seated(base))
    ph = _phases("reach_grasp", T, rng, base.fps, moves={"reach": max(np.linalg.norm(palm - pb[0]) + 0.05, lt),
                                                         "release": max(np.linalg.norm(palm - pb[-1]) + 0.05, lt)})
    g0, g1 = ph["grasp"]
    rot, root, off = _base_arrays(base)
    lean = _ramp(T, 0, g0) * (1 - _ramp(T, g1, T - 1))
    rot, root = _lean_pose(rot, root, off, pitch * lean, drop * lean, _is_seated(base))
    P, _ = forward_kinematics(rot, root, off)
    palm_b = palm_points(P)[:, 0 if side == "left" else 1]
    out = _unit(_unit(palm - surf) + [0.0, 0.0, 1.0])  # arrive from outside and above (clear the support)
    s_in = np.arange(T) / max(g0, 1)
    s_out = (T - 1 - np.arange(T)) / max(T - 1 - g1, 1)
    path = np.where((np.arange(T) <= g0)[:, None], _reach_path(palm_b, palm, out, s_in),
                    _reach_path(palm_b, palm, out, s_out))
    w = np.clip(np.minimum(s_in, s_out) * 4, 0, 1)  # orientation weight reaches 1 early in the reach
    hold = (np.arange(T) >= g0) & (np.arange(T) <= g1)
    path[hold] = palm
    w = np.where(hold, 1.0, ease(w))
    rot, reached = place_arm(rot, root, off, side, path, np.broadcast_to(Rh, (T, 3, 3)), w)
    _require(reached, hold, f"reach_grasp {obj.name}")
    return _finish(base, rot, root, [ActionInterval("reach", 0, g0), ActionInterval("grasp", g0, g1)],
                   {obj.name: np.broadcast_to(pose, (T, 4, 4)).copy()}, {WRIST[side]: hold})


def pick_up(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, rng: np.random.Generator,
            carry_point: np.ndarray | None = None) -> tuple[Motion, Hold]:
    """Reach for ``obj`` at world ``pose`` (4, 4), grasp it, lift it to the carry pose and hold it.

    Labels 'reach' (start -> grasp frame), 'grasp' (short closing of the hand), 'pick_up' (lift to
    the carry pose), 'carry' (the rest). ``carry_point`` (3,) palm point in the heading frame
    (default: drawn from ``rng``, in front of the hip). Returns (motion, hold) — hand ``hold`` to
    ``carry`` / ``drink`` / ``phone_call`` / ``put_down``; the motion ends at the carry pose."""
    _check_side(side)
    pose = _check_pose(pose, "pose")
    T = base.num_frames
    surf, palm, Rh, pitch, drop = _grasp_phase(base, obj, pose, side, 0)
    rot, root, off = _base_arrays(base)
    carry = _default_carry(off, side, rng, _is_seated(base)) if carry_point is None \
        else np.asarray(carry_point, dtype=np.float64)
    c0 = _apply(heading_frame(base)[0], carry)
    lt = lean_travel(rot[0], root[0], off, pitch, drop, _is_seated(base))
    ph = _phases("pick_up", T, rng, base.fps, moves={
        "reach": max(np.linalg.norm(palm - _base_palm(base, side)[0]) + 0.05, lt),
        "pick_up": max(np.linalg.norm(palm - c0) + 0.1, 1.7 * lt)})
    g0, g1 = ph["grasp"]
    p0, p1 = ph["pick_up"]
    t = np.arange(T)
    s_lift = np.clip((t - p0) / max(p1 - p0, 1), 0, 1)
    e_move = ease(np.clip(1.3 * s_lift - 0.3, 0, 1))  # palm grasp -> carry, after a short lift
    # The torso straightens once the object is on its way in (a straightening torso with the hand
    # still at the support would over-extend the arm).
    lean = _ramp(T, 0, g0) * (1 - ease(np.clip((s_lift - 0.4) / 0.6, 0, 1)))
    seated = _is_seated(base)
    rot, root = _lean_pose(rot, root, off, pitch * lean, drop * lean, seated)
    P, _ = forward_kinematics(rot, root, off)
    F = heading_frame(Motion(rot, root, off))
    # Carry orientation: the grasp orientation seen from the body's heading at the grasp frame.
    carry_rot = F[g0, :3, :3].T @ Rh
    hold = Hold(obj.name, side, np.eye(4), carry, carry_rot)
    palm_b = palm_points(P)[:, 0 if side == "left" else 1]
    out = _unit(_unit(palm - surf) + [0.0, 0.0, 1.0])  # arrive from outside and above (clear the support)
    path = _reach_path(palm_b, palm, out, t / max(g0, 1))
    R = np.broadcast_to(Rh, (T, 3, 3)).copy()
    w = ease(np.clip(t / max(g0, 1) * 1.6, 0, 1))
    path[g0:p0 + 1] = palm
    # Lift: palm from the grasp point to the carry point, first up (clear the support), then in.
    c_w = _apply(F, carry)
    s = s_lift
    e = ease(s)[:, None]
    up = 0.06 * _actor_scale(off) * np.sin(np.pi * np.clip(1.5 * s, 0, 1))[:, None] * _UP
    lift = palm * (1 - e_move[:, None]) + c_w * e_move[:, None] + up
    R_c = F[:, :3, :3] @ carry_rot
    sel = t > p0
    path[sel] = lift[sel]
    R[sel] = slerp_rot(np.broadcast_to(Rh, (T, 3, 3)), R_c, e[:, 0])[sel]
    w[t >= g0] = 1.0
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    _require(reached, (t >= g0) & (t <= p0), f"pick_up {obj.name}")  # then the object follows the hand
    H = _hand_world(rot, root, off, side)
    hold.offset = _inv_h(H[g0]) @ pose
    track = np.broadcast_to(pose, (T, 4, 4)).copy()
    track[g0:] = H[g0:] @ hold.offset
    actions = [ActionInterval("reach", 0, g0), ActionInterval("grasp", g0, g1), ActionInterval("pick_up", g1, p1)]
    if p1 < T - 1:
        actions.append(ActionInterval("carry", p1, T - 1))
    return _finish(base, rot, root, actions, {obj.name: track}, {WRIST[side]: t >= g0}), hold


def carry(base: Motion, hold: Hold) -> Motion:
    """Carry a held object over the base motion (e.g. a ``locomotion.walk``): the holding arm stays
    at the carry pose, the object follows the hand. Label 'carry' on every frame."""
    rot, root, off = _base_arrays(base)
    T = base.num_frames
    palm, R = carry_pose(base, hold)
    rot, _ = place_arm(rot, root, off, hold.side, palm, R, np.ones(T))
    # (an unreached carry target leaves the arm stretched towards it; the object follows the hand)
    H = _hand_world(rot, root, off, hold.side)
    return _finish(base, rot, root, [ActionInterval("carry", 0, T - 1)], {hold.name: H @ hold.offset},
                   {WRIST[hold.side]: np.ones(T, dtype=bool)})


def put_down(base: Motion, hold: Hold, target: np.ndarray, rng: np.random.Generator,
             exact_yaw: bool = False) -> Motion:
    """Put a held object down at world ``target`` (4, 4) object pose (e.g. standing on a table),
    release it and bring the arm back to the base pose. Label 'put_down' on every frame; the object
    follows the hand until the release frame and stays at the placed pose after it (read it from
    ``objects[name][-1]``). Unless ``exact_yaw``, the target is turned about the world vertical so
    that the object keeps the yaw it has relative to the body while carried (the wrist need not
    twist); its position and tilt are kept."""
    target = _check_pose(target, "target")
    side = hold.side
    T = base.num_frames
    rot, root, off = _base_arrays(base)
    if not exact_yaw:
        carried = heading_frame(base)[-1, :3, :3] @ hold.carry_rot @ hold.offset[:3, :3]
        d_yaw = np.arctan2(carried[1, 0], carried[0, 0]) - np.arctan2(target[1, 0], target[0, 0])
        target = target.copy()
        target[:3, :3] = yaw_matrix(d_yaw) @ target[:3, :3]
    Ht = target @ _inv_h(hold.offset)  # hand transform that puts the object at the target
    Rh = Ht[:3, :3]
    palm = _wrist_to_palm(Ht[:3, 3], Rh, off, side)
    pitch, drop = choose_lean(rot[0], root[0], off, side, Ht[:3, 3][None], _is_seated(base))
    c0 = carry_pose(base, hold)[0][0]
    lt = lean_travel(rot[0], root[0], off, pitch, drop, _is_seated(base))
    ph = _phases("put_down", T, rng, base.fps, moves={
        "put_down": max(np.linalg.norm(palm - c0) + 0.1, lt),
        "retract": max(np.linalg.norm(palm - _base_palm(base, side)[-1]) + 0.05, lt)})
    d0, d1 = ph["put_down"]
    r0, r1 = ph["release"]
    t = np.arange(T)
    s = np.clip((t - d0) / max(d1 - d0, 1), 0, 1)
    e = ease(s)
    lean = e * (1 - _ramp(T, r1, T - 1))  # the torso leans in as the object goes out
    rot, root = _lean_pose(rot, root, off, pitch * lean, drop * lean, _is_seated(base))
    c_p, c_R = carry_pose(Motion(rot, root, off), hold)
    hover = (0.05 * 4.0 * e * (1 - e))[:, None] * _UP  # over the support's edge, then down
    path = c_p * (1 - e[:, None]) + palm * e[:, None] + hover
    R = slerp_rot(c_R, np.broadcast_to(Rh, (T, 3, 3)), ease(s))
    w = np.ones(T)
    sel = t >= d1
    path[sel] = palm
    R[sel] = Rh
    # Retract: the hand moves back off the object along its grasp direction, then blends out.
    so = np.clip((t - r1) / max(T - 1 - r1, 1), 0, 1)
    out_dir = _unit(palm - target[:3, 3])  # away from the object's origin (bottom centre)
    back = t > r1
    path[back] = (palm + 0.06 * np.sin(np.pi * so)[:, None] * out_dir)[back]
    w[back] = 1 - ease(so[back])
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    held = t <= r0
    _require(reached, (t >= d1) & (t <= r1), f"put_down {hold.name}")
    H = _hand_world(rot, root, off, side)
    track = H @ hold.offset
    track[r0:] = track[r0]
    return _finish(base, rot, root, [ActionInterval("put_down", 0, T - 1)], {hold.name: track},
                   {WRIST[side]: held})


def _wrist_to_palm(wrist: np.ndarray, R: np.ndarray, offsets: np.ndarray, side: Side) -> np.ndarray:
    return wrist + 0.5 * (R @ offsets[INDEX1[side]])


def _to_face(base: Motion, hold: Hold, kind: str, rng: np.random.Generator, obj_target) -> Motion:
    """Shared timing of drink / phone_call: raise the object to ``obj_target(rot, root, s)`` ->
    (T, 4, 4) object poses, keep it there, lower back to the carry pose."""
    side = hold.side
    T = base.num_frames
    rot, root, off = _base_arrays(base)
    c_p, c_R = carry_pose(base, hold)
    H0 = obj_target(rot[:1], root[:1], off, np.zeros(1))[0] @ _inv_h(hold.offset)
    dist = np.linalg.norm(_wrist_to_palm(H0[:3, 3], H0[:3, :3], off, side) - c_p[0]) + 0.15
    ph = _phases(kind, T, rng, base.fps, moves={"raise": dist, "lower": dist})
    a0, a1 = ph["raise"]
    b0, b1 = ph[list(ph)[1]]
    t = np.arange(T)
    w = _ramp(T, a0, a1) * (1 - _ramp(T, b1, T - 1))
    To = obj_target(rot, root, off, np.clip((t - b0) / max(b1 - b0, 1), 0, 1))
    Ht = To @ _inv_h(hold.offset)
    palm_t = _wrist_to_palm(Ht[:, :3, 3], Ht[:, :3, :3], off, side)
    # The arm is at the carry pose at both ends; the face pose is blended in with w.
    F = heading_frame(base)
    bow = F[:, :3, :3] @ (_actor_scale(off) * np.array([0.15, 0.05 * SIGN[side], 0.0]))
    path = c_p + w[:, None] * (palm_t - c_p) + (4.0 * w * (1 - w))[:, None] * bow  # keep clear of the shoulder
    R = slerp_rot(c_R, Ht[:, :3, :3], w)
    elbow = (1 - w)[:, None] * _ELBOW_DIR[side] + w[:, None] * np.array([0.2, 0.9 * SIGN[side], -1.0])
    rot, reached = place_arm(rot, root, off, side, path, R, np.ones(T), elbow_dir=elbow)
    _require(reached, t == a1, f"{kind} {hold.name}")  # the object arrives at the face
    H = _hand_world(rot, root, off, side)
    return _finish(base, rot, root, [ActionInterval(kind, 0, T - 1)], {hold.name: H @ hold.offset},
                   {WRIST[side]: np.ones(T, dtype=bool)})


def _face_frame(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head positions (T, 3) and heading rotations (T, 3, 3)."""
    P, _ = forward_kinematics(rot, root, offsets)
    yaw = np.arctan2(rot[:, 0, 1, 0], rot[:, 0, 0, 0])
    return P[:, JOINT_INDEX["head"]], yaw_matrix(yaw)


def drink(base: Motion, hold: Hold, obj: SceneObject, rng: np.random.Generator) -> Motion:
    """Drink from a held bottle / cup: raise its top to the mouth, tilt it back (60 -> 95 deg over
    the sip), lower it to the carry pose. Starts and ends at the carry pose; label 'drink'."""
    top = np.array([0.0, 0.0, _object_height(obj)])
    tilt0, tilt1 = np.radians(rng.uniform(50, 65)), np.radians(rng.uniform(85, 105))
    sc = _actor_scale(base.offsets)
    R_carry_obj = hold.carry_rot @ hold.offset[:3, :3]  # object rotation in the heading frame

    def target(rot, root, off, s):
        head, Ry = _face_frame(rot, root, off)
        mouth = head + (Ry @ (sc * np.array([0.10, 0.0, -0.05])))
        tilt = tilt0 + (tilt1 - tilt0) * ease(s)
        left = Ry[:, :, 1]
        Ro = _rodrigues(left, -tilt) @ Ry @ R_carry_obj  # top of the object tips back towards the mouth
        return _to_h(Ro, mouth - (Ro @ top))

    return _to_face(base, hold, "drink", rng, target)


def phone_call(base: Motion, hold: Hold, obj: SceneObject, rng: np.random.Generator) -> Motion:
    """Hold a phone to the ear on the holding hand's side: its face (local z) turned away from the
    head, its long axis from the ear towards the mouth; back to the carry pose. Label 'phone_call'."""
    sc = _actor_scale(base.offsets)
    c = obj.mesh.bounds.mean(axis=0)
    sz = obj.meta.get("size", obj.mesh.extents.tolist())
    long_axis = 1 if sz[1] >= sz[0] else 0
    sgn = SIGN[hold.side]
    pitch = np.radians(rng.uniform(35, 55))

    def target(rot, root, off, s):
        head, Ry = _face_frame(rot, root, off)
        ear = head + Ry @ (sc * np.array([0.0, sgn * 0.10, 0.02]))
        out = Ry @ np.array([0.0, sgn, 0.0])  # local +z (the palm side) points away from the head
        along = Ry @ np.array([np.sin(pitch), 0.0, -np.cos(pitch)])  # ear -> mouth-ish, forward-down
        z = out
        a = _unit(along - (along * z).sum(-1, keepdims=True) * z)
        if long_axis == 1:  # local y = a, local x = y x z
            Ro = np.stack([np.cross(a, z), a, z], axis=-1)
        else:
            Ro = np.stack([a, np.cross(z, a), z], axis=-1)
        p = ear + 0.5 * sz[2] * out - (Ro @ c)
        return _to_h(Ro, p)

    return _to_face(base, hold, "phone_call", rng, target)
