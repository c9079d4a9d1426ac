"""Augment one sequence for a set of object variations: contacts -> intervals -> offsets -> IK.

Contacts are found with the TRUMANS joint rule (``trumans.contacts.rule``; the floor counts, so
planted feet are contacts with an unchanged object and stay planted), within ``HOLD_THRESHOLD`` of
the body surface, and cut into intervals by ``trumans.contacts.intervals``. Contacts with a changed
object get the A2 offset ``v'_m - v_m`` (variations.map_contact_points); every other contact is
held where it was (zero offset). See ``trumans.augment.contact_ik`` for the two IK passes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from trumans.scenes.scene import Scene, SceneObject
from trumans.contacts.intervals import joint_contact_intervals
from trumans.intervals import runs
from trumans.contacts.rule import FLOOR_NAME, HOLD_THRESHOLD, ContactScene, joint_contacts
from trumans.ik.ccd import ROOT_GROUP, IKConfig
from trumans.ik.fit import fit_rotations
from trumans.rotations import fit_yaw, matrix_to_6d, sixd_to_matrix, yaw_matrix
from trumans.sequence import ObjectTrack, Sequence
from trumans.skeleton import (ANKLES, FEET, INDEX1, KNEES, NUM_JOINTS, PARENTS, WRISTS, forward_kinematics,
                              offsets_from_pose)

from trumans.augment.offsets import ContactInterval
from trumans.augment.contact_ik import RetargetResult, retarget_many
from trumans.augment.variations import Variation, apply_variation, map_contact_points, move_matrix

__all__ = ["AugmentConfig", "AugmentOutput", "SequenceContacts", "sequence_pose", "sequence_contacts", "find_intervals",
           "merge_body_contacts", "rigid_body_offsets", "rigid_hand_offsets", "augment_sequence", "augment_many"]


@dataclass
class AugmentConfig:
    """window_s: A3 fade window in seconds (W = 30 frames at 30 fps); threshold: distance beyond
    the body surface (m) within which a joint is held to its surface (``HOLD_THRESHOLD``); contact
    runs shorter than min_len frames are dropped and gaps of up to max_gap frames closed."""

    window_s: float = 1.0
    threshold: float = HOLD_THRESHOLD
    min_len: int = 3
    max_gap: int = 2
    ik: IKConfig = field(default_factory=IKConfig)

    def window(self, fps: float) -> float:
        return max(1.0, self.window_s * fps)


@dataclass
class AugmentOutput:
    """The augmented sequence and scene, the IK result, the contact intervals (with offsets) and
    a JSON-able report of what changed."""

    sequence: Sequence
    scene: Scene
    result: RetargetResult
    intervals: list[ContactInterval]
    report: dict


def sequence_pose(seq: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(joints (T, 24, 3), global_rot (T, 24, 3, 3), offsets (24, 3)) float64 of a sequence.

    Uses the stored 6D rotations + root_pos (offsets recovered from the pose,
    ``trumans.skeleton.offsets_from_pose``); sequences with joints only are fitted with
    ``trumans.ik.fit.fit_rotations``."""
    P = np.asarray(seq.joints, dtype=np.float64)
    if seq.rotations is not None:
        rot = sixd_to_matrix(np.asarray(seq.rotations, dtype=np.float64))
        _, G = forward_kinematics(rot, P[:, 0], np.zeros((NUM_JOINTS, 3)))  # global rotations need no offsets
        off = offsets_from_pose(P, G)
        J, G = forward_kinematics(rot, P[:, 0], off)
        if np.abs(J - P).max() > 5e-3:
            raise ValueError(f"the sequence's rotations do not reproduce its joints (max {np.abs(J - P).max():.3f} m); "
                             "drop 'rotations' to refit them")
        return J, G, off
    rot, root, off = fit_rotations(P)
    J, G = forward_kinematics(np.asarray(rot, np.float64), np.asarray(root, np.float64), np.asarray(off, np.float64))
    return J, G, np.asarray(off, np.float64)


def _object_poses(seq: Sequence, scene: Scene) -> dict[str, np.ndarray]:
    return {n: np.asarray(t.pose, np.float64) for n, t in seq.objects.items()
            if n in scene.objects and scene.objects[n].dynamic}


