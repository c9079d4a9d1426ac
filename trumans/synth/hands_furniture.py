"""Hands on articulated and pushable furniture: doors (hinge), drawers (slide), chairs / tables
(pushed or pulled along the floor). Conventions (palm point, hand frame, grasp flags on the wrist
joint) are those of ``trumans.synth.hands``.

Drawers are worked from a standing base (``locomotion.stand``) at the stance returned by
``drawer_stance`` (walk there first); the torso leans / the knees bend as needed with the feet
planted. Doors open towards the person (``scenes.furniture.door``): ``door_stance`` plans where to
take the handle and how far to step back; ``open_door`` / ``close_door`` build their own base
(stand, step back / forwards with the hand on the handle, stand), like push / pull: stand (hands go
to the object), walk with it (``locomotion.walk``, forwards for push, backwards for pull), stand
(hands let go).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.ndimage import gaussian_filter1d

from scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.contacts.rule import JOINT_RADIUS
from trumans.rotations import yaw_matrix
from trumans.skeleton import JOINT_INDEX, JOINT_NAMES, forward_kinematics
from . import locomotion
from .hands import (
    HAND_SPEED,
    PALM_GAP,
    SHOULDER,
    WRIST,
    OutOfReach,
    Side,
    _apply,
    _actor_scale,
    _base_arrays,
    _check_pose,
    _check_side,
    _finish,
    _is_seated,
    _lean_candidates,
    _lean_pose,
    _phases,
    _ramp,
    _reach_path,
    _require,
    _to_h,
    _unit,
    _wrist_targets,
    PLAN_FRAC,
    choose_lean,
    hand_frame,
    lean_travel,
    palm_points,
    place_arm,
)
from trumans.ik.limb import limb_reach
from .motion import Motion, concat_motions
from .poses import ease

__all__ = [
    "door_pose",
    "drawer_pose",
    "Stance",
    "DoorStance",
    "door_stance",
    "drawer_stance",
    "open_door",
    "close_door",
    "open_drawer",
    "close_drawer",
    "push_handles",
    "push",
    "pull",
]

_PHASES: dict[str, dict[str, tuple[float, float]]] = {
    "open_door": {"reach": (0.9, 1.2), "grasp": (0.2, 0.3), "move": (1.3, 2.0), "release": (0.15, 0.25),
                  "retract": (0.8, 1.1)},
    "close_door": {"reach": (0.9, 1.2), "grasp": (0.2, 0.3), "move": (1.2, 1.8), "release": (0.15, 0.25),
                   "retract": (0.8, 1.1)},
    "open_drawer": {"reach": (1.3, 1.7), "grasp": (0.2, 0.3), "move": (1.2, 1.8), "release": (0.15, 0.25),
                    "retract": (1.2, 1.6)},
    "close_drawer": {"reach": (1.3, 1.7), "grasp": (0.15, 0.25), "move": (1.1, 1.6), "release": (0.1, 0.2),
                     "retract": (1.2, 1.6)},
}


# ----------------------------------------------------------------------------- object kinematics


def door_pose(door: SceneObject, closed: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """World pose(s) (..., 4, 4) of ``door`` opened by ``angle`` (...,) rad in [0, max_angle] from
    its closed world pose ``closed`` (4, 4): rotation by ``open_sign * angle`` about its hinge axis."""
    if door.dof != "hinge":
        raise ValueError(f"object {door.name!r} is not a hinge (dof {door.dof!r})")
    a = np.asarray(angle, dtype=np.float64) * float(door.meta.get("open_sign", 1.0))
    k = door.axis
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + np.sin(a)[..., None, None] * K + (1 - np.cos(a))[..., None, None] * (K @ K)
    h = door.hinge_point
    local = _to_h(R, h - (R @ h))
    return closed @ local


def drawer_pose(drawer: SceneObject, closed: np.ndarray, travel: np.ndarray | float) -> np.ndarray:
    """World pose(s) (..., 4, 4) of ``drawer`` pulled out by ``travel`` (...,) m along its slide
    axis (local frame) from its closed world pose ``closed`` (4, 4)."""
    if drawer.dof != "slide" or drawer.axis is None:
        raise ValueError(f"object {drawer.name!r} is not a drawer sliding along an axis (dof {drawer.dof!r})")
    tr = np.asarray(travel, dtype=np.float64)
    local = _to_h(np.broadcast_to(np.eye(3), tr.shape + (3, 3)), tr[..., None] * drawer.axis)
    return closed @ local


@dataclass
class Stance:
    """Where to stand for a door / drawer: pelvis xy ``pos`` (2,) m, heading ``yaw`` rad, the hand
    ``side``, and the largest opening (rad for a door, m for a drawer) reachable from there."""

    pos: np.ndarray
    yaw: float
    side: Side
    reach: float


# Lean limits (pitch rad, drop m) per object kind: a door handle at hip height needs no squat.
_LEAN_LIMIT = {"door": (np.radians(25.0), 0.05), "drawer": (np.inf, np.inf)}


# Arm joints are left out of the body-object clearance test (the hand is on the handle).
_ARMS = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("elbow", "wrist", "index1")]
_BODY = np.array([j for j in range(24) if j not in _ARMS])
CLEAR_PLAN = 0.01  # m, extra clearance kept when planning (the idle base sways about 1 cm)
CLEAR_TOL = 0.015  # m, the generated motion is rejected if the body surface goes deeper than this


def _solid_boxes(obj: SceneObject, poses: np.ndarray, closed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes the body must keep clear of, at each opening: (frames (A, B, 4, 4) world-from-box,
    lo (B, 3), hi (B, 3)). The object's own bounding box (moving with it); for a drawer also the
    cabinet around it: everything behind the closed drawer's front face, at any height."""
    b = obj.mesh.bounds
    if obj.category != "drawer":
        return poses[:, None], b[:1], b[1:]
    front = float(obj.meta["handle"][0]) - 0.0125
    lo2 = np.array([[-1e3, b[0, 1] - 0.05, -1e3]])
    hi2 = np.array([[front, b[1, 1] + 0.05, 1e3]])
    frames = np.stack([poses, np.broadcast_to(closed, poses.shape)], axis=1)
    return frames, np.concatenate([b[:1], lo2]), np.concatenate([b[1:], hi2])


