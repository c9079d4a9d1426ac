"""Recompute a motion so that its contacts follow changed objects (TRUMANS §3.3, appendix B.5).

Two CCD passes: (1) every contact joint gets its own faded, blended offset target (A2-A5) in its
window; the IK moves other joints too (the *drift*). (2) toward the window edges the targets hand
over to the drift found at the first free frame (A5-A6, ``offsets.handover``) and the IK is solved
again, so each joint passes smoothly from its contact offset to wherever the body takes it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from trumans.skeleton import NUM_JOINTS

from trumans.ik.ccd import IKConfig, solve_ik
from trumans.augment.offsets import ContactInterval, Tracks, blend_tracks, contact_tracks, handover, smooth_ratio

__all__ = ["RetargetResult", "retarget", "retarget_many"]


@dataclass
class RetargetResult:
    """joints (T, 24, 3) m; local_rot / global_rot (T, 24, 3, 3); targets (T, 24, 3) final IK
    targets l'; window (T, 24) bool joints with targets; error (T, 24) m joint-to-target distance;
    unreachable (T, 24) bool; contact (T, 24) bool frames inside contact intervals;
    contact_target (T, 24, 3) the exact A1 targets l + (v'_m - v_m) per contact frame;
    smooth (T-1, 24) the A13 ratio of the targets; tracks: every offset track used."""

    joints: np.ndarray
    local_rot: np.ndarray
    global_rot: np.ndarray
    targets: np.ndarray
    window: np.ndarray
    error: np.ndarray
    unreachable: np.ndarray
    contact: np.ndarray
    contact_target: np.ndarray
    smooth: np.ndarray
    tracks: Tracks


def retarget(
    joints: np.ndarray,
    global_rot: np.ndarray,
    intervals: list[ContactInterval],
    W: float = 30.0,
    config: IKConfig | None = None,
) -> RetargetResult:
    """joints: (T, 24, 3) m world; global_rot: (T, 24, 3, 3) consistent with joints; intervals:
    the contacts (with their offsets; zero offset = hold the joint); W: fade window in frames."""
    return retarget_many([(joints, global_rot, intervals, W)], config)[0]


def retarget_many(items: list[tuple[np.ndarray, np.ndarray, list[ContactInterval], float]],
                  config: IKConfig | None = None) -> list[RetargetResult]:
    """``retarget`` for many clips at once: [(joints, global_rot, intervals, W)]. The IK is per
    frame, so all clips' frames are solved in one batch (the vectorisation pays off on long
    batches; Python overhead per CCD step is paid once)."""
    if not items:
        return []
    prep = []
    for joints, global_rot, intervals, W in items:
        P = np.asarray(joints, dtype=np.float64)
        T = P.shape[0]
        if P.ndim != 3 or P.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"joints must be (T, 24, 3), got {P.shape}")
        for iv in intervals:
            if iv.end > T:
                raise ValueError(f"contact interval [{iv.start}, {iv.end}) of joint {iv.joint} exceeds {T} frames")
        own = contact_tracks(intervals, T, W)
        off1, win = blend_tracks(own, T)
        prep.append((P, np.asarray(global_rot, np.float64), intervals, W, own, off1, win, own.strength()))
    cut = np.cumsum([0] + [len(p[0]) for p in prep])
    Pa = np.concatenate([p[0] for p in prep])
    Ga = np.concatenate([p[1] for p in prep])
    Sa = np.concatenate([p[7] for p in prep])
    r1 = solve_ik(Pa, Ga, Pa + np.concatenate([p[5] for p in prep]), Sa, config=config, local=False)
    off2, dns = [], []
    for i, p in enumerate(prep):
        o, dn = handover(p[5], p[7], r1.joints[cut[i]:cut[i + 1]] - p[0])
        off2.append(o)
        dns.append(dn)
    tgt_all = Pa + np.concatenate(off2)
    # pass 2 warm-starts from the regularised pass-1 pose and only corrects the hand-over frames
    cfg2 = replace(config or IKConfig(), reg=0.0)
    r2 = solve_ik(Pa, Ga, tgt_all, Sa, config=cfg2, init=(r1.joints, r1.global_rot))

    out = []
    for i, (P, _, intervals, W, own, _, win, _) in enumerate(prep):
        sl = slice(cut[i], cut[i + 1])
        T = len(P)
        tgt = tgt_all[sl]
        contact = np.zeros((T, NUM_JOINTS), bool)
        ctgt = P.copy()
        for iv in intervals:
            contact[iv.start:iv.end, iv.joint] = True
            fo = iv.offset if iv.frame_offset is None else np.asarray(iv.frame_offset).reshape(-1, 3)
            ctgt[iv.start:iv.end, iv.joint] = P[iv.start:iv.end, iv.joint] + fo
        out.append(RetargetResult(
            joints=r2.joints[sl], local_rot=r2.local_rot[sl], global_rot=r2.global_rot[sl], targets=tgt, window=win,
            error=r2.error[sl], unreachable=r2.unreachable[sl], contact=contact, contact_target=ctgt,
            smooth=smooth_ratio(P, np.where(win[..., None], tgt, P), own, W, mask=win, extra=dns[i]), tracks=own,
        ))
    return out
