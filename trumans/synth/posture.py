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

Lying comes in two leg postures: straight (pose 'lie') and, where the surface is too short for
the actor (a sofa between its arms), knees up with the feet flat on the surface ``leg_reach`` m
from the pelvis along the body axis. ``fit_lying`` chooses the posture and where along the
surface the pelvis goes; ``lying_extent`` gives the body's extent along the axis.
"""
from __future__ import annotations

import numpy as np

from trumans.actions import ActionInterval
from trumans.contacts.rule import JOINT_RADIUS
from trumans.rotations import euler_to_matrix, yaw_matrix
from trumans.rotations import unit
from trumans.skeleton import ANKLES, FEET, HIPS, JOINT_INDEX, KNEES, NUM_JOINTS, forward_kinematics
from trumans.ik.limb import limb_reach
from .legs import foot_places, pelvis_height_limit, rest_ankle_rel, solve_legs, standing_state
from .motion import Motion
from .poses import POSES, ease, pose, slerp_poses, slerp_rot

__all__ = [
    "seat_clearance",
    "draw_stagger",
    "seated_feet",
    "seated_state",
    "lying_state",
    "lying_extent",
    "fit_lying",
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


Stagger = tuple[float, float]  # fore-aft offset (m, + forward) of the left / right ankle while seated


def draw_stagger(rng: np.random.Generator) -> Stagger:
    """A sitting's foot stagger: one foot (either) drawn back or pushed forward by 2.5-8 cm, the
    other where it stood (people do not sit mirror-symmetric; real: 2-10 cm)."""
    side = int(rng.integers(2))
    out = [0.0, 0.0]
    out[side] = float(rng.uniform(0.025, 0.08) * rng.choice([-1.0, 1.0]))
    return out[0], out[1]


def _check_stagger(stagger: Stagger) -> np.ndarray:
    st = np.asarray(stagger, dtype=np.float64)
    if st.shape != (2,) or not np.isfinite(st).all() or np.abs(st).max() > 0.2:
        raise ValueError(f"stagger must be the (left, right) fore-aft ankle offsets in m, each within "
                         f"+-0.2 m, got {stagger!r}")
    return st


def seated_feet(offsets: np.ndarray, stand_pos: np.ndarray, sit_yaw: float,
                stagger: Stagger = (0.0, 0.0)) -> np.ndarray:
    """(2, 3) world ankle places of the seated feet: where they stood in ``standing_state(offsets,
    stand_pos, sit_yaw)``, each moved ``stagger`` m along the sitting direction."""
    fwd = np.array([np.cos(sit_yaw), np.sin(sit_yaw), 0.0])
    return foot_places(offsets, stand_pos, sit_yaw) + _check_stagger(stagger)[:, None] * fwd


def seated_state(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
                 base_pose: str = "sit", stagger: Stagger = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Seated state: (rot (24, 3, 3), root (3,)). Pelvis above ``seat_center`` (3,) by
    ``seat_clearance``, facing ``sit_yaw`` (rad), upper body ``base_pose``, feet planted at
    ``seated_feet(offsets, stand_pos, sit_yaw, stagger)``. Raises ValueError when the feet
    cannot reach the floor from this seat."""
    offsets = _offsets(offsets)
    seat_center = _vec3(seat_center, "seat_center")
    stand_pos = _vec2(stand_pos, "stand_pos")
    if base_pose not in POSES:
        raise ValueError(f"unknown base_pose {base_pose!r}; choose one of {sorted(POSES)}")
    rot = pose(base_pose, offsets)[None].copy()
    rot[0, 0] = yaw_matrix(sit_yaw)
    root = (seat_center + np.array([0.0, 0.0, seat_clearance(offsets)]))[None]
    feet = seated_feet(offsets, stand_pos, sit_yaw, stagger)[None]
    rot, reached = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(sit_yaw), (1, 2, 3, 3)))
    if not reached.all():
        raise ValueError(f"feet at stand_pos {stand_pos.tolist()} cannot reach the floor from the seat at "
                         f"{seat_center.tolist()}: choose a stand_pos closer to the seat or a lower seat")
    return rot[0], root[0]


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


def _breathing(rot0: np.ndarray, frames: int, rng: np.random.Generator, fps: float, amp: float) -> np.ndarray:
    """(frames, 24, 3, 3): the resting state rot0 (24, 3, 3) breathing (spine pitch of amplitude ``amp``
    rad) with slow head turns, eased in and out (starts and ends exactly at rot0)."""
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    T = int(frames)
    rot = np.repeat(rot0[None], T, axis=0)
    env = _envelope(T, fps)
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


