"""Keyframe poses as per-joint local rotations, and eased per-joint slerp between them.

Pose convention: a pose is ``(24, 3, 3)`` local rotations with the root entry identity (the caller
sets the root's yaw/pitch). Joint angles are given in degrees as intrinsic ``ZYX`` Euler angles
``(z, y, x)`` = ``Rz(z) @ Ry(y) @ Rx(x)``: a vector is first rolled about x, then pitched about y,
then yawed about z (axes of the parent frame; the rest pose faces +x, left = +y, z up).
Useful signs: hip flexion (thigh forward) is y < 0, knee flexion y > 0, spine forward lean y > 0;
the left arm hangs down at x = -90 (right arm x = +90) and a hanging arm swings forward with y < 0;
left elbow flexion is z < 0 (right elbow z > 0).
"""
from __future__ import annotations

import numpy as np

from trumans.rotations import euler_to_matrix, matrix_to_quat, quat_to_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS
from .motion import Motion

__all__ = [
    "POSES",
    "pose",
    "pose_from_angles",
    "ease",
    "slerp_rot",
    "slerp_poses",
    "keyframe_track",
    "blend_into",
]

_ARMS_DOWN = {
    "left_collar": (0, 0, -5), "right_collar": (0, 0, 5),
    "left_shoulder": (0, -2, -82), "right_shoulder": (0, -2, 82),
    "left_elbow": (-14, 0, 0), "right_elbow": (14, 0, 0),
}
_SIT_LEGS = {
    "left_hip": (3, -90, 0), "right_hip": (-3, -90, 0),
    "left_knee": (0, 90, 0), "right_knee": (0, 90, 0),
}

# name -> {joint: (z, y, x) degrees}. Legs are usually overridden by leg IK to planted feet.
POSES: dict[str, dict[str, tuple[float, float, float]]] = {
    "stand": {**_ARMS_DOWN, "spine1": (0, 1, 0), "neck": (0, -2, 0)},
    "sit": {
        **_SIT_LEGS, "spine1": (0, 6, 0), "spine2": (0, 3, 0), "neck": (0, -4, 0),
        "left_collar": (0, 0, -5), "right_collar": (0, 0, 5),
        "left_shoulder": (-8, -28, -78), "right_shoulder": (8, -28, 78),
        "left_elbow": (-55, 0, 0), "right_elbow": (55, 0, 0),
    },
    "lie": {
        "left_collar": (0, 0, -5), "right_collar": (0, 0, 5),
        "left_shoulder": (0, 0, -75), "right_shoulder": (0, 0, 75),
        "left_elbow": (-10, 0, 0), "right_elbow": (10, 0, 0),
        "neck": (0, 12, 0), "left_hip": (-3, -11, 4), "right_hip": (3, -11, -4),
        "left_knee": (0, 10, 0), "right_knee": (0, 10, 0), "left_ankle": (0, 5, 0), "right_ankle": (0, 5, 0),
    },
    "reach": {
        **_ARMS_DOWN, "spine1": (0, 8, 0), "spine2": (0, 4, 0),
        "right_collar": (0, -5, 5), "right_shoulder": (10, -80, 88), "right_elbow": (12, 0, 0),
    },
    "drink": {
        **_ARMS_DOWN, "neck": (0, -8, 0), "head": (0, -8, 0),
        "right_shoulder": (-15, -38, 70), "right_elbow": (135, 0, 0), "right_wrist": (0, 0, -30),
    },
    "phone": {
        **_ARMS_DOWN, "head": (0, 0, 6),
        "right_shoulder": (-35, -25, 45), "right_elbow": (150, 0, 0), "right_wrist": (0, 0, -60),
    },
    "type": {
        **_SIT_LEGS, "spine1": (0, 10, 0), "spine2": (0, 4, 0), "neck": (0, 8, 0),
        "left_collar": (0, 0, -5), "right_collar": (0, 0, 5),
        "left_shoulder": (-12, -30, -80), "right_shoulder": (12, -30, 80),
        "left_elbow": (-70, 0, 0), "right_elbow": (70, 0, 0),
        "left_wrist": (0, 0, 75), "right_wrist": (0, 0, -75),
    },
}


def pose_from_angles(angles: dict[str, tuple[float, float, float]]) -> np.ndarray:
    """{joint name: (z, y, x) degrees, intrinsic ZYX} -> (24, 3, 3) local rotations (others identity)."""
    rot = np.tile(np.eye(3), (NUM_JOINTS, 1, 1))
    for name, zyx in angles.items():
        if name not in JOINT_INDEX:
            raise ValueError(f"unknown joint {name!r}; joints are {list(JOINT_INDEX)}")
        rot[JOINT_INDEX[name]] = euler_to_matrix(np.radians(np.asarray(zyx, dtype=np.float64)), "ZYX")
    return rot


# Hand-target poses are refined by arm IK for the actor: (limb, effector, target relative to the
# head joint in the body frame (m, for a 1.0-scale actor), elbow pole relative to the shoulder).
_HAND_TARGETS: dict[str, tuple[str, str, tuple[float, float, float], tuple[float, float, float]]] = {
    "drink": ("right_arm", "tip", (0.12, -0.02, -0.07), (0.2, -0.6, -1.0)),
    "phone": ("right_arm", "end", (0.03, -0.10, -0.10), (0.1, -1.0, -0.6)),
}


