"""Procedural locomotion: walking along a path, turning in place and idle standing.

Every motion starts and ends in the *canonical standing state* of ``standing_state`` (pose 'stand',
pelvis at the actor's rest height, feet at their rest places, legs solved by IK), so primitives
concatenate without jumps. Feet are planted by leg IK: during a (flat-foot) stance the ankle target
is fixed in the world and the foot keeps its world orientation, so planted joints do not slide.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from trumans.actions import ActionInterval
from trumans.rotations import euler_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX
from trumans.ik.limb import limb_reach
from .footsteps import SWING_LAND, Style, foot_tracks, stance_plan
from .gait_plan import Timeline, arc_length, smooth_path, turn_plan, walk_plan
from .legs import foot_places, pelvis_height_limit, solve_legs, stand_height, standing_state, wrap_angle
from .motion import Motion
from .poses import POSES, ease, pose

__all__ = ["walk", "turn", "stand"]

# Pelvis height while walking at >= 1.2 m/s (scaled down with the speed): lowered WALK_CROUCH m below
# the standing height, so no leg reaches full extension (where the IK knee position jerks), and
# bobbing +- PELVIS_BOB m once per step, highest in single support, lowest in double support.
WALK_CROUCH = 0.035
PELVIS_BOB = 0.007


def _arm_phase(tl: Timeline, t: np.ndarray) -> np.ndarray:
    """Arm swing signal (T,) in about [-1, 1] at times t (s): +1 (left arm back, right forward) at
    each left heel strike, -1 at each right one, a C2 cubic spline in between, so the arms never
    pause while the feet are planted (real arm swing is continuous)."""
    strikes = sorted((c - dur / 2 + SWING_LAND * dur, 1.0 if f == 0 else -1.0) for c, f, dur in tl.swings)
    if len(strikes) < 2:
        return np.zeros_like(t)
    tk, vk = (np.array(v) for v in zip(*strikes))
    keep = np.concatenate([[True], np.diff(tk) > 1e-3])
    if keep.sum() < 2:
        return np.zeros_like(t)
    # Clamped (zero slope at the first / last strike), held constant outside: C1 everywhere.
    return CubicSpline(tk[keep], vk[keep], bc_type="clamped")(np.clip(t, tk[keep][0], tk[keep][-1]))


def _bob_phase(tl: Timeline, t: np.ndarray) -> np.ndarray:
    """Pelvis drop signal (T,) in about [-1, 1] at times t (s): -1 (highest) at the middle of each
    swing (single support), +1 (lowest) half way between two swings (double support); a C2 cubic
    spline through those knots, held constant before the first and after the last swing."""
    c = np.array(sorted(c for c, _, _ in tl.swings))
    if len(c) < 2:
        return np.zeros_like(t)
    c = c[np.concatenate([[True], np.diff(c) > 1e-3])]
    if len(c) < 2:
        return np.zeros_like(t)
    tk = np.concatenate([c, 0.5 * (c[1:] + c[:-1])])
    vk = np.concatenate([-np.ones(len(c)), np.ones(len(c) - 1)])
    o = np.argsort(tk)
    return CubicSpline(tk[o], vk[o], bc_type="clamped")(np.clip(t, tk.min(), tk.max()))


def _gait_motion(tl: Timeline, offsets: np.ndarray, rng: np.random.Generator, base_pose: str) -> Motion:
    """Turn a root plan + swings into a full-body Motion (legs by IK to the foot tracks)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    style = Style.draw(rng)
    fps = tl.fps
    xy = np.concatenate(tl.xy)
    yaw = np.concatenate(tl.yaw)
    speed = np.concatenate(tl.speed)
    T = len(xy)
    stances = stance_plan(tl, offsets, style, rng)
    ank, frot, contact = foot_tracks(stances, offsets, T, fps, style)

    # Gait phase signal: +1 when the left foot is ahead of the right one along the heading.
    fwd = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    leg_len = limb_reach(offsets, "left_leg")[1]
    d = np.clip(((ank[:, 0, :2] - ank[:, 1, :2]) * fwd).sum(1) / (0.8 * leg_len), -1, 1)
    vfac = np.clip(speed / 1.2, 0, 1.3)
    # Envelope that is 0 (with zero slope) at both ends so the motion starts/ends canonically.
    t = np.arange(T) / fps
    env = ease(t / 0.4) * ease((t[-1] - t) / 0.4) if T > 2 else np.zeros(T)

    # Lateral pelvis sway towards the stance foot, proportional to which foot is unloaded.
    lat = np.stack([-np.sin(yaw), np.cos(yaw)], axis=1)
    load = contact[:, 0].astype(float) - contact[:, 1].astype(float)
    load = gaussian_filter1d(load, 0.12 * fps) if T > 3 else load
    xy_root = xy + (0.018 * load * env)[:, None] * lat

    twist = -style.twist * d * np.minimum(vfac, 1.0) * env
    lean = style.lean * vfac * env
    R0 = yaw_matrix(yaw + twist) @ euler_to_matrix(np.stack([np.zeros(T), lean * 0.5, 0.03 * load * env], -1), "ZYX")

    rot = np.repeat(pose(base_pose, offsets)[None], T, axis=0)
    rot[:, 0] = R0
    carry_arms = base_pose != "stand"
    E = lambda z, y, x: euler_to_matrix(np.stack([z, y, x], -1), "ZYX")  # noqa: E731
    zero = np.zeros(T)
    # Counter-rotate the trunk against the pelvis and lean it a bit forward.
    rot[:, JOINT_INDEX["spine3"]] = E(-0.8 * twist, lean * 0.5, zero) @ rot[:, JOINT_INDEX["spine3"]]
    rot[:, JOINT_INDEX["head"]] = E(zero, style.head * env, zero) @ rot[:, JOINT_INDEX["head"]]
    if not carry_arms:  # arms swing opposite to the legs, continuously (see _arm_phase)
        a = style.arm_swing * np.minimum(vfac, 1.2) * _arm_phase(tl, t) * env
        rot[:, JOINT_INDEX["left_shoulder"]] = E(zero, a, zero) @ rot[:, JOINT_INDEX["left_shoulder"]]
        rot[:, JOINT_INDEX["right_shoulder"]] = E(zero, -a, zero) @ rot[:, JOINT_INDEX["right_shoulder"]]
        eb = style.elbow * np.minimum(vfac, 1.0) * env
        le, re = JOINT_INDEX["left_elbow"], JOINT_INDEX["right_elbow"]
        a_abs = np.sqrt(a**2 + 0.05**2) - 0.05  # smooth |a|: no kink (jerk) where the swing changes sign
        rot[:, le] = E(-eb - 0.15 * (a_abs - a), zero, zero) @ rot[:, le]
        rot[:, re] = E(eb + 0.15 * (a_abs + a), zero, zero) @ rot[:, re]

    # Pelvis height: crouched a little and bobbing with the steps (see WALK_CROUCH), lowered further
    # where an ankle target would be out of reach.
    h_lim = pelvis_height_limit(rot, xy_root, offsets, ank)
    h_rest = stand_height(offsets)
    h_nom = h_rest - (WALK_CROUCH + PELVIS_BOB * _bob_phase(tl, t)) * np.minimum(vfac, 1.0) * env
    deficit = np.maximum(h_nom - (h_lim - 0.002), 0.0)
    if T > 3:  # spread the dips smoothly (a max-filter first so the smoothed dip covers the raw one)
        w = max(int(0.08 * fps), 1)
        deficit = gaussian_filter1d(maximum_filter1d(deficit, 2 * w + 1), 0.06 * fps, mode="constant")
    h = np.minimum(h_nom - deficit, h_lim - 0.001)
    root = np.column_stack([xy_root, h])

    knee_dir = np.stack([np.cos(yaw), np.sin(yaw), np.zeros(T)], axis=1)
    rot, _ = solve_legs(rot, root, offsets, ank, foot_rot=frot, pole_dir=knee_dir)
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact, actions=list(tl.labels))


