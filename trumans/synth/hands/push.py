"""Pushing and pulling furniture along the floor (chairs, stools, tables): stand (hands go to the
object), walk with it (``locomotion.walk``, forwards for push, backwards for pull), stand (hands let
go). Conventions (palm point, hand frame, grasp flags on the wrist joint) are those of ``hands.core``.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.skeleton import forward_kinematics
from trumans.rotations import unit
from .. import locomotion
from ..legs import standing_state
from ..motion import Motion, concat_motions
from .core import (
    PALM_GAP, WRIST, actor_scale, apply_h, base_arrays, check_pose, finish_motion, hand_frame, palm_points,
    reach_hold_retract, wrist_targets,
)
from .lean import choose_lean, lean_between
from .timing import HAND_SPEED

__all__ = ["push_handles", "push_stance", "push", "pull"]

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
    palm = np.stack([apply_h(poses, h) for h in handles], 1) + PALM_GAP * up[:, None]
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
    pose = check_pose(pose, "pose")
    if not 0.05 <= distance <= 5.0:
        raise ValueError(f"distance must be in [0.05, 5] m, got {distance}")
    handles, face = push_handles(obj)
    pos, yaw = push_stance(offsets, obj, pose)
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    rot0, root0 = standing_state(offsets, pos, yaw)
    P0, _ = forward_kinematics(rot0[None], root0[None], offsets)
    dist = np.linalg.norm(apply_h(pose, handles) - palm_points(P0)[0], axis=-1).max() + 0.05
    t_move = 0.25 + dist / HAND_SPEED
    n1 = int(max(rng.uniform(0.8, 1.1), t_move) * fps)
    n3 = int(max(rng.uniform(0.7, 1.0), t_move) * fps)
    m1 = locomotion.stand(offsets, pos, yaw, n1, rng, fps=fps)
    m2 = locomotion.walk(np.stack([pos, pos + distance * fwd]), offsets, rng, speed=float(rng.uniform(0.45, 0.7)),
                         fps=fps, start_yaw=yaw, end_yaw=yaw)
    m3 = locomotion.stand(offsets, pos + distance * fwd, yaw, n3, rng, fps=fps)
    base = concat_motions([m1, m2, m3])
    T = base.num_frames
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
    rot, root, off = base_arrays(base)
    wr = np.concatenate([wrist_targets(palm[g0, k], R[g0, k], off, s)[None] for k, s in enumerate(("left", "right"))])
    # Slack for the gait (the object follows the smoothed pelvis; the body sways and bobs).
    slack = 0.04 * np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]])
    leans = [choose_lean(rot[g0], root[g0], off, s, wr[k] + slack, False) for k, s in enumerate(("left", "right"))]
    pitch, drop = max(lp[0] for lp in leans), max(lp[1] for lp in leans)
    rot, root = lean_between(rot, root, off, pitch, drop, False, g0, g1)
    P, _ = forward_kinematics(rot, root, off)
    up = pose[:3, 2]
    grasp = {}
    for k, side in enumerate(("left", "right")):
        rot, grasp[WRIST[side]] = reach_hold_retract(rot, root, off, side, palm_points(P)[:, k], palm[:, k], R[:, k],
                                                     g0, g1, (palm[g0, k], up), (palm[-1, k], up), 2.0,
                                                     f"{label} {obj.name} ({side} hand)")
    return finish_motion(base, rot, root, [ActionInterval("reach", 0, g0 + 1), ActionInterval(label, g0, T)],
                         {obj.name: poses}, grasp)


def push_stance(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """Pelvis xy (2,) and heading (rad) for pushing ``obj`` at world ``pose`` (4, 4): facing the
    push direction, the pelvis 0.36 m (x actor scale) behind the midpoint of the hand points."""
    handles, face = push_handles(obj)
    f = pose[:3, :3] @ face
    yaw = float(np.arctan2(f[1], f[0]))
    mid = apply_h(pose, handles.mean(0))
    d = 0.36 * actor_scale(np.asarray(offsets, dtype=np.float64))
    return mid[:2] - d * np.array([np.cos(yaw), np.sin(yaw)]), yaw


def pull(offsets: np.ndarray, obj: SceneObject, pose: np.ndarray, distance: float, rng: np.random.Generator,
         fps: float = 30.0) -> Motion:
    """Pull ``obj`` towards oneself by ``distance`` m walking backwards: starts in the canonical
    standing state at ``push_stance(offsets, obj, pose)`` and ends at the stance of the moved
    object. It is a push towards the start played backwards (planted feet stay planted). Label
    'pull' on every frame; the object's pose track and grasp flags are reversed with it."""
    pose = check_pose(pose, "pose")
    handles, face = push_handles(obj)
    f = pose[:3, :3] @ face
    back = np.eye(4)
    back[:2, 3] = -distance * unit(np.array([f[0], f[1]]))
    return push(offsets, obj, back @ pose, distance, rng, fps, label="pull").reversed("pull")
