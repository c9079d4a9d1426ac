"""Posture transitions: sitting down / seated idle / standing up, lying down / lying idle / getting up.

Exact shared states make the primitives concatenate without jumps:
``walk(..., end=stand_pos, end_yaw=sit_yaw)`` ends in ``standing_state(offsets, stand_pos, sit_yaw)``
= the first frame of ``sit_down``; ``sit_down`` ends in ``seated_state(...)`` = first/last frame of
``sit`` = first frame of ``stand_up`` (whose last frame is the standing state again) and of
``lie_down``, which ends in ``lying_state(...)`` = first/last frame of ``lie`` = first frame of
``get_up`` (ending in the seated state).

Heights: the pelvis joint sits inside the body, ``seat_clearance(offsets)`` (~0.095 m for an average
actor, scaled by leg length) above the surface it rests on, so the buttocks/back skin touches the
seat or bed instead of sinking into it. ``seat_center``/``lie_center`` are world points ON the
surface (z = surface height).
"""
from __future__ import annotations

import numpy as np

from ..actions import ActionInterval
from ..rotations import euler_to_matrix, yaw_matrix
from ..skeleton import JOINT_INDEX
from .limb_ik import limb_reach
from .locomotion import foot_places, pelvis_height_limit, solve_legs, standing_state
from .motion import Motion
from .poses import POSES, ease, pose, slerp_poses, slerp_rot

__all__ = [
    "seat_clearance",
    "seated_state",
    "lying_state",
    "sit_down",
    "sit",
    "stand_up",
    "lie_down",
    "lie",
    "get_up",
]

def _leg_scale(offsets: np.ndarray) -> float:
    return limb_reach(offsets, "left_leg")[1] / 0.784


def seat_clearance(offsets: np.ndarray) -> float:
    """Height (m) of the pelvis joint above a seat/bed surface it rests on (0.095 m x leg scale)."""
    return 0.095 * _leg_scale(np.asarray(offsets, dtype=np.float64))


def _vec3(x: np.ndarray, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (3,):
        raise ValueError(f"{name} must be a (3,) world point (m), got {x.shape}")
    return x


def _vec2(x: np.ndarray, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.shape[-1:] not in ((2,), (3,)) or x.ndim != 1:
        raise ValueError(f"{name} must be a (2,) world xy point (m), got {x.shape}")
    return x[:2]


def _offsets(offsets: np.ndarray) -> np.ndarray:
    offsets = np.asarray(offsets, dtype=np.float64)
    if offsets.shape != (24, 3):
        raise ValueError(f"offsets must be (24, 3) (trumans.skeleton.rest_offsets(scale)), got {offsets.shape}")
    return offsets


def seated_state(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
                 base_pose: str = "sit") -> tuple[np.ndarray, np.ndarray]:
    """Seated state: (rot (24, 3, 3), root (3,)). Pelvis above ``seat_center`` (3,) by
    ``seat_clearance``, facing ``sit_yaw`` (rad), upper body ``base_pose``, feet planted where they
    stood in ``standing_state(offsets, stand_pos, sit_yaw)``. Raises ValueError when the feet
    cannot reach the floor from this seat."""
    offsets = _offsets(offsets)
    seat_center = _vec3(seat_center, "seat_center")
    stand_pos = _vec2(stand_pos, "stand_pos")
    if base_pose not in POSES:
        raise ValueError(f"unknown base_pose {base_pose!r}; choose one of {sorted(POSES)}")
    rot = pose(base_pose, offsets)[None].copy()
    rot[0, 0] = yaw_matrix(sit_yaw)
    root = (seat_center + np.array([0.0, 0.0, seat_clearance(offsets)]))[None]
    feet = foot_places(offsets, stand_pos, sit_yaw)[None]
    rot, reached = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(sit_yaw), (1, 2, 3, 3)))
    if not reached.all():
        raise ValueError(f"feet at stand_pos {stand_pos.tolist()} cannot reach the floor from the seat at "
                         f"{seat_center.tolist()}: choose a stand_pos closer to the seat or a lower seat")
    return rot[0], root[0]


