"""Object motion driven by the hands within the object's degrees of freedom (iReplica supp. §10).

Every function returns world-frame rigid motions ``M (n, 4, 4)`` relative to the first frame of
a contact segment (``M[0] = I``); the object's pose during the segment is ``M[t] @ pose_start``.
Hand positions are "the middle of each hand" (``hand_points``: midpoint of wrist and index1).

- two hands, sliding on the floor (§10 A): translation of the right hand (eq. 3) and the SIGNED
  angle between the initial and current right->left hand vectors, ``atan2(cross, dot)`` (eq. 4
  with the sign of the cross product, correct beyond 90 deg; unwrapped over time); the rotation
  is about the vertical through the right hand, so the right hand's contact point moves exactly
  with the hand (eq. 7 written about the contact point).
- one hand, sliding (§10 B): translation only (eq. 5), horizontal, or along the slide axis for
  objects such as drawers that slide along one direction.
- hinged (§10 C): the angle between the hinge->hand vectors (eq. 6) about the hinge axis, signed
  by the axis and unwrapped over time (a door may swing past +-180 deg).
- free: the object follows the hand's pose (position and orientation of the wrist); held between
  two hands ``TWO_HAND_SPAN_M`` or more apart (a box), it follows the frame between them
  (``two_hand_free_motion``).
"""
from __future__ import annotations

import numpy as np

from trumans.rotations import axis_angle_to_matrix
from trumans.skeleton import JOINT_INDEX

__all__ = [
    "dof_limits", "dof_value", "hinge_frame", "rotation_angles",
    "signed_angle",
    "hand_points",
    "two_hand_motion",
    "one_hand_motion",
    "hinge_motion",
    "free_motion",
    "two_hand_free_motion",
    "TWO_HAND_SPAN_M",
    "rotation_about_axis",
]

_UP = np.array([0.0, 0.0, 1.0])


def signed_angle(u: np.ndarray, v: np.ndarray, axis: np.ndarray = _UP) -> np.ndarray:
    """Signed angle (rad, in (-pi, pi]) from u to v about ``axis`` (unit): u, v (..., 3) or
    (..., 2) (then axis = +z). ``atan2(axis . (u x v), u . v)`` after projecting onto the plane
    normal to the axis."""
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    if u.shape[-1] == 2:
        u = np.concatenate([u, np.zeros(u.shape[:-1] + (1,))], -1)
        v = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], -1)
    a = np.asarray(axis, dtype=np.float64)
    u = u - (u @ a)[..., None] * a
    v = v - (v @ a)[..., None] * a
    return np.arctan2(np.cross(u, v) @ a, (u * v).sum(-1))


def hand_points(joints: np.ndarray) -> np.ndarray:
    """(T, 24, 3) joints -> (T, 2, 3) the middle of the left and right hand (wrist-index1 midpoint)."""
    j = np.asarray(joints, dtype=np.float64)
    left = 0.5 * (j[:, JOINT_INDEX["left_wrist"]] + j[:, JOINT_INDEX["left_index1"]])
    right = 0.5 * (j[:, JOINT_INDEX["right_wrist"]] + j[:, JOINT_INDEX["right_index1"]])
    return np.stack([left, right], axis=1)


