"""Real takes of the synth dataset: the corpus's train clips (``trumans.mocap_corpus``), each placed
in a procedural room made for it (``real_place.place_clip``), labelled, with contacts, written as
the same files as a procedural take.

Labels: the per-frame body states of ``trumans.motion_labels`` (stand / walk / turn / sit_down /
sit / stand_up / lie_down / lie / get_up are names of ``SYNTH_ACTIONS``) as half-open intervals
(``trumans.actions``); where the CMU description names a whole-clip activity (drinking, a phone
call, typing) it labels the held stand / sit frames, and "carry" labels the walking frames.
Objects picked up, carried and put down (``real_objects``: detected from the hands where the
description hints at it) are dynamic objects of the room with their pose tracks, their
pick_up / carry / put_down intervals replace the description's "carry", and ``extra/grasp`` flags
the holding hands. Contacts: ``trumans.contacts.rule`` on the room with its fitted seats / beds /
supports and the objects at their per-frame poses, as for procedural takes. Rotations: ``trumans.ik.fit.fit_rotations``; the joints are their forward kinematics (exact
bone lengths, as in procedural takes), within ``fit_error_max_mm`` (a few mm) of the recording.
The sequence says where it comes from: ``extra/source = "cmu:<clip>"``.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from trumans.eval import metrics
from trumans.actions import ActionInterval, labels_from_intervals
from trumans.intervals import runs
from trumans.contacts.rule import CONTACT_THRESHOLD, ContactScene, contact_rule
from trumans.ik.fit import fit_rotations
from trumans.mocap_corpus import MocapClip, load_corpus
from trumans.motion_labels import MOTION_STATES
from trumans.rotations import matrix_to_6d, yaw_matrix
from trumans.sequence import ObjectTrack, Sequence, atomic_write, save_sequence
from trumans.skeleton import FEET, WRISTS, forward_kinematics
from .real_objects import fit_handled_objects, handled_footprints
from .real_place import place_clip
from .vocab import SYNTH_ACTIONS

__all__ = ["select_clips", "real_room_id", "clip_labels", "real_sequence", "build_real_room", "DESCRIPTION_ACTIONS"]

REAL_VERSION = "6"  # bump when the placement, labels or contacts of real takes change (rebuilds real rooms)

TRIM_ERROR_M = 0.01  # m, leading / trailing frames fitted worse than this are dropped

# description word -> (action, the body states it labels)
DESCRIPTION_ACTIONS: dict[str, tuple[str, tuple[str, ...]]] = {
    "drink": ("drink", ("stand", "sit")),
    "phone": ("phone_call", ("stand", "sit")),
    "typing": ("type", ("stand", "sit")),
    "carry": ("carry", ("walk",)),
}


def select_clips(clips: list[MocapClip], share: float, seed: int) -> list[MocapClip]:
    """A seeded ``share`` in [0, 1] of ``clips`` (rounded; in corpus order). Test-split clips are refused."""
    if not (0.0 <= share <= 1.0):
        raise ValueError(f"real share must be in [0, 1], got {share}")
    test = [c.name for c in clips if c.split != "train"]
    if test:
        raise ValueError(f"clips {test[:3]} are not of the corpus's train split; real takes use train clips only")
    n = int(round(share * len(clips)))
    keep = np.sort(np.random.default_rng([seed, 11]).permutation(len(clips))[:n])
    return [clips[i] for i in keep]


def real_room_id(clip: MocapClip) -> str:
    return f"real_{clip.name}"


def clip_labels(states: np.ndarray, description: str, handled: list[ActionInterval] = ()) -> np.ndarray:
    """(T, N_A) action labels with progress over ``SYNTH_ACTIONS`` from per-frame ``states`` (T,),
    the description's whole-clip activities and the ``handled`` object intervals (pick_up / carry /
    put_down of ``real_objects``; where they carry, the description's "carry" is not used)."""
    states = np.asarray(states)
    T = len(states)
    intervals = [ActionInterval(name, s, e) for k, name in enumerate(MOTION_STATES) for s, e in runs(states == k)]
    intervals += list(handled)
    found = {iv.name for iv in handled}
    desc = description.lower()
    for word, (action, on) in DESCRIPTION_ACTIONS.items():
        if word in desc and action not in found:
            mask = np.isin(states, [MOTION_STATES.index(s) for s in on])
            intervals += [ActionInterval(action, s, e) for s, e in runs(mask)]
    return labels_from_intervals(intervals, list(SYNTH_ACTIONS), T)