def _clear(P: np.ndarray, frames: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N, A) bool: body joints P (N, 24, 3) keep their contact radius (plus CLEAR_PLAN) clear of
    every box at every opening (frames (A, B, 4, 4), lo / hi (B, 3) box corners, box frame)."""
    inv = np.linalg.inv(frames)  # (A, B, 4, 4)
    Q = P[:, _BODY]  # (N, J, 3)
    loc = np.einsum("abij,nkj->nabki", inv[..., :3, :3], Q) + inv[None, :, :, None, :3, 3]  # (N, A, B, J, 3)
    gap = np.maximum(np.maximum(lo[None, None, :, None] - loc, loc - hi[None, None, :, None]), 0.0)
    dist = np.linalg.norm(gap, axis=-1)  # (N, A, B, J), 0 inside
    return (dist >= JOINT_RADIUS[_BODY] + CLEAR_PLAN).all(axis=(2, 3))


def _lean_table(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side, wrists: np.ndarray,
                solids, limit: tuple[float, float], seated: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per body state and opening, the cheapest feasible lean. rot (N, 24, 3, 3), root (N, 3) body
    states; wrists (A, 3) wrist targets of openings 0..A-1; solids: ``_solid_boxes`` at them.
    Returns (feasible (N, A) bool, pitch (N, A) rad, drop (N, A) m): the lean lets the shoulder reach
    the target with the body clear of the object at that opening."""
    N, A = rot.shape[0], len(wrists)
    pitch, drop, _ = _lean_candidates(seated, _actor_scale(offsets), *limit)
    K = len(pitch)
    # Each lean at full strength and on its way in / out (2/3, 1/3): the body passes through those.
    sc = np.array([1.0, 2.0 / 3.0, 1.0 / 3.0])
    pp = (sc[:, None] * pitch[None]).ravel()
    dd = (sc[:, None] * drop[None]).ravel()
    rr, ro = _lean_pose(np.repeat(rot, 3 * K, 0), np.repeat(root, 3 * K, 0), offsets, np.tile(pp, N),
                        np.tile(dd, N), seated)
    P, _ = forward_kinematics(rr, ro, offsets)
    lo, hi = limb_reach(offsets, f"{side}_arm")
    Pf = P.reshape(N, 3, K, 24, 3)[:, 0].reshape(N * K, 24, 3)
    d = np.linalg.norm(wrists[None] - Pf[:, SHOULDER[side]][:, None], axis=-1)  # (N*K, A)
    clear_all = _clear(P, *solids).reshape(N, 3, K, A)
    clear = clear_all.all(axis=1)
    ok = ((d <= PLAN_FRAC * hi) & (d >= 1.15 * lo)).reshape(N, K, A) & clear
    # The upright body (candidate 0: no lean) must be clear too: it stands there before and after.
    ok &= clear[:, :1]
    first = np.argmax(ok, axis=1)  # cheapest feasible candidate (candidates are sorted by cost)
    return ok.any(axis=1), np.take_along_axis(np.broadcast_to(pitch, (N, K)), first, 1), \
        np.take_along_axis(np.broadcast_to(drop, (N, K)), first, 1)


def _grid_stance(offsets: np.ndarray, yaw: float | np.ndarray, side: Side, cands: np.ndarray,
                 wrists: np.ndarray, limit: tuple[float, float], solids) -> tuple[int, int, float]:
    """Best (stance index, opening index, its cost): cands (S, 2) pelvis xy, facing ``yaw`` (rad,
    one for all or (S,)); wrists (A, 3) wrist targets of openings 0..A-1 (increasing); solids:
    ``_solid_boxes`` at those openings. Maximises the opening up to which every opening is
    reachable with the body clear of the object (the torso may lean differently at each opening),
    then minimises the total lean. Raises OutOfReach when no stance gets past the first opening."""
    S = len(cands)
    rot0, root0 = locomotion.standing_state(offsets, np.zeros(2), 0.0)
    rot = np.repeat(rot0[None], S, 0)
    rot[:, 0] = yaw_matrix(np.broadcast_to(np.asarray(yaw, dtype=np.float64), (S,)))  # the stance is yaw-invariant
    root = np.repeat(root0[None], S, 0)
    root[:, :2] = cands
    ok, pitch, drop = _lean_table(rot, root, offsets, side, wrists, solids, limit)
    ok = np.cumprod(ok, axis=-1).astype(bool)  # opening a counts only if all smaller ones work too
    best_a = ok.sum(-1) - 1  # (S,)
    if best_a.max() < 1:  # at least one opening step beyond the start
        raise OutOfReach("no stance in front of the object lets the hand reach its handle with the body "
                         "clear of it, even leaning and squatting")
    cost = np.where(ok, pitch / np.radians(60.0) + 1.5 * drop / 0.4, 0.0).sum(-1) / np.maximum(ok.sum(-1), 1)
    s = int(np.argmax(best_a * 10.0 - cost))
    return s, int(best_a[s]), float(cost[s])