def _check_common(offsets: np.ndarray, fps: float) -> np.ndarray:
    offsets = np.asarray(offsets, dtype=np.float64)
    if offsets.shape != (24, 3):
        raise ValueError(f"offsets must be (24, 3) (trumans.skeleton.rest_offsets(scale)), got {offsets.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return offsets


def _check_pose(base_pose: str) -> None:
    if base_pose not in POSES:
        raise ValueError(f"unknown base_pose {base_pose!r}; choose one of {sorted(POSES)}")


def walk(
    path: np.ndarray,
    offsets: np.ndarray,
    rng: np.random.Generator,
    speed: float = 1.2,
    fps: float = 30.0,
    start_yaw: float | None = None,
    end_yaw: float | None = None,
    base_pose: str = "stand",
    turn_threshold: float = np.radians(35),
    step_length: float | None = None,
) -> Motion:
    """Walk along world xy waypoints ``path`` (K, 2) m at cruise ``speed`` m/s, starting and stopping
    at rest in the canonical standing state (pelvis xy on the first/last waypoint).

    Heading follows the path tangent; if ``start_yaw``/``end_yaw`` (rad) differ from it by more
    than ``turn_threshold`` the walk begins/ends with a stepping turn in place (label 'turn'),
    smaller differences are blended into the walk. Labels: 'turn', 'walk'. ``foot_contact`` marks
    flat-foot stance frames, during which the ankle and foot joints are fixed in the world.
    ``base_pose`` names the upper-body pose (arms swing only for 'stand'). ``step_length`` (m):
    the cruise step length (default: from the leg length and the speed), e.g. short steps when
    handling something.
    """
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 2:
        raise ValueError(f"path must be (K >= 2, 2) world xy waypoints, got {path.shape}")
    if not 0.2 <= speed <= 2.5:
        raise ValueError(f"speed must be a walking speed in [0.2, 2.5] m/s, got {speed}")
    pts = smooth_path(path)
    if arc_length(pts)[-1] < 0.05:
        raise ValueError("path is shorter than 5 cm; use turn() or stand() instead")
    tang0, tang1 = pts[min(3, len(pts) - 1)] - pts[0], pts[-1] - pts[max(len(pts) - 4, 0)]
    y_path0, y_path1 = float(np.arctan2(tang0[1], tang0[0])), float(np.arctan2(tang1[1], tang1[0]))
    y0 = y_path0 if start_yaw is None else float(start_yaw)
    y1 = y_path1 if end_yaw is None else float(end_yaw)
    leg = limb_reach(offsets, "left_leg")[1]
    step_len = leg * min(0.50 + 0.25 * speed, 0.74) * rng.uniform(0.95, 1.05)  # longer steps, slower cadence
    if step_length is not None:
        if not 0.1 <= step_length <= 1.2:
            raise ValueError(f"step_length must be in [0.1, 1.2] m, got {step_length}")
        step_len = float(step_length)

    tl = Timeline(fps)
    if abs(wrap_angle(y_path0 - y0)) > turn_threshold:
        tl.add(*turn_plan(pts[0], y0, y_path0, fps, None), label="turn")
        y0 = y_path0
    ff = tl.next_foot()
    xy, yaw, vel, swings = walk_plan(pts, speed, step_len, fps, y0,
                                     y_path1 if abs(wrap_angle(y_path1 - y1)) > turn_threshold else y1,
                                     int(rng.integers(2)) if ff is None else ff)
    if tl.T:  # the turn's last frame is the walk's first state: drop the duplicate
        xy, yaw, vel = xy[1:], yaw[1:], vel[1:]
        swings = [(c - 1 / fps, f, d) for c, f, d in swings]
    tl.add(xy, yaw, vel, swings, label="walk")
    if abs(wrap_angle(y_path1 - y1)) > turn_threshold:
        txy, tyaw, tv, tsw = turn_plan(pts[-1], float(yaw[-1]), y1, fps, tl.next_foot())
        tl.add(txy[1:], tyaw[1:], tv[1:], [(c - 1 / fps, f, d) for c, f, d in tsw], label="turn")
    return _gait_motion(tl, offsets, rng, base_pose)


def turn(offsets: np.ndarray, pos: np.ndarray, yaw0: float, yaw1: float, rng: np.random.Generator,
         fps: float = 30.0, base_pose: str = "stand") -> Motion:
    """Stepping turn in place at pelvis xy ``pos`` (2,) from heading ``yaw0`` to ``yaw1`` (rad); label 'turn'."""
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    tl = Timeline(fps)
    tl.add(*turn_plan(np.asarray(pos, dtype=np.float64), float(yaw0), float(yaw1), fps, None), label="turn")
    return _gait_motion(tl, offsets, rng, base_pose)


def stand(offsets: np.ndarray, pos: np.ndarray, yaw: float, frames: int, rng: np.random.Generator,
          fps: float = 30.0, base_pose: str = "stand") -> Motion:
    """Idle standing for ``frames`` frames at pelvis xy ``pos`` (2,), heading ``yaw`` (rad): breathing,
    a slight sway, feet planted (contact on every frame); starts and ends in the canonical standing
    state. Label 'stand'."""
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    rot0, root0 = standing_state(offsets, np.asarray(pos, dtype=np.float64), float(yaw), base_pose)
    T = int(frames)
    t = np.arange(T) / fps
    env = ease(t / 0.6) * ease((t[-1] - t) / 0.6) if T > 2 else np.zeros(T)
    f_b = rng.uniform(0.2, 0.3)  # breathing, Hz
    ph = rng.uniform(0, 2 * np.pi, 4)
    breath = np.sin(2 * np.pi * f_b * t + ph[0]) * env
    sway = np.stack([np.sin(2 * np.pi * 0.11 * t + ph[1]), np.sin(2 * np.pi * 0.07 * t + ph[2])], 1)
    sway = sway * rng.uniform(0.004, 0.01) * env[:, None]
    rot = np.repeat(rot0[None], T, axis=0)
    E = lambda z, y, x: euler_to_matrix(np.stack([z, y, x], -1), "ZYX")  # noqa: E731
    zero = np.zeros(T)
    rot[:, JOINT_INDEX["spine2"]] = E(zero, -0.015 * breath, zero) @ rot[:, JOINT_INDEX["spine2"]]
    rot[:, JOINT_INDEX["spine3"]] = E(zero, -0.015 * breath, zero) @ rot[:, JOINT_INDEX["spine3"]]
    rot[:, JOINT_INDEX["head"]] = E(0.05 * np.sin(2 * np.pi * 0.05 * t + ph[3]) * env, 0.01 * breath, zero) \
        @ rot[:, JOINT_INDEX["head"]]
    for side, sgn in (("left", -1.0), ("right", 1.0)):
        j = JOINT_INDEX[f"{side}_shoulder"]
        rot[:, j] = E(zero, zero, sgn * 0.02 * breath) @ rot[:, j]
    root = np.repeat(root0[None], T, axis=0)
    root[:, :2] += (yaw_matrix(yaw)[:2, :2] @ sway.T).T
    root[:, 2] -= 0.01 * env  # soften the knees a little while swaying
    feet = np.repeat(foot_places(offsets, pos, yaw)[None], T, axis=0)
    frot = np.broadcast_to(yaw_matrix(yaw), (T, 2, 3, 3))
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=frot)
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=np.ones((T, 2), dtype=bool),
                  actions=[ActionInterval("stand", 0, T)])
