"""Figures of a sampled motion (the sampling issue's synthesis benchmark), pure functions of arrays.

All inputs are world joints (T, 24, 3) float, metres, z-up, at ``fps``. Definitions:
- ``goal_err_cm``: at each episode's last frame, the hip midpoint's floor distance to the pelvis
  subgoal (not the pinned pelvis itself), or the hand joint's 3D distance to a hand goal;
- ``penetration_*_cm``: body penetration into the scene (``trumans.contacts.rule`` joint radii,
  the same definition as the dataset figures), mean over (frame, joint) pairs that penetrate,
  and max, floor excluded (that is ``floor_err_cm``);
- ``floor_err_cm``: mean depth of the lowest foot joint under its resting height above the floor
  (feet under the floor), ``floor_err_max_cm`` its max;
- ``contact``: Table 2's contact score (DIMOS protocol): share of frames whose lowest foot joint
  is within 5 cm of its resting height and moves slower than 10 cm/s (a foot supports the body);
- ``foot_skate_near_floor_cm``: mean horizontal slide per foot contact, a contact being a foot joint within
  5 cm of its resting height (``trumans.eval.metrics.foot_skate_cm``);
- ``pelvis_speed_max_ms``: the pelvis's fastest horizontal speed between two frames, m/s (a one-frame
  jump of the whole body);
- ``bone_length_cv``: per bone std / mean over time, the median over bones;
- ``transition_jerk_ratio``: mean joint jerk (third difference) around the episode seams over
  the mean jerk inside episodes;
- ``seam_jerk_peak_ratio``: the joint jerk folded on the episode cycle (``cycle`` = new frames per
  episode, phase 0 = an episode's first new frame): the mean jerk of the loudest phase over the
  median phase (``seam_jerk_peak_phase`` says which phase peaks). Unlike ``transition_jerk_ratio``
  it does not average a one-frame hitch with its quiet neighbours. ``real_seam_jerk_peak_ratio``
  (and ``_p10`` / ``_p90``) is the same fold on the held-out real clips of the mocap corpus
  (``real_seam_reference``): motion without seams, whose peak phase is only sampling noise.
"""
from __future__ import annotations

import numpy as np

from functools import lru_cache

from trumans.contacts.rule import ContactScene, joint_contacts
from trumans.eval.metrics import foot_skate_cm
from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT, JOINT_INDEX, PARENTS

__all__ = ["goal_errors_cm", "penetration_cm", "floor_err_cm", "contact_score", "bone_length_cv",
           "transition_jerk_ratio", "folded_jerk", "seam_jerk_peak_ratio", "seam_piece_ratios", "real_seam_reference",
           "foot_skate_near_floor_cm", "seat_height_errors_cm", "pelvis_speed_max", "motion_figures"]

_FEET = list(FOOT_JOINTS)
_HIPS = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]


def goal_errors_cm(joints: np.ndarray, goals: list[tuple[int, str, np.ndarray]]) -> np.ndarray:
    """goals: (frame, joint name, point (2,) or (3,) world) -> (n,) errors, cm (see module doc)."""
    out = []
    for f, joint, p in goals:
        p = np.asarray(p, dtype=np.float64)
        if joint == "pelvis":
            hip = joints[f, _HIPS, :2].mean(0)
            out.append(np.linalg.norm(hip - p[:2]))
        else:
            out.append(np.linalg.norm(joints[f, JOINT_INDEX[joint]] - p))
    return np.asarray(out) * 100.0


def penetration_cm(joints: np.ndarray, contact_scene: ContactScene) -> tuple[float, float]:
    """(mean over penetrating (frame, joint) pairs, max), cm, floor excluded."""
    res = joint_contacts(joints, contact_scene, floor=False)
    pen = np.asarray(res.penetration, dtype=np.float64)
    pos = pen[pen > 1e-6]
    return (float(pos.mean() * 100.0) if pos.size else 0.0), (float(pen.max() * 100.0) if pen.size else 0.0)


def _lowest_foot(joints: np.ndarray) -> np.ndarray:
    """(T,) height of the lowest foot joint above its resting height, m."""
    return (joints[:, _FEET, 2] - FOOT_REST_HEIGHT).min(axis=1)


def floor_err_cm(joints: np.ndarray) -> tuple[float, float]:
    """(mean, max) depth of the feet under the floor, cm."""
    under = np.maximum(0.0, -_lowest_foot(joints))
    return float(under.mean() * 100.0), float(under.max() * 100.0)


