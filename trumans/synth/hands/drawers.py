"""Drawers (slide): worked from a standing base (``locomotion.stand``) at the stance returned by
``drawer_stance`` (walk there first); the torso leans / the knees bend as needed with the feet
planted. Conventions (palm point, hand frame, grasp flags on the wrist joint) are those of
``hands.core``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import unit, yaw_matrix
from trumans.skeleton import forward_kinematics
from ..legs import standing_state
from ..motion import Motion, yaw_of
from ..poses import ease
from .clearance import LEAN_LIMIT, lean_table, require_body_clear, solid_boxes
from .core import (
    PALM_GAP, WRIST, OutOfReach, Side, actor_scale, apply_h, base_arrays, check_pose, check_side, finish_motion,
    hand_frame, is_seated, palm_points, reach_hold_retract, to_h, wrist_targets,
)
from .lean import lean_between, lean_steps, lean_travel
from .timing import phases

__all__ = ["drawer_pose", "Stance", "drawer_stance", "open_drawer", "close_drawer"]

def drawer_pose(drawer: SceneObject, closed: np.ndarray, travel: np.ndarray | float) -> np.ndarray:
    """World pose(s) (..., 4, 4) of ``drawer`` pulled out by ``travel`` (...,) m along its slide
    axis (local frame) from its closed world pose ``closed`` (4, 4)."""
    if drawer.dof != "slide" or drawer.axis is None:
        raise ValueError(f"object {drawer.name!r} is not a drawer sliding along an axis (dof {drawer.dof!r})")
    tr = np.asarray(travel, dtype=np.float64)
    local = to_h(np.broadcast_to(np.eye(3), tr.shape + (3, 3)), tr[..., None] * drawer.axis)
    return closed @ local


@dataclass
class Stance:
    """Where to stand for a door / drawer: pelvis xy ``pos`` (2,) m, heading ``yaw`` rad, the hand
    ``side``, and the largest opening (rad for a door, m for a drawer) reachable from there."""

    pos: np.ndarray
    yaw: float
    side: Side
    reach: float


def _grid_stance(offsets: np.ndarray, yaw: float | np.ndarray, side: Side, cands: np.ndarray,
                 wrists: np.ndarray, limit: tuple[float, float], solids) -> tuple[int, int, float]:
    """Best (stance index, opening index, its cost): cands (S, 2) pelvis xy, facing ``yaw`` (rad,
    one for all or (S,)); wrists (A, 3) wrist targets of openings 0..A-1 (increasing); solids:
    ``solid_boxes`` at those openings. Maximises the opening up to which every opening is
    reachable with the body clear of the object (the torso may lean differently at each opening),
    then minimises the total lean. Raises OutOfReach when no stance gets past the first opening."""
    S = len(cands)
    rot0, root0 = standing_state(offsets, np.zeros(2), 0.0)
    rot = np.repeat(rot0[None], S, 0)
    rot[:, 0] = yaw_matrix(np.broadcast_to(np.asarray(yaw, dtype=np.float64), (S,)))  # the stance is yaw-invariant
    root = np.repeat(root0[None], S, 0)
    root[:, :2] = cands
    ok, pitch, drop = lean_table(rot, root, offsets, side, wrists, solids, limit)
    ok = np.cumprod(ok, axis=-1).astype(bool)  # opening a counts only if all smaller ones work too
    best_a = ok.sum(-1) - 1  # (S,)
    if best_a.max() < 1:  # at least one opening step beyond the start
        raise OutOfReach("no stance in front of the object lets the hand reach its handle with the body "
                         "clear of it, even leaning and squatting")
    cost = np.where(ok, pitch / np.radians(60.0) + 1.5 * drop / 0.4, 0.0).sum(-1) / np.maximum(ok.sum(-1), 1)
    s = int(np.argmax(best_a * 10.0 - cost))
    return s, int(best_a[s]), float(cost[s])


def _drawer_hand(drawer: SceneObject, poses: np.ndarray, side: Side) -> tuple[np.ndarray, np.ndarray]:
    """Palm points (..., 3) in front of the drawer's bar handle, palm facing the drawer, fingers down."""
    h = np.asarray(drawer.meta["handle"], dtype=np.float64)
    fx = poses[..., :3, 0]
    palm = apply_h(poses, h) + (0.0125 + PALM_GAP) * fx
    R = hand_frame(-fx, -poses[..., :3, 2], side)
    return palm, R


def _stance_for(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray, hand_fn, kin_fn, openings: np.ndarray,
                side: Side | None, limit: tuple[float, float]) -> Stance:
    """Shared door / drawer stance search: facing the object's -x from its +x side."""
    offsets = np.asarray(offsets, dtype=np.float64)
    pose = check_pose(pose, "pose")
    yaw = float(yaw_of(pose) + np.pi)
    h_local = np.asarray(obj.meta["handle"], dtype=np.float64)
    if side is None:  # the hand on the handle's side of the object, as seen by the person facing it
        side = "right" if h_local[1] > 0 else "left"
    check_side(side)
    sc = actor_scale(offsets)
    poses = kin_fn(openings)
    palm, R = hand_fn(obj, poses, side)
    wr = wrist_targets(palm, R, offsets, side)  # (A, 3)
    sgn = 1.0 if side == "left" else -1.0
    h_world = apply_h(pose, h_local)
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    left = np.array([-fwd[1], fwd[0]])
    xs = sc * np.linspace(0.20, 0.80, 6)
    ys = sc * np.linspace(-0.30, 0.30, 5)
    cands = np.array([h_world[:2] - x * fwd - sgn * y * left for x in xs for y in ys])
    s, a, _ = _grid_stance(offsets, yaw, side, cands, wr, limit, solid_boxes(obj, poses, pose))
    # One planning step below the largest feasible opening: the motion in between is interpolated.
    return Stance(pos=cands[s], yaw=yaw, side=side, reach=float(openings[max(a - 1, 1)]))


