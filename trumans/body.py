"""Resting heights of the body on a support: how high the pelvis joint sits above a seat or bed.

One convention for the data world (``trumans.synth.posture``, ``trumans.synth.lying``) and the
generator (``trumans.sample.rollout``): the pelvis joint sits ``seat_clearance`` (0.095 m for an
average 0.784-m leg, scaled with the leg) above the surface, raised until the skin of the seat
joints (pelvis and hips: joint height minus ``JOINT_RADIUS``) is not below it.
"""
from __future__ import annotations

import numpy as np

from trumans.contacts.rule import JOINT_RADIUS
from trumans.ik.limb import limb_reach
from trumans.skeleton import SEAT, offsets_from_joints

__all__ = ["leg_scale", "seat_clearance", "sit_offset"]

AVERAGE_LEG = 0.784  # m, hip to ankle of the average body the clearances were set on
PELVIS_CLEARANCE = 0.095  # m, pelvis joint above a seat for the average leg


def leg_scale(offsets: np.ndarray) -> float:
    """Leg length of ``offsets`` (24, 3) m over the average leg's (``AVERAGE_LEG``)."""
    return limb_reach(np.asarray(offsets, dtype=np.float64), "left_leg")[1] / AVERAGE_LEG


def seat_clearance(offsets: np.ndarray) -> float:
    """Height (m) of the pelvis joint above a seat/bed surface it rests on (0.095 m x leg scale)."""
    return PELVIS_CLEARANCE * leg_scale(offsets)


def sit_offset(pose: np.ndarray) -> float:
    """Pelvis height (m) above a seat surface for the body of ``pose`` (24, 3) world m: the seated
    pelvis (``seat_clearance`` above the surface, trunk upright: a seated pelvis turns only about z,
    so each hip sits its rest offset's height above the pelvis) raised until no seat joint's skin
    is below the surface. For an average body the hips decide: 0.171 m, the median seated pelvis
    height above the seat in the default dataset's procedural takes."""
    offsets = offsets_from_joints(np.asarray(pose, dtype=np.float64)[None])
    seat = list(SEAT)
    rise = np.where(np.array(seat) == 0, 0.0, offsets[seat, 2])  # seat joints above the pelvis joint, m
    clearance = seat_clearance(offsets)
    gap = clearance + rise - JOINT_RADIUS[seat]
    return float(clearance + max(0.0, -gap.min()))