def pelvis_speed_max(joints: np.ndarray, fps: float) -> float:
    """The pelvis's fastest horizontal speed between two frames, m/s: a one-frame jump of the whole
    body shows here (people walk at 1-2 m/s; a cleanup that throws the body 30 cm in a frame at 10 fps
    gives 3 m/s)."""
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (24, 3) or not fps > 0:
        raise ValueError(f"need joints (T, 24, 3) and fps > 0, got {J.shape} and {fps}")
    if len(J) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(J[:, JOINT_INDEX["pelvis"], :2], axis=0), axis=-1).max() * fps)


def contact_score(joints: np.ndarray, fps: float, height: float = 0.05, speed: float = 0.10) -> float:
    """Share of frames where a foot supports the body (see module doc)."""
    h = joints[:, _FEET, 2] - FOOT_REST_HEIGHT  # (T, 4)
    v = np.zeros_like(h)
    v[1:] = np.linalg.norm(np.diff(joints[:, _FEET, :2], axis=0), axis=-1) * fps
    ok = (np.abs(h) < height) & (v < speed)
    return float(ok.any(axis=1).mean())


def foot_skate_near_floor_cm(joints: np.ndarray) -> float:
    """joints (T, 24, 3) m -> mean horizontal slide (cm) per foot contact, a contact being a foot joint
    (ankle or toe base) within 5 cm of its resting height (``FOOT_REST_HEIGHT``)."""
    feet = joints[:, _FEET]
    contact = (feet[..., 2] - FOOT_REST_HEIGHT) < 0.05
    return foot_skate_cm(feet, contact)


def bone_length_cv(joints: np.ndarray) -> float:
    """Median over bones of std / mean of the bone's length over time."""
    par = np.asarray(PARENTS[1:])
    L = np.linalg.norm(joints[:, 1:] - joints[:, par], axis=-1)  # (T, 23)
    return float(np.median(L.std(0) / np.maximum(L.mean(0), 1e-9)))


def transition_jerk_ratio(joints: np.ndarray, seams: list[int]) -> float:
    """Mean jerk at the seams (frames seam-2 .. seam+1) over the mean jerk elsewhere."""
    T = len(joints)
    if T < 8 or not seams:
        return float("nan")
    jerk = np.linalg.norm(np.diff(joints, n=3, axis=0), axis=-1).mean(axis=1)  # (T-3,) jerk at frames i..i+3
    at = np.zeros(len(jerk), dtype=bool)
    for s in seams:
        at[max(0, s - 3): min(len(jerk), s + 1)] = True
    if not at.any() or at.all():
        return float("nan")
    return float(jerk[at].mean() / max(jerk[~at].mean(), 1e-12))


def folded_jerk(joints: np.ndarray, cycle: int, first_seam: int = 0) -> np.ndarray:
    """joints (T, J, 3) m -> (cycle,) mean joint jerk per phase of the cycle, m per frame^3 (multiply
    by fps^3 for m/s^3). Jerk window t (frames t..t+3, the third difference) is at phase
    (t + 2 - first_seam) mod cycle, so a jump between frames s - 1 and s, whose middle window is
    the loudest, lands on phase s - first_seam. Phases without a window are NaN."""
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[-1] != 3:
        raise ValueError(f"joints must be (T, J, 3), got {joints.shape}")
    if int(cycle) != cycle or cycle < 2:
        raise ValueError(f"cycle must be an integer >= 2 frames (the new frames per episode), got {cycle}")
    cycle = int(cycle)
    jerk = np.linalg.norm(np.diff(joints, n=3, axis=0), axis=-1).mean(axis=1)  # (T-3,)
    phase = (np.arange(len(jerk)) + 2 - int(first_seam)) % cycle
    total = np.bincount(phase, weights=jerk, minlength=cycle)
    count = np.bincount(phase, minlength=cycle)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def seam_jerk_peak_ratio(joints: np.ndarray, cycle: int, first_seam: int = 0) -> tuple[float, int]:
    """(loudest phase's mean jerk / the median phase's, the loudest phase) of ``folded_jerk``:
    ~1 for motion without a cycle, high when every ``cycle``-th frame jerks. NaN, -1 when fewer
    than two whole cycles of jerk windows exist or the motion does not move."""
    joints = np.asarray(joints, np.float64)
    if len(joints) - 3 < 2 * cycle:
        return float("nan"), -1
    f = folded_jerk(joints, cycle, first_seam)
    med = float(np.median(f))
    if not med > 1e-12:
        return float("nan"), -1
    return float(f.max() / med), int(np.argmax(f))