def lying_state(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """Supine state: (rot (24, 3, 3), root (3,)). Pelvis above ``lie_center`` (3,) by ``seat_clearance``,
    the spine-to-head direction horizontal along ``lie_yaw`` (rad), face up, pose 'lie'."""
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
    return rot, root


def _breathing(rot: np.ndarray, rng: np.random.Generator, fps: float, amp: float, env: np.ndarray) -> np.ndarray:
    T = rot.shape[0]
    t = np.arange(T) / fps
    b = np.sin(2 * np.pi * rng.uniform(0.2, 0.3) * t + rng.uniform(0, 2 * np.pi)) * env
    head = 0.06 * np.sin(2 * np.pi * rng.uniform(0.03, 0.08) * t + rng.uniform(0, 2 * np.pi)) * env
    z = np.zeros(T)
    for name, zyx in (("spine2", (z, -amp * b, z)), ("spine3", (z, -amp * b, z)), ("head", (head, 0.3 * amp * b, z))):
        j = JOINT_INDEX[name]
        rot[:, j] = euler_to_matrix(np.stack(zyx, -1), "ZYX") @ rot[:, j]
    return rot


def _envelope(T: int, fps: float, ramp: float = 0.6) -> np.ndarray:
    t = np.arange(T) / fps
    return ease(t / ramp) * ease((t[-1] - t) / ramp) if T > 2 else np.zeros(T)


def sit_down(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
             rng: np.random.Generator, fps: float = 30.0) -> Motion:
    """Sit down from ``standing_state(offsets, stand_pos, sit_yaw)`` (standing in front of the seat,
    facing away from it) to ``seated_state(offsets, seat_center, sit_yaw, stand_pos)``: hips go back
    and down with a forward trunk lean, feet stay planted (leg IK). Label 'sit_down'; about 1.5-2.1 s."""
    offsets = _offsets(offsets)
    rot0, root0 = standing_state(offsets, _vec2(stand_pos, "stand_pos"), sit_yaw)
    rot1, root1 = seated_state(offsets, seat_center, sit_yaw, stand_pos)
    dur = rng.uniform(1.5, 2.1)
    T = int(round(dur * fps)) + 1
    s = np.linspace(0.0, 1.0, T)
    w_xy = ease(s / 0.85)
    w_z = ease((s - 0.08) / 0.92)
    root = np.empty((T, 3))
    root[:, :2] = root0[:2] + w_xy[:, None] * (root1[:2] - root0[:2])
    root[:, 2] = root0[2] + w_z * (root1[2] - root0[2])
    # Upper body: stand -> sit per joint, with a hip-hinge lean forward in the middle.
    rot = slerp_poses(rot0, rot1, ease(s))
    lean = np.radians(rng.uniform(25, 38)) * np.sin(np.pi * s) ** 1.5
    z = np.zeros(T)
    rot[:, 0] = yaw_matrix(sit_yaw) @ euler_to_matrix(np.stack([z, 0.6 * lean, z], -1), "ZYX")
    j = JOINT_INDEX["spine1"]
    rot[:, j] = euler_to_matrix(np.stack([z, 0.4 * lean, z], -1), "ZYX") @ rot[:, j]
    for side in ("left", "right"):  # arms come forward for balance
        j = JOINT_INDEX[f"{side}_shoulder"]
        rot[:, j] = euler_to_matrix(np.stack([z, -1.2 * lean, z], -1), "ZYX") @ rot[:, j]
    feet = np.repeat(foot_places(offsets, stand_pos, sit_yaw)[None], T, axis=0)
    h_lim = pelvis_height_limit(rot, root[:, :2], offsets, feet)
    root[:, 2] = np.minimum(root[:, 2], h_lim - 0.001)
    frot = np.broadcast_to(yaw_matrix(sit_yaw), (T, 2, 3, 3))
    knee = np.broadcast_to(np.array([np.cos(sit_yaw), np.sin(sit_yaw), 0.0]), (T, 3))
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=frot, pole_dir=knee)
    rot[-1], root[-1] = rot1, root1
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=np.ones((T, 2), dtype=bool),
                  actions=[ActionInterval("sit_down", 0, T - 1)])


def sit(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray, frames: int,
        rng: np.random.Generator, fps: float = 30.0) -> Motion:
    """Seated idle for ``frames`` frames (breathing, small head turns), starting and ending exactly in
    ``seated_state(offsets, seat_center, sit_yaw, stand_pos)``; feet planted. Label 'sit'."""
    offsets = _offsets(offsets)
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    rot0, root0 = seated_state(offsets, seat_center, sit_yaw, stand_pos)
    T = int(frames)
    rot = _breathing(np.repeat(rot0[None], T, axis=0), rng, fps, 0.015, _envelope(T, fps))
    root = np.repeat(root0[None], T, axis=0)
    feet = np.repeat(foot_places(offsets, stand_pos, sit_yaw)[None], T, axis=0)
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(sit_yaw), (T, 2, 3, 3)),
                        pole_dir=np.broadcast_to(np.array([np.cos(sit_yaw), np.sin(sit_yaw), 0.0]), (T, 3)))
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=np.ones((T, 2), dtype=bool),
                  actions=[ActionInterval("sit", 0, T - 1)])