def _door_hand(door: SceneObject, poses: np.ndarray, side: Side) -> tuple[np.ndarray, np.ndarray]:
    """Palm points (..., 3) just in front of the lever handle's outer end and wrist rotations
    (..., 3, 3) (palm facing the leaf, fingers down, hooked around the lever; the fingers keep clear
    of the leaf) for door poses (..., 4, 4)."""
    h = np.asarray(door.meta["handle"], dtype=np.float64)
    fx = poses[..., :3, 0]
    palm = _apply(poses, h) + (0.015 + PALM_GAP) * fx  # the lever ends 1.5 cm beyond the handle point
    R = hand_frame(-fx, -poses[..., :3, 2], side)
    return palm, R


def _drawer_hand(drawer: SceneObject, poses: np.ndarray, side: Side) -> tuple[np.ndarray, np.ndarray]:
    """Palm points (..., 3) in front of the drawer's bar handle, palm facing the drawer, fingers down."""
    h = np.asarray(drawer.meta["handle"], dtype=np.float64)
    fx = poses[..., :3, 0]
    palm = _apply(poses, h) + (0.0125 + PALM_GAP) * fx
    R = hand_frame(-fx, -poses[..., :3, 2], side)
    return palm, R


def _stance_for(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray, hand_fn, kin_fn, openings: np.ndarray,
                side: Side | None, limit: tuple[float, float]) -> Stance:
    """Shared door / drawer stance search: facing the object's -x from its +x side."""
    offsets = np.asarray(offsets, dtype=np.float64)
    pose = _check_pose(pose, "pose")
    yaw = float(np.arctan2(pose[1, 0], pose[0, 0]) + np.pi)
    h_local = np.asarray(obj.meta["handle"], dtype=np.float64)
    if side is None:  # the hand on the handle's side of the object, as seen by the person facing it
        side = "right" if h_local[1] > 0 else "left"
    _check_side(side)
    sc = _actor_scale(offsets)
    poses = kin_fn(openings)
    palm, R = hand_fn(obj, poses, side)
    wr = _wrist_targets(palm, R, offsets, side)  # (A, 3)
    sgn = 1.0 if side == "left" else -1.0
    h_world = _apply(pose, h_local)
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    left = np.array([-fwd[1], fwd[0]])
    xs = sc * np.linspace(0.20, 0.80, 6)
    ys = sc * np.linspace(-0.30, 0.30, 5)
    cands = np.array([h_world[:2] - x * fwd - sgn * y * left for x in xs for y in ys])
    s, a, _ = _grid_stance(offsets, yaw, side, cands, wr, limit, _solid_boxes(obj, poses, pose))
    # One planning step below the largest feasible opening: the motion in between is interpolated.
    return Stance(pos=cands[s], yaw=yaw, side=side, reach=float(openings[max(a - 1, 1)]))


@dataclass
class DoorStance:
    """How a person works a door that opens towards them (``scenes.furniture.door``): standing at
    pelvis xy ``pos`` (2,) facing ``yaw`` (rad), the ``side`` hand takes the closed door's handle
    and the person steps straight back (keeping the heading) to ``open_pos`` (2,) while pulling the
    door open by ``reach`` (rad); the opening grows in proportion to the distance walked back
    (``at``). Closing is the same path walked forwards."""

    pos: np.ndarray
    yaw: float
    side: Side
    reach: float
    open_pos: np.ndarray

    def at(self, angle: float) -> np.ndarray:
        """Pelvis xy (2,) where the person stands with the door opened by ``angle`` rad."""
        return self.pos + (float(angle) / self.reach) * (self.open_pos - self.pos)


_DOOR_REACHES = (1.4, 1.2, 1.0, 0.8, 0.6, 0.4)  # rad, openings tried, largest first
DOOR_GAIT_CLEAR = 0.08  # m, extra clearance from the leaf planned for a body that steps
_DOOR_FRACTIONS = np.linspace(0.0, 1.0, 6)  # points of the back-step path checked when planning


