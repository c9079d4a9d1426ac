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
- ``bone_length_cv``: per bone std / mean over time, the median over bones;
- ``transition_jerk_ratio``: mean joint jerk (third difference) around the episode seams over
  the mean jerk inside episodes.
"""
from __future__ import annotations

import numpy as np

from trumans.contacts.rule import ContactScene, joint_contacts
from trumans.eval.metrics import foot_skate_cm
from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT, JOINT_INDEX, PARENTS

__all__ = ["goal_errors_cm", "penetration_cm", "floor_err_cm", "contact_score", "bone_length_cv",
           "transition_jerk_ratio", "foot_skate_near_floor_cm", "seat_height_errors_cm", "motion_figures"]

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
        "bone_length_cv": round(bone_length_cv(J), 5), "raw_bone_length_cv": round(float(result.raw_bone_cv), 4),
        "transition_jerk_ratio": round(transition_jerk_ratio(J, result.episode_starts[1:]), 3),
    }
