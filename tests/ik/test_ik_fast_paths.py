"""The CCD solver's vectorised steps (trumans.ik.ccd, trumans.ik.sweep) against the straightforward forms they replaced (issue 38).

The references below are the solver's earlier code (``rodrigues`` rotations, per-joint FK, whole
subtree rotation updates); the fast steps must give the same poses to float rounding. Leaves'
global rotations are not maintained while solving (``solve_ik`` rebuilds them), so the step checks
compare positions and the non-leaf rotations."""
import numpy as np
import pytest

import trumans.ik.ccd as ccd
from trumans.rotations import axis_angle_to_matrix, fit_yaw, matrix_to_axis_angle, yaw_matrix
import trumans.ik.sweep as sw
from trumans.ik import soa
from trumans.skeleton import HINGE_AXES, NUM_JOINTS, PARENTS, TORSO, bone_offsets, forward_kinematics, global_to_local, \
    rest_offsets

INNER = ccd._INNER


# --- references: the solver's steps before issue 38 -------------------------------------------------

def _ref_aim(a, b, limit):
    cross = np.cross(a, b)
    sn = np.linalg.norm(cross, axis=-1)
    ang = np.minimum(np.arctan2(sn, (a * b).sum(-1)), limit)
    ok = (sn > 1e-12) & (np.linalg.norm(a, axis=-1) > 1e-6) & (np.linalg.norm(b, axis=-1) > 1e-6)
    return np.where(ok[:, None], cross / np.maximum(sn, 1e-12)[:, None] * ang[:, None], 0.0)


def _ref_bend(pu, pm, pe, target, hinge, limit):
    a, b = pu - pm, pe - pm
    la, lb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    D = np.clip(np.linalg.norm(target - pu, axis=-1), np.abs(la - lb) + 1e-9, la + lb - 1e-9)
    phi = np.arccos(np.clip((a * b).sum(-1) / np.maximum(la * lb, 1e-12), -1.0, 1.0))
    phi2 = np.arccos(np.clip((la**2 + lb**2 - D**2) / np.maximum(2 * la * lb, 1e-12), -1.0, 1.0))
    n = np.cross(a, b)
    nn = np.linalg.norm(n, axis=-1)
    hinge_u = hinge / np.maximum(np.linalg.norm(hinge, axis=-1), 1e-12)[:, None]
    axis = np.where((nn > 1e-6)[:, None], n / np.maximum(nn, 1e-12)[:, None], -hinge_u)
    return axis * np.clip(phi2 - phi, -limit, limit)[:, None]


def _ref_sweep(P, G, target, e, chain, limits, gain, spine_gain):
    n = P.shape[0]
    pe = P[:, e].copy()
    ops = []
    for j in chain:
        pj = P[:, j]
        g = gain * spine_gain if j in sw._SPINE else gain
        if j in HINGE_AXES and len(ops) == 0 and len(chain) > 1:
            rv = _ref_bend(P[:, chain[1]], pj, pe, target, G[:, j] @ HINGE_AXES[j], limits[j])
        else:
            rv = _ref_aim(pe - pj, target - pj, limits[j])
        dA = axis_angle_to_matrix(g[:, None] * rv)
        pe = np.einsum("nij,nj->ni", dA, pe - pj) + pj
        ops.append((j, dA))
    Rc = np.broadcast_to(np.eye(3), (n, 3, 3))
    tc = np.zeros((n, 3))
    for m in range(len(ops) - 1, -1, -1):
        j, dR = ops[m]
        pj = P[:, j]
        tc = np.einsum("nij,nj->ni", Rc, pj - np.einsum("nij,nj->ni", dR, pj)) + tc
        Rc = Rc @ dR
        sub = sw.ring(j, ops[m - 1][0] if m > 0 else -1)
        P[:, sub] = np.einsum("nij,nkj->nki", Rc, P[:, sub]) + tc[:, None]
        G[:, sub] = Rc[:, None] @ G[:, sub]


def _ref_regularise(P, G, R0, off, reg):
    L = global_to_local(G)
    rv = matrix_to_axis_angle(R0[:, ccd._ROTATED] @ np.swapaxes(L[:, ccd._ROTATED], -1, -2))
    L[:, ccd._ROTATED] = axis_angle_to_matrix(reg * rv) @ L[:, ccd._ROTATED]
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        G[:, j] = G[:, p] @ L[:, j]
        P[:, j] = P[:, p] + np.einsum("nij,nj->ni", G[:, p], off[:, j])


def _ref_regularise_soa_args(P, G, R0s, offs, reg):
    """``_ref_regularise`` called with the solver's component-major R0 (18 rows) and offsets."""
    R0 = np.broadcast_to(np.eye(3), G.shape).copy()
    R0[:, ccd._ROTATED] = soa.from_soa(R0s)
    _ref_regularise(P, G, R0, soa.from_soa(offs), reg)