def rotation_about_axis(angle: np.ndarray, axis: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(n,) angles (rad) about a unit ``axis`` (3,) through ``point`` (3,) -> (n, 4, 4) rigid motions."""
    angle = np.asarray(angle, dtype=np.float64)
    k = np.asarray(axis, dtype=np.float64)
    R = axis_angle_to_matrix(angle[:, None] * (k / np.linalg.norm(k)))
    M = np.tile(np.eye(4), (len(angle), 1, 1))
    M[:, :3, :3] = R
    M[:, :3, 3] = point - np.einsum("nij,j->ni", R, point)
    return M


def _check_track(x: np.ndarray, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or len(x) < 1:
        raise ValueError(f"{name} must be (n, 3) with n >= 1 frames, got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"{name} contains NaN or inf")
    return x


def two_hand_motion(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Sliding object held by two hands (§10 A). left, right: (n, 3) hand points (m, world).
    Returns (n, 4, 4): rotation about +z by the unwrapped signed angle of the right->left vector,
    about the right hand's first position, then the right hand's horizontal translation."""
    left, right = _check_track(left, "left"), _check_track(right, "right")
    h = (left - right)[:, :2]
    angle = np.unwrap(signed_angle(np.broadcast_to(h[0], h.shape), h))
    M = rotation_about_axis(angle, _UP, right[0])
    M[:, :2, 3] += right[:, :2] - right[0, :2]  # eq. 3
    return M


def one_hand_motion(hand: np.ndarray, axis: np.ndarray | None = None) -> np.ndarray:
    """Sliding object pushed/pulled by one hand (§10 B): translation only. hand: (n, 3) m;
    axis: (3,) unit world slide direction, or None to slide anywhere on the floor (horizontal)."""
    hand = _check_track(hand, "hand")
    d = hand - hand[0]
    if axis is None:
        d[:, 2] = 0.0
    else:
        a = np.asarray(axis, dtype=np.float64)
        a = a / np.linalg.norm(a)
        d = (d @ a)[:, None] * a
    M = np.tile(np.eye(4), (len(hand), 1, 1))
    M[:, :3, 3] = d
    return M


def hinge_motion(hand: np.ndarray, point: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Hinged object (§10 C): rotation about ``axis`` (3,) through ``point`` (3,) (world) by the
    angle between the initial and current hinge->hand vectors (eq. 6), unwrapped over time.
    hand: (n, 3) m."""
    hand = _check_track(hand, "hand")
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    v = hand - np.asarray(point, dtype=np.float64)
    angle = np.unwrap(signed_angle(np.broadcast_to(v[0], v.shape), v, a))
    return rotation_about_axis(angle, a, np.asarray(point, dtype=np.float64))


def free_motion(hand_rot: np.ndarray, hand_pos: np.ndarray) -> np.ndarray:
    """Free object following the hand's pose: hand_rot (n, 3, 3) world rotations of the wrist,
    hand_pos (n, 3) m. Returns H[t] @ inv(H[0])."""
    hand_pos = _check_track(hand_pos, "hand_pos")
    R = np.asarray(hand_rot, dtype=np.float64)
    if R.shape != (len(hand_pos), 3, 3):
        raise ValueError(f"hand_rot must be ({len(hand_pos)}, 3, 3), got {R.shape}")
    H = np.tile(np.eye(4), (len(R), 1, 1))
    H[:, :3, :3], H[:, :3, 3] = R, hand_pos
    inv0 = np.eye(4)
    inv0[:3, :3] = R[0].T
    inv0[:3, 3] = -R[0].T @ hand_pos[0]
    return H @ inv0


TWO_HAND_SPAN_M = 0.10  # m, two hands this far apart hold an object between them (a box), not one small object


def two_hand_free_motion(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Free object held between two hands (a box; not in the paper, whose free objects ride on one
    hand): it moves with the frame whose origin is the hands' midpoint, y from the right hand to the
    left one and z as near +z as that allows (the holding frame of ``trumans.synth.real_objects``), so
    it stays level between the palms instead of turning with one wrist. left, right: (n, 3) hand
    points (m, world). Returns H[t] @ inv(H[0]) (n, 4, 4)."""
    left, right = _check_track(left, "left"), _check_track(right, "right")
    y = left - right
    y /= np.maximum(np.linalg.norm(y, axis=-1, keepdims=True), 1e-9)
    z = _UP - (y @ _UP)[:, None] * y
    z /= np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), 1e-9)
    R = np.stack([np.cross(y, z), y, z], axis=-1)
    return free_motion(R, 0.5 * (left + right))


def dof_limits(obj) -> tuple[float, float]:
    """(low, high) of a hinge's angle (rad, from the scene pose, ``open_sign * [0, max_angle]``) or
    a slide's travel along its axis (m, ``[0, max_travel]``); (-inf, inf) when the meta has none."""
    if obj.dof == "hinge" and "max_angle" in obj.meta:
        a = float(obj.meta.get("open_sign", 1.0)) * float(obj.meta["max_angle"])
        return min(0.0, a), max(0.0, a)
    if obj.dof == "slide" and "max_travel" in obj.meta:
        return 0.0, float(obj.meta["max_travel"])
    return -np.inf, np.inf


def rotation_angles(M: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Rotation angles (n,) about ``axis`` of (n, 4, 4) motions that rotate about it."""
    ref = np.cross(axis, [1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.cross(axis, [0.0, 1.0, 0.0])
    return np.unwrap(signed_angle(np.broadcast_to(ref, (len(M), 3)), M[:, :3, :3] @ ref, axis))


def hinge_frame(obj) -> tuple[np.ndarray, np.ndarray]:
    """A hinged object's world (axis (3,), point (3,)) at its scene pose."""
    R, t = obj.pose[:3, :3], obj.pose[:3, 3]
    return R @ obj.axis, R @ obj.hinge_point + t


def dof_value(obj, pose: np.ndarray) -> float:
    """Hinge angle (rad) / slide travel (m) of ``pose`` (4, 4) relative to the scene pose."""
    if obj.dof == "hinge":
        axis, _ = hinge_frame(obj)
        return float(signed_angle(obj.pose[:3, 0], pose[:3, 0], axis))
    return float((pose[:3, 3] - obj.pose[:3, 3]) @ (obj.pose[:3, :3] @ obj.axis)) if obj.axis is not None else 0.0