def fit_clip(joints: np.ndarray) -> tuple[slice, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rotations of a recorded clip (T, 24, 3) m, without the leading / trailing frames that no
    pose of one skeleton reproduces within ``TRIM_ERROR_M`` (a few corpus clips start with a
    converter's frame of other bone lengths). Returns (kept frames, rot (T', 24, 3, 3), root (T', 3),
    offsets (24, 3), per-frame fit error (T',) m)."""
    rec = np.asarray(joints, np.float64)
    rot, root, off = fit_rotations(rec)
    P, _ = forward_kinematics(rot, root, off)
    err = np.linalg.norm(P - rec, axis=-1).max(axis=1)
    good = np.flatnonzero(err <= TRIM_ERROR_M)
    if len(good) == 0:
        raise ValueError(f"no frame of the clip fits one skeleton within {TRIM_ERROR_M} m")
    keep = slice(int(good[0]), int(good[-1]) + 1)
    if keep != slice(0, len(rec)):  # refit without the odd frames: they skew the measured offsets
        rot, root, off = fit_rotations(rec[keep])
        P, _ = forward_kinematics(rot, root, off)
        err = np.linalg.norm(P - rec[keep], axis=-1).max(axis=1)
    return keep, rot, root, off, err


def real_sequence(clip: MocapClip, seed: int) -> tuple[Sequence, dict] | None:
    """The clip placed in its room as a dataset sequence (``scene`` = its room id) and its metric
    terms (with the ``Placement``); None if it fits no room."""
    rid = real_room_id(clip)
    keep, rot, root, off, err = fit_clip(clip.joints)
    states = clip.states[keep]
    P0, G0 = forward_kinematics(rot, root, off)
    handled = fit_handled_objects(P0, G0[:, list(WRISTS)], clip.description, seed, clip.fps)
    pl = place_clip(clip.joints[keep], states, seed, clip.name, clip.fps, extra=handled.objects + handled.supports,
                    free=handled_footprints(handled))
    if pl is None:
        return None
    pl.scene.name = rid
    # the placement turns the whole clip by yaw about z and moves it: only the root changes
    Rz = yaw_matrix(pl.yaw)
    rot = rot.copy()
    rot[:, 0] = Rz @ rot[:, 0]
    root = root @ Rz.T + np.array([pl.shift[0], pl.shift[1], 0.0])
    P, G = forward_kinematics(rot, root, off)  # joints and rotations agree exactly (as in procedural takes)
    T = len(P)
    contacts = ContactScene(pl.scene)
    tracks = {n: (pl.transform @ handled.tracks[n] if n in handled.tracks else
                  np.broadcast_to(o.pose, (T, 4, 4)).astype(np.float64))
              for n, o in pl.scene.objects.items() if o.dynamic}
    res = contacts.query(P, tracks)
    con = contact_rule(P, res, threshold=CONTACT_THRESHOLD, global_rot=G)
    foot_floor = con.contact[:, list(FEET)] & (np.abs(con.closest[:, list(FEET), 2]) < 0.005)
    seq = Sequence(
        joints=P.astype(np.float32), fps=clip.fps, rotations=matrix_to_6d(rot).astype(np.float32),
        root_pos=root.astype(np.float32), actions=clip_labels(states, clip.description, handled.intervals),
        action_names=list(SYNTH_ACTIONS), contacts=con.contact, scene=rid,
        objects={n: ObjectTrack(pose=p.astype(np.float32), category=pl.scene.objects[n].category)
                 for n, p in tracks.items()},
        extra={"offsets": off.astype(np.float32), "foot_contact": foot_floor, "grasp": handled.grasp,
               "source": np.asarray(f"cmu:{clip.name}")},
    )
    terms = {"fit_error_max_mm": 1e3 * float(err.max()), "trimmed_frames": len(clip.joints) - T, "penetration": con.penetration.astype(np.float64),
             "foot_floor": foot_floor, "offsets": off, "placement": pl}
    return seq, terms


def build_real_room(out: Path, clip: MocapClip, seed: int, key: str) -> dict:
    """Write the room and the take of one real clip under ``out``; returns the room record (the same
    fields as a procedural room's, ``trumans.synth.build``), also written to ``rooms/<id>.json``.
    A clip that fits no room gives a record with ``skipped`` and no sequences."""
    from trumans.dataset import record_outputs
    from trumans.scenes.io import save_scene, scene_files
    from trumans.scenes.occupancy import scene_occupancy

    t0 = time.perf_counter()
    rid = real_room_id(clip)
    rec_path = out / "rooms" / f"{rid}.json"
    if rec_path.is_file():
        try:
            rec = json.loads(rec_path.read_text())
            if rec.get("key") == key and all((out / p).is_file() for p in rec["sequences"]) and \
                    (rec.get("skipped") or (out / rec["scene_dir"] / "occupancy.npz").is_file()):
                rec["resumed"] = True
                return rec
        except (json.JSONDecodeError, KeyError, TypeError, RecursionError):
            pass
    made = real_sequence(clip, seed)
    rec: dict = {"room": rid, "key": key, "real": f"cmu:{clip.name}", "scene_dir": f"scenes/{rid}", "sequences": [],
                 "frames": 0, "action_frames": {a: 0 for a in SYNTH_ACTIONS}, "categories": {}, "activities": {},
                 "skip_examples": {}, "scene_categories": [], "bone_length_dev_mm": 0.0, "penetration_max_cm": 0.0,
                 "foot_slide_sum_m": 0.0, "foot_steps": 0, "grasp_gap_sum_m": 0.0, "grasp_frames": 0}
    if made is None:
        rec["skipped"] = "fits no room"
    else:
        seq, terms = made
        pl = terms["placement"]
        rel = f"sequences/{rid}.npz"
        record_outputs(out, [f"scenes/{rid}/{f}" for f in scene_files(pl.scene)] + [rel])
        save_scene(pl.scene, out / "scenes" / rid)
        scene_occupancy(pl.scene, out / "scenes" / rid)
        save_sequence(seq, out / rel)
        slides = metrics.foot_slides(seq.joints[:, list(FEET)], terms["foot_floor"])
        on = seq.actions > 0
        rec.update({
            "sequences": [rel], "frames": seq.num_frames,
            "action_frames": {n: int(on[:, a].sum()) for a, n in enumerate(seq.action_names)},
            "categories": {ob.category: 0 for ob in pl.scene.objects.values()},
            "scene_categories": sorted({o.category for o in pl.scene.objects.values()}),
            "bone_length_dev_mm": metrics.bone_length_dev_mm(seq.joints, terms["offsets"]),
            "penetration_max_cm": metrics.penetration_max_cm(terms["penetration"]),
            "foot_slide_sum_m": float(slides.sum()), "foot_steps": int(len(slides)),
            "fit_error_max_mm": terms["fit_error_max_mm"], "trimmed_frames": terms["trimmed_frames"],
            "removed_for_path": pl.removed, "fitted": pl.fitted,
            "placement_attempt": pl.attempt,
        })
    rec["seconds"] = time.perf_counter() - t0

    def _write(tmp: str) -> None:
        with open(tmp, "w") as f:
            json.dump(rec, f, indent=1)

    record_outputs(out, [f"rooms/{rid}.json"])
    atomic_write(rec_path, _write)
    return rec


def train_clips(share: float, seed: int, corpus: str | None = None) -> list[MocapClip]:
    """The seeded ``share`` of the corpus's train clips (never the test split)."""
    return select_clips(load_corpus(corpus, split="train"), share, seed)
