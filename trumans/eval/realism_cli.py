"""`trumans eval realism [DATASET] --reference REAL --json` and `trumans eval realism --generated
SAMPLE.npz ...`: the realism statistics (``trumans.eval.realism``) of a dataset or of generated motion
against real motion (default reference: every held-out clip of the shipped CMU corpus), per
statistic the value, the real p10-p90 range with its bootstrap intervals, inside / outside, and
"k of n inside"."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from trumans.eval.realism import MIN_CLIPS, MIN_EVENTS, N_BOOT, RealismClip
from trumans.summary import print_summary


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", nargs="?", help="dataset folder (index.json + sequences/), a corpus .npz, or "
                   "'corpus:train' / 'corpus:test' (default: corpus:train; not with --generated)")
    p.add_argument("--generated", nargs="+", metavar="SAMPLE.npz",
                   help="score these npz files written by `trumans sample` instead of a dataset (their seams and "
                        "scene are measured too)")
    p.add_argument("--reference", default="corpus:test",
                   help="the real motion to compare with: same forms as DATASET (default corpus:test, the held-out CMU clips)")
    p.add_argument("--split", choices=["train", "val", "test", "all"], default="all",
                   help="which split of a dataset folder to measure (default all)")
    p.add_argument("--source", choices=["all", "real", "procedural"], default="all",
                   help="which takes of a `trumans data synth` dataset to measure: the real (mocap) takes its index "
                        "lists under 'real', the procedural ones, or all (default)")
    p.add_argument("--max-clips", type=int, help="measure at most this many clips of DATASET (the first ones)")
    p.add_argument("--min-events", type=int, default=MIN_EVENTS,
                   help=f"fewest real events (and >= {MIN_CLIPS} clips) for a statistic to get a range (default {MIN_EVENTS})")
    p.add_argument("--bootstrap", type=int, default=N_BOOT, help=f"bootstrap resamples of the reference clips (default {N_BOOT})")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default 0)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")


def load_clips(spec: str, split: str = "all", max_clips: int | None = None, source: str = "all") -> list[np.ndarray]:
    """Joints (T, 24, 3) at 30 fps of every clip of a dataset folder, a corpus npz or 'corpus:SPLIT'
    (``source``: "real" / "procedural" keeps a dataset folder's real / procedural takes only)."""
    from trumans.mocap_corpus import load_corpus

    if spec.startswith("corpus:"):
        which = spec.split(":", 1)[1] or None
        clips = [c.joints for c in load_corpus(split=None if which == "all" else which)]
    elif spec.endswith(".npz"):
        clips = [c.joints for c in load_corpus(spec)]
    else:
        from trumans.resample import resample_sequence
        from trumans.sequence import load_sequence

        root = Path(spec)
        if not (root / "index.json").is_file():
            raise FileNotFoundError(f"{root} is not a dataset folder (no index.json); pass a dataset built by "
                                    "`trumans data synth` / `trumans data import`, a corpus .npz or corpus:test")
        from trumans.dataset import load_index

        index = load_index(root)
        rels = [r for s, rs in index["splits"].items() if split in ("all", s) for r in rs]
        if source != "all":
            real = set(index.get("real", {}))
            rels = [r for r in rels if (r in real) == (source == "real")]
        if max_clips:
            rels = rels[:max_clips]
        clips = []
        for r in rels:
            seq = load_sequence(root / r)
            if abs(seq.fps - 30.0) > 1e-6:
                seq = resample_sequence(seq, 30.0)
            clips.append(seq.joints)
        return clips
    return clips[:max_clips] if max_clips else clips


def load_generated(paths: list[str]) -> list[RealismClip]:
    """``trumans sample`` npz files -> clips with their episode seams (from the recorded goals) and
    scene (the spec it records: 'room:SEED', a scene folder or a mesh file). Raises ValueError naming
    a file that is not a sampled sequence."""
    from trumans.eval.realism import seams_from_goals
    from trumans.sequence import GOAL_JOINTS_KEY, GOALS_KEY, SAMPLER_CONFIG_KEY, load_sequence

    clips = []
    for p in paths:
        seq = load_sequence(p)
        if SAMPLER_CONFIG_KEY not in seq.extra or GOALS_KEY not in seq.extra:
            raise ValueError(f"{p} is not a sequence written by `trumans sample` (no extra/{SAMPLER_CONFIG_KEY} and "
                             f"extra/{GOALS_KEY}); score a dataset folder as DATASET instead")
        if seq.num_frames < 2:
            raise ValueError(f"{p} has {seq.num_frames} frame(s); realism needs a motion")
        seams = seams_from_goals(seq.extra[GOALS_KEY], seq.extra.get(GOAL_JOINTS_KEY, np.zeros(0, str)))
        clips.append(RealismClip(seq.joints, seq.fps, seams=seams, scene=_scene_of(seq, Path(p)), name=str(p)))
    return clips


def _scene_of(seq, path: Path):
    """The ``trumans.scenes.Scene`` a sampled sequence records, or None when it names none that exists."""
    from trumans.scenes.spec import SCENE_UP_KEY, procedural_seed

    spec = seq.scene or ""
    if not spec:
        return None
    seed = procedural_seed(spec)
    if seed is not None:
        from trumans.scenes.procedural import make_room

        return make_room(seed)
    for cand in (Path(spec), path.parent / spec):
        if cand.is_dir() and (cand / "scene.json").is_file():
            from trumans.scenes.io import load_scene

            return load_scene(cand)
        if cand.is_file():
            from trumans.scenes.io import import_mesh
            from trumans.scenes.scene import Scene

            up = str(seq.extra[SCENE_UP_KEY]) if SCENE_UP_KEY in seq.extra else "z"
            return Scene(name=cand.stem, static={"mesh": import_mesh(cand, up=up)})
    return None


def _reference(spec: str) -> list[RealismClip]:
    """The reference clips at 30 fps, a corpus's with its stored states and the postures its
    descriptions vouch for (``trumans.eval.realism.described_postures``)."""
    from trumans.eval.realism import described_postures
    from trumans.mocap_corpus import load_corpus

    if spec.startswith("corpus:") or spec.endswith(".npz"):
        which = spec.split(":", 1)[1] if spec.startswith("corpus:") else None
        corpus = load_corpus(split=None if which in (None, "all") else which) if spec.startswith("corpus:") \
            else load_corpus(spec)
        return [RealismClip(c.joints, c.fps, c.states, name=c.name,
                            postures=described_postures(c.description) if c.description.strip() else None)
                for c in corpus]
    return [RealismClip(j) for j in load_clips(spec)]


def run(args: argparse.Namespace) -> int:
    from trumans.eval.realism import score

    if args.min_events < 1 or args.bootstrap < 1:
        raise ValueError(f"--min-events and --bootstrap must be >= 1, got {args.min_events} and {args.bootstrap}")
    if args.generated:
        if args.dataset or args.source != "all" or args.split != "all":
            raise ValueError("--generated scores sample npz files; drop DATASET / --source / --split")
        data = load_generated(args.generated[:args.max_clips] if args.max_clips else args.generated)
        what = " ".join(args.generated)
    else:
        spec = args.dataset or "corpus:train"
        if args.source != "all" and (spec.startswith("corpus:") or spec.endswith(".npz")):
            raise ValueError(f"--source {args.source} selects takes of a dataset folder; {spec} "
                             "is a corpus (all real): drop --source")
        data = [RealismClip(j) for j in load_clips(spec, args.split, args.max_clips, args.source)]
        what = spec
    ref = _reference(args.reference)
    if not data or not ref:
        raise ValueError(f"nothing to compare: {len(data)} input clips, {len(ref)} reference clips")
    report = score(data, ref, n_boot=args.bootstrap, seed=args.seed, min_events=args.min_events)
    report["dataset"] = what
    report["reference"] = args.reference
    if args.json:
        print_summary(report)
        return 0
    for line in format_report(report):
        print(line)
    return 0


def format_report(report: dict) -> list[str]:
    """The report as text lines: per statistic value, real p10-p90 [bootstrap intervals], verdict."""
    def fmt(v):
        return "-" if v is None else f"{v:.3g}"

    lo_q, hi_q = report["percentiles"]
    lines = [f"{'statistic':32s} {'value':>8} {'unit':9s} real p{lo_q:g}-p{hi_q:g} [95% bootstrap of each end]  verdict"]
    for k, r in report["statistics"].items():
        ref = r["reference"]
        if ref["lo"] is not None:
            rng = (f"{fmt(ref['lo'])} [{fmt(ref['lo_ci'][0])},{fmt(ref['lo_ci'][1])}] - {fmt(ref['hi'])} "
                   f"[{fmt(ref['hi_ci'][0])},{fmt(ref['hi_ci'][1])}] ({ref['events']} events)")
        else:
            rng = ref["note"] or ""
        mark = {True: "inside", False: "OUTSIDE", None: ""}[r["inside"]] + (" (borderline)" if r["borderline"] else "")
        if r["value"] is None:
            mark = r["note"]
        lines.append(f"{k:32s} {fmt(r['value']):>8} {r['unit']:9s} {rng}  {mark}")
    lines.append(f"{report['inside_count']} of {report['compared']} inside the real range "
                 f"({report['clips']} clips against {report['reference_clips']} real clips)")
    return lines
