"""`trumans eval contacts --real`: the interaction tracker on real motion (issue 36.6).

Clips: the CMU corpus clips of one split (``--real-split``, default the held-out test subjects)
that handle something: the description hints at picking up / carrying (``real_objects.HINT_WORDS``)
or a palm reaches down (``real_objects.find_reaches``: a wrist goes low, then up; getting up from
the floor or a chair does this too, so those clips test that nothing is held where nothing was
fitted). Each clip is placed in its room with its fitted seats, supports and picked-up objects
exactly as a real take of the dataset (``real_takes.real_sequence``, the room seed of
``trumans data synth --seed S``): the fitted objects' pose tracks and holding hands
(``extra/grasp``) are the ground truth; every other object of the room never moves. The root is
moved by the same simulated localisation error as the procedural benchmark
(``evaluate.simulate_drift``), the tracker runs with its defaults.

Figures per clip and pooled (means over clips' frames / events, not over clips):
- ``ap``: per-hand contact probability against the contact rule's hand labels (as the procedural
  benchmark); ``held_ap``: the same against the fitted holding hands (``extra/grasp``);
- ``held_iou``: frames the tracker holds a fitted object (inside one of its interactions with that
  object) vs the frames the fitting holds it, intersection over union; ``held_share``: the share
  of the fitted held frames the tracker holds that object;
- ``obj_center_err_cm``: fitted objects' bounding-box centre, tracked vs fitted, mean over the
  frames from the first fitted grasp to the clip's end (carried and put down);
  ``obj_center_err_end_cm``: at the last frame;
- ``hand_obj_dist_cm``: on the fitted held frames, the holding hands' skin (nearest of wrist /
  index1 minus its radius) to the tracked object's surface (output body and object);
- ``float_cm`` / ``float_max_cm`` / ``floating``: at each release by the tracker (the frame after
  an interaction with a free object ends), the object's bottom height above the surface under
  its centre (``trumans.track.support``): mean, max, and how many releases leave it more than
  ``FLOAT_TOL_M`` up;
- ``false_hold_s``: seconds the tracker holds (moves) an object the fitting does not hold then
  (any object: the room's own never move in a real take); ``out_of_reach_s``: seconds the
  tracker holds an object none of whose contacting hands is within ``REACH_M`` of it;
  ``contact_nothing_s``: hand-seconds the output says a hand is in contact (``extra/contact_mask``)
  with no surface of the scene (static meshes, every object at its tracked pose) within ``REACH_M``
  of its skin (``_raw``: the same for the predicted contacts, thresholded and gap-filled, which
  the tracker output before issue 36.6).
"""
from __future__ import annotations

import argparse

import numpy as np

from trumans.summary import print_summary

__all__ = ["REACH_M", "FLOAT_TOL_M", "handling_clips", "real_case", "clip_figures", "pool", "run_real"]

REACH_M = 0.10  # m, a holding hand's skin farther than this from the object does not hold it
FLOAT_TOL_M = 0.02  # m, a let-go object's bottom this far above the surface under it floats


def handling_clips(split: str, corpus: str | None = None) -> list:
    """Corpus clips of ``split`` that handle something (module doc): hinted ones first, in corpus order."""
    from trumans.mocap_corpus import load_corpus
    from trumans.synth.real_objects import find_reaches, hinted

    clips = load_corpus(corpus, split=split)
    hint = [c for c in clips if hinted(c.description)]
    reach = [c for c in clips if not hinted(c.description) and find_reaches(c.joints)]
    return hint + reach


def real_case(clip, seed: int):
    """(Sequence, Scene) of a corpus clip placed as the dataset's real take with ``seed`` (the room
    seed of ``trumans data synth --seed``), or None when it fits no room."""
    import hashlib

    from trumans.synth.real_takes import real_sequence

    name_seed = int(hashlib.sha256(clip.name.encode()).hexdigest()[:8], 16)
    room_seed = int(np.random.SeedSequence([seed, name_seed]).generate_state(1)[0])
    made = real_sequence(clip, room_seed)
    if made is None:
        return None
    seq, terms = made
    return seq, terms["placement"].scene