def _ref_root_step(P, G, target, wt, leg_len, reach, yaw_limit):
    rg = list(TORSO)
    w = wt[:, rg].copy()
    w[:, 0] *= 2.0
    ws = w.sum(1)
    has = ws > 0
    if not has.any():
        return
    idx = np.flatnonzero(has)
    w, ws = w[idx], ws[idx]
    p, t = P[idx][:, rg], target[idx][:, rg]
    cp = (p * w[..., None]).sum(1) / ws[:, None]
    ct = (t * w[..., None]).sum(1) / ws[:, None]
    th = np.clip(fit_yaw(p - cp[:, None], t - ct[:, None], w), -yaw_limit, yaw_limit)
    Rz = yaw_matrix(th)
    res = ct - cp
    s = np.ones(len(idx))
    for (h, _, an), L in zip(ccd._LEGS, leg_len):
        on = wt[idx, an] > 0
        if not on.any():
            continue
        u = P[idx[on], h] - target[idx[on], an]
        d = res[on]
        R = np.maximum(reach * L, np.linalg.norm(P[idx[on], h] - P[idx[on], an], axis=-1))
        A = (d * d).sum(-1)
        B = 2 * (u * d).sum(-1)
        C = (u * u).sum(-1) - R ** 2
        root = (-B + np.sqrt(np.maximum(B * B - 4 * A * C, 0.0))) / np.maximum(2 * A, 1e-12)
        s_leg = np.where(A + B + C <= 0, 1.0, np.clip(root, 0.0, 1.0))
        s_leg = np.where(C > 0, np.where(B < 0, 1.0, 0.0), s_leg)
        s[on] = np.minimum(s[on], s_leg)
    c = cp[:, None]
    P[idx] = np.einsum("nij,nkj->nki", Rz, P[idx] - c) + c + (s[:, None] * res)[:, None]
    G[idx] = Rz[:, None] @ G[idx]


def _ref_sweep_on(P, G, target, e, chain, limits, gain, spine_gain, frames):
    if frames is None:
        return _ref_sweep(P, G, target, e, chain, limits, gain, spine_gain)
    Pe, Ge = P[frames], G[frames]
    _ref_sweep(Pe, Ge, target, e, chain, limits, gain, spine_gain)
    P[frames], G[frames] = Pe, Ge


# --- cases ---------------------------------------------------------------------------------------------

def _random_pose(n: int, seed: int, spread: float = 0.4):
    rng = np.random.default_rng(seed)
    rot = axis_angle_to_matrix(rng.normal(0, spread, (n, NUM_JOINTS, 3)))
    P, G = forward_kinematics(rot, rng.normal(0, 0.5, (n, 3)), rest_offsets())
    return P, G, rng


def test_soa_arithmetic_matches_frame_major():
    rng = np.random.default_rng(2)
    A, B = axis_angle_to_matrix(rng.normal(size=(4, 50, 3))), axis_angle_to_matrix(rng.normal(size=(4, 50, 3)))
    v = rng.normal(size=(4, 50, 3))
    As, Bs, vs = (np.moveaxis(x, 1, -1) for x in (A, B, v))  # (4, ..., 50)
    assert np.abs(np.moveaxis(soa.matmul(As, Bs), -1, 1) - A @ B).max() < 1e-14
    assert np.abs(np.moveaxis(soa.matmul(As, soa.transpose(Bs)), -1, 1) - A @ np.swapaxes(B, -1, -2)).max() < 1e-14
    assert np.abs(np.moveaxis(soa.apply(As, vs), -1, 1) - np.einsum("knij,knj->kni", A, v)).max() < 1e-14
    assert np.abs(np.moveaxis(soa.cross(vs, vs[::-1]), -1, 1) - np.cross(v, v[::-1])).max() < 1e-14
    # rotation vectors, including the identity and half turns (the scipy route)
    rv = rng.normal(size=(4, 50, 3))
    rv[0, :3] = 0.0
    rv[1, :4] *= ((np.pi - np.array([0.0, 1e-5, 5e-4, 2e-3])) / np.linalg.norm(rv[1, :4], axis=-1))[:, None]
    R = axis_angle_to_matrix(rv)
    got = np.moveaxis(soa.axis_angle(np.moveaxis(R, 1, -1)), -1, 1)
    assert np.abs(got - matrix_to_axis_angle(R)).max() < 1e-12
    assert np.abs(axis_angle_to_matrix(got) - R).max() < 1e-9
    x = rng.normal(size=(7, 24, 3, 3))
    assert np.array_equal(soa.from_soa(soa.to_soa(x)), x)


