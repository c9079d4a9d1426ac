"""Torso lean for the hands: a forward hip hinge (and, standing, a squat) that brings a shoulder
within reach of a target, with the feet kept where the base motion puts them (leg IK)."""
from __future__ import annotations

import numpy as np

from trumans.rotations import rodrigues
from trumans.skeleton import ANKLES, JOINT_INDEX, forward_kinematics
from trumans.ik.limb import limb_reach
from ..legs import pelvis_height_limit, solve_legs
from ..motion import yaw_of
from .core import PLAN_FRAC, SHOULDER, OutOfReach, Side, actor_scale
from .timing import ramp

__all__ = ["lean_pose", "lean_candidates", "choose_lean", "lean_travel", "lean_steps", "lean_between"]

def lean_pose(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, pitch: np.ndarray, drop: np.ndarray,
              seated: bool) -> tuple[np.ndarray, np.ndarray]:
    """Forward lean ``pitch`` (T,) rad (hip hinge 55 %, spine 45 %) and pelvis drop ``drop`` (T,) m;
    feet kept where the input puts them (leg IK). Seated bodies keep the pelvis on the seat."""
    rot, root = rot.copy(), root.copy()
    if not (np.any(pitch) or np.any(drop)):
        return rot, root
    P, G = forward_kinematics(rot, root, offsets)
    ank = P[:, list(ANKLES)]
    frot = G[:, list(ANKLES)]
    yaw = yaw_of(rot[:, 0])
    fwd = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], -1)
    left = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], -1)
    rot[:, 0] = rodrigues(left, 0.55 * pitch) @ rot[:, 0]
    ey = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (len(pitch), 3))
    for j, f in ((JOINT_INDEX["spine1"], 0.25), (JOINT_INDEX["spine2"], 0.2)):
        rot[:, j] = rodrigues(ey, f * pitch) @ rot[:, j]
    if not seated:
        root[:, :2] -= (0.12 * np.sin(0.55 * pitch))[:, None] * fwd[:, :2]  # hips back to balance
        root[:, 2] -= drop
        h_lim = pelvis_height_limit(rot, root[:, :2], offsets, ank)
        root[:, 2] = np.minimum(root[:, 2], h_lim - 0.001)
    rot, _ = solve_legs(rot, root, offsets, ank, foot_rot=frot, pole_dir=fwd)
    return rot, root


def lean_candidates(seated: bool, scale: float, max_pitch: float = np.inf,
                    max_drop: float = np.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pitch (K,), drop (K,), cost (K,)) candidate leans (pitch <= max_pitch rad, drop <= max_drop m),
    cheapest first."""
    pitch = np.radians(np.linspace(0.0, 55.0 if seated else 75.0, 12 if seated else 11))
    drops = np.array([0.0]) if seated else scale * np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    pp, dd = np.meshgrid(pitch, drops, indexing="ij")
    pp, dd = pp.ravel(), dd.ravel()
    cost = pp / np.radians(60.0) + 1.5 * dd / 0.4  # a squat costs more than a lean
    keep = (pp <= max_pitch + 1e-9) & (dd <= max_drop + 1e-9)
    pp, dd, cost = pp[keep], dd[keep], cost[keep]
    o = np.argsort(cost, kind="stable")
    return pp[o], dd[o], cost[o]


def choose_lean(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, side: Side, wrists: np.ndarray,
                seated: bool, max_pitch: float = np.inf, max_drop: float = np.inf,
                clear=None) -> tuple[float, float]:
    """Cheapest (pitch rad, drop m) lean of the body state rot1 (24, 3, 3), root1 (3,) from which
    the ``side`` shoulder reaches every wrist target in ``wrists`` (M, 3) (leans limited to
    ``max_pitch`` rad / ``max_drop`` m; ``clear``: optional test joints (K, 24, 3) -> (K,) bool that
    a leaned body must pass, e.g. keeping clear of the object). Raises OutOfReach."""
    pitch, drop, _ = lean_candidates(seated, actor_scale(offsets), max_pitch, max_drop)
    K = len(pitch)
    rot, root = lean_pose(np.repeat(rot1[None], K, 0), np.repeat(root1[None], K, 0), offsets, pitch, drop, seated)
    P, _ = forward_kinematics(rot, root, offsets)
    lo, hi = limb_reach(offsets, f"{side}_arm")
    d = np.linalg.norm(np.asarray(wrists)[None] - P[:, SHOULDER[side]][:, None], axis=-1)  # (K, M)
    ok = ((d <= PLAN_FRAC * hi) & (d >= 1.15 * lo)).all(axis=1)
    if clear is not None:
        ok &= clear(P)
    if not ok.any():
        raise OutOfReach(f"the {side} hand cannot reach {np.round(wrists, 3).tolist()} from the pelvis at "
                         f"{np.round(root1, 3).tolist()} even leaning (nearest shoulder distance "
                         f"{d.max(axis=1).min():.2f} m, arm reach {PLAN_FRAC * hi:.2f} m): stand closer")
    k = int(np.flatnonzero(ok)[0])
    return float(pitch[k]), float(drop[k])


def lean_travel(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, pitch: float, drop: float,
                seated: bool) -> float:
    """Largest joint displacement (m) that a lean (pitch rad, drop m) causes on the state rot1
    (24, 3, 3), root1 (3,) — the lean's own path length, used to time the phase it happens in."""
    if pitch == 0.0 and drop == 0.0:
        return 0.0
    rot, root = lean_pose(np.stack([rot1, rot1]), np.stack([root1, root1]), offsets, np.array([0.0, pitch]),
                          np.array([0.0, drop]), seated)
    P, _ = forward_kinematics(rot, root, offsets)
    return float(np.linalg.norm(P[1] - P[0], axis=-1).max())


def lean_steps(rot1: np.ndarray, root1: np.ndarray, offsets: np.ndarray, pitch: np.ndarray, drop: np.ndarray,
               seated: bool) -> np.ndarray:
    """(A - 1,) largest joint displacement (m) between consecutive leans (pitch, drop) (A,)."""
    A = len(pitch)
    rot, root = lean_pose(np.repeat(rot1[None], A, 0), np.repeat(root1[None], A, 0), offsets, pitch, drop, seated)
    P, _ = forward_kinematics(rot, root, offsets)
    return np.linalg.norm(np.diff(P, axis=0), axis=-1).max(axis=1)


def lean_between(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, pitch: np.ndarray | float,
                 drop: np.ndarray | float, seated: bool, full: int, back: int) -> tuple[np.ndarray, np.ndarray]:
    """``lean_pose`` of the body rot (T, 24, 3, 3), root (T, 3) with the lean (pitch rad, drop m;
    scalars or (T,)) eased in over frames 0..``full`` and out over ``back``..T-1."""
    T = rot.shape[0]
    w = ramp(T, 0, full) * (1 - ramp(T, back, T - 1))
    return lean_pose(rot, root, offsets, pitch * w, drop * w, seated)
