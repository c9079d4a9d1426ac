"""Skeletons of other tools mapped onto our 24 joints, shared by the BVH and FBX importers.

``map_joints`` picks, for each of our joints, the foreign joint it comes from: a named built-in
map (``SKELETON_MAPS``: the Daz-style skeleton of the CMU FBX library and Daz BVH, and the
CMU / MotionBuilder-style one of the cgspeed BVH) or, by default, the first present candidate of
``DEFAULT_JOINT_MAP``. ``retarget_joints`` turns the foreign joints' world positions into our 24
(absent collars / spine joints interpolated along the chain, index1 placed beyond the wrist) and
``sequence_from_joints`` fits rotations to them (``trumans.ik.fit``). ``place_on_floor`` checks where
the feet are and, when asked, moves the motion so they stand on z = 0.

Leaf joints of a foreign skeleton can be mapped through their end: a BVH ``End Site`` or an FBX
bone's ``LimbLength`` end is a joint named ``<joint>_end`` (the Daz skeleton has no toe bones; its
``lFoot_end`` is the toe).
"""
from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Mapping

import numpy as np

from trumans.ik.fit import fit_error, fit_rotations
from trumans.rotations import matrix_to_6d
from trumans.sequence import Sequence
from trumans.skeleton import FOOT_JOINTS, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS, REST_JOINTS

__all__ = ["DEFAULT_JOINT_MAP", "SKELETON_MAPS", "KNOWN_UNITS", "map_joints", "detect_skeleton", "retarget_joints",
           "guess_unit_scale", "sequence_from_joints", "floor_height", "place_on_floor", "place_pelvis"]

log = logging.getLogger(__name__)

# Our joint -> candidate foreign names, first present (and not yet taken) wins. Covers our own export,
# the CMU "3dsMax-friendly" conversion (LeftHip/LeftKnee/LeftAnkle/LeftToe, lowerback/Chest/Chest2,
# LeftCollar/LeftShoulder/LeftElbow/LeftWrist, LFingers), the CMU/Mixamo style (LeftUpLeg/LeftLeg/
# LeftFoot/LeftToeBase, Spine/Spine1/Spine2, LeftShoulder = clavicle, LeftArm/LeftForeArm/LeftHand)
# and a few others. Joints resolve in this order, so "LeftShoulder" is the upper arm only where no
# "LeftArm" exists. Extend it with ``import_bvh(joint_map={our_name: bvh_name})``.
DEFAULT_JOINT_MAP: dict[str, list[str]] = {
    "pelvis": ["pelvis", "Hips", "hip", "Hip", "Pelvis", "Root"],
    "left_hip": ["left_hip", "LeftHip", "LeftUpLeg", "LeftThigh", "LThigh", "lThigh"],
    "right_hip": ["right_hip", "RightHip", "RightUpLeg", "RightThigh", "RThigh", "rThigh"],
    "left_knee": ["left_knee", "LeftKnee", "LeftLeg", "LeftShin", "LeftLowLeg", "LShin", "lShin"],
    "right_knee": ["right_knee", "RightKnee", "RightLeg", "RightShin", "RightLowLeg", "RShin", "rShin"],
    "left_ankle": ["left_ankle", "LeftAnkle", "LeftFoot", "LFoot", "lFoot"],
    "right_ankle": ["right_ankle", "RightAnkle", "RightFoot", "RFoot", "rFoot"],
    "left_foot": ["left_foot", "LeftToe", "LeftToeBase", "LeftToes", "LToe", "lToe", "lFoot_end", "LeftFoot_end"],
    "right_foot": ["right_foot", "RightToe", "RightToeBase", "RightToes", "RToe", "rToe", "rFoot_end", "RightFoot_end"],
    "spine1": ["spine1", "lowerback", "Spine", "LowerBack", "Abdomen", "abdomen"],
    "spine2": ["spine2", "Chest", "Spine1", "Spine2", "chest"],
    "spine3": ["spine3", "Chest2", "Spine2", "Spine3", "UpperChest", "upperback"],
    "neck": ["neck", "Neck", "Neck1", "neck1"],
    "head": ["head", "Head"],
    "left_shoulder": ["left_shoulder", "LeftArm", "LeftUpArm", "LeftUpperArm", "LShldr", "lShldr", "LeftShoulder"],
    "right_shoulder": ["right_shoulder", "RightArm", "RightUpArm", "RightUpperArm", "RShldr", "rShldr", "RightShoulder"],
    "left_collar": ["left_collar", "LeftCollar", "LeftClavicle", "LCollar", "lCollar", "LeftShoulder"],
    "right_collar": ["right_collar", "RightCollar", "RightClavicle", "RCollar", "rCollar", "RightShoulder"],
    "left_elbow": ["left_elbow", "LeftElbow", "LeftForeArm", "LeftLowArm", "LForeArm", "lForeArm"],
    "right_elbow": ["right_elbow", "RightElbow", "RightForeArm", "RightLowArm", "RForeArm", "rForeArm"],
    "left_wrist": ["left_wrist", "LeftWrist", "LeftHand", "LHand", "lHand"],
    "right_wrist": ["right_wrist", "RightWrist", "RightHand", "RHand", "rHand"],
    "left_index1": ["left_index1", "LeftHandIndex1", "LeftFingerBase", "LeftInHandIndex", "LFingers", "lIndex1"],
    "right_index1": ["right_index1", "RightHandIndex1", "RightFingerBase", "RightInHandIndex", "RFingers", "rIndex1"],
}