def _gt_holder(seq, scene) -> np.ndarray:
    """(T,) index into the sorted fitted dynamic objects of the object held on each frame (-1: none):
    on a frame the fitting flags a holding hand, the fitted object nearest the holding palms."""
    from trumans.track.objects import hand_points

    names = sorted(n for n in seq.objects if n.startswith("fit_") and scene.objects[n].dynamic)
    grasp = np.asarray(seq.extra.get("grasp", np.zeros((seq.num_frames, 2), bool)), bool)
    out = np.full(seq.num_frames, -1, np.int64)
    if not names or not grasp.any():
        return out
    hands = hand_points(seq.joints)
    centres = np.stack([seq.objects[n].pose[:, :3, :3] @ scene.objects[n].mesh.bounds.mean(0) + seq.objects[n].pose[:, :3, 3]
                        for n in names], 1)  # (T, K, 3)
    for t in np.flatnonzero(grasp.any(1)):
        p = hands[t, grasp[t]].mean(0)
        out[t] = int(np.argmin(np.linalg.norm(centres[t] - p, axis=-1)))
    return out


def clip_figures(seq, scene, res) -> dict:
    """Figures (module doc) of one clip: ``seq`` the fitted take (truth), ``res`` the tracker's
    ``TrackResult`` on its drifted copy. Sums and lists, pooled by ``pool``."""
    from trumans.track.evaluate import _Dist, _hand_surface_dist
    from trumans.track.labels import hand_labels
    from trumans.contacts.rule import JOINT_RADIUS
    from trumans.track.object_choice import ObjectQueries
    from trumans.track.postprocess import PostprocessConfig, contact_mask
    from trumans.track.predictor import HAND_JOINTS, HANDS
    from trumans.track.support import SupportQuery

    T, fps = seq.num_frames, float(seq.fps)
    out = res.sequence
    names = sorted(n for n in seq.objects if n.startswith("fit_") and scene.objects[n].dynamic)
    holder = _gt_holder(seq, scene)
    grasp = np.asarray(seq.extra.get("grasp", np.zeros((T, 2), bool)), bool)
    queries = _Dist(scene)
    held = {}  # object -> (T,) bool, the tracker holds it
    reach_bad = np.zeros(T, bool)
    for it in res.interactions:
        m = held.setdefault(it.name, np.zeros(T, bool))
        for seg in it.segments:
            sl = slice(seg.start, seg.end)
            m[sl] = True
            d = np.stack([_hand_surface_dist(queries, it.name, out.objects[it.name].pose[sl].astype(np.float64),
                                             out.joints[sl].astype(np.float64), h) for h in (0, 1) if seg.hands[h]], 1)
            reach_bad[sl] |= d.min(1) > REACH_M
    inter = union = gt_frames = 0
    false_hold = np.zeros(T, bool)
    for name, m in held.items():
        gt = holder == names.index(name) if name in names else np.zeros(T, bool)
        false_hold |= m & ~gt
    for k, name in enumerate(names):
        gt, m = holder == k, held.get(name, np.zeros(T, bool))
        inter, union, gt_frames = inter + int((gt & m).sum()), union + int((gt | m).sum()), gt_frames + int(gt.sum())
    centre_err, end_err, hand_d = [], [], []
    for k, name in enumerate(names):
        first = np.flatnonzero(holder == k)
        if not len(first):
            continue
        c = scene.objects[name].mesh.bounds.mean(0)
        gp, tp = seq.objects[name].pose.astype(np.float64), out.objects[name].pose.astype(np.float64)
        d = np.linalg.norm((gp[:, :3, :3] @ c + gp[:, :3, 3]) - (tp[:, :3, :3] @ c + tp[:, :3, 3]), axis=-1) * 100
        centre_err.append(d[first[0]:])
        end_err.append(float(d[-1]))
        for h in (0, 1):
            fr = first[grasp[first, h]]
            if len(fr):
                hand_d.append(_hand_surface_dist(queries, name, tp[fr], out.joints[fr].astype(np.float64), h) * 100)
    support = SupportQuery(scene)
    floats = []
    for it in res.interactions:
        if it.dof != "free" or it.end >= T:
            continue
        poses = {n: o.pose[it.end].astype(np.float64) for n, o in out.objects.items()}
        floats.append(100 * max(support.gap(it.name, poses[it.name], poses), 0.0))
    labels = hand_labels(seq.contacts)
    raw = contact_mask(res.prob, fps, PostprocessConfig())  # the predicted contacts as thresholded and gap-filled
    objects = ObjectQueries(scene)
    nothing = np.zeros((T, 2), bool)
    for h, hand in enumerate(HANDS):
        jj = list(HAND_JOINTS[hand])
        d = objects.surface_distance(out.joints[:, jj].astype(np.float64),
                                     {n: o.pose.astype(np.float64) for n, o in out.objects.items()})
        nothing[:, h] = (d - JOINT_RADIUS[jj]).min(1) > REACH_M
    return {"clip": str(seq.extra.get("source", seq.scene)), "frames": T, "fps": fps, "fitted": names,
            "prob": res.prob, "labels": labels, "grasp": grasp,
            "held_inter": inter, "held_union": union, "gt_held_frames": gt_frames,
            "tracker_held_frames": int(np.any(list(held.values()), axis=0).sum()) if held else 0,
            "false_hold_frames": int(false_hold.sum()), "out_of_reach_frames": int(reach_bad.sum()),
            "contact_nothing_frames": int((res.mask & nothing).sum()), "raw_nothing_frames": int((raw & nothing).sum()),
            "centre_err": centre_err, "end_err": end_err, "hand_d": hand_d, "floats": floats,
            "interactions": [f"{it.name} {it.dof} {it.start}-{it.end}" for it in res.interactions]}