def seam_piece_ratios(joints: np.ndarray, cycle: int, cycles_per_piece: int = 30) -> list[float]:
    """joints (T, J, 3) m of one clip without seams -> ``seam_jerk_peak_ratio`` (1) of each piece of
    ``cycles_per_piece`` cycles (a generated plan's length; the last piece kept when >= 10 cycles),
    finite values only: how loud the loudest phase of seamless motion is by chance at this fold."""
    vals = []
    n = cycle * cycles_per_piece
    for a in range(0, len(joints), n):
        piece = joints[a:a + n]
        if len(piece) >= 10 * cycle:
            r, _ = seam_jerk_peak_ratio(piece, cycle)
            if np.isfinite(r):
                vals.append(r)
    return vals


@lru_cache(maxsize=8)
def real_seam_reference(cycle: int, fps: float, cycles_per_piece: int = 30) -> tuple[float, float, float, int]:
    """``seam_jerk_peak_ratio`` of real motion at the same fold: the mocap corpus's held-out clips
    (``trumans.mocap_corpus``, test split) resampled to ``fps``, cut into pieces of
    ``cycles_per_piece`` cycles (a generated plan's length; the last piece kept when >= 10 cycles)
    -> (median, 10th, 90th percentile over the pieces, pieces)."""
    from trumans.mocap_corpus import load_corpus
    from trumans.resample import resample_sequence
    from trumans.sequence import Sequence

    vals = []
    for c in load_corpus(split="test"):
        vals += seam_piece_ratios(resample_sequence(Sequence(joints=c.joints, fps=c.fps), fps).joints, cycle,
                                  cycles_per_piece)
    if not vals:
        return float("nan"), float("nan"), float("nan"), 0
    return (float(np.median(vals)), float(np.percentile(vals, 10)), float(np.percentile(vals, 90)), len(vals))


def seat_height_errors_cm(joints: np.ndarray, phase: np.ndarray, phases: list, offset: float) -> np.ndarray:
    """Per seated phase: |median seated pelvis height - (seat height + offset)|, cm, where
    offset is the pelvis height above the seat surface in the training data."""
    out = []
    for i, p in enumerate(phases):
        if p.kind != "sit" or "seat_height" not in p.info:
            continue
        sel = phase == i
        if sel.sum() < 3:
            continue
        z = np.median(joints[sel, JOINT_INDEX["pelvis"], 2])
        out.append(abs(z - (p.info["seat_height"] + offset)))
    return np.asarray(out) * 100.0


def motion_figures(result, sc, sit_offset: float | None = None) -> dict:
    """The figures of a ``SampleResult`` in a ``SampleScene`` (first sample; see module doc)."""
    J = result.joints[0].astype(np.float64)
    goals = [(f, j, p) for (f, b, j, p) in result.goals if b == 0]
    ge = goal_errors_cm(J, goals)
    pen_mean, pen_max = penetration_cm(J, ContactScene(sc.scene, floor=False))
    fl_mean, fl_max = floor_err_cm(J)
    off = result.sit_offset if sit_offset is None else sit_offset
    seat = seat_height_errors_cm(J, result.phase[0], result.phases, off)
    return {
        "goal_err_cm": round(float(ge.mean()), 2) if ge.size else None,
        "seat_height_err_cm": round(float(seat.mean()), 2) if seat.size else None,
        "penetration_mean_cm": round(pen_mean, 2), "penetration_max_cm": round(pen_max, 2),
        "contact": round(contact_score(J, result.fps), 3), "foot_skate_near_floor_cm": round(foot_skate_near_floor_cm(J), 2),
        "floor_err_cm": round(fl_mean, 2), "floor_err_max_cm": round(fl_max, 2),
        "pelvis_speed_max_ms": round(pelvis_speed_max(J, result.fps), 2),
        "bone_length_cv": round(bone_length_cv(J), 5), "raw_bone_length_cv": round(float(result.raw_bone_cv), 4),
        "transition_jerk_ratio": round(transition_jerk_ratio(J, result.episode_starts[1:]), 3),
        **_seam_figures(J, result),
    }


def _seam_figures(J: np.ndarray, result) -> dict:
    """seam_jerk_peak_ratio / _phase of one sample and the real corpus's value at the same fold."""
    starts = list(result.episode_starts)
    if len(starts) < 2:
        return {"seam_jerk_peak_ratio": None, "seam_jerk_peak_phase": None, "real_seam_jerk_peak_ratio": None}
    cycle = starts[1] - starts[0]
    ratio, phase = seam_jerk_peak_ratio(J, cycle, starts[1] + result.context_frames)
    med, lo, hi, _ = real_seam_reference(cycle, float(result.fps))
    return {"seam_jerk_peak_ratio": round(ratio, 3) if np.isfinite(ratio) else None,
            "seam_jerk_peak_phase": phase if phase >= 0 else None,
            "real_seam_jerk_peak_ratio": round(med, 3), "real_seam_jerk_peak_ratio_p10": round(lo, 3),
            "real_seam_jerk_peak_ratio_p90": round(hi, 3)}
