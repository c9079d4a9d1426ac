"""`trumans eval augment`: benchmark figures of contact-preserving augmentation (issue #3).

By default on a held-out synthetic set built here (trumans.synth.cases: sitting, lying, one hand, two
hands, successive contacts; seeds disjoint from the tests'), or on ``--data DIR`` (a dataset's
``--split``). Every touched object gets ``--variations`` random variations. Figures (last line,
JSON): contact_err_cm (mean A1 residual |p'_t - (l_t + v'_m - v_m)| over contact frames of changed
objects), bone_length_err_mm (max deviation from the source's bone lengths,
``trumans.eval.metrics.bone_length_dev_mm``), smooth_ratio (max A13 ratio of the IK targets; targets the
variation leaves unchanged meet it with equality, so smooth_ratio_moved gives the max over the
moved ones),
foot_skate_added_cm (mean per output of ``trumans.eval.metrics.foot_skate_cm`` after minus before, feet
in floor contact), joint_centre_inside_max_cm (deepest joint centre inside a changed object,
``trumans.eval.metrics.joint_centre_inside_cm``; not the body penetration figure ``penetration_max_cm``
of ``trumans.eval.metrics``), unreachable_frac (contact frames
with an unreachable target / contact frames), frames_per_s (augmented frames per CPU second of this
single-threaded process: pose, contact detection, variation sampling and mapping, both IK passes,
IK batched over all clips' frames; CPU time so that other jobs on a shared machine do not count;
frames_per_wall_s gives the wall-clock figure).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from trumans.argtypes import int_in
from trumans.limits import MAX_CASES, MAX_EVAL_SEQUENCES, MAX_VARIATIONS
from trumans.contacts.rule import FLOOR_NAME
from trumans.eval.metrics import bone_length_dev_mm, foot_skate_cm, joint_centre_inside_cm
from trumans.skeleton import FEET

from trumans.augment.core import AugmentConfig, augment_many, sequence_contacts
from trumans.augment.pipeline import contacted_objects
from trumans.augment.variations import KINDS, sample_variation
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["add_arguments", "run", "evaluate_cases"]

_FEET = list(FEET)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", default=None, help="dataset folder to evaluate on (default: a held-out synthetic set)")
    p.add_argument("--split", default="test", help="split of --data to use (default test)")
    p.add_argument("--max-seqs", type=int_in(1, MAX_EVAL_SEQUENCES, limit="MAX_EVAL_SEQUENCES"), default=20,
                   help="at most this many sequences of --data (default 20)")
    p.add_argument("--cases", type=int_in(1, MAX_CASES, limit="MAX_CASES"), default=4,
                   help=f"synthetic clips per contact kind (default 4, at most {MAX_CASES:,})")
    p.add_argument("--variations", type=int_in(1, MAX_VARIATIONS, limit="MAX_VARIATIONS"), default=2,
                   help="variations per touched object (default 2)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on the last line")


def _floor_feet(intervals, T: int) -> np.ndarray:
    m = np.zeros((T, 2), bool)
    for iv in intervals:
        if iv.obj == FLOOR_NAME and iv.joint in _FEET:
            m[iv.start:iv.end, _FEET.index(iv.joint)] = True
    return m


def evaluate_cases(cases, n_var: int, rng: np.random.Generator, libraries, cfg: AugmentConfig | None = None,
                   batch_frames: int = 20000, max_pen_cm: float = 3.0, tries: int = 4) -> dict:
    """cases: [(label, Sequence, Scene)]; libraries: category -> {name: mesh} for replacements.
    Variations are augmented in batches of about ``batch_frames`` frames (one IK batch each); a
    variation whose motion puts a joint centre deeper than max(original, ``max_pen_cm``) into the
    changed object is redrawn (``tries`` rounds; the last draw is kept whatever it gives)."""
    cfg = cfg or AugmentConfig()
    t0, c0 = time.perf_counter(), time.process_time()
    jobs = []  # (label, SequenceContacts, Variation, library)
    pen0: dict = {}  # (sequence, object) -> joint_centre_inside_cm of the original motion
    for label, seq, scene in cases:
        sc = sequence_contacts(seq, scene, cfg)
        for name in contacted_objects(sc.intervals, scene):
            lib = libraries.get(scene.objects[name].category, {})
            pen0[(id(sc), name)] = joint_centre_inside_cm(sc.joints, scene, [name])
            for _ in range(n_var):
                jobs.append((label, sc, sample_variation(scene.objects[name], rng, KINDS, lib), lib))
    # augment in frame batches; a draw that puts a joint centre deeper than max(original, max_pen_cm)
    # inside the changed object is redrawn, as the pipeline does (up to ``tries`` rounds)
    outs: list = [None] * len(jobs)
    pens: list = [None] * len(jobs)  # joint_centre_inside_cm of each kept output (reported below)
    todo = list(range(len(jobs)))
    rejected = 0
    for round_ in range(tries):
        if not todo:
            break
        res = []
        i = 0
        while i < len(todo):
            n, j = 0, i
            while j < len(todo) and (n == 0 or n + len(jobs[todo[j]][1].joints) <= batch_frames):
                n += len(jobs[todo[j]][1].joints)
                j += 1
            batch = [jobs[k] for k in todo[i:j]]
            lib = {k: m for job in batch for k, m in job[3].items()}
            res += augment_many([(job[1], [job[2]]) for job in batch], lib, cfg)
            i = j
        again = []
        for k, out in zip(todo, res):
            label, sc, var, lib = jobs[k]
            pen = joint_centre_inside_cm(out.sequence.joints, out.scene, [var.object])
            if round_ + 1 < tries and pen > max(pen0[(id(sc), var.object)], max_pen_cm):
                rejected += 1
                jobs[k] = (label, sc, sample_variation(sc.scene.objects[var.object], rng, KINDS, lib), lib)
                again.append(k)
            else:
                outs[k], pens[k] = out, pen
        todo = again
    elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0

    err_sum = err_n = 0.0
    bone = smooth = smooth_moved = pen = 0.0
    skate: list[float] = []
    unreach = cframes = frames = 0
    per_case: dict[str, dict[str, list[float]]] = {}
    for (label, sc, var, _), out, pk in zip(jobs, outs, pens):
        seq, name, r = sc.seq, var.object, out.result
        P0 = sc.joints
        frames += len(P0)
        cm = np.zeros(r.contact.shape, bool)
        for iv in out.intervals:
            if iv.obj == name:
                cm[iv.start:iv.end, iv.joint] = True
        e = np.linalg.norm(r.joints - r.contact_target, axis=-1)[cm]
        err_sum += float(e.sum())
        err_n += e.size
        bone = max(bone, bone_length_dev_mm(r.joints, sc.offsets))
        smooth = max(smooth, float(r.smooth.max()) if r.smooth.size else 0.0)
        moved = np.linalg.norm(r.targets - P0, axis=-1) > 1e-6  # targets that the variation moved
        mv = r.smooth[(moved[1:] | moved[:-1]) & r.window[1:] & r.window[:-1]]
        smooth_moved = max(smooth_moved, float(mv.max()) if mv.size else 0.0)
        feet = _floor_feet(out.intervals, len(P0))
        skate.append(foot_skate_cm(r.joints[:, _FEET], feet) - foot_skate_cm(P0[:, _FEET], feet))
        pen = max(pen, pk)  # out.sequence.joints are r.joints in float32, the precision the test casts to
        un = int((r.unreachable & cm).any(1).sum())
        unreach += un
        cframes += int(cm.any(1).sum())
        d = per_case.setdefault(f"{label}/{var.kind}", {"contact_err_cm": [], "joint_centre_inside_cm": [],
                                                                  "unreachable": []})
        d["contact_err_cm"].append(float(e.mean() * 100) if e.size else 0.0)
        d["joint_centre_inside_cm"].append(pk)
        d["unreachable"].append(un / max(int(cm.any(1).sum()), 1))
    return {
        "contact_err_cm": err_sum / max(err_n, 1) * 100,
        "bone_length_err_mm": bone,
        "smooth_ratio": smooth,
        "smooth_ratio_moved": smooth_moved,
        "foot_skate_added_cm": float(np.mean(skate)) if skate else 0.0,
        "foot_skate_added_max_cm": float(np.max(skate)) if skate else 0.0,
        "joint_centre_inside_max_cm": pen,
        "unreachable_frac": unreach / max(cframes, 1),
        "frames_per_s": frames / max(cpu, 1e-9),
        "frames_per_wall_s": frames / max(elapsed, 1e-9),
        "outputs": len(outs),
        "redrawn": rejected,
        "frames": frames,
        "by_case": {k: {m: round(float(np.mean(v)), 4) for m, v in d.items()} for k, d in sorted(per_case.items())},
    }


def run(args: argparse.Namespace) -> int:
    try:
        import torch
        torch.set_num_threads(1)
    except ImportError:
        pass
    rng = np.random.default_rng(args.seed)
    if args.data is None:
        from trumans.synth.cases import make_cases, replacement_library
        cases = make_cases(10_000 + args.seed, per_kind=args.cases)  # tests use small seeds: held out
        libraries = {c: replacement_library(c, 20_000 + args.seed) for c in ("chair", "bed")}
        tall = next(sc for kind, _, sc in cases if "table" in sc.objects)  # counter-height tables
        libraries["table"] = replacement_library("table", 20_000 + args.seed, 4, tall)
        source = f"synthetic held-out set ({args.cases} clips x 5 kinds, seed {args.seed})"
    else:
        from trumans.dataset import Dataset
        ds = Dataset(args.data)
        paths = ds.split(args.split)[: args.max_seqs]
        if not paths:
            counts = {s: len(ds.split(s)) for s in ds.split_names}
            raise ValueError(f"split {args.split!r} of {args.data} holds no sequences ({counts}); choose a split "
                             f"that has some with --split")
        cases = []
        libraries: dict = {}
        for sid in ds.scene_ids:
            for n, o in ds.scene(sid).objects.items():
                libraries.setdefault(o.category, {})[f"{sid}/{n}"] = o.mesh
        for p in paths:
            seq = ds.load(p)
            cases.append((p.stem, seq, ds.scene(seq.scene)))
        source = f"{args.data} split {args.split} ({len(cases)} sequences)"
    fig = evaluate_cases(cases, args.variations, rng, libraries)
    if fig["outputs"] == 0 or fig["frames"] == 0:
        raise ValueError(f"nothing to evaluate: no sequence of {source} touches an interactable object "
                         f"(figures over zero outputs would read as perfect); use sequences with object contacts")
    fig["source"] = source
    if not args.json:
        for k, v in fig.items():
            if k == "by_case":
                for c, m in v.items():
                    print(f"{c:>24}: {m}")
            else:
                print(f"{k:>24}: {v}")
    else:
        for k, v in fig["by_case"].items():
            print(f"{k:>24}: {v}")
        print_summary(fig)
    return 0