def _door_plan(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, side: Side, pos: np.ndarray,
               yaw: np.ndarray, back: np.ndarray, fractions: np.ndarray = _DOOR_FRACTIONS
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For candidate paths (pelvis xy ``pos`` (N, 2), heading ``yaw`` (N,), back step ``back`` (N,) m)
    and each opening R of _DOOR_REACHES: is the door handle within the ``side`` hand's reach (leaning
    as needed, the body clear of the leaf) at every checked point f of the path, the door opened by
    f * R there? Returns (ok (N, R) bool, pitch (N, R, F), drop (N, R, F), cost (N, R))."""
    N, F = len(pos), len(fractions)
    reaches = np.asarray(_DOOR_REACHES)
    rot0, root0 = locomotion.standing_state(offsets, np.zeros(2), 0.0)
    fwd = np.stack([np.cos(yaw), np.sin(yaw)], -1)
    ok = np.ones((N, len(reaches)), dtype=bool)
    pitch = np.zeros((N, len(reaches), F))
    drop = np.zeros((N, len(reaches), F))
    for k, f in enumerate(fractions):
        live = np.flatnonzero(ok.any(axis=1))  # paths still feasible for some opening
        if len(live) == 0:
            break
        rot = np.repeat(rot0[None], len(live), 0)
        rot[:, 0] = yaw_matrix(yaw[live])  # the standing state is yaw-invariant
        root = np.repeat(root0[None], len(live), 0)
        root[:, :2] = pos[live] - (f * back[live])[:, None] * fwd[live]
        poses = door_pose(door, closed, f * reaches)
        palm, R = _door_hand(door, poses, side)
        frames, lo, hi = _solid_boxes(door, poses, closed)
        grow = np.array([DOOR_GAIT_CLEAR, DOOR_GAIT_CLEAR, 0.0])  # room for the gait's swinging feet and sway
        ok_k, p_k, d_k = _lean_table(rot, root, offsets, side, _wrist_targets(palm, R, offsets, side),
                                     (frames, lo - grow, hi + grow), _LEAN_LIMIT["door"])
        ok[live] &= ok_k
        pitch[live, :, k], drop[live, :, k] = p_k, d_k
    cost = (pitch / np.radians(60.0) + 1.5 * drop / 0.4).mean(-1)
    return ok, pitch, drop, cost


def door_stance(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, side: Side | None = None) -> DoorStance:
    """Plan opening ``door`` (closed world pose (4, 4)) towards oneself: where to stand, which hand
    (``side``, default: the better one), how far to step back and how far the door then opens
    (``DoorStance.reach``, the largest of 1.4, 1.2, ... 0.4 rad that works, preferring a small lean).

    Candidates: pelvis 0.35-0.65 m (x actor scale) in front of the closed handle and up to 0.45 m
    aside, facing the door +-0.5 rad, stepping back 0.3-0.8 m. Raises OutOfReach when the door
    cannot be opened even 0.4 rad."""
    offsets = np.asarray(offsets, dtype=np.float64)
    closed = _check_pose(closed, "closed")
    if door.dof != "hinge":
        raise ValueError(f"object {door.name!r} is not a hinge (dof {door.dof!r})")
    h_local = np.asarray(door.meta["handle"], dtype=np.float64)
    handle = _apply(closed, h_local)[:2]
    n = closed[:2, 0] / np.linalg.norm(closed[:2, 0])  # the door's +x: into the room
    free = closed[:2, :2] @ np.array([0.0, h_local[1] - door.hinge_point[1]])  # hinge -> handle
    free /= np.linalg.norm(free)
    sc = _actor_scale(offsets)
    face = float(np.arctan2(-n[1], -n[0]))
    turn = float(np.sign(free[0] * n[1] - free[1] * n[0]))  # a positive yaw offset turns towards the free edge
    grid = np.array([(dn, dt, dy, L) for dn in (0.35, 0.5, 0.65) for dt in (-0.15, 0.0, 0.15, 0.3, 0.45)
                     for dy in (-0.5, -0.25, 0.0, 0.25, 0.5) for L in (0.3, 0.55, 0.8)])
    pos = handle + sc * (grid[:, :1] * n + grid[:, 1:2] * free)
    yaw = face + turn * grid[:, 2]
    back = sc * grid[:, 3]
    best = None
    for sd in ([side] if side else ["left", "right"]):
        _check_side(sd)
        ok, _, _, cost = _door_plan(offsets, door, closed, sd, pos, yaw, back)
        for r, R in enumerate(_DOOR_REACHES):
            if not ok[:, r].any():
                continue
            c = np.where(ok[:, r], cost[:, r] + 0.2 * back, np.inf)  # a shorter step back is nicer
            i = int(np.argmin(c))
            if best is None or (R, -c[i]) > (best[0], -best[1]):
                best = (R, float(c[i]), DoorStance(pos=pos[i].copy(), yaw=float(yaw[i]), side=sd, reach=float(R),
                                                   open_pos=pos[i] - back[i] * np.array([np.cos(yaw[i]),
                                                                                         np.sin(yaw[i])])))
            break
    if best is None:
        raise OutOfReach(f"no stance in front of {door.name} lets a hand pull it open 0.4 rad with the body "
                         f"clear of the leaf")
    return best[2]


def drawer_stance(offsets: np.ndarray, drawer: SceneObject, closed: np.ndarray, side: Side | None = None) -> Stance:
    """Stance in front of a drawer facing it, from which the hand (default: right) can pull it
    furthest out (``Stance.reach``, m) with the feet planted (low drawers: bending / squatting)."""
    tr = np.linspace(0.0, float(drawer.meta["max_travel"]), 9)
    return _stance_for(offsets, drawer, closed, _drawer_hand, lambda x: drawer_pose(drawer, closed, x), tr,
                       side or "right", _LEAN_LIMIT["drawer"])


# ----------------------------------------------------------------------------- door / drawer motion


def _lean_steps(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, pitch: np.ndarray, drop: np.ndarray,
                seated: bool) -> np.ndarray:
    """(A - 1,) largest joint displacement (m) between consecutive leans (pitch, drop) (A,)."""
    A = len(pitch)
    rot, root = _lean_pose(np.repeat(rot1[None], A, 0), np.repeat(root1[None], A, 0), offsets, pitch, drop, seated)
    P, _ = forward_kinematics(rot, root, offsets)
    return np.linalg.norm(np.diff(P, axis=0), axis=-1).max(axis=1)


def _articulate(base: Motion, obj: SceneObject, kin_fn, hand_fn, q0: float, q1: float, label: str,
                side: Side, rng: np.random.Generator) -> Motion:
    """Reach the handle at opening q0, move it to q1 (eased), let go, retract."""
    _check_side(side)
    T = base.num_frames
    rot, root, off = _base_arrays(base)
    qs = np.linspace(q0, q1, 17)
    p_s, R_s = hand_fn(obj, kin_fn(qs), side)
    limit = _LEAN_LIMIT["door" if "door" in label else "drawer"]
    solids = _solid_boxes(obj, kin_fn(qs), kin_fn(0.0))
    ok, pitch_q, drop_q = _lean_table(rot[:1], root[:1], off, side, _wrist_targets(p_s, R_s, off, side), solids,
                                      limit, _is_seated(base))
    ok = ok[0]
    if not (ok[0] and ok[-1]):
        raise OutOfReach(f"{label} {obj.name}: from this stance the hand cannot reach the handle at "
                         f"{q0 if not ok[0] else q1:.2f} with the body clear of the object; use door_stance / "
                         f"drawer_stance and an opening up to its reach")
    # Openings in between that no lean candidate serves exactly take the neighbours' lean.
    k_ok = np.flatnonzero(ok)
    pitch_q = np.interp(np.arange(len(qs)), k_ok, pitch_q[0, k_ok])
    drop_q = np.interp(np.arange(len(qs)), k_ok, drop_q[0, k_ok])
    pb0 = palm_points(base.joints())[:, 0 if side == "left" else 1]
    seated = _is_seated(base)
    lt = max(lean_travel(rot[0], root[0], off, float(p), float(d), seated)
             for p, d in ((pitch_q[0], drop_q[0]), (pitch_q[-1], drop_q[-1])))
    # Opening progress is paced by the larger of the hand's and the torso's step between planned
    # openings, so a lean that changes quickly somewhere is given the time it needs.
    step = np.maximum(np.linalg.norm(np.diff(p_s, axis=0), axis=1),
                      _lean_steps(rot[0], root[0], off, pitch_q, drop_q, seated)) + 1e-6
    C = np.concatenate([[0.0], np.cumsum(step)])
    ph = _phases(label, T, rng, base.fps, _PHASES, moves={
        "reach": max(np.linalg.norm(p_s[0] - pb0[0]) + 0.1, lt), "move": float(C[-1]),
        "retract": max(np.linalg.norm(p_s[-1] - pb0[-1]) + 0.1, lt)})
    g0 = ph["grasp"][0]
    m0, m1 = ph["move"]
    r1 = ph["release"][1]
    t = np.arange(T)
    kpos = np.interp(ease((t - m0) / max(m1 - m0, 1)) * C[-1], C, np.arange(len(qs)))  # planned opening index
    q = np.interp(kpos, np.arange(len(qs)), qs)
    poses = kin_fn(q)
    palm, R = hand_fn(obj, poses, side)
    # The torso leans as each opening needs (interpolated between the 17 planned openings).
    env = _ramp(T, 0, g0) * (1 - _ramp(T, r1, T - 1))
    pitch = env * np.interp(kpos, np.arange(len(qs)), pitch_q)
    drop = env * np.interp(kpos, np.arange(len(qs)), drop_q)
    rot, root = _lean_pose(rot, root, off, pitch, drop, seated)
    P, _ = forward_kinematics(rot, root, off)
    pb = palm_points(P)[:, 0 if side == "left" else 1]
    out_in = _unit(palm[g0] - _apply(poses[g0], np.asarray(obj.meta["handle"], dtype=np.float64)))
    out_out = _unit(palm[-1] - _apply(poses[-1], np.asarray(obj.meta["handle"], dtype=np.float64)))
    s_in = t / max(g0, 1)
    s_out = (T - 1 - t) / max(T - 1 - r1, 1)
    path = np.where((t <= g0)[:, None], _reach_path(pb, palm[g0], out_in, s_in),
                    _reach_path(pb, palm[-1], out_out, s_out))
    hold = (t >= g0) & (t <= r1)
    path[hold] = palm[hold]
    w = np.where(hold, 1.0, ease(np.clip(np.minimum(s_in, s_out) * 2.0, 0, 1)))
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    _require(reached, hold, f"{label} {obj.name}")
    # Final check on every frame: the body (arms aside) keeps clear of the object as it moves.
    P, _ = forward_kinematics(rot, root, off)
    fr, lo_b, hi_b = _solid_boxes(obj, poses, kin_fn(0.0))
    inv = np.linalg.inv(fr)  # (T, B, 4, 4)
    loc = np.einsum("tbij,tkj->tbki", inv[..., :3, :3], P[:, _BODY]) + inv[:, :, None, :3, 3]
    gap = np.linalg.norm(np.maximum(np.maximum(lo_b[None, :, None] - loc, loc - hi_b[None, :, None]), 0.0), axis=-1)
    bad = (gap < JOINT_RADIUS[_BODY] - CLEAR_TOL).any(axis=(1, 2))
    if bad.any():
        depth = float((JOINT_RADIUS[_BODY] - gap).max())
        raise OutOfReach(f"{label} {obj.name}: the body would touch the object on {int(bad.sum())} frames "
                         f"(first {int(np.flatnonzero(bad)[0])}, {100 * depth:.1f} cm deep); use the stance "
                         f"from door_stance / drawer_stance")
    return _finish(base, rot, root, [ActionInterval(label, 0, T - 1)], {obj.name: poses}, {WRIST[side]: hold})


def _door_close_walk(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, angle: float,
                     stance: DoorStance, rng: np.random.Generator, fps: float, label: str) -> Motion:
    """Closing ``door`` from ``angle`` rad: stand at ``stance.at(angle)``, take the handle, walk
    forwards to ``stance.pos`` pushing the door shut (its opening follows the walked distance),
    let go. The hand follows the handle; the torso leans as planned along the path."""
    offsets = np.asarray(offsets, dtype=np.float64)
    side, yaw = stance.side, float(stance.yaw)
    p_open, p_shut = stance.at(angle), np.asarray(stance.pos, dtype=np.float64)
    rot_s, root_s = locomotion.standing_state(offsets, p_open, yaw)
    P_s, _ = forward_kinematics(rot_s[None], root_s[None], offsets)
    k = 0 if side == "left" else 1
    palm_open, _ = _door_hand(door, door_pose(door, closed, angle), side)
    palm_shut, _ = _door_hand(door, door_pose(door, closed, 0.0), side)
    t_in = 0.25 + (np.linalg.norm(palm_open - palm_points(P_s)[0, k]) + 0.05) / HAND_SPEED
    t_out = 0.25 + (np.linalg.norm(palm_shut - palm_points(P_s)[0, k]) + 0.05) / HAND_SPEED
    n1 = int(max(rng.uniform(0.8, 1.1), t_in) * fps)
    n3 = int(max(rng.uniform(0.7, 1.0), t_out) * fps)
    parts = [locomotion.stand(offsets, p_open, yaw, n1, rng, fps=fps)]
    if np.linalg.norm(p_shut - p_open) >= 0.06:
        parts.append(locomotion.walk(np.stack([p_open, p_shut]), offsets, rng, speed=float(rng.uniform(0.4, 0.6)),
                                     fps=fps, start_yaw=yaw, end_yaw=yaw,
                                     step_length=_actor_scale(offsets) * float(rng.uniform(0.22, 0.3))))
    else:
        parts.append(locomotion.stand(offsets, p_open, yaw, int(rng.uniform(1.0, 1.4) * fps), rng, fps=fps))
        p_shut = p_open
    parts.append(locomotion.stand(offsets, p_shut, yaw, n3, rng, fps=fps))
    base = concat_motions(parts)
    T = base.num_frames
    t = np.arange(T)
    g0, g1 = n1 - 1, n1 + parts[1].num_frames
    # Door opening: follows the pelvis' smoothed progress along the path (no gait sway).
    u = p_shut - p_open
    L = float(np.linalg.norm(u))
    if L > 0:
        prog = gaussian_filter1d((base.root[:, :2] - p_open) @ (u / L), 0.25 * fps, mode="nearest")
        prog[:g0 + 1] = 0.0
        prog = np.maximum.accumulate(np.clip(prog, 0.0, None))
        prog = prog / max(prog[g1], 1e-9)
    else:
        prog = _ramp(T, g0, g1)
    prog[g1:] = 1.0
    q = angle * (1.0 - np.clip(prog, 0.0, 1.0))
    poses = door_pose(door, closed, q)
    palm, R = _door_hand(door, poses, side)
    # Lean along the way: planned at a few points of the path, interpolated by progress.
    rot, root, off = _base_arrays(base)
    fr = _DOOR_FRACTIONS
    idx = np.clip(np.searchsorted(prog, fr * (1 - 1e-9)), g0, g1)  # frames at those progress points
    no_boxes = (np.zeros((len(idx), 0, 4, 4)), np.zeros((0, 3)), np.zeros((0, 3)))  # clearance: checked below
    ok, pitch_f, drop_f = _lean_table(rot[idx], root[idx], off, side,
                                      _wrist_targets(palm[idx], R[idx], off, side), no_boxes, _LEAN_LIMIT["door"])
    diag = np.arange(len(idx))
    if not ok[diag, diag].all():
        raise OutOfReach(f"{label} {door.name}: the hand cannot follow the handle from this path; "
                         f"use door_stance and an opening up to its reach")
    env = _ramp(T, 0, g0) * (1 - _ramp(T, g1, T - 1))
    pitch = env * np.interp(prog, prog[idx], pitch_f[diag, diag])
    drop = env * np.interp(prog, prog[idx], drop_f[diag, diag])
    rot, root = _lean_pose(rot, root, off, pitch, drop, False)
    P, _ = forward_kinematics(rot, root, off)
    pb = palm_points(P)[:, k]
    hp = _apply(poses, np.asarray(door.meta["handle"], dtype=np.float64))
    s_in = t / max(g0, 1)
    s_out = (T - 1 - t) / max(T - 1 - g1, 1)
    path = np.where((t <= g0)[:, None], _reach_path(pb, palm[g0], _unit(palm[g0] - hp[g0]), s_in),
                    _reach_path(pb, palm[-1], _unit(palm[-1] - hp[-1]), s_out))
    hold = (t >= g0) & (t <= g1)
    path[hold] = palm[hold]
    w = np.where(hold, 1.0, ease(np.clip(np.minimum(s_in, s_out) * 2.0, 0, 1)))
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    _require(reached, hold, f"{label} {door.name}")
    # Final check on every frame: the body (arms aside) keeps clear of the swinging leaf.
    P, _ = forward_kinematics(rot, root, off)
    fr_b, lo_b, hi_b = _solid_boxes(door, poses, closed)
    inv = np.linalg.inv(fr_b)
    loc = np.einsum("tbij,tkj->tbki", inv[..., :3, :3], P[:, _BODY]) + inv[:, :, None, :3, 3]
    gap = np.linalg.norm(np.maximum(np.maximum(lo_b[None, :, None] - loc, loc - hi_b[None, :, None]), 0.0), axis=-1)
    bad = (gap < JOINT_RADIUS[_BODY] - CLEAR_TOL).any(axis=(1, 2))
    if bad.any():
        depth = JOINT_RADIUS[_BODY] - gap  # (T, B, J)
        j = _BODY[int(np.unravel_index(int(depth.argmax()), depth.shape)[2])]
        raise OutOfReach(f"{label} {door.name}: the body would touch the door on {int(bad.sum())} frames "
                         f"(first {int(np.flatnonzero(bad)[0])}, {100 * float(depth.max()):.1f} cm deep, "
                         f"{JOINT_NAMES[j]}); use door_stance")
    return _finish(base, rot, root, [ActionInterval(label, 0, T - 1)], {door.name: poses}, {WRIST[side]: hold})


def _check_door_angle(door: SceneObject, angle: float, stance: DoorStance) -> None:
    a_max = float(door.meta["max_angle"])
    if not 0.0 < angle <= min(a_max, stance.reach) + 1e-9:
        raise ValueError(f"door angle must lie in (0, min(max_angle {a_max}, stance.reach {stance.reach:.2f})] "
                         f"rad, got {angle}")


def open_door(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, angle: float, rng: np.random.Generator,
              stance: DoorStance, fps: float = 30.0) -> Motion:
    """Pull ``door`` (closed world pose (4, 4)) open by ``angle`` rad (at most ``stance.reach``,
    from ``door_stance``) towards oneself: from the canonical standing state at ``stance.pos`` the
    ``stance.side`` hand takes the handle, the person steps back to ``stance.at(angle)`` (the hand
    following the handle along its arc), lets go and stands. A door closing played backwards
    (``close_door`` with its own timing). Label 'open_door'; the door's pose track is returned."""
    closed = _check_pose(closed, "closed")
    _check_door_angle(door, angle, stance)
    m = _door_close_walk(offsets, door, closed, angle, stance, rng, fps, "open_door")
    return Motion(rot=m.rot[::-1].copy(), root=m.root[::-1].copy(), offsets=m.offsets, fps=m.fps,
                  foot_contact=m.foot_contact[::-1].copy(), actions=[ActionInterval("open_door", 0, m.num_frames - 1)],
                  objects={k: v[::-1].copy() for k, v in m.objects.items()},
                  grasp={k: v[::-1].copy() for k, v in m.grasp.items()})