def _transfer(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
              rng: np.random.Generator, fps: float, arm_swing: float, up: bool, stagger: Stagger) -> Motion:
    """Sit-down (``up`` False: standing -> seated) or stand-up (True: seated -> standing), each with
    its own timing: the sit-down hinges at the hips while the pelvis goes back and down (peak lean
    mid-descent); the stand-up first leans the trunk forward over the feet, then rises. Lean
    U(50, 64) deg (root and lower spine pitch at the peak, 70 % at the hip, 30 % in the lower spine).
    A staggered foot (``stagger``) steps to its seated place early in the sit-down (weight still on
    the feet, pelvis high) and back late in the stand-up, lifted 2 cm; planted otherwise."""
    offsets = _offsets(offsets)
    stand = standing_state(offsets, _vec2(stand_pos, "stand_pos"), sit_yaw)
    seated = seated_state(offsets, seat_center, sit_yaw, stand_pos, stagger=stagger)
    (rot0, root0), (rot1, root1) = (seated, stand) if up else (stand, seated)
    T = int(round((rng.uniform(1.7, 2.5) if up else rng.uniform(1.5, 2.1)) * fps)) + 1
    s = np.linspace(0.0, 1.0, T)
    if up:  # lean forward first (pelvis still on the seat), then rise as the trunk straightens
        peak = rng.uniform(0.3, 0.4)
        w_pose, w_xy, w_z = ease((s - 0.15) / 0.85), ease((s - 0.1) / 0.7), ease((s - peak + 0.05) / (1.05 - peak))
        bump = np.where(s < peak, ease(s / peak), 1.0 - ease((s - peak) / (1.0 - peak)))
    else:  # hips back and down while the trunk hinges forward
        w_pose, w_xy, w_z = ease(s), ease(s / 0.85), ease((s - 0.08) / 0.92)
        bump = np.sin(np.pi * s) ** 1.5
    root = np.empty((T, 3))
    root[:, :2] = root0[:2] + w_xy[:, None] * (root1[:2] - root0[:2])
    root[:, 2] = root0[2] + w_z * (root1[2] - root0[2])
    rot = slerp_poses(rot0, rot1, w_pose)
    lean = np.radians(rng.uniform(50, 64)) * bump
    z = np.zeros(T)
    rot[:, 0] = yaw_matrix(sit_yaw) @ euler_to_matrix(np.stack([z, 0.7 * lean, z], -1), "ZYX")
    j = JOINT_INDEX["spine1"]
    rot[:, j] = euler_to_matrix(np.stack([z, 0.3 * lean, z], -1), "ZYX") @ rot[:, j]
    # Arms: brought forward with the trunk so the hands stay near the thighs (``arm_swing`` 1), a
    # little further on some takes; 0 leaves them hanging from the leaning trunk (towards the seat).
    arms = arm_swing * rng.uniform(0.2, 0.6)
    for side in ("left", "right"):
        j = JOINT_INDEX[f"{side}_shoulder"]
        rot[:, j] = euler_to_matrix(np.stack([z, -arms * lean, z], -1), "ZYX") @ rot[:, j]
    a, b = (0.6, 0.95) if up else (0.05, 0.4)  # the staggered foot's step (fractions of the transfer)
    u = np.clip((s - a) / (b - a), 0.0, 1.0)
    w = (1.0 - ease(u) if up else ease(u))[:, None, None]  # 0: standing places, 1: seated ones
    feet = (1.0 - w) * foot_places(offsets, stand_pos, sit_yaw) + w * seated_feet(offsets, stand_pos, sit_yaw, stagger)
    moved = np.abs(_check_stagger(stagger)) > 0
    feet[:, moved, 2] += (0.02 * np.sin(np.pi * u))[:, None]
    h_lim = pelvis_height_limit(rot, root[:, :2], offsets, feet)
    root[:, 2] = np.minimum(root[:, 2], h_lim - 0.001)
    frot = np.broadcast_to(yaw_matrix(sit_yaw), (T, 2, 3, 3))
    knee = np.broadcast_to(np.array([np.cos(sit_yaw), np.sin(sit_yaw), 0.0]), (T, 3))
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=frot, pole_dir=knee)
    rot[0], root[0] = rot0, root0
    rot[-1], root[-1] = rot1, root1
    contact = np.ones((T, 2), dtype=bool)
    contact[:, moved] = ((u <= 0.0) | (u >= 1.0))[:, None]
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact,
                  actions=[ActionInterval("stand_up" if up else "sit_down", 0, T)])


def sit_down(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
             rng: np.random.Generator, fps: float = 30.0, arm_swing: float = 1.0,
             stagger: Stagger = (0.0, 0.0)) -> Motion:
    """Sit down from ``standing_state(offsets, stand_pos, sit_yaw)`` (standing in front of the seat,
    facing away from it) to ``seated_state(offsets, seat_center, sit_yaw, stand_pos, stagger=stagger)``:
    hips go back and down with a forward hip-hinge lean, the arms come forward with the trunk
    (``arm_swing`` scales that, e.g. 0 at a desk), feet planted (leg IK) but for the staggered foot's
    short step early on. Label 'sit_down'; about 1.5-2.1 s."""
    return _transfer(offsets, seat_center, sit_yaw, stand_pos, rng, fps, arm_swing, up=False, stagger=stagger)


