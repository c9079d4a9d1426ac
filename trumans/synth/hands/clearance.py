"""Keeping the body clear of a door leaf or a drawer's cabinet while a hand works it: box
clearance of the body joints and the cheapest lean per body state and opening."""
from __future__ import annotations

import numpy as np

from trumans.scenes.scene import SceneObject

from trumans.contacts.rule import JOINT_RADIUS
from trumans.skeleton import ELBOWS, INDEX1, JOINT_NAMES, NUM_JOINTS, WRISTS, forward_kinematics
from trumans.ik.limb import limb_reach
from .core import PLAN_FRAC, SHOULDER, OutOfReach, Side, actor_scale
from .lean import lean_candidates, lean_pose

__all__ = ["LEAN_LIMIT", "ARM_JOINTS", "BODY_JOINTS", "CLEAR_PLAN", "CLEAR_TOL", "solid_boxes", "body_clear",
           "lean_table", "require_body_clear"]

# Lean limits (pitch rad, drop m) per object kind: a door handle at hip height needs no squat.
LEAN_LIMIT = {"door": (np.radians(25.0), 0.05), "drawer": (np.inf, np.inf)}


# Arm joints are left out of the body-object clearance test (the hand is on the handle).
ARM_JOINTS = [j for side in zip(ELBOWS, WRISTS, INDEX1) for j in side]  # elbow, wrist, index1 per side
BODY_JOINTS = np.array([j for j in range(NUM_JOINTS) if j not in ARM_JOINTS])
CLEAR_PLAN = 0.01  # m, extra clearance kept when planning (the idle base sways about 1 cm)
CLEAR_TOL = 0.015  # m, the generated motion is rejected if the body surface goes deeper than this


def solid_boxes(obj: SceneObject, poses: np.ndarray, closed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes the body must keep clear of, at each opening: (frames (A, B, 4, 4) world-from-box,
    lo (B, 3), hi (B, 3)). The object's own bounding box (moving with it); for a drawer also the
    cabinet around it: everything behind the closed drawer's front face, at any height."""
    b = obj.mesh.bounds
    if obj.category != "drawer":
        return poses[:, None], b[:1], b[1:]
    front = float(obj.meta["handle"][0]) - 0.0125
    lo2 = np.array([[-1e3, b[0, 1] - 0.05, -1e3]])
    hi2 = np.array([[front, b[1, 1] + 0.05, 1e3]])
    frames = np.stack([poses, np.broadcast_to(closed, poses.shape)], axis=1)
    return frames, np.concatenate([b[:1], lo2]), np.concatenate([b[1:], hi2])


def body_clear(P: np.ndarray, frames: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N, A) bool: body joints P (N, 24, 3) keep their contact radius (plus CLEAR_PLAN) clear of
    every box at every opening (frames (A, B, 4, 4), lo / hi (B, 3) box corners, box frame)."""
    inv = np.linalg.inv(frames)  # (A, B, 4, 4)
    Q = P[:, BODY_JOINTS]  # (N, J, 3)
    loc = np.einsum("abij,nkj->nabki", inv[..., :3, :3], Q) + inv[None, :, :, None, :3, 3]  # (N, A, B, J, 3)
    gap = np.maximum(np.maximum(lo[None, None, :, None] - loc, loc - hi[None, None, :, None]), 0.0)
    dist = np.linalg.norm(gap, axis=-1)  # (N, A, B, J), 0 inside
    return (dist >= JOINT_RADIUS[BODY_JOINTS] + CLEAR_PLAN).all(axis=(2, 3))


def lean_table(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, side: Side, wrists: np.ndarray,
               solids, limit: tuple[float, float], seated: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per body state and opening, the cheapest feasible lean. rot (N, 24, 3, 3), root (N, 3) body
    states; wrists (A, 3) wrist targets of openings 0..A-1; solids: ``solid_boxes`` at them.
    Returns (feasible (N, A) bool, pitch (N, A) rad, drop (N, A) m): the lean lets the shoulder reach
    the target with the body clear of the object at that opening."""
    N, A = rot.shape[0], len(wrists)
    pitch, drop, _ = lean_candidates(seated, actor_scale(offsets), *limit)
    K = len(pitch)
    # Each lean at full strength and on its way in / out (2/3, 1/3): the body passes through those.
    sc = np.array([1.0, 2.0 / 3.0, 1.0 / 3.0])
    pp = (sc[:, None] * pitch[None]).ravel()
    dd = (sc[:, None] * drop[None]).ravel()
    rr, ro = lean_pose(np.repeat(rot, 3 * K, 0), np.repeat(root, 3 * K, 0), offsets, np.tile(pp, N),
                       np.tile(dd, N), seated)
    P, _ = forward_kinematics(rr, ro, offsets)
    lo, hi = limb_reach(offsets, f"{side}_arm")
    Pf = P.reshape(N, 3, K, 24, 3)[:, 0].reshape(N * K, 24, 3)
    d = np.linalg.norm(wrists[None] - Pf[:, SHOULDER[side]][:, None], axis=-1)  # (N*K, A)
    clear_all = body_clear(P, *solids).reshape(N, 3, K, A)
    clear = clear_all.all(axis=1)
    ok = ((d <= PLAN_FRAC * hi) & (d >= 1.15 * lo)).reshape(N, K, A) & clear
    # The upright body (candidate 0: no lean) must be clear too: it stands there before and after.
    ok &= clear[:, :1]
    first = np.argmax(ok, axis=1)  # cheapest feasible candidate (candidates are sorted by cost)
    return ok.any(axis=1), np.take_along_axis(np.broadcast_to(pitch, (N, K)), first, 1), \
        np.take_along_axis(np.broadcast_to(drop, (N, K)), first, 1)


def require_body_clear(P: np.ndarray, solids: tuple[np.ndarray, np.ndarray, np.ndarray], what: str, hint: str) -> None:
    """Final check on every frame of a generated motion: the body joints P (T, 24, 3), arms aside,
    keep their contact radius (less ``CLEAR_TOL``) clear of the boxes ``solids`` (``solid_boxes``
    at the T frames: (T, B, 4, 4) world-from-box, lo / hi (B, 3)). Raises OutOfReach naming the
    deepest joint and ``hint`` (how to fix it)."""
    frames, lo, hi = solids
    inv = np.linalg.inv(frames)  # (T, B, 4, 4)
    loc = np.einsum("tbij,tkj->tbki", inv[..., :3, :3], P[:, BODY_JOINTS]) + inv[:, :, None, :3, 3]
    gap = np.linalg.norm(np.maximum(np.maximum(lo[None, :, None] - loc, loc - hi[None, :, None]), 0.0), axis=-1)
    bad = (gap < JOINT_RADIUS[BODY_JOINTS] - CLEAR_TOL).any(axis=(1, 2))
    if bad.any():
        depth = JOINT_RADIUS[BODY_JOINTS] - gap  # (T, B, J)
        j = BODY_JOINTS[int(np.unravel_index(int(depth.argmax()), depth.shape)[2])]
        raise OutOfReach(f"{what}: the body would touch it on {int(bad.sum())} frames (first "
                         f"{int(np.flatnonzero(bad)[0])}, {100 * float(depth.max()):.1f} cm deep, {JOINT_NAMES[j]}); "
                         f"{hint}")