def close_door(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, angle: float, rng: np.random.Generator,
               stance: DoorStance, fps: float = 30.0) -> Motion:
    """Push ``door`` from ``angle`` rad back to closed: from the standing state at ``stance.at(angle)``
    the hand takes the handle, the person walks forwards to ``stance.pos`` and lets go. Label
    'close_door'."""
    closed = _check_pose(closed, "closed")
    _check_door_angle(door, angle, stance)
    return _door_close_walk(offsets, door, closed, angle, stance, rng, fps, "close_door")


def open_drawer(base: Motion, drawer: SceneObject, closed: np.ndarray, travel: float, rng: np.random.Generator,
                side: Side = "right", start: float = 0.0) -> Motion:
    """Pull ``drawer`` (closed world pose (4, 4)) out from ``start`` to ``travel`` m (within
    [0, max_travel]) by its handle. Label 'open_drawer'; the drawer's pose track is returned."""
    closed = _check_pose(closed, "closed")
    mt = float(drawer.meta["max_travel"])
    if not 0.0 <= start <= mt or not 0.0 <= travel <= mt:
        raise ValueError(f"drawer travel must lie in [0, {mt}] m, got start={start}, travel={travel}")
    return _articulate(base, drawer, lambda x: drawer_pose(drawer, closed, x), _drawer_hand, start, travel,
                       "open_drawer", side, rng)