# Built-in maps of named skeleton styles ({our joint: their joint}); joints left out (spine3, and
# collars where absent) are interpolated along the chain.
SKELETON_MAPS: dict[str, dict[str, str]] = {
    # Daz / Poser style: the CMU "Huge FBX Mocap Library" (Blender FBX 6.1) and the Daz-friendly CMU BVH
    "daz": {"pelvis": "hip", "left_hip": "lThigh", "right_hip": "rThigh", "spine1": "abdomen", "left_knee": "lShin",
            "right_knee": "rShin", "spine2": "chest", "left_ankle": "lFoot", "right_ankle": "rFoot",
            "left_foot": "lFoot_end", "right_foot": "rFoot_end", "neck": "neck", "left_collar": "lCollar",
            "right_collar": "rCollar", "head": "head", "left_shoulder": "lShldr", "right_shoulder": "rShldr",
            "left_elbow": "lForeArm", "right_elbow": "rForeArm", "left_wrist": "lHand", "right_wrist": "rHand",
            "left_index1": "lIndex1", "right_index1": "rIndex1"},
    # CMU / MotionBuilder style: the cgspeed "MotionBuilder-friendly" CMU BVH (Hips, LHipJoint, LeftUpLeg, ...).
    # Its Neck and the clavicles (LeftShoulder) sit on Spine1 (zero offsets); our neck is Neck1, above
    # the shoulder line, and the clavicles are re-synthesised (degenerate against Spine1).
    "cmu_mb": {"pelvis": "Hips", "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "spine1": "Spine",
               "left_knee": "LeftLeg", "right_knee": "RightLeg", "spine2": "Spine1", "left_ankle": "LeftFoot",
               "right_ankle": "RightFoot", "left_foot": "LeftToeBase", "right_foot": "RightToeBase", "neck": "Neck1",
               "left_collar": "LeftShoulder", "right_collar": "RightShoulder", "head": "Head",
               "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
               "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
               "left_index1": "LeftHandIndex1", "right_index1": "RightHandIndex1"},
}
# Resolution order: upper arms before clavicles (see above), then the rest.
_RESOLVE_ORDER = ["left_shoulder", "right_shoulder"] + [n for n in JOINT_NAMES if n not in ("left_shoulder", "right_shoulder")]
# Joints that may be synthesised when absent or degenerate (sitting on their parent), between the
# (parent, nearest present chain descendant), or (index1) from the wrist along the forearm.
_CHAIN_NEXT = {"spine1": "spine2", "spine2": "spine3", "spine3": "neck", "neck": "head",
               "left_collar": "left_shoulder", "right_collar": "right_shoulder"}
