"""Analytic two-bone limb IK on the 24-joint skeleton (vectorised over frames).

Chains: arms shoulder -> elbow -> wrist, legs hip -> knee -> ankle. The middle joint (elbow/knee)
is a hinge: its local rotation is ``Rot(h, phi)`` about a fixed per-limb flexion axis ``h`` (in the
parent's frame, positive phi = flexion), and phi follows from the law of cosines so that the
chain spans the shoulder/hip-to-target distance. The upper joint's local rotation aims the chain
at the target with the bend plane turned towards the pole. The end joint's *global* orientation
is kept (a planted foot keeps its orientation, a hand keeps its grip orientation).
"""
from __future__ import annotations

from typing import Literal

import numpy as np

from trumans.rotations import rodrigues, unit
from trumans.skeleton import HINGE_AXES, INDEX1, JOINT_INDEX, LIMB_CHAINS, NUM_JOINTS, PARENTS, forward_kinematics

__all__ = ["LIMBS", "Limb", "solve_limb", "set_global_rotation", "limb_reach", "two_bone_positions"]

Limb = Literal["left_arm", "right_arm", "left_leg", "right_leg"]

# (upper, middle, end, tip or -1, flexion axis of the middle joint: trumans.skeleton.HINGE_AXES)
LIMBS: dict[str, tuple[int, int, int, int, np.ndarray]] = {
    name: (a, b, c, INDEX1[name.startswith("right")] if name.endswith("arm") else -1, HINGE_AXES[b])
    for name, (a, b, c) in LIMB_CHAINS.items()
}
# Default pole directions in the pelvis frame (forward, left, up): knees forward, elbows back-down-out.
_DEFAULT_POLE = {
    "left_arm": np.array([-0.5, 0.6, -1.0]),
    "right_arm": np.array([-0.5, -0.6, -1.0]),
    "left_leg": np.array([1.0, 0.0, 0.0]),
    "right_leg": np.array([1.0, 0.0, 0.0]),
}
_EPS = 1e-9


def _hinge_terms(u: np.ndarray, v: np.ndarray, h: np.ndarray) -> tuple[float, float, float, float]:
    """For |u + Rot(h, phi) v|^2 = base + 2 rho cos(phi - psi): returns (base, rho, psi, uv_par)."""
    v_par = (v @ h) * h
    v_perp = v - v_par
    A = float(u @ v_par)
    B = float(u @ v_perp)
    C = float(u @ np.cross(h, v_perp))
    base = float(u @ u + v @ v) + 2.0 * A
    return base, float(np.hypot(B, C)), float(np.arctan2(C, B)), A


def limb_reach(offsets: np.ndarray, limb: Limb) -> tuple[float, float]:
    """(min, max) distance (m) from the upper joint to the end joint that the hinge chain can span."""
    if limb not in LIMBS:
        raise ValueError(f"limb must be one of {list(LIMBS)}, got {limb!r}")
    a, b, c, _, h = LIMBS[limb]
    base, rho, _, _ = _hinge_terms(offsets[b], offsets[c], h)
    return float(np.sqrt(max(base - 2 * rho, 0.0))), float(np.sqrt(base + 2 * rho))


def _check(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray) -> int:
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"rot must be (T, 24, 3, 3), got {rot.shape}")
    T = rot.shape[0]
    if root.shape != (T, 3):
        raise ValueError(f"root must be ({T}, 3) to match rot, got {root.shape}")
    if offsets.shape != (NUM_JOINTS, 3):
        raise ValueError(f"offsets must be (24, 3) (use trumans.skeleton.rest_offsets), got {offsets.shape}")
    return T


