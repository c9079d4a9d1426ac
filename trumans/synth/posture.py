"""Sitting: sitting down / seated idle / standing up (lying down and getting up: ``lying``).

Exact shared states make the primitives concatenate without jumps:
``walk(..., end=stand_pos, end_yaw=sit_yaw)`` ends in ``standing_state(offsets, stand_pos, sit_yaw)``
= the first frame of ``sit_down``; ``sit_down`` ends in ``seated_state(...)`` = first/last frame of
``sit`` = first frame of ``stand_up`` (whose last frame is the standing state again) and of
``lying.lie_down``. One foot may stay staggered (``stagger``, ``draw_stagger``) over the whole
sitting: it steps to its place in the sit-down and back in the stand-up.

Heights: the pelvis joint sits inside the body, ``seat_clearance(offsets)`` (~0.095 m for an average
actor, scaled by leg length) above the surface it rests on, so the buttocks/back skin touches the
seat or bed instead of sinking into it. ``seat_center`` is a world point ON the surface (z =
surface height).
"""
from __future__ import annotations

import numpy as np

from trumans.actions import ActionInterval
from trumans.body import leg_scale as _leg_scale, seat_clearance
from trumans.rotations import euler_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX
from .legs import foot_places, pelvis_height_limit, solve_legs, standing_state
from .motion import Motion
from .poses import POSES, ease, pose, slerp_poses

__all__ = [
    "Stagger",
    "seat_clearance",
    "draw_stagger",
    "seated_feet",
    "seated_state",
    "sit_down",
    "sit",
    "stand_up",
]

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
    """A sitting's foot stagger: one foot (either) drawn back or pushed forward by 2-6.5 cm, the
    other where it stood (people do not sit mirror-symmetric; real: 2-10 cm)."""
    side = int(rng.integers(2))
    out = [0.0, 0.0]
    out[side] = float(rng.uniform(0.02, 0.065) * rng.choice([-1.0, 1.0]))
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
    # Sit-down 2.2-3.0 s: other labs' sitters lower their hips 10 -> 90 % in 0.87-2.10 s and move them back
    # at 0.19-0.40 m/s at most (issue 35); 1.5-2.1 s gave 0.73-0.93 s and 0.43-0.56 m/s.
    T = int(round((rng.uniform(1.7, 2.5) if up else rng.uniform(2.2, 3.0)) * fps)) + 1
    s = np.linspace(0.0, 1.0, T)
    if up:  # lean forward first (pelvis still on the seat), then rise as the trunk straightens
        peak = rng.uniform(0.3, 0.4)
        w_pose, w_xy, w_z = ease((s - 0.15) / 0.85), ease((s - 0.1) / 0.7), ease((s - peak + 0.05) / (1.05 - peak))
        bump = np.where(s < peak, ease(s / peak), 1.0 - ease((s - peak) / (1.0 - peak)))
    else:  # hips back and down while the trunk hinges forward
        w_pose, w_xy, w_z = ease(s), ease(s), ease((s - 0.08) / 0.92)  # hips back over the whole descent
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
    # Each arm its own share (people are not mirror-symmetric: real wrist heights differ ~1.5 cm),
    # drawn from a child stream (``Generator.spawn`` leaves ``rng``'s own position alone), so every
    # later draw of the take is what it was before the arms were told apart.
    arms = arm_swing * rng.uniform(0.2, 0.6) * rng.spawn(1)[0].uniform(0.75, 1.25, 2)
    for side, a_side in zip(("left", "right"), arms):
        j = JOINT_INDEX[f"{side}_shoulder"]
        rot[:, j] = euler_to_matrix(np.stack([z, -a_side * lean, z], -1), "ZYX") @ rot[:, j]
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
    short step early on. Label 'sit_down'; about 2.2-3.0 s."""
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