_DEGENERATE_M = 0.01  # a mapped joint closer than this (median) to its mapped parent is re-synthesised
KNOWN_UNITS = {"metres": 1.0, "centimetres": 0.01, "millimetres": 0.001, "inches": 0.0254,
                "CMU units (1/0.0564444 m)": 0.0564444}


def detect_skeleton(names: list[str]) -> str | None:
    """The built-in skeleton style all of whose joints are in ``names`` (None if none is)."""
    for style, m in SKELETON_MAPS.items():
        if all(v in names for v in m.values()):
            return style
    return None


def map_joints(names: list[str], joint_map: dict[str, str] | None = None,
               skeleton: str | None = "auto") -> dict[str, int | None]:
    """Our joint name -> index of the foreign joint it comes from (None = to be synthesised).

    skeleton: a ``SKELETON_MAPS`` style ("daz", "cmu_mb"), "auto" (the style whose joints are all
    present, else the ``DEFAULT_JOINT_MAP`` candidates) or None (the candidates). ``joint_map``
    ({our_name: their_name}) overrides either; unknown names on either side raise."""
    if skeleton not in (None, "auto") and skeleton not in SKELETON_MAPS:
        raise ValueError(f"unknown skeleton style {skeleton!r}; use one of {sorted(SKELETON_MAPS)} or 'auto'")
    style = detect_skeleton(names) if skeleton == "auto" else skeleton
    if style is not None:
        base = dict(SKELETON_MAPS[style])
        absent = {k: v for k, v in base.items() if v not in names}
        if absent:
            raise ValueError(f"the skeleton is not {style!r}: it lacks {absent}; it has: {', '.join(names)}")
        if joint_map is not None and not isinstance(joint_map, Mapping):
            raise TypeError(f"joint_map must be a dict {{our_joint_name: their_joint_name}}, got "
                            f"{type(joint_map).__name__} {joint_map!r}")
        base.update(joint_map or {})
        joint_map = base
    if joint_map is not None and not isinstance(joint_map, Mapping):
        raise TypeError(f"joint_map must be a dict {{our_joint_name: their_joint_name}}, got {type(joint_map).__name__} "
                        f"{joint_map!r}")
    user = dict(joint_map or {})
    bad_ours = [k for k in user if k not in JOINT_INDEX]
    if bad_ours:
        raise ValueError(f"joint_map keys {bad_ours} are not our joints; use names from trumans.skeleton.JOINT_NAMES: "
                         f"{', '.join(JOINT_NAMES)}")
    bad_theirs = {k: v for k, v in user.items() if v not in names}
    if bad_theirs:
        raise ValueError(f"joint_map values {bad_theirs} are not joints of the skeleton; it has: {', '.join(names)}")
    out: dict[str, int | None] = {}
    taken = {v for v in user.values()}
    for ours in _RESOLVE_ORDER:
        if ours in user:
            out[ours] = names.index(user[ours])
            continue
        out[ours] = None
        for cand in DEFAULT_JOINT_MAP[ours]:
            if cand in names and cand not in taken:
                out[ours] = names.index(cand)
                taken.add(cand)
                break
    missing = [n for n, v in out.items() if v is None and n not in _CHAIN_NEXT and not n.endswith("_index1")]
    if missing:
        raise ValueError(f"joints for {missing} not found (tried {[DEFAULT_JOINT_MAP[m] for m in missing]}); "
                         f"pass joint_map={{our_name: their_name}}. The skeleton has: {', '.join(names)}")
    return {n: out[n] for n in JOINT_NAMES}


