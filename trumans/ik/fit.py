"""Joint positions -> local rotations of the 24-joint skeleton (inverse kinematics by fitting).

``fit_rotations`` first solves every joint analytically, parent before child and vectorised over
frames:

- joints with several children (pelvis, spine3): the rotation that best maps the rest offsets of
  all children onto the observed child bones (weighted Kabsch / SVD);
- joints with one child: the *swing* that turns the rest bone onto the observed bone, taking the
  parent's frame as the twist reference ("follow the parent"); at the hips and shoulders the twist
  is instead chosen so that the knee / elbow below is a pure hinge about its anatomical axis
  (of the two such twists, the one that bends the limb the anatomical way), blended in as the
  knee / elbow bends, since a straight limb does not show its twist;
- leaf joints (head, feet, index1) keep their parent's orientation (their twist is unobservable).

Then a few Adam steps on 6D rotations (``trumans.rotations``) reduce the joint position error
through ``trumans.skeleton.forward_kinematics``; per frame the better of the two solutions is kept.
"""
from __future__ import annotations

import logging

import numpy as np
import torch

from trumans.rotations import axis_angle_to_matrix, least_rotation, matrix_to_6d, sixd_to_matrix, unit
from trumans.skeleton import (HINGE_AXES, NUM_JOINTS, PARENTS, children, forward_kinematics, global_to_local,
                              offsets_from_joints, offsets_from_pose)

# offsets_from_joints lives in trumans.skeleton; re-exported here, where it was first defined
__all__ = ["fit_rotations", "offsets_from_joints", "fit_error", "kabsch"]

log = logging.getLogger(__name__)

_CHILDREN = [children(j) for j in range(NUM_JOINTS)]
_BEND_LO, _BEND_HI = 0.05, 0.25  # sin(bend angle) below which the limb plane is ignored / fully trusted