def _reverse(m: Motion, label: str) -> Motion:
    return Motion(rot=m.rot[::-1].copy(), root=m.root[::-1].copy(), offsets=m.offsets, fps=m.fps,
                  foot_contact=m.foot_contact[::-1].copy(), actions=[ActionInterval(label, 0, m.num_frames - 1)])


def stand_up(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
             rng: np.random.Generator, fps: float = 30.0) -> Motion:
    """Stand up from ``seated_state`` to ``standing_state(offsets, stand_pos, sit_yaw)`` (a sit-down
    played backwards, with its own timing from ``rng``); feet planted. Label 'stand_up'."""
    return _reverse(sit_down(offsets, seat_center, sit_yaw, stand_pos, rng, fps), "stand_up")


def lie_down(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, seat_center: np.ndarray,
             rng: np.random.Generator, *, sit_yaw: float, stand_pos: np.ndarray, fps: float = 30.0) -> Motion:
    """Lie down from sitting on the bed's edge (``seated_state(offsets, seat_center, sit_yaw, stand_pos)``)
    to ``lying_state(offsets, lie_center, lie_yaw)``: the trunk reclines and turns while the pelvis
    slides to ``lie_center`` at constant clearance over the surface, the legs swing up (the knees
    straighten a little ahead of the hips). Label 'lie_down'; about 2.4-3.2 s."""
    offsets = _offsets(offsets)
    rot0, root0 = seated_state(offsets, seat_center, sit_yaw, stand_pos)
    rot1, root1 = lying_state(offsets, lie_center, lie_yaw)
    T = int(round(rng.uniform(2.4, 3.2) * fps)) + 1
    s = np.linspace(0.0, 1.0, T)
    w_body = ease(s)
    w_leg = np.empty((T, 24))
    w_leg[:] = w_body[:, None]
    w_hip = ease((s - 0.2) / 0.8)
    w_knee = ease((s - 0.1) / 0.8)
    for n in ("left_hip", "right_hip"):
        w_leg[:, JOINT_INDEX[n]] = w_hip
    for n in ("left_knee", "right_knee", "left_ankle", "right_ankle", "left_foot", "right_foot"):
        w_leg[:, JOINT_INDEX[n]] = w_knee
    rot = slerp_poses(rot0, rot1, w_leg)
    rot[:, 0] = slerp_rot(rot0[0][None], rot1[0][None], w_body[:, None])[:, 0]
    root = root0 + w_body[:, None] * (root1 - root0)
    contact = np.zeros((T, 2), dtype=bool)
    contact[s < 0.08] = True  # the feet leave the floor as the legs start to swing
    rot[-1], root[-1] = rot1, root1
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact,
                  actions=[ActionInterval("lie_down", 0, T - 1)])


def lie(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, frames: int, rng: np.random.Generator,
        fps: float = 30.0) -> Motion:
    """Lying idle (supine, breathing, small head turns) for ``frames`` frames, starting and ending
    exactly in ``lying_state(offsets, lie_center, lie_yaw)``. Label 'lie'."""
    offsets = _offsets(offsets)
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    rot0, root0 = lying_state(offsets, lie_center, lie_yaw)
    T = int(frames)
    rot = _breathing(np.repeat(rot0[None], T, axis=0), rng, fps, 0.012, _envelope(T, fps))
    return Motion(rot=rot, root=np.repeat(root0[None], T, axis=0), offsets=offsets, fps=fps,
                  foot_contact=np.zeros((T, 2), dtype=bool), actions=[ActionInterval("lie", 0, T - 1)])


def get_up(offsets: np.ndarray, lie_center: np.ndarray, lie_yaw: float, seat_center: np.ndarray,
           rng: np.random.Generator, *, sit_yaw: float, stand_pos: np.ndarray, fps: float = 30.0) -> Motion:
    """From ``lying_state`` back to sitting on the edge (``seated_state``): a lie-down played backwards
    with its own timing from ``rng``. Label 'get_up'."""
    return _reverse(lie_down(offsets, lie_center, lie_yaw, seat_center, rng, sit_yaw=sit_yaw,
                             stand_pos=stand_pos, fps=fps), "get_up")