def _random_holds(T: int, fps: float, rng: np.random.Generator, scale: np.ndarray,
                  hold: tuple[float, float] = (1.0, 3.0), move: float = 0.8) -> np.ndarray:
    """(T, d) smooth idle shifts: held random levels (uniform in +-``scale`` (d,)) changed by eased
    moves of ``move`` s every ``hold`` s; exactly 0 at the first and last frame (eased in and out)."""
    scale = np.asarray(scale, dtype=np.float64)
    t = np.arange(T) / fps
    starts = np.cumsum(rng.uniform(*hold, size=int(t[-1] / hold[0]) + 2)) - 0.5 * hold[0]  # move start times (s)
    levels = rng.uniform(-1.0, 1.0, (len(starts) + 1, scale.size)) * scale
    levels[0] = 0.0
    k = np.searchsorted(starts, t, side="right")  # moves begun by t
    km = np.maximum(k - 1, 0)
    w = ease((t - starts[km]) / move)[:, None]
    out = np.where(k[:, None] > 0, levels[km] + w * (levels[k] - levels[km]), 0.0)
    return out * _envelope(T, fps, ramp=min(1.0, 0.25 * t[-1]))[:, None]


def sit(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray, frames: int,
        rng: np.random.Generator, fps: float = 30.0, shift: float = 1.0, stagger: Stagger = (0.0, 0.0)) -> Motion:
    """Seated idle for ``frames`` frames, starting and ending exactly in ``seated_state(offsets,
    seat_center, sit_yaw, stand_pos, stagger=stagger)``: breathing and head turns, the pelvis shifting
    on the seat (up to ``shift`` x (6 cm towards the front edge, 2 cm sideways)) with the trunk
    slouching and leaning; both feet stay planted where the sit-down put them (``stagger``: one
    foot drawn back or pushed forward, see ``draw_stagger``). Label 'sit'."""
    offsets = _offsets(offsets)
    rot0, root0 = seated_state(offsets, seat_center, sit_yaw, stand_pos, stagger=stagger)
    rot = _breathing(rot0, frames, rng, fps, 0.015)
    T = len(rot)
    fwd = np.array([np.cos(sit_yaw), np.sin(sit_yaw), 0.0])
    left = np.array([-np.sin(sit_yaw), np.cos(sit_yaw), 0.0])
    # Pelvis shifts on the seat (fore-aft biased forward: the backrest is behind), with the trunk
    # slouching back as the pelvis slides forward and leaning sideways a little.
    sh = _random_holds(T, fps, rng, np.array([0.06, 0.02, 0.06, 0.05]))
    sh[:, 0] = np.abs(sh[:, 0]) * rng.uniform(0.6, 1.4)  # forward slide (m)
    sh[:, :2] *= shift
    root = root0 + sh[:, :1] * fwd + sh[:, 1:2] * left
    z = np.zeros(T)
    # rad, spine pitch (+ forward): a per-take forward lean (elbows towards the knees), less as the
    # pelvis slides forward and the back slouches
    slouch = rng.uniform(0.1, 0.35) * _envelope(T, fps, ramp=min(1.0, 0.25 * (T - 1) / fps)) - 3.0 * sh[:, 0] + sh[:, 2]
    for name, part in (("spine1", 0.5), ("spine2", 0.3), ("spine3", 0.2)):
        j = JOINT_INDEX[name]
        rot[:, j] = euler_to_matrix(np.stack([z, part * slouch, part * sh[:, 3]], -1), "ZYX") @ rot[:, j]
    j = JOINT_INDEX["neck"]  # the head stays roughly level
    rot[:, j] = euler_to_matrix(np.stack([z, -0.5 * slouch, -0.5 * sh[:, 3]], -1), "ZYX") @ rot[:, j]
    feet = np.repeat(seated_feet(offsets, stand_pos, sit_yaw, stagger)[None], T, axis=0)
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(sit_yaw), (T, 2, 3, 3)),
                        pole_dir=np.broadcast_to(fwd, (T, 3)))
    contact = np.ones((T, 2), dtype=bool)
    rot[0], root[0], rot[-1], root[-1] = rot0, root0, rot0, root0
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact,
                  actions=[ActionInterval("sit", 0, T)])


def stand_up(offsets: np.ndarray, seat_center: np.ndarray, sit_yaw: float, stand_pos: np.ndarray,
             rng: np.random.Generator, fps: float = 30.0, arm_swing: float = 1.0,
             stagger: Stagger = (0.0, 0.0)) -> Motion:
    """Stand up from ``seated_state(..., stagger=stagger)`` to ``standing_state(offsets, stand_pos,
    sit_yaw)`` with its own timing (not a sit-down reversed): the trunk leans forward over the feet
    first, then the pelvis rises while the trunk straightens; feet planted but for the staggered
    foot's step back beside the other late in the rise. Label 'stand_up'; about 1.7-2.5 s."""
    return _transfer(offsets, seat_center, sit_yaw, stand_pos, rng, fps, arm_swing, up=True, stagger=stagger)


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