def find_intervals(P: np.ndarray, G: np.ndarray, seq: Sequence, scene: Scene, cfg: AugmentConfig
                   ) -> tuple[list[ContactInterval], np.ndarray]:
    """Contact intervals per (joint, object) and the closest surface points (T, 24, 3) world m."""
    res = joint_contacts(P, ContactScene(scene), cfg.threshold, G, _object_poses(seq, scene))
    out = [ContactInterval(*c) for c in joint_contact_intervals(res.object_index, res.names, cfg.max_gap, cfg.min_len)]
    return merge_body_contacts(out, len(P), cfg.max_gap), res.closest.astype(np.float64)


def merge_body_contacts(intervals: list[ContactInterval], T: int, max_gap: int = 2) -> list[ContactInterval]:
    """Seat / bed contacts are one contact of the rigid torso: root-group joints (pelvis, hips,
    spine, ...) touching the same object get the union of their intervals, so they fade in and
    out together instead of pulling the rigid torso apart."""
    rg = set(ROOT_GROUP)
    keep = [iv for iv in intervals if iv.joint not in rg or iv.obj == FLOOR_NAME]
    body = [iv for iv in intervals if iv.joint in rg and iv.obj != FLOOR_NAME]
    for obj in sorted({iv.obj for iv in body}):
        mine = [iv for iv in body if iv.obj == obj]
        union = np.zeros(T, bool)
        for iv in mine:
            union[iv.start:iv.end] = True
        for s, e in runs(union, max_gap):
            joints = sorted({iv.joint for iv in mine if iv.start < e and iv.end > s})
            keep += [ContactInterval(j, obj, s, e) for j in joints]
    return keep


_LEGS = [*KNEES, *ANKLES, *FEET]


def rigid_body_offsets(intervals: list[ContactInterval], closest: np.ndarray, changed: set[str], T: int) -> None:
    """Lying / sitting: the body resting on one changed object cannot stretch with it, so the new
    contact points of its *resting group* -- the root-group joints touching the object, plus every
    touching joint whose parent is in the group (an arm or leg lying on the bed) -- are mapped
    together, by the yaw + translation that best fits their individually mapped points (per
    frame); so are the knees, ankles and feet touching the object while the body rests on it. A
    hand on a chair's armrest (elbow free) still follows the armrest. Edits
    ``frame_offset`` in place."""
    for obj in changed:
        mine = [iv for iv in intervals if iv.obj == obj and iv.frame_offset is not None]
        if not any(iv.joint in ROOT_GROUP for iv in mine):
            continue
        touch = np.zeros((T, NUM_JOINTS), bool)
        vm2 = closest.copy()
        for iv in mine:
            touch[iv.start:iv.end, iv.joint] = True
            vm2[iv.start:iv.end, iv.joint] = closest[iv.start:iv.end, iv.joint] + iv.frame_offset
        on = np.zeros_like(touch)
        on[:, list(ROOT_GROUP)] = touch[:, list(ROOT_GROUP)]
        for j in range(1, NUM_JOINTS):  # parents come before children in the joint order
            on[:, j] |= touch[:, j] & on[:, PARENTS[j]]
        # a leg resting on the same surface (knees-up lying: feet on the mattress, knees in the
        # air) rests with the body even when the joints between touch nothing
        resting = on[:, list(ROOT_GROUP)].any(1)
        on[:, _LEGS] |= touch[:, _LEGS] & resting[:, None]
        w = on.astype(np.float64)
        n = w.sum(1)
        ok = n >= 2
        if not ok.any():
            continue
        c = (closest * w[..., None]).sum(1) / np.maximum(n, 1)[:, None]
        c2 = (vm2 * w[..., None]).sum(1) / np.maximum(n, 1)[:, None]
        a, b = closest - c[:, None], vm2 - c2[:, None]
        rig = np.einsum("tij,tkj->tki", yaw_matrix(fit_yaw(a, b, w)), a) + c2[:, None]
        for iv in mine:
            fr = np.arange(iv.start, iv.end)
            use = ok[fr] & on[fr, iv.joint]
            iv.frame_offset[use] = rig[fr[use], iv.joint] - closest[fr[use], iv.joint]


_HANDS = tuple(zip(WRISTS, INDEX1))  # (wrist, index1) per hand


