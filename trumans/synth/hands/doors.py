"""Doors (hinge) that open towards the person (``trumans.scenes.furniture.door``): ``door_stance`` plans
where to take the handle and how far to step back; ``open_door`` / ``close_door`` build their own
base (stand, step back / forwards with the hand on the handle, stand). Conventions (palm point,
hand frame, grasp flags on the wrist joint) are those of ``hands.core``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import rodrigues, unit, yaw_matrix
from trumans.skeleton import forward_kinematics
from .. import locomotion
from ..legs import standing_state
from ..motion import Motion, concat_motions
from .clearance import LEAN_LIMIT, lean_table, require_body_clear, solid_boxes
from .core import (
    PALM_GAP, WRIST, OutOfReach, Side, actor_scale, apply_h, base_arrays, check_pose, check_side, finish_motion,
    hand_frame, palm_points, reach_hold_retract, to_h, wrist_targets,
)
from .lean import lean_between
from .timing import HAND_SPEED, ramp

__all__ = ["door_pose", "DoorStance", "door_stance", "open_door", "close_door"]

def door_pose(door: SceneObject, closed: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """World pose(s) (..., 4, 4) of ``door`` opened by ``angle`` (...,) rad in [0, max_angle] from
    its closed world pose ``closed`` (4, 4): rotation by ``open_sign * angle`` about its hinge axis."""
    if door.dof != "hinge":
        raise ValueError(f"object {door.name!r} is not a hinge (dof {door.dof!r})")
    a = np.asarray(angle, dtype=np.float64) * float(door.meta.get("open_sign", 1.0))
    R = rodrigues(np.asarray(door.axis, dtype=np.float64), a)
    h = door.hinge_point
    local = to_h(R, h - (R @ h))
    return closed @ local


def _door_hand(door: SceneObject, poses: np.ndarray, side: Side) -> tuple[np.ndarray, np.ndarray]:
    """Palm points (..., 3) just in front of the lever handle's outer end and wrist rotations
    (..., 3, 3) (palm facing the leaf, fingers down, hooked around the lever; the fingers keep clear
    of the leaf) for door poses (..., 4, 4)."""
    h = np.asarray(door.meta["handle"], dtype=np.float64)
    fx = poses[..., :3, 0]
    palm = apply_h(poses, h) + (0.015 + PALM_GAP) * fx  # the lever ends 1.5 cm beyond the handle point
    R = hand_frame(-fx, -poses[..., :3, 2], side)
    return palm, R


@dataclass
class DoorStance:
    """How a person works a door that opens towards them (``trumans.scenes.furniture.door``): standing at
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
    rot0, root0 = standing_state(offsets, np.zeros(2), 0.0)
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
        frames, lo, hi = solid_boxes(door, poses, closed)
        grow = np.array([DOOR_GAIT_CLEAR, DOOR_GAIT_CLEAR, 0.0])  # room for the gait's swinging feet and sway
        ok_k, p_k, d_k = lean_table(rot, root, offsets, side, wrist_targets(palm, R, offsets, side),
                                     (frames, lo - grow, hi + grow), LEAN_LIMIT["door"])
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
    closed = check_pose(closed, "closed")
    if door.dof != "hinge":
        raise ValueError(f"object {door.name!r} is not a hinge (dof {door.dof!r})")
    h_local = np.asarray(door.meta["handle"], dtype=np.float64)
    handle = apply_h(closed, h_local)[:2]
    n = closed[:2, 0] / np.linalg.norm(closed[:2, 0])  # the door's +x: into the room
    free = closed[:2, :2] @ np.array([0.0, h_local[1] - door.hinge_point[1]])  # hinge -> handle
    free /= np.linalg.norm(free)
    sc = actor_scale(offsets)
    face = float(np.arctan2(-n[1], -n[0]))
    turn = float(np.sign(free[0] * n[1] - free[1] * n[0]))  # a positive yaw offset turns towards the free edge
    grid = np.array([(dn, dt, dy, L) for dn in (0.35, 0.5, 0.65) for dt in (-0.15, 0.0, 0.15, 0.3, 0.45)
                     for dy in (-0.5, -0.25, 0.0, 0.25, 0.5) for L in (0.3, 0.55, 0.8)])
    pos = handle + sc * (grid[:, :1] * n + grid[:, 1:2] * free)
    yaw = face + turn * grid[:, 2]
    back = sc * grid[:, 3]
    best = None
    for sd in ([side] if side else ["left", "right"]):
        check_side(sd)
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


