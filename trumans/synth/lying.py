"""Lying: lying down from sitting on the edge / lying idle / getting up (sitting: ``posture``).

``posture.seated_state(...)`` (sitting on the edge) = first frame of ``lie_down``, which ends in
``lying_state(...)`` = first/last frame of ``lie`` = first frame of ``get_up`` (ending in the seated
state). ``lie_center`` is a world point ON the surface (z = surface height); the pelvis rests
``posture.seat_clearance`` above it.

Lying comes in two leg postures: straight (pose 'lie') and, where the surface is too short for
the actor (a sofa between its arms), knees up with the feet flat on the surface ``leg_reach`` m
from the pelvis along the body axis. ``fit_lying`` chooses the posture and where along the
surface the pelvis goes; ``lying_extent`` gives the body's extent along the axis.
"""
from __future__ import annotations

import numpy as np

from trumans.actions import ActionInterval
from trumans.contacts.rule import JOINT_RADIUS
from trumans.rotations import euler_to_matrix, unit, yaw_matrix
from trumans.skeleton import ANKLES, FEET, HIPS, JOINT_INDEX, KNEES, NUM_JOINTS, forward_kinematics
from .legs import rest_ankle_rel, solve_legs
from .motion import Motion
from .poses import ease, pose, slerp_poses, slerp_rot
from .posture import Stagger, _breathing, _leg_scale, _offsets, _random_holds, _vec3, seat_clearance, seated_state

__all__ = ["HEAD_TOP", "min_leg_reach", "lying_state", "lying_extent", "fit_lying", "lie_down", "lie", "get_up"]

_LEGS = [j for side in zip(HIPS, KNEES, ANKLES, FEET) for j in side]  # hip, knee, ankle, foot per side
_ANKLES = list(ANKLES)
_HIPS = list(HIPS)
_KNEES = list(KNEES)
_UPPER = [j for j in range(NUM_JOINTS) if j not in _LEGS]
HEAD_TOP = 0.12  # m, head joint to the top of the skull (further than its contact radius)


def min_leg_reach(offsets: np.ndarray) -> float:
    """Shortest ``leg_reach`` (m) of a knees-up lying posture (knees bent about 120 deg)."""
    return 0.45 * _leg_scale(_offsets(offsets))