def test_rotmat_is_rodrigues():
    rng = np.random.default_rng(1)
    axis = rng.normal(size=(500, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    ang = np.concatenate([rng.uniform(-np.pi, np.pi, 497), [0.0, np.pi, -1e-9]])
    R = np.moveaxis(soa.rotmat(axis.T.copy(), ang), -1, 0)  # (3, 3, n) -> (n, 3, 3)
    assert np.abs(R - axis_angle_to_matrix(axis * ang[:, None])).max() < 1e-14
    assert np.array_equal(soa.rotmat(axis[:1].T.copy(), np.zeros(1))[..., 0], np.eye(3))


@pytest.mark.parametrize("e", [20, 21, 18, 22, 7, 10, 15, 4])
def test_sweep_matches_reference(e):
    n = 97
    P, G, rng = _random_pose(n, e)
    target = P[:, e] + rng.normal(0, 0.1, (n, 3))
    target[:3] = P[:3, e]  # already on target: a zero step
    limits = ccd.IKConfig().limits()
    gain, sg = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    gain[5] = 0.0
    chain = ccd.CHAINS[e]
    P1, G1, P2, G2 = P.copy(), G.copy(), P.copy(), G.copy()
    _ref_sweep(P1, G1, target, e, chain, limits, gain, sg)
    sw.sweep(P2, G2, target, e, chain, limits, gain, sg)
    assert np.abs(P1 - P2).max() < 1e-10
    assert np.abs(G1[:, INNER] - G2[:, INNER]).max() < 1e-10
    assert np.abs(P1 - P).max() > 1e-3  # the sweep did move the chain
    # on a subset of the frames (the solver's usual call): those frames as above, the others untouched
    fr = np.arange(0, n, 3)
    P3, G3 = P.copy(), G.copy()
    sw.sweep(P3, G3, target[fr], e, chain, limits, gain[fr], sg[fr], frames=fr)
    assert np.abs(P3[fr] - P2[fr]).max() < 1e-12 and np.abs(G3[fr][:, INNER] - G2[fr][:, INNER]).max() < 1e-12
    rest = np.setdiff1d(np.arange(n), fr)
    assert np.array_equal(P3[rest], P[rest]) and np.array_equal(G3[rest], G[rest])


def test_regularise_matches_reference():
    n = 64
    P, G, rng = _random_pose(n, 3)
    P0, G0, _ = _random_pose(n, 4, 0.2)
    R0, off = global_to_local(G0), bone_offsets(P0, G0)
    P1, G1, P2, G2 = P.copy(), G.copy(), P.copy(), G.copy()
    _ref_regularise(P1, G1, R0, off, 0.25)
    ccd._regularise(P2, G2, soa.to_soa(R0, ccd._ROTATED), soa.to_soa(off), 0.25)
    assert np.abs(P1 - P2).max() < 1e-10
    assert np.abs(G1[:, INNER] - G2[:, INNER]).max() < 1e-10


@pytest.mark.parametrize("every_frame", [True, False])
def test_root_step_matches_reference(every_frame):
    n = 50
    P, G, rng = _random_pose(n, 5)
    target = P + rng.normal(0, 0.05, P.shape)
    wt = np.zeros((n, NUM_JOINTS))
    wt[:, [0, 3, 7, 8]] = rng.uniform(0.2, 1.0, (n, 4))
    if not every_frame:
        wt[::3, :3] = 0.0
        wt[::3, 3] = 0.0
    leg_len = [0.8, 0.8]
    P1, G1, P2, G2 = P.copy(), G.copy(), P.copy(), G.copy()
    _ref_root_step(P1, G1, target, wt, leg_len, 0.97, 0.1)
    ccd._root_step(P2, G2, target, wt, leg_len, 0.97, 0.1)
    assert np.abs(P1 - P2).max() < 1e-10
    assert np.abs(G1[:, INNER] - G2[:, INNER]).max() < 1e-10


def test_solve_ik_matches_reference_steps(monkeypatch):
    """The whole solve, fast steps against the reference steps: same joints and rotations."""
    n = 80
    P, G, rng = _random_pose(n, 6, 0.3)
    tgt = P.copy()
    act = np.zeros((n, NUM_JOINTS))
    for j in (0, 7, 10, 20, 21, 22):
        tgt[:, j] += rng.normal(0, 0.03, (n, 3))
        act[:, j] = rng.uniform(0.3, 1.0, n)
    act[::4, 20] = 0.0
    fast = ccd.solve_ik(P, G, tgt, act)
    monkeypatch.setattr(ccd, "sweep", lambda P, G, t, e, c, lim, g, sg, frames=None: _ref_sweep_on(P, G, t, e, c, lim, g, sg, frames))
    monkeypatch.setattr(ccd, "_regularise", _ref_regularise_soa_args)
    monkeypatch.setattr(ccd, "_root_step", _ref_root_step)
    ref = ccd.solve_ik(P, G, tgt, act)
    assert np.abs(fast.joints - ref.joints).max() < 1e-9
    assert np.abs(fast.global_rot - ref.global_rot).max() < 1e-9
    assert np.abs(fast.local_rot - ref.local_rot).max() < 1e-9
    assert np.array_equal(fast.unreachable, ref.unreachable)