def drawer_stance(offsets: np.ndarray, drawer: SceneObject, closed: np.ndarray, side: Side | None = None) -> Stance:
    """Stance in front of a drawer facing it, from which the hand (default: right) can pull it
    furthest out (``Stance.reach``, m) with the feet planted (low drawers: bending / squatting)."""
    tr = np.linspace(0.0, float(drawer.meta["max_travel"]), 9)
    return _stance_for(offsets, drawer, closed, _drawer_hand, lambda x: drawer_pose(drawer, closed, x), tr,
                       side or "right", LEAN_LIMIT["drawer"])


def _articulate(base: Motion, obj: SceneObject, kin_fn, hand_fn, q0: float, q1: float, label: str,
                side: Side, rng: np.random.Generator) -> Motion:
    """Reach the handle at opening q0, move it to q1 (eased), let go, retract."""
    check_side(side)
    T = base.num_frames
    rot, root, off = base_arrays(base)
    qs = np.linspace(q0, q1, 17)
    p_s, R_s = hand_fn(obj, kin_fn(qs), side)
    limit = LEAN_LIMIT["drawer"]
    solids = solid_boxes(obj, kin_fn(qs), kin_fn(0.0))
    ok, pitch_q, drop_q = lean_table(rot[:1], root[:1], off, side, wrist_targets(p_s, R_s, off, side), solids,
                                     limit, is_seated(base))
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
    seated = is_seated(base)
    lt = max(lean_travel(rot[0], root[0], off, float(p), float(d), seated)
             for p, d in ((pitch_q[0], drop_q[0]), (pitch_q[-1], drop_q[-1])))
    # Opening progress is paced by the larger of the hand's and the torso's step between planned
    # openings, so a lean that changes quickly somewhere is given the time it needs.
    step = np.maximum(np.linalg.norm(np.diff(p_s, axis=0), axis=1),
                      lean_steps(rot[0], root[0], off, pitch_q, drop_q, seated)) + 1e-6
    C = np.concatenate([[0.0], np.cumsum(step)])
    ph = phases(label, T, rng, base.fps, moves={
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
    rot, root = lean_between(rot, root, off, np.interp(kpos, np.arange(len(qs)), pitch_q),
                             np.interp(kpos, np.arange(len(qs)), drop_q), seated, g0, r1)
    P, _ = forward_kinematics(rot, root, off)
    pb = palm_points(P)[:, 0 if side == "left" else 1]
    handle = np.asarray(obj.meta["handle"], dtype=np.float64)
    rot, hold = reach_hold_retract(rot, root, off, side, pb, palm, R, g0, r1,
                                   (palm[g0], unit(palm[g0] - apply_h(poses[g0], handle))),
                                   (palm[-1], unit(palm[-1] - apply_h(poses[-1], handle))), 2.0, f"{label} {obj.name}")
    require_body_clear(forward_kinematics(rot, root, off)[0], solid_boxes(obj, poses, kin_fn(0.0)),
                       f"{label} {obj.name}", "use the stance from drawer_stance")
    return finish_motion(base, rot, root, [ActionInterval(label, 0, T)], {obj.name: poses}, {WRIST[side]: hold})


def _move_drawer(base: Motion, drawer: SceneObject, closed: np.ndarray, q0: float, q1: float, label: str,
                 side: Side, rng: np.random.Generator) -> Motion:
    closed = check_pose(closed, "closed")
    mt = float(drawer.meta["max_travel"])
    if not (0.0 <= q0 <= mt and 0.0 <= q1 <= mt):
        raise ValueError(f"drawer travel must lie in [0, {mt}] m, got {q0} -> {q1}")
    return _articulate(base, drawer, lambda x: drawer_pose(drawer, closed, x), _drawer_hand, q0, q1, label, side, rng)


def open_drawer(base: Motion, drawer: SceneObject, closed: np.ndarray, travel: float, rng: np.random.Generator,
                side: Side = "right", start: float = 0.0) -> Motion:
    """Pull ``drawer`` (closed world pose (4, 4)) out from ``start`` to ``travel`` m (within
    [0, max_travel]) by its handle. Label 'open_drawer'; the drawer's pose track is returned."""
    return _move_drawer(base, drawer, closed, start, travel, "open_drawer", side, rng)


def close_drawer(base: Motion, drawer: SceneObject, closed: np.ndarray, travel: float, rng: np.random.Generator,
                 side: Side = "right", end: float = 0.0) -> Motion:
    """Push ``drawer`` from ``travel`` m back to ``end`` (default closed). Label 'close_drawer'."""
    return _move_drawer(base, drawer, closed, travel, end, "close_drawer", side, rng)