def rigid_hand_offsets(intervals: list[ContactInterval], changed: set[str], T: int) -> None:
    """A hand gripping a changed object moves as one piece: on frames where the wrist and its
    index1 both touch the object, both get the mean of their two mapped offsets (scaling maps them
    to points a few mm apart in different directions, which the rigid hand cannot reach at once).
    Edits ``frame_offset`` in place."""
    for obj in changed:
        for wrist, finger in _HANDS:
            ivs = [iv for iv in intervals if iv.obj == obj and iv.joint in (wrist, finger) and iv.frame_offset is not None]
            if not any(iv.joint == wrist for iv in ivs) or not any(iv.joint == finger for iv in ivs):
                continue
            off = np.full((2, T, 3), np.nan)
            for iv in ivs:
                off[int(iv.joint == finger), iv.start:iv.end] = iv.frame_offset
            both = ~np.isnan(off[..., 0]).any(0)
            mean = off.mean(0)
            for iv in ivs:
                fr = np.arange(iv.start, iv.end)
                use = both[fr]
                iv.frame_offset[use] = mean[fr[use]]


@dataclass
class SequenceContacts:
    """A sequence's pose and contacts, computed once and shared by all its variations."""

    seq: Sequence
    scene: Scene
    joints: np.ndarray  # (T, 24, 3) float64
    global_rot: np.ndarray  # (T, 24, 3, 3)
    intervals: list[ContactInterval]
    closest: np.ndarray  # (T, 24, 3)
    offsets: np.ndarray  # (24, 3) the actor's rest offsets (m), see ``sequence_pose``


def sequence_contacts(seq: Sequence, scene: Scene, config: AugmentConfig | None = None) -> SequenceContacts:
    """Pose (``sequence_pose``) and contact intervals (``find_intervals``) of a sequence."""
    cfg = config or AugmentConfig()
    P, G, off = sequence_pose(seq)
    intervals, closest = find_intervals(P, G, seq, scene, cfg)
    return SequenceContacts(seq, scene, P, G, intervals, closest, off)


def augment_sequence(
    seq: Sequence,
    scene: Scene,
    variations: list[Variation],
    replacements: dict[str, trimesh.Trimesh] | None = None,
    config: AugmentConfig | None = None,
    new_scene_id: str | None = None,
) -> AugmentOutput:
    """Apply ``variations`` to ``scene`` and recompute ``seq`` so every contact holds (module doc).

    replacements: name -> mesh (object frame) for 'replace' variations. Raises ValueError for an
    unknown object name, a missing replacement, or a variation of an object the sequence never
    touches (nothing to preserve)."""
    cfg = config or AugmentConfig()
    sc = sequence_contacts(seq, scene, cfg)
    return augment_many([(sc, variations)], replacements, cfg, [new_scene_id])[0]


def augment_many(
    jobs: list[tuple[SequenceContacts, list[Variation]]],
    replacements: dict[str, trimesh.Trimesh] | None = None,
    config: AugmentConfig | None = None,
    new_scene_ids: list[str | None] | None = None,
) -> list[AugmentOutput]:
    """``augment_sequence`` for many (sequence contacts, variations) jobs, the IK of all of them in
    one frame batch (see ``retarget_many``)."""
    cfg = config or AugmentConfig()
    replacements = replacements or {}
    new_scene_ids = new_scene_ids or [None] * len(jobs)
    preps = []
    for sc, variations in jobs:
        preps.append(_prepare(sc, variations, replacements))
    results = retarget_many([(sc.joints, sc.global_rot, ivs, cfg.window(sc.seq.fps))
                             for (sc, _), (ivs, _) in zip(jobs, preps)], cfg.ik)
    return [_finish(sc, variations, ivs, new_objs, res, cfg.window(sc.seq.fps), sid)
            for (sc, variations), (ivs, new_objs), res, sid in zip(jobs, preps, results, new_scene_ids)]