def _ap(prob: list[np.ndarray], labels: list[np.ndarray]) -> float:
    from trumans.track.scores import average_precision

    p, y = np.concatenate(prob).ravel(), np.concatenate(labels).ravel()
    return average_precision(p, y) if y.any() else float("nan")


def pool(rows: list[dict]) -> dict:
    """Pooled figures (module doc) over per-clip rows of ``clip_figures``."""
    mean = lambda xs: float(np.mean(np.concatenate(xs))) if xs and sum(len(x) for x in xs) else float("nan")
    inter, union, gt = (sum(r[k] for r in rows) for k in ("held_inter", "held_union", "gt_held_frames"))
    floats = [f for r in rows for f in r["floats"]]
    return {
        "ap": _ap([r["prob"] for r in rows], [r["labels"] for r in rows]),
        "held_ap": _ap([r["prob"] for r in rows], [r["grasp"] for r in rows]),
        "held_iou": inter / union if union else float("nan"),
        "held_share": inter / gt if gt else float("nan"),
        "obj_center_err_cm": mean([c for r in rows for c in r["centre_err"]]),
        "obj_center_err_end_cm": float(np.mean([e for r in rows for e in r["end_err"]])) if any(r["end_err"] for r in rows) else float("nan"),
        "hand_obj_dist_cm": mean([d for r in rows for d in r["hand_d"]]),
        "float_cm": float(np.mean(floats)) if floats else float("nan"),
        "float_max_cm": float(np.max(floats)) if floats else float("nan"),
        "floating": int(sum(f > 100 * FLOAT_TOL_M for f in floats)), "releases": len(floats),
        "false_hold_s": sum(r["false_hold_frames"] / r["fps"] for r in rows),
        "out_of_reach_s": sum(r["out_of_reach_frames"] / r["fps"] for r in rows),
        "contact_nothing_s": sum(r["contact_nothing_frames"] / r["fps"] for r in rows),
        "contact_nothing_s_raw": sum(r["raw_nothing_frames"] / r["fps"] for r in rows),
        "held_s": sum(r["tracker_held_frames"] / r["fps"] for r in rows),
        "fitted_held_s": sum(r["gt_held_frames"] / r["fps"] for r in rows),
        "clips": len(rows), "motion_min": sum(r["frames"] / r["fps"] for r in rows) / 60,
    }