def close_drawer(base: Motion, drawer: SceneObject, closed: np.ndarray, travel: float, rng: np.random.Generator,
                 side: Side = "right", end: float = 0.0) -> Motion:
    """Push ``drawer`` from ``travel`` m back to ``end`` (default closed). Label 'close_drawer'."""
    closed = _check_pose(closed, "closed")
    mt = float(drawer.meta["max_travel"])
    if not 0.0 <= end <= mt or not 0.0 <= travel <= mt:
        raise ValueError(f"drawer travel must lie in [0, {mt}] m, got travel={travel}, end={end}")
    return _articulate(base, drawer, lambda x: drawer_pose(drawer, closed, x), _drawer_hand, travel, end,
                       "close_drawer", side, rng)


# ----------------------------------------------------------------------------- push / pull


def push_handles(obj: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    """Local (2, 3) left/right hand points on top of the object's edge and the local direction (3,)
    the person faces while pushing: a chair's ``push_handles`` (person behind the backrest, facing
    +x), otherwise the near edge of a table top (person on the +x side facing -x)."""
    if "push_handles" in obj.meta:
        h = np.asarray(obj.meta["push_handles"], dtype=np.float64)
        return h[np.argsort(-h[:, 1])], np.array([1.0, 0.0, 0.0])  # facing +x: left = +y first
    if "surface_size" in obj.meta:
        sx, sy = obj.meta["surface_size"]
        z = float(obj.meta["surface_height"])
        d = min(0.25, sy / 2 - 0.05)
        x = sx / 2 - 0.05
        return np.array([[x, -d, z], [x, d, z]]), np.array([-1.0, 0.0, 0.0])  # facing -x: left = -y
    raise ValueError(f"object {obj.name!r} ({obj.category}) has neither push_handles nor surface_size meta")


def _push_palms(poses: np.ndarray, handles: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Palm points (T, 2, 3) and wrist rotations (T, 2, 3, 3): palms down on the edge, fingers forward."""
    up = poses[:, :3, 2]
    palm = np.stack([_apply(poses, h) for h in handles], 1) + PALM_GAP * up[:, None]
    f = poses[:, :3, :3] @ face
    R = np.stack([hand_frame(-up, f, s) for s in ("left", "right")], 1)
    return palm, R


def push(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray, distance: float, rng: np.random.Generator,
         fps: float = 30.0, label: Literal["push", "pull"] = "push") -> Motion:
    """Push ``obj`` (world ``pose`` (4, 4)) along the floor. The body starts in the canonical
    standing state at ``push_stance(offsets, obj, pose)`` (behind the object's hand points), puts
    both hands on the object's edge, walks ``distance`` m forwards pushing it (the object slides on
    the floor by the pelvis' smoothed displacement, exactly ``distance`` in the end; it neither turns
    nor lifts) and lets go. Labels: 'reach' while the hands go to the object, ``label`` ('push', or
    'pull' when called by ``pull``) after. Grasp flags on both wrists while the hands are on it."""
    if label not in ("push", "pull"):
        raise ValueError(f"label must be 'push' or 'pull', got {label!r}")
    offsets = np.asarray(offsets, dtype=np.float64)
    pose = _check_pose(pose, "pose")
    if not 0.05 <= distance <= 5.0:
        raise ValueError(f"distance must be in [0.05, 5] m, got {distance}")
    handles, face = push_handles(obj)
    pos, yaw = push_stance(offsets, obj, pose)
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    rot0, root0 = locomotion.standing_state(offsets, pos, yaw)
    P0, _ = forward_kinematics(rot0[None], root0[None], offsets)
    dist = np.linalg.norm(_apply(pose, handles) - palm_points(P0)[0], axis=-1).max() + 0.05
    t_move = 0.25 + dist / HAND_SPEED
    n1 = int(max(rng.uniform(0.8, 1.1), t_move) * fps)
    n3 = int(max(rng.uniform(0.7, 1.0), t_move) * fps)
    m1 = locomotion.stand(offsets, pos, yaw, n1, rng, fps=fps)
    m2 = locomotion.walk(np.stack([pos, pos + distance * fwd]), offsets, rng, speed=float(rng.uniform(0.45, 0.7)),
                         fps=fps, start_yaw=yaw, end_yaw=yaw)
    m3 = locomotion.stand(offsets, pos + distance * fwd, yaw, n3, rng, fps=fps)
    base = concat_motions([m1, m2, m3])
    T = base.num_frames
    t = np.arange(T)
    g0, g1 = n1 - 1, n1 + m2.num_frames
    # Object displacement: the pelvis' xy displacement along the walk, smoothed (no gait sway).
    disp = base.root[:, :2] - pos
    disp = gaussian_filter1d(disp, 0.25 * fps, axis=0, mode="nearest")
    disp[:g0 + 1] = 0.0
    disp[g1:] = disp[g1]
    along = disp @ fwd
    along = np.maximum.accumulate(np.clip(along, 0, None))
    along = along * (distance / max(along[g1], 1e-9))  # exactly ``distance`` when the walk stops
    along[g1:] = distance
    shift = along[:, None] * fwd
    poses = np.broadcast_to(pose, (T, 4, 4)).copy()
    poses[:, :2, 3] += shift
    palm, R = _push_palms(poses, handles, face)
    rot, root, off = _base_arrays(base)
    wr = np.concatenate([_wrist_targets(palm[g0, k], R[g0, k], off, s)[None] for k, s in enumerate(("left", "right"))])
    # Slack for the gait (the object follows the smoothed pelvis; the body sways and bobs).
    slack = 0.04 * np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]])
    leans = [choose_lean(rot[g0], root[g0], off, s, wr[k] + slack, False) for k, s in enumerate(("left", "right"))]
    pitch, drop = max(lp[0] for lp in leans), max(lp[1] for lp in leans)
    lean = _ramp(T, 0, g0) * (1 - _ramp(T, g1, T - 1))
    rot, root = _lean_pose(rot, root, off, pitch * lean, drop * lean, False)
    P, _ = forward_kinematics(rot, root, off)
    hold = (t >= g0) & (t <= g1)
    s_in = t / max(g0, 1)
    s_out = (T - 1 - t) / max(T - 1 - g1, 1)
    up = pose[:3, 2]
    for k, side in enumerate(("left", "right")):
        pb = palm_points(P)[:, k]
        path = np.where((t <= g0)[:, None], _reach_path(pb, palm[g0, k], up, s_in),
                        _reach_path(pb, palm[-1, k], up, s_out))
        path[hold] = palm[hold, k]
        w = np.where(hold, 1.0, ease(np.clip(np.minimum(s_in, s_out) * 2.0, 0, 1)))
        rot, reached = place_arm(rot, root, off, side, path, R[:, k], w)
        _require(reached, hold, f"{label} {obj.name} ({side} hand)")
    grasp = {WRIST[s]: hold.copy() for s in ("left", "right")}
    return _finish(base, rot, root, [ActionInterval("reach", 0, g0), ActionInterval(label, g0, T - 1)],
                   {obj.name: poses}, grasp)


def push_stance(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """Pelvis xy (2,) and heading (rad) for pushing ``obj`` at world ``pose`` (4, 4): facing the
    push direction, the pelvis 0.36 m (x actor scale) behind the midpoint of the hand points."""
    handles, face = push_handles(obj)
    f = pose[:3, :3] @ face
    yaw = float(np.arctan2(f[1], f[0]))
    mid = _apply(pose, handles.mean(0))
    d = 0.36 * _actor_scale(np.asarray(offsets, dtype=np.float64))
    return mid[:2] - d * np.array([np.cos(yaw), np.sin(yaw)]), yaw


def pull(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray, distance: float, rng: np.random.Generator,
         fps: float = 30.0) -> Motion:
    """Pull ``obj`` towards oneself by ``distance`` m walking backwards: starts in the canonical
    standing state at ``push_stance(offsets, obj, pose)`` and ends at the stance of the moved
    object. It is a push towards the start played backwards (planted feet stay planted). Label
    'pull' on every frame; the object's pose track and grasp flags are reversed with it."""
    pose = _check_pose(pose, "pose")
    handles, face = push_handles(obj)
    f = pose[:3, :3] @ face
    back = np.eye(4)
    back[:2, 3] = -distance * _unit(np.array([f[0], f[1]]))
    m = push(offsets, obj, back @ pose, distance, rng, fps, label="pull")
    T = m.num_frames
    return Motion(rot=m.rot[::-1].copy(), root=m.root[::-1].copy(), offsets=m.offsets, fps=m.fps,
                  foot_contact=m.foot_contact[::-1].copy(), actions=[ActionInterval("pull", 0, T - 1)],
                  objects={k: v[::-1].copy() for k, v in m.objects.items()},
                  grasp={k: v[::-1].copy() for k, v in m.grasp.items()})