def lying_state(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float,
                leg_reach: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Supine state: (rot (24, 3, 3), root (3,)). Pelvis above ``lie_center`` (3,) by ``seat_clearance``
    (raised further if an upper-body joint's surface would be below the surface), the spine-to-head
    direction horizontal along ``lie_yaw`` (rad), face up, pose 'lie'. ``leg_reach`` (m): None for
    straight legs, else knees up with the ankles on the surface that far from the pelvis towards
    the feet, feet flat (at least ``min_leg_reach``)."""
    offsets = _offsets(offsets)
    lie_center = _vec3(lie_center, "lie_center")
    rot = pose("lie", offsets).copy()
    # Root pitched by -90 deg (head -> -x, face up), then turned so the head points along lie_yaw.
    # The rest spine leans back a little (neck behind the pelvis); pitch less than 90 deg by that
    # angle so the upper back lies level with the pelvis.
    neck = offsets[[3, 6, 9, 12]].sum(0)
    back = np.arctan2(-neck[0], neck[2])
    rot[0] = yaw_matrix(lie_yaw + np.pi) @ euler_to_matrix(np.array([0.0, back - np.pi / 2, 0.0]), "ZYX")
    root = lie_center + np.array([0.0, 0.0, seat_clearance(offsets)])
    P, _ = forward_kinematics(rot[None], root[None], offsets)
    gap = P[0, _UPPER, 2] - lie_center[2] - JOINT_RADIUS[_UPPER]
    root[2] += max(0.0, -float(gap.min()))
    if leg_reach is not None:
        if not leg_reach >= min_leg_reach(offsets) - 1e-9:
            raise ValueError(f"leg_reach must be >= {min_leg_reach(offsets):.3f} m for this actor "
                             f"(min_leg_reach), got {leg_reach}")
        axis = np.array([np.cos(lie_yaw), np.sin(lie_yaw), 0.0])
        P, _ = forward_kinematics(rot[None], root[None], offsets)
        z0 = offsets[0, 2] + rest_ankle_rel(offsets)[0, 2]  # ankle height of a flat foot
        feet = np.empty((1, 2, 3))
        for k, h in enumerate(_HIPS):
            lateral = P[0, h] - root - ((P[0, h] - root) @ axis) * axis
            feet[0, k] = root - leg_reach * axis + lateral
            feet[0, k, 2] = lie_center[2] + z0
        frot = np.broadcast_to(yaw_matrix(lie_yaw + np.pi), (1, 2, 3, 3))
        rot, reached = solve_legs(rot[None], root[None], offsets, feet, foot_rot=frot,
                                  pole_dir=np.array([[0.0, 0.0, 1.0]]))
        if not reached.all():
            raise ValueError(f"leg_reach {leg_reach} m is out of the legs' reach; use fit_lying")
        rot = rot[0]
    return rot, root


def lying_extent(offsets: np.ndarray, leg_reach: float | None = None) -> tuple[float, float]:
    """(head, feet) extent (m) of the lying body along its axis from the pelvis: the furthest body
    surface towards the head (the skull top, ``HEAD_TOP`` beyond the head joint) and towards the
    feet (joint contact radii included)."""
    rot, root = lying_state(offsets, np.zeros(3), 0.0, leg_reach)
    P, _ = forward_kinematics(rot[None], root[None], _offsets(offsets))
    r = JOINT_RADIUS.copy()
    r[JOINT_INDEX["head"]] = HEAD_TOP
    x = P[0, :, 0]
    return float((x + r).max()), float((r - x).max())


def fit_lying(offsets: np.ndarray, length: float, head_margin: float = 0.03,
              foot_margin: float = 0.03, prefer_reach: float | None = None) -> tuple[float, float | None]:
    """Where and how the actor lies on a surface ``length`` m long (along the lying axis, centred on
    its ``lie_center``): (shift (m) of the pelvis from the centre towards the head end, leg_reach).
    Straight legs (leg_reach None) when the body fits with the margins, centred if possible, else
    knees up with the head ``head_margin`` from the head end. ``prefer_reach`` (m, >= ``min_leg_reach``):
    lie knees up with that leg reach by choice (centred if possible) where it fits. Raises
    ValueError when even the shortest knees-up posture does not fit."""
    offsets = _offsets(offsets)
    half = 0.5 * float(length)
    if prefer_reach is not None:
        head, feet = lying_extent(offsets, prefer_reach)
        lo, hi = feet + foot_margin - half, half - head_margin - head
        if lo <= hi:
            return float(np.clip(0.0, lo, hi)), float(prefer_reach)
    head, feet = lying_extent(offsets)
    lo, hi = feet + foot_margin - half, half - head_margin - head  # pelvis shift range
    if lo <= hi:
        return float(np.clip(0.0, lo, hi)), None
    r_min = min_leg_reach(offsets)
    head, feet_min = lying_extent(offsets, r_min)
    shift = half - head_margin - head
    room = half + shift - foot_margin  # pelvis to the foot end
    if room < feet_min:
        raise ValueError(f"a {length:.2f} m surface is too short for this actor to lie on, even with the "
                         f"knees up (needs {head + head_margin + feet_min + foot_margin:.2f} m)")
    reach = r_min + (room - feet_min)  # the feet extent grows one for one with the reach
    rot, root = lying_state(offsets, np.zeros(3), 0.0)
    P, _ = forward_kinematics(rot[None], root[None], offsets)
    straight = -float(P[0, _ANKLES, 0].mean())  # pelvis to ankles of the straight legs
    return float(shift), float(min(reach, 0.85 * straight))


def _knee_dirs(P: np.ndarray) -> np.ndarray:
    """(T, 3) mean unit direction in which the knees stick out of the hip-ankle lines (T, 24, 3)."""
    out = np.zeros(P.shape[:1] + (3,))
    for h, k, a in zip(_HIPS, _KNEES, _ANKLES):
        line = unit(P[:, a] - P[:, h])
        v = P[:, k] - P[:, h]
        out += v - (v * line).sum(-1, keepdims=True) * line
    return unit(out)


def lie_down(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, seat_center: np.ndarray,
             rng: np.random.Generator, *, sit_yaw: float, stand_pos: np.ndarray, fps: float = 30.0,
             leg_reach: float | None = None, stagger: Stagger = (0.0, 0.0)) -> Motion:
    """Lie down from sitting on the edge (``seated_state(offsets, seat_center, sit_yaw, stand_pos, stagger=stagger)``)
    to ``lying_state(offsets, lie_center, lie_yaw, leg_reach)``: the trunk reclines and turns, the
    pelvis slides to ``lie_center`` at constant clearance over the surface; the feet stay planted a
    moment, then lift (knees up) above the surface height before they swing over the edge onto it
    (ankle paths by leg IK). Label 'lie_down'; about 2.6-3.4 s."""
    offsets = _offsets(offsets)
    lie_center = _vec3(lie_center, "lie_center")
    rot0, root0 = seated_state(offsets, seat_center, sit_yaw, stand_pos, stagger=stagger)
    rot1, root1 = lying_state(offsets, lie_center, lie_yaw, leg_reach)
    T = int(round(rng.uniform(2.6, 3.4) * fps)) + 1
    s = np.linspace(0.0, 1.0, T)
    w_trunk = ease(s / 0.8)
    w_pelvis = ease((s - 0.1) / 0.85)
    rot = slerp_poses(rot0, rot1, w_trunk)
    rot[:, 0] = slerp_rot(rot0[0][None], rot1[0][None], w_trunk[:, None])[:, 0]
    root = root0 + w_pelvis[:, None] * (root1 - root0)
    # Legs: ankle paths that rise above the surface before crossing its edge.
    P0, G0 = forward_kinematics(rot0[None], root0[None], offsets)
    P1, G1 = forward_kinematics(rot1[None], root1[None], offsets)
    a0, a1 = P0[0, _ANKLES], P1[0, _ANKLES]  # (2, 3)
    z_clear = lie_center[2] + JOINT_RADIUS[_ANKLES[0]] + 0.07
    rise, fall = ease((s - 0.1) / 0.4), ease((s - 0.72) / 0.28)
    across = ease((s - 0.3) / 0.6)
    ank = a0[None] + across[:, None, None] * (a1 - a0)[None]
    ank[..., 2] = a0[None, :, 2] + rise[:, None] * (z_clear - a0[None, :, 2]) \
        + fall[:, None] * (a1[None, :, 2] - z_clear)
    w_foot = ease((s - 0.2) / 0.7)
    frot = np.stack([slerp_rot(G0[0, a][None], G1[0, a][None], w_foot[:, None])[:, 0] for a in _ANKLES], 1)
    k0, k1 = _knee_dirs(P0)[0], _knee_dirs(P1)[0]
    w_knee = ease((s - 0.1) / 0.6)[:, None]
    pole = (1 - w_knee) * k0 + w_knee * (k1 if k1 @ k1 > 0.5 else np.array([0.0, 0.0, 1.0]))
    rot, _ = solve_legs(rot, root, offsets, ank, foot_rot=frot, pole_dir=pole)
    # Ease exactly into the shared states at both ends (the IK's hip twist may differ slightly).
    w_end = np.zeros((T, NUM_JOINTS))
    w_end[:, _LEGS] = ease((s - 0.9) / 0.1)[:, None]
    rot = slerp_rot(rot, np.broadcast_to(rot1, rot.shape), w_end)
    w_start = np.zeros((T, NUM_JOINTS))
    w_start[:, _LEGS] = 1.0 - ease(s / 0.1)[:, None]
    rot = slerp_rot(rot, np.broadcast_to(rot0, rot.shape), w_start)
    contact = np.zeros((T, 2), dtype=bool)
    contact[s < 0.1] = True  # the feet leave the floor as the legs start to lift
    rot[0], root[0] = rot0, root0
    rot[-1], root[-1] = rot1, root1
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact,
                  actions=[ActionInterval("lie_down", 0, T)])


def lie(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, frames: int, rng: np.random.Generator,
        fps: float = 30.0, leg_reach: float | None = None, shift: float = 1.0) -> Motion:
    """Lying idle for ``frames`` frames, starting and ending exactly in ``lying_state(offsets,
    lie_center, lie_yaw, leg_reach)``: breathing, head turns, and the body shifting on the surface
    (pelvis moved up to ``shift`` x (6 cm along, 10 cm across the surface) at constant height, the
    spine bending sideways, a knee falling outwards when knees up). Label 'lie'. With the knees up
    (``leg_reach``) the feet stay planted on the surface (``foot_contact`` set, leg IK)."""
    offsets = _offsets(offsets)
    rot0, root0 = lying_state(offsets, lie_center, lie_yaw, leg_reach)
    rot = _breathing(rot0, frames, rng, fps, 0.012)
    T = len(rot)
    axis = np.array([np.cos(lie_yaw), np.sin(lie_yaw), 0.0])
    across = np.array([-np.sin(lie_yaw), np.cos(lie_yaw), 0.0])
    sh = _random_holds(T, fps, rng, np.array([0.06 * shift, 0.10 * shift, 0.12, 0.15]), hold=(1.5, 3.5), move=1.2)
    root = root0 + sh[:, :1] * axis + sh[:, 1:2] * across
    z = np.zeros(T)
    for name in ("spine1", "spine2", "spine3"):  # sideways bend: in the plane of the surface
        j = JOINT_INDEX[name]
        rot[:, j] = euler_to_matrix(np.stack([z, z, sh[:, 2] / 3], -1), "ZYX") @ rot[:, j]
    if leg_reach is not None:
        P, G = forward_kinematics(rot0[None], root0[None], offsets)
        feet = np.repeat(P[:, _ANKLES], T, axis=0)
        frot = np.repeat(G[:, _ANKLES], T, axis=0)
        side = np.where(rng.random() < 0.5, 1.0, -1.0)  # the knee that falls outwards
        k0 = _knee_dirs(P)[0]
        pole = np.repeat(k0[None], T, axis=0) + np.abs(sh[:, 3:4]) * side * across
        rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=frot, pole_dir=pole)
    rot[0], root[0], rot[-1], root[-1] = rot0, root0, rot0, root0
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps,
                  foot_contact=np.full((T, 2), leg_reach is not None), actions=[ActionInterval("lie", 0, T)])


def get_up(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, seat_center: np.ndarray,
           rng: np.random.Generator, *, sit_yaw: float, stand_pos: np.ndarray, fps: float = 30.0,
           leg_reach: float | None = None, stagger: Stagger = (0.0, 0.0)) -> Motion:
    """From ``lying_state`` back to sitting on the edge (``seated_state(..., stagger=stagger)``): a
    lie-down played backwards with its own timing from ``rng``. Label 'get_up'."""
    return lie_down(offsets, lie_center, lie_yaw, seat_center, rng, sit_yaw=sit_yaw, stand_pos=stand_pos, fps=fps,
                    leg_reach=leg_reach, stagger=stagger).reversed("get_up")
