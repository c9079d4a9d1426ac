"""`trumans eval realism [DATASET] --reference REAL --json`: issue 9's realism statistics of a
dataset against real motion (default reference: the held-out clips of the shipped CMU corpus)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from trumans.summary import print_summary


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", nargs="?", help="dataset folder (index.json + sequences/), a corpus .npz, or "
                   "'corpus:train' / 'corpus:test' (default: corpus:train)")
    p.add_argument("--reference", default="corpus:test",
                   help="the real motion to compare with: same forms as DATASET (default corpus:test, the held-out CMU clips)")
    p.add_argument("--split", choices=["train", "val", "test", "all"], default="all",
                   help="which split of a dataset folder to measure (default all)")
    p.add_argument("--source", choices=["all", "real", "procedural"], default="all",
                   help="which takes of a `trumans data synth` dataset to measure: the real (mocap) takes its index "
                        "lists under 'real', the procedural ones, or all (default)")
    p.add_argument("--max-clips", type=int, help="measure at most this many clips of DATASET (the first ones)")
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


def run(args: argparse.Namespace) -> int:
    from trumans.eval.realism import compare

    spec = args.dataset or "corpus:train"
    if args.source != "all" and (spec.startswith("corpus:") or spec.endswith(".npz")):
        raise ValueError(f"--source {args.source} selects takes of a dataset folder; {spec} "
                         "is a corpus (all real): drop --source")
    data = load_clips(spec, args.split, args.max_clips, args.source)
    ref = load_clips(args.reference)
    if not data or not ref:
        raise ValueError(f"nothing to compare: {len(data)} dataset clips, {len(ref)} reference clips")
    report = compare(data, ref)
    report["dataset"] = args.dataset or "corpus:train"
    report["reference"] = args.reference
    if args.json:
        print_summary(report)
        return 0
    for k, r in report["statistics"].items():
        fmt = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
        mark = {True: "in", False: "OUT", None: ""}[r["inside"]]
        print(f"{k:32s} {fmt(r['dataset']):>8} {r['unit']:9s} real {fmt(r['reference_min'])}-{fmt(r['reference_max'])} "
              f"(median {fmt(r['reference_median'])}) {mark}")
    fi = report["fraction_inside"]
    print(f"inside the real range: {report['compared'] and round(fi * report['compared'])}/{report['compared']}"
          f" ({fi if fi is None else round(fi, 2)})", file=sys.stderr)
    return 0