def pose(name: str, offsets: np.ndarray | None = None) -> np.ndarray:
    """Named keyframe pose -> (24, 3, 3) float64 local rotations (root identity).

    Poses that put a hand at the face ('drink': index finger at the mouth, 'phone': wrist at the
    ear) are refined by arm IK for the actor's ``offsets`` (24, 3) (default: the average actor)."""
    if name not in POSES:
        raise ValueError(f"unknown pose {name!r}; choose one of {sorted(POSES)}")
    rot = pose_from_angles(POSES[name])
    if name in _HAND_TARGETS:
        from trumans.skeleton import forward_kinematics, rest_offsets
        from trumans.ik.limb import LIMBS, solve_limb

        off = rest_offsets() if offsets is None else np.asarray(offsets, dtype=np.float64)
        limb, eff, rel, pole = _HAND_TARGETS[name]
        root = off[0][None]
        P, _ = forward_kinematics(rot[None], root, off)
        s = np.linalg.norm(off[JOINT_INDEX["head"]]) / np.linalg.norm(rest_offsets()[JOINT_INDEX["head"]])
        target = P[:, JOINT_INDEX["head"]] + s * np.asarray(rel)
        pole_w = P[:, LIMBS[limb][0]] + np.asarray(pole)
        rot = solve_limb(rot[None], root, off, limb, target, pole=pole_w, effector=eff)[0][0]
    return rot


def ease(t: np.ndarray) -> np.ndarray:
    """Quintic smootherstep on [0, 1] (zero velocity and acceleration at both ends); input clipped."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    return t * t * t * (t * (6.0 * t - 15.0) + 10.0)


def slerp_rot(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Spherical interpolation of rotations a, b (..., 3, 3) with weights w broadcastable to (...)
    (0 -> a, 1 -> b); shortest path, vectorised via quaternions."""
    a, b, w = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), np.asarray(w, dtype=np.float64)
    if a.shape[-2:] != (3, 3) or b.shape[-2:] != (3, 3):
        raise ValueError(f"a and b must be (..., 3, 3) rotations, got {a.shape} and {b.shape}")
    lead = np.broadcast_shapes(a.shape[:-2], b.shape[:-2], w.shape)
    qa = matrix_to_quat(np.broadcast_to(a, lead + (3, 3)))
    qb = matrix_to_quat(np.broadcast_to(b, lead + (3, 3)))
    w = np.broadcast_to(w, lead)[..., None]
    dot = (qa * qb).sum(-1, keepdims=True)
    qb = np.where(dot < 0, -qb, qb)
    dot = np.abs(dot).clip(max=1.0)
    omega = np.arccos(dot)
    so = np.sin(omega)
    small = so < 1e-6
    so_safe = np.where(small, 1.0, so)
    wa = np.where(small, 1.0 - w, np.sin((1.0 - w) * omega) / so_safe)
    wb = np.where(small, w, np.sin(w * omega) / so_safe)
    return quat_to_matrix(wa * qa + wb * qb)


def slerp_poses(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-joint slerp of two poses a, b (24, 3, 3) at weights w (T,) or (T, 24) -> (T, 24, 3, 3)."""
    w = np.asarray(w, dtype=np.float64)
    if w.ndim == 1:
        w = np.broadcast_to(w[:, None], (w.shape[0], NUM_JOINTS))
    if w.ndim != 2 or w.shape[1] != NUM_JOINTS:
        raise ValueError(f"w must be (T,) or (T, 24), got {w.shape}")
    return slerp_rot(a[None], b[None], w)


def keyframe_track(keys: list[tuple[int, np.ndarray]], num_frames: int) -> np.ndarray:
    """Eased per-joint slerp through keyframes ``[(frame, pose (24, 3, 3)), ...]`` (frames increasing)
    -> (num_frames, 24, 3, 3); held constant before the first and after the last key."""
    if not keys:
        raise ValueError("keyframe_track needs at least one (frame, pose) key")
    frames = [int(f) for f, _ in keys]
    if any(f1 <= f0 for f0, f1 in zip(frames, frames[1:])):
        raise ValueError(f"keyframe frames must be strictly increasing, got {frames}")
    out = np.empty((num_frames, NUM_JOINTS, 3, 3))
    t = np.arange(num_frames)
    out[t <= frames[0]] = keys[0][1]
    out[t >= frames[-1]] = keys[-1][1]
    for (f0, p0), (f1, p1) in zip(keys, keys[1:]):
        sel = (t > f0) & (t <= f1)
        if sel.any():
            out[sel] = slerp_poses(p0, p1, ease((t[sel] - f0) / (f1 - f0)))
    return out


def blend_into(prev: Motion, nxt: Motion, frames: int) -> Motion:
    """Copy of ``nxt`` whose first ``frames`` frames blend from ``prev``'s last state into ``nxt``
    (eased per-joint slerp of local rotations, eased lerp of the root), so ``concat_motions([prev,
    out])`` has no jump. Use it when two primitives do not share an exact end/start state; feet may
    slide a little inside the blend window, and contact flags there are cleared."""
    if not np.allclose(prev.offsets, nxt.offsets):
        raise ValueError("blend_into: prev and nxt must share the actor's offsets")
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    n = min(int(frames), nxt.num_frames)
    w = ease((np.arange(n) + 1) / (n + 1))  # excludes both end points: first frame already moves
    rot = nxt.rot.copy()
    root = nxt.root.copy()
    rot[:n] = slerp_rot(prev.rot[-1][None], nxt.rot[:n], w[:, None])
    root[:n] = prev.root[-1] + w[:, None] * (nxt.root[:n] - prev.root[-1])
    contact = nxt.foot_contact.copy()
    moved = np.linalg.norm(root[:n] - nxt.root[:n], axis=1) > 1e-4
    contact[:n][moved] = False
    return Motion(rot=rot, root=root, offsets=nxt.offsets, fps=nxt.fps, foot_contact=contact,
                  actions=list(nxt.actions), objects=dict(nxt.objects), grasp=dict(nxt.grasp))
