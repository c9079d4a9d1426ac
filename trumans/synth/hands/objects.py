"""Hands on small objects: reach + grasp, pick up / carry / put down (conventions in ``hands.core``).

Rotationally symmetric upright objects (bottle, cup, vase) are grasped on the side facing the
reaching shoulder: their ``grasp_point`` turned about the object's vertical axis. The arm is back
at its base pose on the base's last frame unless the object is still held, in which case it is at
the carry pose (``carry_pose``), a deterministic function of the body state, so consecutive
primitives join without a jump.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import unit, yaw_matrix
from trumans.skeleton import forward_kinematics
from ..motion import Motion, yaw_of
from ..poses import ease, slerp_rot
from .core import (
    PALM_GAP, SHOULDER, SIGN, UP, WRIST, Side, actor_scale, apply_h, base_arrays, base_palm, check_pose, check_side,
    finish_motion, hand_frame, hand_world, heading_frame, inv_h, is_seated, palm_points, place_arm,
    reach_hold_retract, reach_path, require_reached, wrist_targets, wrist_to_palm,
)
from .lean import choose_lean, lean_between, lean_pose, lean_travel
from .timing import phases, ramp

__all__ = ["Hold", "carry_pose", "grasp_target", "hand_for", "reach_grasp", "pick_up", "carry", "put_down"]

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


def carry_pose(m: Motion, hold: Hold) -> tuple[np.ndarray, np.ndarray]:
    """World palm-point targets (T, 3) and wrist rotations (T, 3, 3) of a carried object over ``m``."""
    F = heading_frame(m)
    return apply_h(F, hold.carry), F[:, :3, :3] @ hold.carry_rot


def object_height(obj: SceneObject) -> float:
    return float(obj.mesh.bounds[1, 2])


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
    ga = unit(np.asarray(obj.meta["grasp_axis"], dtype=np.float64))
    R = pose[:3, :3]
    upright = R[2, 2] > np.cos(np.radians(10))
    reach = shoulder - apply_h(pose, [0.0, 0.0, gp[2]])
    reach_h = unit(np.array([reach[0], reach[1], 0.0]))
    if abs(ga[2]) < 0.3 and upright and np.hypot(gp[0], gp[1]) > 1e-4 and obj.category in ("bottle", "cup", "vase"):
        # Revolved around local z: grasp the side turned towards the shoulder, rotated towards the midline.
        turn = np.radians(35.0) * (1.0 if side == "right" else -1.0)
        out = yaw_matrix(turn) @ reach_h  # outward surface direction (from the axis to the palm)
        r = np.hypot(gp[0], gp[1])
        axis_pt = apply_h(pose, [0.0, 0.0, gp[2]])
        surf = axis_pt + r * out
        n = -out
        fingers = np.cross(n, UP) if side == "right" else np.cross(UP, n)
        return surf, surf + PALM_GAP * out, hand_frame(n, fingers, side)  # thumb up
    surf = apply_h(pose, gp)
    n = R @ ga
    cand = np.concatenate([R[:, :2].T, -R[:, :2].T])  # object's local +-x, +-y in world
    d = -reach_h
    cand = cand - (cand @ n)[:, None] * n
    fingers = cand[np.argmax(unit(cand) @ d)]
    return surf, surf - PALM_GAP * n, hand_frame(n, fingers, side)


def _default_carry(offsets: np.ndarray, side: Side, rng: np.random.Generator, seated: bool) -> np.ndarray:
    """Carry palm point in the heading frame (m): in front of the hip, higher when seated (above the thighs)."""
    s = actor_scale(offsets)
    return s * np.array([0.30 + rng.uniform(-0.02, 0.03), SIGN[side] * (0.17 + rng.uniform(-0.02, 0.02)),
                         (0.28 if seated else 0.10) + rng.uniform(-0.03, 0.03)])


def hand_for(base: Motion, point: np.ndarray, frame: int = 0) -> Side:
    """The hand on the side of the body where world ``point`` (3,) lies at ``frame`` of ``base``."""
    rel = inv_h(heading_frame(base)[frame]) @ np.r_[np.asarray(point, dtype=np.float64)[:3], 1.0]
    return "left" if rel[1] > 0 else "right"


def _grasp_phase(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, frame: int):
    """Lean + grasp target of ``obj`` for the body at base frame ``frame``."""
    rot, root, off = base_arrays(base)
    P, _ = forward_kinematics(rot[frame:frame + 1], root[frame:frame + 1], off)
    surf, palm, Rh = grasp_target(obj, pose, P[0, SHOULDER[side]], side)
    pitch, drop = choose_lean(rot[frame], root[frame], off, side, wrist_targets(palm, Rh, off, side)[None],
                              is_seated(base))
    return surf, palm, Rh, pitch, drop


def reach_grasp(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, rng: np.random.Generator) -> Motion:
    """Reach for ``obj`` (at world ``pose`` (4, 4)), hold it without lifting, let go and return.

    base: the body's own motion (T frames, e.g. ``locomotion.stand``; see ``nominal_frames``).
    Labels 'reach' (to the grasp frame) and 'grasp' (grasp frame to release). The object does not
    move (its constant pose is returned in ``objects[obj.name]``); grasp flags on the wrist."""
    check_side(side)
    pose = check_pose(pose, "pose")
    T = base.num_frames
    surf, palm, Rh, pitch, drop = _grasp_phase(base, obj, pose, side, 0)
    pb = base_palm(base, side)
    lt = lean_travel(base.rot[0], base.root[0], base.offsets, pitch, drop, is_seated(base))
    ph = phases("reach_grasp", T, rng, base.fps, moves={"reach": max(np.linalg.norm(palm - pb[0]) + 0.05, lt),
                                                         "release": max(np.linalg.norm(palm - pb[-1]) + 0.05, lt)})
    g0, g1 = ph["grasp"]
    rot, root, off = base_arrays(base)
    rot, root = lean_between(rot, root, off, pitch, drop, is_seated(base), g0, g1)
    P, _ = forward_kinematics(rot, root, off)
    palm_b = palm_points(P)[:, 0 if side == "left" else 1]
    out = unit(unit(palm - surf) + [0.0, 0.0, 1.0])  # arrive from outside and above (clear the support)
    rot, hold = reach_hold_retract(rot, root, off, side, palm_b, np.broadcast_to(palm, (T, 3)),
                                   np.broadcast_to(Rh, (T, 3, 3)), g0, g1, (palm, out), (palm, out), 4.0,
                                   f"reach_grasp {obj.name}")
    return finish_motion(base, rot, root, [ActionInterval("reach", 0, g0 + 1), ActionInterval("grasp", g0, g1 + 1)],
                         {obj.name: np.broadcast_to(pose, (T, 4, 4)).copy()}, {WRIST[side]: hold})


def pick_up(base: Motion, obj: SceneObject, pose: np.ndarray, side: Side, rng: np.random.Generator,
            carry_point: np.ndarray | None = None) -> tuple[Motion, Hold]:
    """Reach for ``obj`` at world ``pose`` (4, 4), grasp it, lift it to the carry pose and hold it.

    Labels 'reach' (start -> grasp frame), 'grasp' (short closing of the hand), 'pick_up' (lift to
    the carry pose), 'carry' (the rest). ``carry_point`` (3,) palm point in the heading frame
    (default: drawn from ``rng``, in front of the hip). Returns (motion, hold) — hand ``hold`` to
    ``carry`` / ``drink`` / ``phone_call`` / ``put_down``; the motion ends at the carry pose."""
    check_side(side)
    pose = check_pose(pose, "pose")
    T = base.num_frames
    surf, palm, Rh, pitch, drop = _grasp_phase(base, obj, pose, side, 0)
    rot, root, off = base_arrays(base)
    carry = _default_carry(off, side, rng, is_seated(base)) if carry_point is None \
        else np.asarray(carry_point, dtype=np.float64)
    c0 = apply_h(heading_frame(base)[0], carry)
    lt = lean_travel(rot[0], root[0], off, pitch, drop, is_seated(base))
    ph = phases("pick_up", T, rng, base.fps, moves={
        "reach": max(np.linalg.norm(palm - base_palm(base, side)[0]) + 0.05, lt),
        "pick_up": max(np.linalg.norm(palm - c0) + 0.1, 1.7 * lt)})
    g0, g1 = ph["grasp"]
    p0, p1 = ph["pick_up"]
    t = np.arange(T)
    s_lift = np.clip((t - p0) / max(p1 - p0, 1), 0, 1)
    e_move = ease(np.clip(1.3 * s_lift - 0.3, 0, 1))  # palm grasp -> carry, after a short lift
    # The torso straightens once the object is on its way in (a straightening torso with the hand
    # still at the support would over-extend the arm).
    lean = ramp(T, 0, g0) * (1 - ease(np.clip((s_lift - 0.4) / 0.6, 0, 1)))
    seated = is_seated(base)
    rot, root = lean_pose(rot, root, off, pitch * lean, drop * lean, seated)
    P, _ = forward_kinematics(rot, root, off)
    F = heading_frame(Motion(rot, root, off))
    # Carry orientation: the grasp orientation seen from the body's heading at the grasp frame.
    carry_rot = F[g0, :3, :3].T @ Rh
    hold = Hold(obj.name, side, np.eye(4), carry, carry_rot)
    palm_b = palm_points(P)[:, 0 if side == "left" else 1]
    out = unit(unit(palm - surf) + [0.0, 0.0, 1.0])  # arrive from outside and above (clear the support)
    path = reach_path(palm_b, palm, out, t / max(g0, 1))
    R = np.broadcast_to(Rh, (T, 3, 3)).copy()
    w = ease(np.clip(t / max(g0, 1) * 1.6, 0, 1))
    path[g0:p0 + 1] = palm
    # Lift: palm from the grasp point to the carry point, first up (clear the support), then in.
    c_w = apply_h(F, carry)
    s = s_lift
    e = ease(s)[:, None]
    up = 0.06 * actor_scale(off) * np.sin(np.pi * np.clip(1.5 * s, 0, 1))[:, None] * UP
    lift = palm * (1 - e_move[:, None]) + c_w * e_move[:, None] + up
    R_c = F[:, :3, :3] @ carry_rot
    sel = t > p0
    path[sel] = lift[sel]
    R[sel] = slerp_rot(np.broadcast_to(Rh, (T, 3, 3)), R_c, e[:, 0])[sel]
    w[t >= g0] = 1.0
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    require_reached(reached, (t >= g0) & (t <= p0), f"pick_up {obj.name}")  # then the object follows the hand
    H = hand_world(rot, root, off, side)
    hold.offset = inv_h(H[g0]) @ pose
    track = np.broadcast_to(pose, (T, 4, 4)).copy()
    track[g0:] = H[g0:] @ hold.offset
    actions = [ActionInterval("reach", 0, g0 + 1), ActionInterval("grasp", g0, g1 + 1), ActionInterval("pick_up", g1, p1 + 1)]
    if p1 < T - 1:
        actions.append(ActionInterval("carry", p1, T))
    return finish_motion(base, rot, root, actions, {obj.name: track}, {WRIST[side]: t >= g0}), hold


def carry(base: Motion, hold: Hold) -> Motion:
    """Carry a held object over the base motion (e.g. a ``locomotion.walk``): the holding arm stays
    at the carry pose, the object follows the hand. Label 'carry' on every frame."""
    rot, root, off = base_arrays(base)
    T = base.num_frames
    palm, R = carry_pose(base, hold)
    rot, _ = place_arm(rot, root, off, hold.side, palm, R, np.ones(T))
    # (an unreached carry target leaves the arm stretched towards it; the object follows the hand)
    H = hand_world(rot, root, off, hold.side)
    return finish_motion(base, rot, root, [ActionInterval("carry", 0, T)], {hold.name: H @ hold.offset},
                   {WRIST[hold.side]: np.ones(T, dtype=bool)})


def put_down(base: Motion, hold: Hold, target: np.ndarray, rng: np.random.Generator,
             exact_yaw: bool = False) -> Motion:
    """Put a held object down at world ``target`` (4, 4) object pose (e.g. standing on a table),
    release it and bring the arm back to the base pose. Label 'put_down' on every frame; the object
    follows the hand until the release frame and stays at the placed pose after it (read it from
    ``objects[name][-1]``). Unless ``exact_yaw``, the target is turned about the world vertical so
    that the object keeps the yaw it has relative to the body while carried (the wrist need not
    twist); its position and tilt are kept."""
    target = check_pose(target, "target")
    side = hold.side
    T = base.num_frames
    rot, root, off = base_arrays(base)
    if not exact_yaw:
        carried = heading_frame(base)[-1, :3, :3] @ hold.carry_rot @ hold.offset[:3, :3]
        d_yaw = yaw_of(carried) - yaw_of(target)
        target = target.copy()
        target[:3, :3] = yaw_matrix(d_yaw) @ target[:3, :3]
    Ht = target @ inv_h(hold.offset)  # hand transform that puts the object at the target
    Rh = Ht[:3, :3]
    palm = wrist_to_palm(Ht[:3, 3], Rh, off, side)
    pitch, drop = choose_lean(rot[0], root[0], off, side, Ht[:3, 3][None], is_seated(base))
    c0 = carry_pose(base, hold)[0][0]
    lt = lean_travel(rot[0], root[0], off, pitch, drop, is_seated(base))
    ph = phases("put_down", T, rng, base.fps, moves={
        "put_down": max(np.linalg.norm(palm - c0) + 0.1, lt),
        "retract": max(np.linalg.norm(palm - base_palm(base, side)[-1]) + 0.05, lt)})
    d0, d1 = ph["put_down"]
    r0, r1 = ph["release"]
    t = np.arange(T)
    s = np.clip((t - d0) / max(d1 - d0, 1), 0, 1)
    e = ease(s)
    lean = e * (1 - ramp(T, r1, T - 1))  # the torso leans in as the object goes out
    rot, root = lean_pose(rot, root, off, pitch * lean, drop * lean, is_seated(base))
    c_p, c_R = carry_pose(Motion(rot, root, off), hold)
    hover = (0.05 * 4.0 * e * (1 - e))[:, None] * UP  # over the support's edge, then down
    path = c_p * (1 - e[:, None]) + palm * e[:, None] + hover
    R = slerp_rot(c_R, np.broadcast_to(Rh, (T, 3, 3)), ease(s))
    w = np.ones(T)
    sel = t >= d1
    path[sel] = palm
    R[sel] = Rh
    # Retract: the hand moves back off the object along its grasp direction, then blends out.
    so = np.clip((t - r1) / max(T - 1 - r1, 1), 0, 1)
    out_dir = unit(palm - target[:3, 3])  # away from the object's origin (bottom centre)
    back = t > r1
    path[back] = (palm + 0.06 * np.sin(np.pi * so)[:, None] * out_dir)[back]
    w[back] = 1 - ease(so[back])
    rot, reached = place_arm(rot, root, off, side, path, R, w)
    held = t <= r0
    require_reached(reached, (t >= d1) & (t <= r1), f"put_down {hold.name}")
    H = hand_world(rot, root, off, side)
    track = H @ hold.offset
    track[r0:] = track[r0]
    return finish_motion(base, rot, root, [ActionInterval("put_down", 0, T)], {hold.name: track},
                   {WRIST[side]: held})
