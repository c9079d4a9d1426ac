"""Cyclic coordinate descent IK (Kenwright 2012) on the 24-joint skeleton, vectorised over frames.

TRUMANS §3.3 / appendix B.5: after the contact targets move, the pose is recomputed by CCD with
per-bone rotation clipping and regularisation toward the original pose, bones further from the
root being allowed to rotate more. Conventions:

- State: world joint positions ``P (T, 24, 3)`` (m) and global joint rotations ``G (T, 24, 3, 3)``
  (``G[j] = G[parent] @ R_local[j]``, see trumans.skeleton). A CCD step at joint ``j`` is a world
  rotation ``dR`` about ``P[j]`` applied rigidly to j's whole subtree, so bone lengths never change.
- Each effector ``e`` has a chain: its proper ancestors from the parent up to spine1 / hip (the
  pelvis' rotation is never changed: it would swing the planted legs and the whole body).
- Seat / bed contacts (pelvis, hips, spine, neck, head, collars, shoulders: ``ROOT_GROUP``) use the
  root translation as a degree of freedom: each iteration translates the body by the mean residual
  of the active root-group effectors, clamped so planted legs can still reach their feet.
- Per iteration, every CCD joint's local rotation first relaxes toward the original by a fraction
  ``reg`` (regularisation; annealed to 0 over the first ``reg_iters`` iterations so the final
  iterations are pure CCD and converge), then each chain joint takes its CCD step clipped to
  ``limit_deg[j]``. Middle joints of two-bone limbs (knees, elbows) take a law-of-cosines step
  instead of the aiming step (plain CCD crawls on an almost straight limb).
- A target is *unreachable* when its error after ``iterations`` exceeds ``unreachable_tol``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.rotations import fit_yaw
from trumans.skeleton import DEPTH, JOINT_INDEX, LIMB_CHAINS, NUM_JOINTS, PARENTS, TORSO, bone_offsets, global_to_local

from trumans.ik import soa
from trumans.ik.sweep import LEAVES, sweep

__all__ = ["IKConfig", "IKResult", "ROOT_GROUP", "CHAINS", "solve_ik"]

_J = JOINT_INDEX

# Joints moved by translating the root (seat / bed contacts): the rigid trunk.
ROOT_GROUP: tuple[int, ...] = TORSO
# root-group joints above spine1: contacts that bending the spine would tear off
_UPPER: list[int] = [_J[n] for n in ("spine2", "spine3", "neck", "head", "left_collar", "right_collar",
                                      "left_shoulder", "right_shoulder")]


def _chain(e: int) -> tuple[int, ...]:
    out = []
    j = int(PARENTS[e])
    while j > 0:  # stop before the pelvis
        out.append(j)
        j = int(PARENTS[j])
    return tuple(out)


# Effector -> chain of joints whose rotation CCD adjusts, distal first.
CHAINS: dict[int, tuple[int, ...]] = {e: _chain(e) for e in range(NUM_JOINTS)}
_ROTATED: list[int] = sorted({j for c in CHAINS.values() for j in c})


@dataclass
class IKConfig:
    """CCD settings. Angles in degrees, distances in metres."""

    iterations: int = 25
    tol: float = 2e-4  # a frame is done when every active effector is within tol
    unreachable_tol: float = 5e-3  # error above which a target is reported unreachable
    limit_base_deg: float = 3.0  # per-iteration rotation clip = base + per_depth * depth(j)
    limit_per_depth_deg: float = 2.0
    reg: float = 0.25  # fraction of the deviation from the original local rotation removed per iteration
    reg_iters: int = 4  # regularisation anneals linearly to 0 over these iterations
    leg_reach: float = 0.97  # planted legs may stretch to this fraction of their length

    def __post_init__(self) -> None:
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")
        if not (0 <= self.reg < 1):
            raise ValueError(f"reg must be in [0, 1), got {self.reg}")
        if self.tol <= 0 or self.unreachable_tol < self.tol:
            raise ValueError(f"need 0 < tol <= unreachable_tol, got {self.tol}, {self.unreachable_tol}")

    def limits(self) -> np.ndarray:
        """(24,) per-joint per-iteration rotation clip in radians, larger further from the root."""
        return np.deg2rad(self.limit_base_deg + self.limit_per_depth_deg * DEPTH)


@dataclass
class IKResult:
    """joints (T, 24, 3) m; global_rot (T, 24, 3, 3); local_rot (T, 24, 3, 3); error (T, 24) m
    distance of each active effector to its target (0 where inactive); unreachable (T, 24) bool."""

    joints: np.ndarray
    global_rot: np.ndarray
    local_rot: np.ndarray
    error: np.ndarray
    unreachable: np.ndarray


_LEAVES = LEAVES


def _norm(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (...,) lengths (einsum: numpy's sum over a length-3 axis is twice as slow)."""
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3), (..., 3) -> (...,) dot products."""
    return np.einsum("...i,...i->...", a, b)


_LEGS = (LIMB_CHAINS["left_leg"], LIMB_CHAINS["right_leg"])
_INNER: np.ndarray = np.array([j for j in range(NUM_JOINTS) if j not in _LEAVES], dtype=np.int64)
_PARENT_ROT: np.ndarray = PARENTS[_ROTATED]
# FK levels below the root: (joints, their parents, the non-leaf joints, their rows in joints)
# the same in rows of _INNER: (joints, parents, rows of the non-leaf joints, rows of the parents,
# the non-leaf joints' places in joints)
_ROW = {int(j): i for i, j in enumerate(_INNER)}
_ROT_ROW: np.ndarray = np.array([_ROW[j] for j in _ROTATED], dtype=np.int64)
_PARENT_ROW: np.ndarray = np.array([_ROW[int(p)] for p in _PARENT_ROT], dtype=np.int64)
_LEVELS_SOA: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
for _d in range(1, int(DEPTH.max()) + 1):
    _js = np.flatnonzero(DEPTH == _d)
    _in = np.array([i for i, j in enumerate(_js) if j not in _LEAVES], dtype=np.int64)
    _LEVELS_SOA.append((_js, PARENTS[_js], np.array([_ROW[int(j)] for j in _js[_in]], dtype=np.int64),
                        np.array([_ROW[int(p)] for p in PARENTS[_js]], dtype=np.int64), _in))


def _root_step(P, G, target, wt, leg_len, reach, yaw_limit) -> None:
    """Rigid body step from the active root-group effectors (in place): a weighted fit of a yaw
    rotation (clipped to ``yaw_limit`` rad) and a translation, the translation clamped so an
    active ankle target stays within ``reach * leg length`` of its hip (or within the leg's current
    extension, if longer)."""
    rg = list(ROOT_GROUP)
    w = wt[:, rg].copy()
    w[:, 0] *= 2.0  # the pelvis (the seat) counts double
    ws = w.sum(1)
    has = ws > 0
    if not has.any():
        return
    idx = np.flatnonzero(has)
    w, ws = w[idx], ws[idx]
    p, t = P[idx][:, rg], target[idx][:, rg]
    cp = (p * w[..., None]).sum(1) / ws[:, None]
    ct = (t * w[..., None]).sum(1) / ws[:, None]
    a, b = p - cp[:, None], t - ct[:, None]
    th = np.clip(fit_yaw(a, b, w), -yaw_limit, yaw_limit)
    cz, sz = np.cos(th), np.sin(th)
    res = ct - cp
    s = np.ones(len(idx))
    for (h, _, an), L in zip(_LEGS, leg_len):
        on = wt[idx, an] > 0
        if not on.any():
            continue
        # largest s in [0, 1] with |hip + s d - ankle_target| <= R (a quadratic in s), where R is
        # reach L or the leg's current hip-ankle extension if that is longer (a straight leg
        # lying on a moved bed moves with the body; it must not block the root step)
        u = P[idx[on], h] - target[idx[on], an]
        d = res[on]
        R = np.maximum(reach * L, np.linalg.norm(P[idx[on], h] - P[idx[on], an], axis=-1))
        A = (d * d).sum(-1)
        B = 2 * (u * d).sum(-1)
        C = (u * u).sum(-1) - R ** 2
        root = (-B + np.sqrt(np.maximum(B * B - 4 * A * C, 0.0))) / np.maximum(2 * A, 1e-12)
        s_leg = np.where(A + B + C <= 0, 1.0, np.clip(root, 0.0, 1.0))
        s_leg = np.where(C > 0, np.where(B < 0, 1.0, 0.0), s_leg)  # already out of reach: only approach
        s[on] = np.minimum(s[on], s_leg)
    c = cp[:, None]
    sel = slice(None) if len(idx) == len(P) else idx
    # the yaw Rz (about +z by th) mixes only the x and y rows: Rz v = (c x - s y, s x + c y, z)
    q = P[sel] - c
    shift = c + (s[:, None] * res)[:, None]
    cq, sq = cz[:, None], sz[:, None]
    x, y = q[..., 0].copy(), q[..., 1].copy()
    q[..., 0] = cq * x - sq * y
    q[..., 1] = sq * x + cq * y
    P[sel] = q + shift
    # leaves' rotations are never read while solving (solve_ik rebuilds them at the end)
    rows = (idx[:, None], _INNER) if sel is idx else (slice(None), _INNER)
    Gi = G[rows]  # (n, 19, 3, 3): rows 0 and 1 of each rotation mix
    cg, sg = cz[:, None, None], sz[:, None, None]
    g0, g1 = Gi[:, :, 0].copy(), Gi[:, :, 1]
    Gi[:, :, 0] = cg * g0 - sg * g1
    Gi[:, :, 1] = sg * g0 + cg * g1
    G[rows] = Gi


def _regularise(P, G, R0, off, reg) -> None:
    """Pull every CCD joint's local rotation toward the original by the fraction ``reg`` (geodesic),
    then redo FK from the root (in place), one depth level at a time (the joints of a level have
    their parents in the level above), in the component-major layout of ``trumans.ik.soa``.
    P (n, 24, 3), G (n, 24, 3, 3) frame-major; R0: (18, 3, 3, n) the original local rotations of
    the ``_ROTATED`` joints; off: (24, 3, n) per-frame bone offsets (both component-major). Leaves'
    rotations are not rebuilt (never read while solving; solve_ik rebuilds them at the end)."""
    Gs = soa.to_soa(G, _INNER)  # (19, 3, 3, n), rows in _INNER order
    Ps = soa.to_soa(P)  # (24, 3, n)
    L = soa.matmul(soa.transpose(Gs[_PARENT_ROW]), Gs[_ROT_ROW])  # local rotations (18, 3, 3, n)
    rv = reg * soa.axis_angle(soa.matmul(R0, soa.transpose(L)))
    ang = soa.norm(rv)
    E = soa.rotmat(rv / np.maximum(ang, 1e-12)[..., None, :], ang)
    Lr = np.empty_like(Gs)
    Lr[_ROT_ROW] = soa.matmul(E, L)
    for js, ps, rows, prow, pin in _LEVELS_SOA:
        Gp = Gs[prow]
        Ps[js] = Ps[ps] + soa.apply(Gp, off[js])
        if len(rows):
            Gs[rows] = soa.matmul(Gp[pin], Lr[rows])
    P[:] = soa.from_soa(Ps)
    G[:, _INNER] = soa.from_soa(Gs)


def solve_ik(
    joints: np.ndarray,
    global_rot: np.ndarray,
    targets: np.ndarray,
    active: np.ndarray,
    rest_local: np.ndarray | None = None,
    config: IKConfig | None = None,
    local: bool = True,
    init: tuple[np.ndarray, np.ndarray] | None = None,
) -> IKResult:
    """Move ``active`` joints to ``targets`` by CCD (see module doc).

    joints: (T, 24, 3) m world; global_rot: (T, 24, 3, 3) global rotations consistent with joints;
    targets: (T, 24, 3) m world (only entries where ``active``); active: (T, 24) bool effectors,
    or float weights in [0, 1] (> 0 = effector; a lower weight is a lower priority: its CCD steps
    and its share of the root fit are scaled by weight**2, and it is done within tol / weight**2);
    rest_local: (T, 24, 3, 3) local rotations to regularise toward (default: those of global_rot);
    local: also return local rotations (``local_rot`` is None otherwise); init: (joints, global_rot)
    of a previous solve to start from (a warm start; the regularisation still pulls toward the
    original pose).
    Returns IKResult; inactive frames are returned unchanged.
    """
    cfg = config or IKConfig()
    P0 = np.asarray(joints, dtype=np.float64)
    T = P0.shape[0]
    if P0.shape != (T, NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {P0.shape}")
    G0 = np.asarray(global_rot, dtype=np.float64)
    if G0.shape != (T, NUM_JOINTS, 3, 3):
        raise ValueError(f"global_rot must be ({T}, 24, 3, 3), got {G0.shape}")
    tgt = np.asarray(targets, dtype=np.float64)
    wt = np.clip(np.asarray(active, dtype=np.float64), 0.0, 1.0) ** 2
    act = wt > 0
    if tgt.shape != P0.shape or wt.shape != (T, NUM_JOINTS):
        raise ValueError(f"targets must be {P0.shape} and active ({T}, 24), got {tgt.shape}, {wt.shape}")
    if not np.isfinite(tgt[act]).all():
        raise ValueError("targets contain NaN/inf at active joints")
    limits = cfg.limits()
    leg_len = [np.linalg.norm(P0[:, k] - P0[:, h], axis=-1).mean() + np.linalg.norm(P0[:, a] - P0[:, k], axis=-1).mean()
               for h, k, a in _LEGS]

    if init is None:
        P, G = P0.copy(), G0.copy()
    else:
        P, G = (np.array(a, dtype=np.float64) for a in init)
        if P.shape != P0.shape or G.shape != G0.shape:
            raise ValueError(f"init must be (joints {P0.shape}, global_rot {G0.shape})")
    d0 = np.linalg.norm(P - tgt, axis=-1)
    err0 = np.where(act, d0, 0.0).max(1)
    todo = np.flatnonzero(np.where(act, d0 * wt, 0.0).max(1) > cfg.tol)  # frames at their targets need no work
    prev = err0.copy()
    # the working set: frames still to solve, kept compact; frames leave it when done
    Pt, Gt, tt, at, wtt = P[todo], G[todo], tgt[todo], act[todo], wt[todo]
    prevt = prev[todo]
    # the pose regularised toward, only for the working set and only while some iteration regularises
    n_reg = sum(1 for it in range(1, cfg.iterations) if cfg.reg * max(0.0, 1.0 - it / max(cfg.reg_iters, 1)) > 0)
    R0t = offt = None
    if n_reg:
        R0t = global_to_local(G0[todo]) if rest_local is None else np.asarray(rest_local, dtype=np.float64)[todo]
        R0t = soa.to_soa(R0t, _ROTATED)  # component-major (18, 3, 3, n), as _regularise works
        # per-frame bone offsets in the parent's frame (exact for this input), (24, 3, n)
        offt = soa.to_soa(bone_offsets(P0[todo], G0[todo]))
    for it in range(cfg.iterations):
        if len(todo) == 0:
            break
        reg = cfg.reg * max(0.0, 1.0 - it / max(cfg.reg_iters, 1))
        if reg > 0 and it > 0:
            _regularise(Pt, Gt, R0t, offt, reg)
            n_reg -= 1
            if n_reg == 0:
                R0t = offt = None
        _root_step(Pt, Gt, tt, wtt, leg_len, cfg.leg_reach, limits[0])
        for e in np.flatnonzero(at.any(0)):
            chain = CHAINS[int(e)]
            if not chain:
                continue
            need = at[:, e].copy()
            on = np.flatnonzero(need)
            need[on] = _norm(Pt[on, e] - tt[on, e]) > cfg.tol
            if not need.any():
                continue
            # an ancestor that is itself an effector on all these frames pins the chain there
            # (rotating above it would pull it off its target): the foot joint turns only the
            # ankle, an index finger only the wrist
            for i, a in enumerate(chain):
                if at[need, a].all():
                    chain = chain[:i + 1]
                    break
            # limbs may bend the spine only as far as no bed/back contact holds the upper torso
            sg = np.ones(len(Pt)) if e in ROOT_GROUP else 1.0 - wtt[:, _UPPER].max(1)
            if need.all():
                sweep(Pt, Gt, tt[:, e], int(e), chain, limits, wtt[:, e], sg)
            else:
                fr = np.flatnonzero(need)
                sweep(Pt, Gt, tt[fr, e], int(e), chain, limits, wtt[fr, e], sg[fr], frames=fr)
        d = _norm(Pt - tt)
        err = np.where(at, d, 0.0).max(1)
        # a frame is done when every effector is within tol weighted by its priority (a fading
        # effector of weight w is pulled only w-strongly, so tol / w is as close as it is asked to
        # be), or when it stalled after the regularised iterations
        keep = (np.where(at, d * wtt, 0.0).max(1) > cfg.tol) & ((reg > 0) | (err < prevt - 1e-6))
        prevt = err
        if not keep.all():
            done = ~keep
            P[todo[done]], G[todo[done]] = Pt[done], Gt[done]
            todo = todo[keep]
            Pt, Gt, tt, at, wtt, prevt = (a[keep] for a in (Pt, Gt, tt, at, wtt, prevt))
            if R0t is not None:
                R0t, offt = R0t[..., keep], offt[..., keep]
    P[todo], G[todo] = Pt, Gt
    for j in _LEAVES:  # leaves were skipped while solving; their local rotations are unchanged
        p = PARENTS[j]
        G[:, j] = G[:, p] @ (np.swapaxes(G0[:, p], -1, -2) @ G0[:, j])
    err = np.where(act, np.linalg.norm(P - tgt, axis=-1), 0.0)
    return IKResult(joints=P, global_rot=G, local_rot=global_to_local(G) if local else None, error=err,
                    unreachable=act & (err > cfg.unreachable_tol))