def synthesise(P: np.ndarray, have: np.ndarray) -> np.ndarray:
    """Fill joints with have[j] False in P (T, 24, 3): chain joints by interpolating between their
    parent and the nearest present chain descendant at the rest pose's arc-length fraction; index1
    from the wrist along the forearm direction at the rest length ratio."""
    P = P.copy()
    have = have.copy()
    rest_len = np.linalg.norm(REST_JOINTS - REST_JOINTS[np.maximum(PARENTS, 0)], axis=-1)
    for j in range(NUM_JOINTS):
        if have[j]:
            continue
        name = JOINT_NAMES[j]
        p = PARENTS[j]
        if name.endswith("_index1"):
            e = PARENTS[p]
            ratio = rest_len[j] / rest_len[p]
            P[:, j] = P[:, p] + (P[:, p] - P[:, e]) * ratio
        else:
            chain, k = [j], JOINT_INDEX[_CHAIN_NEXT[name]]
            while not have[k]:
                chain.append(k)
                k = JOINT_INDEX[_CHAIN_NEXT[JOINT_NAMES[k]]]
            arcs = np.cumsum([rest_len[c] for c in chain] + [rest_len[k]])
            P[:, j] = P[:, p] + (P[:, k] - P[:, p]) * (arcs[0] / arcs[-1])
        have[j] = True
    return P


def guess_unit_scale(height: float) -> float:
    """Metres per file unit: the common unit that makes the standing height closest to 1.7 m."""
    if not height > 0:
        raise ValueError("cannot guess the file units from a zero-height skeleton; pass unit_scale")
    name, s = min(KNOWN_UNITS.items(), key=lambda kv: abs(np.log(height * kv[1] / 1.7)))
    if not 0.8 <= height * s <= 2.6:
        raise ValueError(f"cannot guess the file units (skeleton height {height:.3g} file units); pass unit_scale "
                         "(metres per file unit)")
    log.info("units guessed as %s (skeleton height %.2f m)", name, height * s)
    return s




def retarget_joints(names: list[str], P: np.ndarray, joint_map: dict[str, str] | None = None,
                    skeleton: str | None = "auto") -> np.ndarray:
    """Our 24 joints (T, 24, 3) from a foreign skeleton's world joints P (T, J, 3), metres, z-up.

    Mapped collars / spine joints that sit on their nearest mapped ancestor (median < 1 cm, e.g. CMU collars) and
    unmapped ones are interpolated along the chain; unmapped index1 joints go beyond the wrist."""
    src = map_joints(names, joint_map, skeleton)
    T = P.shape[0]
    out = np.zeros((T, NUM_JOINTS, 3))
    have = np.zeros(NUM_JOINTS, bool)
    for j, name in enumerate(JOINT_NAMES):
        if src[name] is not None:
            out[:, j] = P[:, src[name]]
            have[j] = True
    for j, name in enumerate(JOINT_NAMES):
        if have[j] and name in _CHAIN_NEXT and (joint_map is None or name not in joint_map):
            a = PARENTS[j]
            while a >= 0 and not have[a]:  # the nearest mapped ancestor (spine3 is never mapped)
                a = PARENTS[a]
            if a >= 0 and np.median(np.linalg.norm(out[:, j] - out[:, a], axis=-1)) < _DEGENERATE_M:
                have[j] = False
    out = synthesise(out, have)
    if joint_map is None or "pelvis" not in joint_map:
        out = place_pelvis(out)
    return out


_PELVIS, _LHIP, _RHIP, _SPINE1 = (JOINT_INDEX[n] for n in ("pelvis", "left_hip", "right_hip", "spine1"))
PELVIS_ABOVE_HIPS_M = 0.04  # a mapped root less than this over the hip joints' line is a hip-level root


def _pelvis_frame(P: np.ndarray) -> np.ndarray:
    """(..., 3, 3) pelvis frames (columns: left, forward, up) from the hips and spine1 of P (..., 24, 3)."""
    x = P[..., _LHIP, :] - P[..., _RHIP, :]
    x = x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-9)
    up = P[..., _SPINE1, :] - 0.5 * (P[..., _LHIP, :] + P[..., _RHIP, :])
    up = up - (up * x).sum(-1, keepdims=True) * x
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-9)
    return np.stack([x, np.cross(up, x), up], -1)