def set_global_rotation(
    rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, joint: int | str, R_world: np.ndarray
) -> np.ndarray:
    """Return a copy of ``rot`` (T, 24, 3, 3) whose ``joint`` has global rotation ``R_world``
    ((T, 3, 3) or (3, 3)); its descendants keep their local rotations (they follow)."""
    rot = np.asarray(rot, dtype=np.float64)
    T = _check(rot, np.asarray(root), np.asarray(offsets))
    j = JOINT_INDEX[joint] if isinstance(joint, str) else int(joint)
    if not 0 <= j < NUM_JOINTS:
        raise ValueError(f"joint must be a name or an index in 0..23, got {joint!r}")
    R_world = np.broadcast_to(np.asarray(R_world, dtype=np.float64), (T, 3, 3))
    out = rot.copy()
    if j == 0:
        out[:, 0] = R_world
        return out
    _, G = forward_kinematics(rot, np.asarray(root, dtype=np.float64), offsets)
    out[:, j] = np.swapaxes(G[:, PARENTS[j]], -1, -2) @ R_world
    return out


def solve_limb(
    rot: np.ndarray,
    root: np.ndarray,
    offsets: np.ndarray,
    limb: Limb,
    target: np.ndarray,
    pole: np.ndarray | None = None,
    effector: Literal["end", "tip"] = "end",
    mask: np.ndarray | None = None,
    keep_end_orientation: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Two-bone analytic IK for one limb.

    rot: (T, 24, 3, 3) local rotations; root: (T, 3) pelvis world position (m); offsets: (24, 3) m;
    target: (T, 3) or (3,) world position (m) for the wrist/ankle (``effector='end'``) or, arms
    only, the index1 joint (``effector='tip'``, with the wrist's current global orientation);
    pole: (T, 3) or (3,) world point the elbow/knee bends towards (default: knee forward of the
    pelvis, elbow backward-down-out); mask: (T,) bool frames to solve (others unchanged).
    Only the upper and middle joints' local rotations change (and the end joint's local rotation,
    so that its global orientation stays as before when ``keep_end_orientation``).
    Returns ``(new rot (T, 24, 3, 3), reached (T,) bool)``; unreachable targets are clamped to
    full extension (or full flexion) along the target direction and reported ``False``.
    """
    rot = np.asarray(rot, dtype=np.float64)
    root = np.asarray(root, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.float64)
    T = _check(rot, root, offsets)
    if limb not in LIMBS:
        raise ValueError(f"limb must be one of {list(LIMBS)}, got {limb!r}")
    if effector not in ("end", "tip"):
        raise ValueError(f"effector must be 'end' or 'tip', got {effector!r}")
    a, b, c, tip, h = LIMBS[limb]
    if effector == "tip" and tip < 0:
        raise ValueError(f"effector='tip' is only defined for arms, not {limb!r}")
    target = np.broadcast_to(np.asarray(target, dtype=np.float64), (T, 3))
    if mask is None:
        mask = np.ones(T, dtype=bool)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != (T,):
        raise ValueError(f"mask must be ({T},) bool, got {mask.shape}")
    out = rot.copy()
    reached = np.ones(T, dtype=bool)
    if not mask.any():
        return out, reached
    P, G = forward_kinematics(rot[mask], root[mask], offsets)
    tgt = target[mask]
    Gc = G[:, c]
    if effector == "tip":
        tgt = tgt - Gc @ offsets[tip]  # wrist position that puts index1 on the target
    if pole is None:
        pole_w = P[:, a] + G[:, 0] @ _DEFAULT_POLE[limb]
    else:
        pole_w = np.broadcast_to(np.asarray(pole, dtype=np.float64), (T, 3))[mask]

    # Middle hinge angle from the law of cosines (generalised to bones not perpendicular to h).
    u, v = offsets[b], offsets[c]
    base, rho, psi, A = _hinge_terms(u, v, h)
    d = tgt - P[:, a]
    dist = np.linalg.norm(d, axis=-1)
    dmin, dmax = np.sqrt(max(base - 2 * rho, 0.0)), np.sqrt(base + 2 * rho)
    tol = 1e-7
    ok = (dist >= dmin - tol) & (dist <= dmax + tol)
    D = np.clip(dist, dmin, dmax)
    cos_arg = np.clip((D**2 - base) / (2.0 * max(rho, _EPS)), -1.0, 1.0)
    phi = psi + np.arccos(cos_arg)  # phi = psi is straight; increasing phi flexes
    Rb = rodrigues(h, phi)  # (N, 3, 3) middle joint local rotation

    # Upper joint: map the local chain frame E onto the world frame F (target direction, pole side).
    v_ac = u[None] + Rb @ v  # (N, 3) upper->end in the upper joint's frame
    e1 = unit(v_ac)
    e3 = unit(h[None] - (e1 @ h)[:, None] * e1)
    e2 = np.cross(e3, e1)
    # Sign so that a flexed chain's middle joint lies on the pole side.
    Rb_test = rodrigues(h, psi + 1.0)
    t1 = unit(u + Rb_test @ v)
    t3 = unit(h - (t1 @ h) * t1)
    k = u - (u @ t1) * t1
    sigma = 1.0 if k @ np.cross(t3, t1) >= 0 else -1.0
    f1 = d / np.maximum(dist, _EPS)[:, None]
    degenerate = dist < _EPS
    if degenerate.any():  # target on the upper joint: any direction; use the current chain direction
        f1[degenerate] = unit(P[degenerate, c] - P[degenerate, a])
    pv = pole_w - P[:, a]
    pv = pv - (pv * f1).sum(-1, keepdims=True) * f1
    bad = np.linalg.norm(pv, axis=-1) < 1e-6
    if bad.any():  # pole on the target line: keep the current bend side
        cur = P[bad, b] - P[bad, a]
        pv[bad] = cur - (cur * f1[bad]).sum(-1, keepdims=True) * f1[bad]
    f2 = sigma * unit(pv)
    f3 = np.cross(f1, f2)
    # E = [e1, e2, e3] is right-handed and the middle joint lies on its sigma*e2 side, so mapping
    # e2 -> sigma * pole direction puts the elbow/knee on the pole side.
    E = np.stack([e1, e2, e3], axis=-1)
    F = np.stack([f1, f2, f3], axis=-1)
    Ga = F @ np.swapaxes(E, -1, -2)
    Gpa = G[:, PARENTS[a]]
    Ra = np.swapaxes(Gpa, -1, -2) @ Ga
    sub = out[mask]
    sub[:, a] = Ra
    sub[:, b] = Rb
    if keep_end_orientation:
        sub[:, c] = np.swapaxes(Ga @ Rb, -1, -2) @ Gc
    out[mask] = sub
    reached[mask] = ok
    return out, reached


def two_bone_positions(hip: np.ndarray, knee: np.ndarray, target: np.ndarray, l1: np.ndarray | float,
                       l2: np.ndarray | float, reach_margin: tuple[float, float] = (1e-4, 1e-3)
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Analytic two-bone IK on positions: the end joint on ``target`` (or as near as the chain
    reaches), the middle joint at ``l1`` (m) from the root joint and ``l2`` from the end, in the plane
    of the current bend (law of cosines). hip, knee, target: (..., 3) world m; l1, l2: (...,) or
    scalars, m. The reach is clamped to ``[|l1 - l2| + margin[0], l1 + l2 - margin[1]]`` (default
    1 mm short of full extension); a straight chain bends sideways of vertical.
    Returns (knee (..., 3), end (..., 3))."""
    l1 = np.asarray(l1, dtype=np.float64)[..., None]
    l2 = np.asarray(l2, dtype=np.float64)[..., None]
    d = target - hip
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    f = d / np.maximum(dist, 1e-9)
    D = np.clip(dist, np.abs(l1 - l2) + reach_margin[0], l1 + l2 - reach_margin[1])
    end = hip + f * D
    a = (l1 ** 2 - l2 ** 2 + D ** 2) / (2 * D)  # root -> middle joint's foot point along the root-end line
    r = np.sqrt(np.maximum(l1 ** 2 - a ** 2, 0.0))
    bend = knee - hip
    perp = bend - (bend * f).sum(-1, keepdims=True) * f
    n = np.linalg.norm(perp, axis=-1, keepdims=True)
    fallback = np.cross(f, np.array([0.0, 0.0, 1.0]))  # a straight chain: bend sideways of vertical
    perp = np.where(n > 1e-6, perp / np.maximum(n, 1e-12), fallback / np.maximum(
        np.linalg.norm(fallback, axis=-1, keepdims=True), 1e-12))
    return hip + f * a + perp * r, end