def _prepare(sc: SequenceContacts, variations: list[Variation], replacements: dict[str, trimesh.Trimesh]
             ) -> tuple[list[ContactInterval], dict[str, SceneObject]]:
    scene = sc.scene
    if not variations:
        raise ValueError("no variations given; pass at least one Variation")
    names = [v.object for v in variations]
    unknown = [n for n in names if n not in scene.objects]
    if unknown:
        raise ValueError(f"unknown object(s) {unknown} in scene {scene.name!r}; it has {sorted(scene.objects)}")
    if len(set(names)) != len(names):
        raise ValueError(f"each object may be varied once per sequence, got {names}")
    new_objs: dict[str, SceneObject] = {}
    for v in variations:
        rep = replacements.get(v.replacement) if v.kind == "replace" else None
        if v.kind == "replace" and rep is None:
            raise ValueError(f"replacement {v.replacement!r} for {v.object!r} not found; known: {sorted(replacements)}")
        new_objs[v.object] = apply_variation(scene.objects[v.object], v, rep)
    intervals = [ContactInterval(iv.joint, iv.obj, iv.start, iv.end) for iv in sc.intervals]
    touched = {iv.obj for iv in intervals}
    untouched = [n for n in names if n not in touched]
    if untouched:
        raise ValueError(f"sequence never touches {untouched}; vary objects it is in contact with "
                         f"(contacts: {sorted(touched) or 'none'})")
    poses = _object_poses(sc.seq, scene)
    closest = sc.closest
    for iv in intervals:
        if iv.obj in new_objs:
            old = scene.objects[iv.obj]
            vm = closest[iv.start:iv.end, iv.joint]
            tr = poses.get(iv.obj)
            iv.frame_offset = map_contact_points(old, new_objs[iv.obj], vm, None if tr is None else tr[iv.start:iv.end]) - vm
    rigid_body_offsets(intervals, closest, set(new_objs), len(sc.joints))
    rigid_hand_offsets(intervals, set(new_objs), len(sc.joints))
    for iv in intervals:
        if iv.frame_offset is not None:
            iv.offset = iv.frame_offset.mean(0)  # A2: the interval's offset (per-frame ones kept)
    return intervals, new_objs


def _finish(sc: SequenceContacts, variations: list[Variation], intervals: list[ContactInterval],
            new_objs: dict[str, SceneObject], res: RetargetResult, W: float, new_scene_id: str | None) -> AugmentOutput:
    seq, scene = sc.seq, sc.scene
    T = len(sc.joints)
    objs = dict(scene.objects)
    objs.update(new_objs)
    sid = new_scene_id or scene.name + "_aug"
    new_scene = Scene(name=sid, static=dict(scene.static), objects=objs, meta=dict(scene.meta))
    tracks = {}
    for n, t in seq.objects.items():
        pose = t.pose
        if n in new_objs:
            pose = (move_matrix(scene.objects[n], new_objs[n]) @ np.asarray(pose, np.float64)).astype(np.float32)
        tracks[n] = ObjectTrack(pose=pose, category=t.category, imu_rot=t.imu_rot, imu_acc=t.imu_acc)
    new_seq = Sequence(
        joints=res.joints.astype(np.float32), fps=seq.fps, rotations=matrix_to_6d(res.local_rot).astype(np.float32),
        root_pos=res.joints[:, 0].astype(np.float32), actions=seq.actions, action_names=list(seq.action_names),
        contacts=seq.contacts, scene=sid, objects=tracks, extra=dict(seq.extra),
    )
    changed = [iv for iv in intervals if iv.obj in new_objs]
    cmask = np.zeros((T, NUM_JOINTS), bool)
    for iv in changed:
        cmask[iv.start:iv.end, iv.joint] = True
    cerr = np.linalg.norm(res.joints - res.contact_target, axis=-1)
    report = {
        "variations": [v.to_json() for v in variations],
        "frames": T,
        "window_frames": W,
        "contact_intervals": len(intervals),
        "changed_intervals": [{"joint": iv.joint, "object": iv.obj, "start": iv.start, "end": iv.end,
                               "offset": [round(float(x), 5) for x in iv.offset]} for iv in changed],
        "contact_err_cm": float(cerr[cmask].mean() * 100) if cmask.any() else 0.0,
        "unreachable_frames": int((res.unreachable & cmask).any(1).sum()),
        "contact_frames": int(cmask.any(1).sum()),
        "smooth_ratio": float(res.smooth.max()) if res.smooth.size else 0.0,
    }
    return AugmentOutput(new_seq, new_scene, res, intervals, report)
