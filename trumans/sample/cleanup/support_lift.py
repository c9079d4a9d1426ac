"""Support lift: the body raised back onto its feet after the projection onto its bones.

The generator can draw a body other than the one it continues: from the CMU start body shipped
before (thigh + shin 0.82 m) its legs came out 0.71-0.79 m long with the ankles on the floor
(``docs/sampling_log.md``, "The start body; the support lift"; procedural bodies are kept within
3 %). ``sampler.project_bones`` keeps the pelvis and lengthens the legs downward, so the feet went 6-11 cm under the floor, and the foot
cleanup's leg IK, which keeps the hip, lifted them back by bending the knees: a standing or drinking
body stood with the knees bent 57 degrees (training data 17-24, the network's own legs 25).

So after the projection, on the frames where the feet carry the body, the whole body moves up by
``w * max(0, -h)``, ``h`` the height of its lowest foot joint above its resting height
(``trumans.skeleton.FOOT_REST_HEIGHT``): the lowest foot back on the floor, the legs as straight as the network
made them. ``w`` comes from the frame's action labels (``support_weights``): 1 standing and walking,
0 seated or lying (the seat carries the pelvis: the seat guidance has put it on the seat and the leg
IK then bends the longer legs down to the floor, as a taller person sits), eased across sitting down
(1 -> 0 over the phase's progress) and standing up (0 -> 1). The context frames stay as committed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT

from trumans.easing import smoothstep

__all__ = ["SEATED_ACTIONS", "SupportLiftConfig", "support_weights", "lowest_foot_height", "lift_onto_feet"]

SEATED_ACTIONS = ("sit", "lie", "lie_down", "get_up")  # the seat or bed carries the body (weight 0)


@dataclass(frozen=True)
class SupportLiftConfig:
    """enabled: raise the body back onto its feet; seated_actions: the actions whose frames the
    seat or bed carries (weight 0; ``support_weights``)."""

    enabled: bool = True
    seated_actions: tuple[str, ...] = SEATED_ACTIONS


def support_weights(labels: np.ndarray, vocabulary: list[str] | tuple[str, ...],
                    seated: tuple[str, ...] = SEATED_ACTIONS) -> np.ndarray:
    """labels (..., L, N_A) (0 off, 1 + progress on; columns ``vocabulary``) -> (..., L) in [0, 1]:
    how much the feet carry the body on each frame (module doc); ``seated``: the actions with weight 0."""
    labels = np.asarray(labels, dtype=np.float64)
    if labels.shape[-1] != len(vocabulary):
        raise ValueError(f"labels have {labels.shape[-1]} actions but the vocabulary {len(vocabulary)}")
    vocab = list(vocabulary)
    w = np.ones(labels.shape[:-1])

    def on(name: str) -> np.ndarray:
        return labels[..., vocab.index(name)] > 0 if name in vocab else np.zeros(w.shape, bool)

    def progress(name: str) -> np.ndarray:
        return np.clip(labels[..., vocab.index(name)] - 1.0, 0.0, 1.0)

    for name in seated:
        w[on(name)] = 0.0
    if "sit_down" in vocab:
        w = np.where(on("sit_down"), 1.0 - smoothstep(progress("sit_down")), w)
    if "stand_up" in vocab:
        w = np.where(on("stand_up"), smoothstep(progress("stand_up")), w)
    return w


def lowest_foot_height(joints: np.ndarray) -> np.ndarray:
    """joints (..., 24, 3) world m, z up -> (...,) height of the lowest foot joint above its rest, m."""
    return (np.asarray(joints)[..., list(FOOT_JOINTS), 2] - FOOT_REST_HEIGHT).min(axis=-1)


def lift_onto_feet(joints: np.ndarray, weight: np.ndarray, fixed: int = 0) -> np.ndarray:
    """joints (B, T, 24, 3) world m projected onto the body's bones; weight (B, T) in [0, 1]
    (``support_weights``) -> copy with frames >= ``fixed`` raised by ``weight * max(0, -h)``
    (``h``: ``lowest_foot_height``). Never lowers a body."""
    joints = np.asarray(joints)
    weight = np.asarray(weight, dtype=np.float64)
    if joints.ndim != 4 or joints.shape[2:] != (24, 3) or weight.shape != joints.shape[:2]:
        raise ValueError(f"need joints (B, T, 24, 3) and weight (B, T), got {joints.shape} and {weight.shape}")
    if not (np.isfinite(weight).all() and (weight >= 0).all() and (weight <= 1).all()):
        raise ValueError("support weights must be finite and in [0, 1]")
    lift = weight * np.maximum(-lowest_foot_height(joints.astype(np.float64)), 0.0)
    lift[:, :fixed] = 0.0
    out = joints.copy()
    out[..., 2] += lift[..., None].astype(joints.dtype)
    return out