def kabsch(a: np.ndarray, b: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Rotation R minimising sum_i w_i |R a_i - b_i|^2 (no translation).

    a: (..., N, 3) source vectors, b: (..., N, 3) targets, w: (N,) or (..., N) weights -> (..., 3, 3)."""
    a, b = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64))
    if w is None:
        w = np.ones(a.shape[-2])
    H = np.einsum("...n,...ni,...nj->...ij", np.broadcast_to(w, a.shape[:-1]), b, a)  # sum w b a^T
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros(H.shape)
    D[..., 0, 0] = D[..., 1, 1] = 1.0
    D[..., 2, 2] = d
    return U @ D @ Vt


def _analytic(P: np.ndarray, off: np.ndarray) -> np.ndarray:
    """Analytic local rotations (T, 24, 3, 3) for joints P (T, 24, 3) with offsets off (24, 3)."""
    T = P.shape[0]
    G = np.zeros((T, NUM_JOINTS, 3, 3))
    eye = np.broadcast_to(np.eye(3), (T, 3, 3))
    for j in range(NUM_JOINTS):
        Gp = eye if j == 0 else G[:, PARENTS[j]]
        kids = _CHILDREN[j]
        if len(kids) >= 2:
            w = np.linalg.norm(off[kids], axis=-1)
            Gj = kabsch(off[kids], P[:, kids] - P[:, j:j + 1], w=(w > 1e-9).astype(float))
        elif len(kids) == 1:
            c = kids[0]
            b1 = P[:, c] - P[:, j]
            Gj = least_rotation(Gp @ off[c], b1) @ Gp
            gk = _CHILDREN[c]
            if c in HINGE_AXES and len(gk) == 1 and np.linalg.norm(off[c]) > 1e-9:
                Gj = _hinge_twist(Gj, off[c], off[gk[0]], HINGE_AXES[c], b1, P[:, gk[0]] - P[:, c])
        else:
            Gj = Gp
        G[:, j] = Gj
    return global_to_local(G)


def _hinge_twist(Gs: np.ndarray, a1: np.ndarray, a2: np.ndarray, axis: np.ndarray, b1: np.ndarray,
                      b2: np.ndarray) -> np.ndarray:
    """Turn the swing solution Gs (T, 3, 3) of a hip / shoulder about its observed bone b1 (T, 3)
    so that the child joint (knee / elbow) is a pure hinge about ``axis`` for the observed next
    bone b2 (T, 3).

    a1, a2: rest offsets (3,) of the child and grandchild; axis: the hinge axis (3,) in the joint's
    rest frame. Of the two twists that make a hinge, the one nearer to putting the rest bend
    direction (axis x a1) into the observed limb plane is kept, so the limb bends the anatomical
    way. The turn is faded out as the limb straightens (the hinge is then unobservable)."""
    h = unit(np.asarray(axis, np.float64))
    c0 = h @ unit(a2)  # h . unit(a2): what a hinge about h keeps constant
    k = unit(b1)
    nb2 = unit(b2)
    # A pure hinge about h at the child joint keeps (G h) . unit(b2) = h . unit(a2) (= c0), where G is
    # this joint's global frame (the child turns about h, which it leaves fixed) and
    # G = Rot(k, theta) @ Gs. With n = Gs h and Rodrigues' formula this reads
    #   A cos(theta) + B sin(theta) + D = c0,
    #   A = n.b2 - (k.n)(k.b2),  B = (k x n).b2,  D = (k.n)(k.b2),
    # i.e. R cos(theta - phi) = c0 - D with R = hypot(A, B), phi = atan2(B, A): two solutions
    # phi +- arccos((c0 - D) / R) (clipped when no exact one exists).
    n = Gs @ h
    kn = (k * n).sum(-1)
    kb = (k * nb2).sum(-1)
    A = (n * nb2).sum(-1) - kn * kb
    B = (np.cross(k, n) * nb2).sum(-1)
    D = kn * kb
    Rab = np.hypot(A, B)
    phi = np.arctan2(B, A)
    delta = np.arccos(np.clip((c0 - D) / np.maximum(Rab, 1e-12), -1.0, 1.0))
    # limb-plane angle: turns the rest bend direction onto the observed bend direction of b2
    hp = unit(np.cross(h, a1))
    perp = b2 - (b2 * k).sum(-1, keepdims=True) * k
    s = np.linalg.norm(perp, axis=-1) / np.maximum(np.linalg.norm(b2, axis=-1), 1e-12)  # sin of the bend angle
    u = Gs @ hp
    v = unit(perp)
    plane = np.arctan2((k * np.cross(u, v)).sum(-1), (u * v).sum(-1))
    cand = np.stack([phi + delta, phi - delta], -1)
    dist = np.abs(np.angle(np.exp(1j * (cand - plane[:, None]))))
    theta = np.take_along_axis(cand, dist.argmin(-1)[:, None], -1)[:, 0]
    theta = np.angle(np.exp(1j * theta))  # wrap to (-pi, pi] so the fade goes the short way
    theta = np.where(Rab > 1e-9, theta, plane)
    wgt = np.clip((s - _BEND_LO) / (_BEND_HI - _BEND_LO), 0.0, 1.0)
    return axis_angle_to_matrix(k * (wgt * theta)[:, None]) @ Gs


def fit_error(joints: np.ndarray, rot: np.ndarray, root: np.ndarray, offsets: np.ndarray) -> dict[str, float]:
    """Joint position error (m) of FK(rot, root, offsets) against ``joints (T, 24, 3)``:
    ``{"mean": ..., "max": ...}`` over frames and joints."""
    J, _ = forward_kinematics(np.asarray(rot, np.float64), np.asarray(root, np.float64), np.asarray(offsets, np.float64))
    e = np.linalg.norm(J - np.asarray(joints, np.float64), axis=-1)
    return {"mean": float(e.mean()) if e.size else 0.0, "max": float(e.max()) if e.size else 0.0}


def _refine(P: np.ndarray, R: np.ndarray, root: np.ndarray, off: np.ndarray, steps: int,
            lr: float = 2e-3) -> tuple[np.ndarray, np.ndarray]:
    """Adam on 6D rotations + root minimising squared joint error; per frame keeps the better one."""
    Pt = torch.as_tensor(P, dtype=torch.float64)
    offt = torch.as_tensor(off, dtype=torch.float64)
    r6 = torch.as_tensor(matrix_to_6d(R), dtype=torch.float64).clone().requires_grad_(True)
    rt = torch.as_tensor(root, dtype=torch.float64).clone().requires_grad_(True)
    opt = torch.optim.Adam([r6, rt], lr=lr)
    for _ in range(steps):
        opt.zero_grad()
        J, _ = forward_kinematics(sixd_to_matrix(r6), rt, offt)
        loss = ((J - Pt) ** 2).sum(-1).mean()
        loss.backward()
        opt.step()
    with torch.no_grad():
        R_new = sixd_to_matrix(r6).numpy()
        root_new = rt.numpy().copy()
    e_old = np.linalg.norm(forward_kinematics(R, root, off)[0] - P, axis=-1).mean(-1)
    e_new = np.linalg.norm(forward_kinematics(R_new, root_new, off)[0] - P, axis=-1).mean(-1)
    better = e_new < e_old
    return np.where(better[:, None, None, None], R_new, R), np.where(better[:, None], root_new, root)


def fit_rotations(
    joints: np.ndarray,
    offsets: np.ndarray | None = None,
    refine_steps: int = 30,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local rotations that reproduce joint positions.

    joints: (T, 24, 3) metres, z-up world. offsets: (24, 3) rest offsets in metres (the skeleton's
    convention); None measures bone lengths from the data (median over frames) along the rest
    directions of ``rest_offsets()`` and then re-estimates each offset as the mean observed bone in
    the fitted parent frames (so that pelvis / spine3 children, whose relative layout differs
    between skeletons, become rigid and consistent with the data).
    refine_steps: Adam steps after the analytic fit (0 = analytic only).
    Returns ``(rot (T, 24, 3, 3) float64, root (T, 3) float64 pelvis positions, offsets (24, 3))``.
    The reconstruction error is logged at INFO; ``fit_error`` computes it.
    """
    P = np.asarray(joints, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {P.shape}")
    if P.shape[0] == 0:
        raise ValueError("joints has no frames")
    if not np.isfinite(P).all():
        raise ValueError("joints contain NaN or inf; clean or interpolate them before fitting rotations")
    if refine_steps < 0:
        raise ValueError(f"refine_steps must be >= 0, got {refine_steps}")
    root = P[:, 0].copy()
    if offsets is None:
        off = offsets_from_joints(P)
        R = _analytic(P, off)
        _, G = forward_kinematics(R, root, off)
        off = offsets_from_pose(P, G)  # the data's bones in the fitted parent frames
    else:
        off = np.asarray(offsets, dtype=np.float64)
        if off.shape != (NUM_JOINTS, 3):
            raise ValueError(f"offsets must be (24, 3), got {off.shape}")
    R = _analytic(P, off)
    if refine_steps > 0:
        before = fit_error(P, R, root, off)["max"]
        if before > 1e-5:
            R, root = _refine(P, R, root, off, refine_steps)
    err = fit_error(P, R, root, off)
    log.info("fit_rotations: %d frames, joint error mean %.2f mm, max %.2f mm", len(P), 1e3 * err["mean"], 1e3 * err["max"])
    return R, root, off