def _row_summary(r: dict) -> dict:
    p = pool([r])
    return {"clip": r["clip"], "fitted": r["fitted"], "interactions": r["interactions"],
            **{k: v for k, v in p.items() if k not in ("clips",)}}


def run_real(model, args: argparse.Namespace) -> int:
    """The ``--real`` evaluation (module doc) with a loaded contact ``model``; prints a line per clip,
    the pooled figures and, with ``--json``, one JSON object."""
    from trumans.sequence import Sequence
    from trumans.track.evaluate import simulate_drift
    from trumans.track.interactions import TrackerConfig, track

    clips = handling_clips(args.real_split)[: args.max_seqs]
    if not clips:
        raise ValueError(f"no clip of the corpus's {args.real_split!r} split handles anything; try --real-split train")
    rng = np.random.default_rng([args.seed, 12])
    rows = []
    for clip in clips:
        case = real_case(clip, args.seed)
        if case is None:
            print(f"{clip.name}: fits no room, skipped")
            continue
        seq, scene = case
        drift = simulate_drift(seq.joints[:, 0, :2].astype(np.float64), seq.fps, rng)
        joints = seq.joints.copy()
        joints[:, :, :2] += drift[:, None].astype(np.float32)
        root = seq.root_pos + np.c_[drift, np.zeros(len(drift))].astype(np.float32)
        noisy = Sequence(joints=joints, fps=seq.fps, rotations=seq.rotations, root_pos=root, scene=seq.scene)
        res = track(noisy, scene, model, TrackerConfig(predict_stride=args.stride))
        r = clip_figures(seq, scene, res)
        rows.append(r)
        s = _row_summary(r)
        print(f"{clip.name:7s} {r['frames'] / r['fps']:5.1f}s fitted {','.join(r['fitted']) or '-':28s} "
              f"held {s['fitted_held_s']:4.1f}s iou {s['held_iou']:.2f} share {s['held_share']:.2f} "
              f"centre {s['obj_center_err_cm']:5.1f} cm hand {s['hand_obj_dist_cm']:5.1f} cm "
              f"float max {s['float_max_cm']:5.1f} cm false hold {s['false_hold_s']:4.1f}s out of reach "
              f"{s['out_of_reach_s']:4.1f}s contact with nothing near {s['contact_nothing_s']:4.1f}s "
              f"(predicted {s['contact_nothing_s_raw']:4.1f}s) | {'; '.join(r['interactions']) or 'no interaction'}")
    fig = pool(rows)
    for k in ("ap", "held_ap", "held_iou", "held_share", "obj_center_err_cm", "obj_center_err_end_cm",
              "hand_obj_dist_cm", "float_cm", "float_max_cm", "false_hold_s", "out_of_reach_s", "contact_nothing_s",
              "contact_nothing_s_raw"):
        print(f"{k:24s} {fig[k]:.3f}")
    print(f"{fig['clips']} clips ({args.real_split}), {fig['motion_min']:.1f} min of motion, fitted objects held "
          f"{fig['fitted_held_s']:.1f} s, the tracker holds {fig['held_s']:.1f} s; {fig['floating']} of "
          f"{fig['releases']} releases float > {100 * FLOAT_TOL_M:.0f} cm")
    if args.json:
        fig["per_clip"] = [_row_summary(r) for r in rows]
        fig["split"], fig["seed"] = args.real_split, args.seed
        print_summary(fig)
    return 0
