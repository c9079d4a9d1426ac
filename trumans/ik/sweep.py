"""One CCD sweep (Kenwright 2012) for one effector, on component-major arrays (``trumans.ik.ccd``).

The solver keeps frame-major state, joints ``P (n, 24, 3)`` m and global rotations ``G (n, 24, 3,
3)``. A sweep touches only the subtree of its chain's top joint, so it gathers that subtree's
joints (and the frames it works on) into component-major copies, ``(J, 3, n)`` and ``(J', 3, 3,
n)``: every 3-vector and 3x3 product is then a few whole-row multiply-adds over the frames
(``trumans.ik.soa``; issue 38: the sweeps took two thirds of ``trumans eval augment``). The arithmetic is the same as the frame-major form's, to float rounding
(``tests/ik/test_ik_fast_paths.py`` checks it against that form).

Conventions: the component-major layout of ``trumans.ik.soa``; angles are radians; rotations act
on column vectors (``v' = R v``) about a pivot.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.skeleton import HINGE_AXES, NUM_JOINTS, PARENTS, SPINE, SUBTREE

from trumans.ik.soa import apply as _apply, cross as _cross, matmul as _matmul, norm as _norm, rotmat as _rotmat

__all__ = ["LEAVES", "ring", "ring_inner", "sweep"]

_SPINE = frozenset(SPINE)
# Leaves: their rotations are never read while solving (their local rotations never change), so
# the solver rebuilds them from their parents once at the end and the sweeps skip them.
LEAVES = frozenset(j for j in range(NUM_JOINTS) if not (PARENTS == j).any())
_RING: dict[tuple[int, int], np.ndarray] = {}
_RING_INNER: dict[tuple[int, int], np.ndarray] = {}


def ring(j: int, inner: int) -> np.ndarray:
    """Joints of subtree(j) not in subtree(inner) (inner = -1: the whole subtree), sorted, cached."""
    key = (j, inner)
    if key not in _RING:
        _RING[key] = SUBTREE[j] if inner < 0 else np.setdiff1d(SUBTREE[j], SUBTREE[inner], assume_unique=True)
    return _RING[key]


def ring_inner(j: int, inner: int) -> np.ndarray:
    """``ring`` without the leaves (``LEAVES``)."""
    key = (j, inner)
    if key not in _RING_INNER:
        _RING_INNER[key] = np.array([k for k in ring(j, inner) if k not in LEAVES], dtype=np.int64)
    return _RING_INNER[key]


@dataclass(frozen=True)
class _Link:
    """One chain joint in the sweep's local numbering: its row in the joints, its row in the
    rotations, its skeleton index, whether the spine gain applies, its hinge axis (local, or None),
    and the rows (joints, rotations) of its ring."""

    p: int
    g: int
    joint: int
    spine: bool
    hinge: np.ndarray | None
    ring_p: np.ndarray | slice
    ring_g: np.ndarray | slice


@dataclass(frozen=True)
class _Plan:
    """A chain's gather lists: the subtree's joints (skeleton indices), its non-leaf joints, the
    effector's row and the links, distal first."""

    joints: np.ndarray
    rotated: np.ndarray
    effector: int
    links: tuple[_Link, ...]


_PLANS: dict[tuple[int, tuple[int, ...]], _Plan] = {}


def _rows(sel: np.ndarray, where: dict[int, int]) -> np.ndarray | slice:
    rows = np.array([where[int(k)] for k in sel], dtype=np.int64)
    if len(rows) and (np.diff(rows) == 1).all():
        return slice(int(rows[0]), int(rows[-1]) + 1)  # a view, not a gather
    return rows


def _plan(e: int, chain: tuple[int, ...]) -> _Plan:
    key = (e, chain)
    if key not in _PLANS:
        joints = SUBTREE[chain[-1]]
        rotated = np.array([k for k in joints if k not in LEAVES], dtype=np.int64)
        pw = {int(k): i for i, k in enumerate(joints)}
        gw = {int(k): i for i, k in enumerate(rotated)}
        links = []
        for m, j in enumerate(chain):
            inner = chain[m - 1] if m > 0 else -1
            links.append(_Link(p=pw[j], g=gw[j], joint=j, spine=j in _SPINE,
                               hinge=HINGE_AXES[j] if (j in HINGE_AXES and m == 0 and len(chain) > 1) else None,
                               ring_p=_rows(ring(j, inner), pw), ring_g=_rows(ring_inner(j, inner), gw)))
        _PLANS[key] = _Plan(joints, rotated, pw[e], tuple(links))
    return _PLANS[key]


def _aim(a: np.ndarray, b: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """The rotation turning direction a (3, n) toward b (3, n): unit axes (3, n) and angles (n,)
    clipped to ``limit`` rad (0 where a, b or their cross product vanish)."""
    cross = _cross(a, b)
    sn = _norm(cross)
    ang = np.minimum(np.arctan2(sn, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]), limit)
    ok = (sn > 1e-12) & (_norm(a) > 1e-6) & (_norm(b) > 1e-6)
    return cross / np.maximum(sn, 1e-12), np.where(ok, ang, 0.0)