def place_pelvis(P: np.ndarray) -> np.ndarray:
    """Our pelvis joint sits inside the pelvis, 9 cm above the hip joints (``REST_JOINTS``); skeletons
    whose root is at hip level (the CMU FBX / BVH "hip" / "Hips") put it there instead. When the mapped
    pelvis of P (T, 24, 3) is less than ``PELVIS_ABOVE_HIPS_M`` above the hips' midpoint (median,
    along the hips-to-spine1 up axis), it is placed where the rest pose has it in the pelvis frame
    of the hips and spine1, scaled by the hips-to-spine1 distance (so it keeps the rest pose's place
    between them); otherwise P is returned unchanged."""
    mid = 0.5 * (P[:, _LHIP] + P[:, _RHIP])
    F = _pelvis_frame(P)  # (T, 3, 3)
    height = np.einsum("ti,ti->t", P[:, _PELVIS] - mid, F[..., 2])
    if np.median(height) >= PELVIS_ABOVE_HIPS_M:
        return P
    R = REST_JOINTS
    rest_mid = 0.5 * (R[_LHIP] + R[_RHIP])
    local = _pelvis_frame(R).T @ (R[_PELVIS] - rest_mid)  # the rest pelvis in its own frame
    scale = np.median(np.linalg.norm(P[:, _SPINE1] - mid, axis=-1)) / np.linalg.norm(R[_SPINE1] - rest_mid)
    out = P.copy()
    out[:, _PELVIS] = mid + scale * np.einsum("tij,j->ti", F, local)
    return out


def sequence_from_joints(joints: np.ndarray, fps: float, target_fps: float | None = None,
                         refine_steps: int = 30) -> Sequence:
    """A Sequence with rotations fitted to our 24 joints (T, 24, 3) m (``trumans.ik.fit``), resampled
    to ``target_fps`` first when given. The fit's error (m) is ``extra["ik_error_mean" / "_max"]``
    and the rest offsets the rotations go with ``extra["offsets"]``."""
    seq = Sequence(joints=np.asarray(joints, np.float32), fps=float(fps))
    if target_fps is not None and abs(target_fps - fps) > 1e-6:
        from trumans.resample import resample_sequence
        seq = resample_sequence(seq, target_fps)
    R, root, off = fit_rotations(seq.joints, refine_steps=refine_steps)
    err = fit_error(seq.joints, R, root, off)
    extra = {"ik_error_mean": np.asarray(err["mean"]), "ik_error_max": np.asarray(err["max"]),
             "offsets": off.astype(np.float32)}
    return Sequence(joints=seq.joints, fps=seq.fps, rotations=matrix_to_6d(R).astype(np.float32),
                    root_pos=root.astype(np.float32), extra=extra)


_REST_FOOT_Z = float(REST_JOINTS[[JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"]], 2].mean())
FLOOR_TOLERANCE_M = 0.10  # feet further than this from standing on z = 0 are reported


def floor_height(joints: np.ndarray) -> float:
    """Where the motion's floor is (m): the 5th percentile over frames of the lowest foot joint
    (ankles, toe bases), minus the rest pose's toe-base height, so a body standing on z = 0 gives 0."""
    low = np.asarray(joints)[:, list(FOOT_JOINTS), 2].min(axis=1)
    return float(np.percentile(low, 5) - _REST_FOOT_Z)


def place_on_floor(seq: Sequence, feet_on_floor: bool, source: str = "the motion") -> Sequence:
    """Check that the feet stand on z = 0; with ``feet_on_floor`` move the motion vertically so they
    do. Without it, feet more than ``FLOOR_TOLERANCE_M`` off the floor raise a loud warning (a BVH
    whose root OFFSET holds the hip height while its position channels replace it imports ~1 m
    under the floor)."""
    h = floor_height(seq.joints)
    if not feet_on_floor:
        if abs(h) > FLOOR_TOLERANCE_M:
            msg = (f"{source}: the feet are {abs(h):.2f} m {'under' if h < 0 else 'above'} the floor (z = 0); "
                   "pass feet_on_floor=True (CLI: --feet-on-floor) to move the motion onto the floor")
            log.warning(msg)
            warnings.warn(msg, stacklevel=2)
        return seq
    shift = np.array([0.0, 0.0, -h], np.float32)
    extra = dict(seq.extra)
    extra["floor_shift_m"] = np.asarray(-h, np.float32)
    return dataclasses.replace(seq, joints=seq.joints + shift, extra=extra,
                               root_pos=None if seq.root_pos is None else seq.root_pos + shift)