def _door_close_walk(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, angle: float,
                     stance: DoorStance, rng: np.random.Generator, fps: float, label: str) -> Motion:
    """Closing ``door`` from ``angle`` rad: stand at ``stance.at(angle)``, take the handle, walk
    forwards to ``stance.pos`` pushing the door shut (its opening follows the walked distance),
    let go. The hand follows the handle; the torso leans as planned along the path."""
    offsets = np.asarray(offsets, dtype=np.float64)
    side, yaw = stance.side, float(stance.yaw)
    p_open, p_shut = stance.at(angle), np.asarray(stance.pos, dtype=np.float64)
    rot_s, root_s = standing_state(offsets, p_open, yaw)
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
                                     step_length=actor_scale(offsets) * float(rng.uniform(0.22, 0.3))))
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
        prog = ramp(T, g0, g1)
    prog[g1:] = 1.0
    q = angle * (1.0 - np.clip(prog, 0.0, 1.0))
    poses = door_pose(door, closed, q)
    palm, R = _door_hand(door, poses, side)
    # Lean along the way: planned at a few points of the path, interpolated by progress.
    rot, root, off = base_arrays(base)
    fr = _DOOR_FRACTIONS
    idx = np.clip(np.searchsorted(prog, fr * (1 - 1e-9)), g0, g1)  # frames at those progress points
    no_boxes = (np.zeros((len(idx), 0, 4, 4)), np.zeros((0, 3)), np.zeros((0, 3)))  # clearance: checked below
    ok, pitch_f, drop_f = lean_table(rot[idx], root[idx], off, side,
                                     wrist_targets(palm[idx], R[idx], off, side), no_boxes, LEAN_LIMIT["door"])
    diag = np.arange(len(idx))
    if not ok[diag, diag].all():
        raise OutOfReach(f"{label} {door.name}: the hand cannot follow the handle from this path; "
                         f"use door_stance and an opening up to its reach")
    rot, root = lean_between(rot, root, off, np.interp(prog, prog[idx], pitch_f[diag, diag]),
                             np.interp(prog, prog[idx], drop_f[diag, diag]), False, g0, g1)
    P, _ = forward_kinematics(rot, root, off)
    pb = palm_points(P)[:, k]
    hp = apply_h(poses, np.asarray(door.meta["handle"], dtype=np.float64))
    rot, hold = reach_hold_retract(rot, root, off, side, pb, palm, R, g0, g1, (palm[g0], unit(palm[g0] - hp[g0])),
                                   (palm[-1], unit(palm[-1] - hp[-1])), 2.0, f"{label} {door.name}")
    # Final check on every frame: the body (arms aside) keeps clear of the swinging leaf.
    require_body_clear(forward_kinematics(rot, root, off)[0], solid_boxes(door, poses, closed),
                       f"{label} {door.name}", "use door_stance")
    return finish_motion(base, rot, root, [ActionInterval(label, 0, T)], {door.name: poses}, {WRIST[side]: hold})


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
    closed = check_pose(closed, "closed")
    _check_door_angle(door, angle, stance)
    return _door_close_walk(offsets, door, closed, angle, stance, rng, fps, "open_door").reversed("open_door")


def close_door(offsets: np.ndarray, door: SceneObject, closed: np.ndarray, angle: float, rng: np.random.Generator,
               stance: DoorStance, fps: float = 30.0) -> Motion:
    """Push ``door`` from ``angle`` rad back to closed: from the standing state at ``stance.at(angle)``
    the hand takes the handle, the person walks forwards to ``stance.pos`` and lets go. Label
    'close_door'."""
    closed = check_pose(closed, "closed")
    _check_door_angle(door, angle, stance)
    return _door_close_walk(offsets, door, closed, angle, stance, rng, fps, "close_door")