def _bend(pu: np.ndarray, pm: np.ndarray, pe: np.ndarray, target: np.ndarray, hinge: np.ndarray,
          limit: float) -> tuple[np.ndarray, np.ndarray]:
    """The rotation at a middle joint (knee / elbow) that sets the upper-joint-to-effector distance
    to the upper-joint-to-target distance (law of cosines), about the bend-plane normal (the hinge
    axis ``hinge`` (3, n) world when the limb is straight), clipped to ``limit`` rad: unit axes
    (3, n) and signed angles (n,). Plain CCD crawls when a two-bone limb is almost straight; this
    step does not."""
    a, b = pu - pm, pe - pm
    la, lb = _norm(a), _norm(b)
    D = np.clip(_norm(target - pu), np.abs(la - lb) + 1e-9, la + lb - 1e-9)
    phi = np.arccos(np.clip((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / np.maximum(la * lb, 1e-12), -1.0, 1.0))
    phi2 = np.arccos(np.clip((la**2 + lb**2 - D**2) / np.maximum(2 * la * lb, 1e-12), -1.0, 1.0))
    n = _cross(a, b)
    nn = _norm(n)
    hinge_u = hinge / np.maximum(_norm(hinge), 1e-12)
    # straight limb: bend so the effector moves the way the hinge flexes (sign of a x b along the hinge)
    axis = np.where(nn > 1e-6, n / np.maximum(nn, 1e-12), -hinge_u)
    return axis, np.clip(phi2 - phi, -limit, limit)


def _sweep_rows(P: np.ndarray, G: np.ndarray, target: np.ndarray, plan: _Plan, limits: np.ndarray,
                gain: np.ndarray, spine_gain: np.ndarray | float) -> None:
    """The sweep on the gathered subtree: P (J, 3, n), G (J', 3, 3, n), target (3, n), in place."""
    links = plan.links
    pe = P[plan.effector]
    ops = []
    for m, ln in enumerate(links):
        pj = P[ln.p]
        g = gain * spine_gain if ln.spine else gain
        if ln.hinge is not None:
            h = G[ln.g, :, 0] * ln.hinge[0] + G[ln.g, :, 1] * ln.hinge[1] + G[ln.g, :, 2] * ln.hinge[2]
            axis, ang = _bend(P[links[1].p], pj, pe, target, h, limits[ln.joint])
        else:
            axis, ang = _aim(pe - pj, target - pj, limits[ln.joint])
        dA = _rotmat(axis, g * ang)
        pe = _apply(dA, pe - pj) + pj
        ops.append(dA)
    # ops at distal joints never move proximal ones, so every op used the sweep-start pivots; now
    # compose from the proximal end, C_m = C_{m+1} o T_m, and move each ring once
    Rc = tc = None
    for m in range(len(ops) - 1, -1, -1):
        ln, dR = links[m], ops[m]
        pj = P[ln.p]
        if Rc is None:  # the most proximal op: C = T
            tc, Rc = pj - _apply(dR, pj), dR
        else:
            tc = _apply(Rc, pj - _apply(dR, pj)) + tc
            Rc = _matmul(Rc, dR)
        P[ln.ring_p] = _apply(Rc, P[ln.ring_p]) + tc
        if not isinstance(ln.ring_g, slice) and len(ln.ring_g) == 0:
            continue
        G[ln.ring_g] = _matmul(Rc, G[ln.ring_g])


def sweep(P: np.ndarray, G: np.ndarray, target: np.ndarray, e: int, chain: tuple[int, ...], limits: np.ndarray,
          gain: np.ndarray, spine_gain: np.ndarray | float, frames: np.ndarray | None = None) -> None:
    """One CCD pass (distal -> proximal) for effector ``e`` along ``chain`` (its ancestors whose
    rotations move, distal first), on ``frames`` of P (N, 24, 3) / G (N, 24, 3, 3) (all frames
    when None), in place. target: (n, 3) m, the effector's target on those frames; limits: (24,)
    per-joint rotation clip, rad; gain (n,) and spine_gain (n,) or scalar scale each step's angle
    (the spine's by gain * spine_gain). Leaves' rotations are not updated (``LEAVES``)."""
    plan = _plan(int(e), tuple(int(j) for j in chain))
    # whole frames first (contiguous rows), then the subtree's joints: several times faster than
    # one two-index gather of small (3,) / (3, 3) items
    Pf, Gf = (P, G) if frames is None else (P[frames], G[frames])
    Pk = np.take(Pf, plan.joints, axis=1).transpose(1, 2, 0).copy()  # (J, 3, n)
    Gk = np.take(Gf, plan.rotated, axis=1).transpose(1, 2, 3, 0).copy()  # (J', 3, 3, n)
    _sweep_rows(Pk, Gk, np.ascontiguousarray(np.asarray(target).T), plan, limits, np.asarray(gain),
                spine_gain if np.isscalar(spine_gain) else np.asarray(spine_gain))
    Pf[:, plan.joints] = Pk.transpose(2, 0, 1)
    Gf[:, plan.rotated] = Gk.transpose(3, 0, 1, 2)
    if frames is not None:
        P[frames], G[frames] = Pf, Gf
