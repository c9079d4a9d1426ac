"""`trumans augment`: contact-preserving CCD-IK augmentation of a dataset (see trumans.augment.pipeline)."""
from __future__ import annotations

import argparse
import sys

from trumans.argtypes import float_in, fraction, int_in, nonneg_int, positive_float
from trumans.contacts.rule import HOLD_THRESHOLD

from trumans.limits import MAX_VARIATIONS
from trumans.augment.pipeline import SOURCES, PipelineConfig, SourcesFailed, augment_dataset
from trumans.augment.variations import KINDS
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_no_progress_argument, out_help
from trumans.shards import add_shard_argument

__all__ = ["add_arguments", "run"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", required=True, help="source dataset folder (index.json + sequences + scenes)")
    p.add_argument("--out", required=True, help=out_help("folder", "the augmented dataset (sequences/, scenes/, "
                   "records/, manifest.json, index.json; with --shard: the shard's files and shard.json); new, empty, "
                   "or this command's own: re-running with the same settings resumes where it stopped"))
    p.add_argument("--overwrite", action="store_true", help="replace the dataset or other run already in --out")
    p.add_argument("--variations", type=int_in(1, MAX_VARIATIONS, limit="MAX_VARIATIONS"), default=2,
                   help=f"variations per touched object, 1..{MAX_VARIATIONS} (default 2, as the paper)")
    p.add_argument("--splits", nargs="+", default=["train"], help="source splits to augment (default: train)")
    p.add_argument("--source", choices=list(SOURCES), default="all",
                   help="which takes of a `trumans data synth` dataset to augment: the real (mocap) takes its index lists "
                        "under 'real', the procedural ones, or all (default)")
    p.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS), help="variation kinds to draw from")
    p.add_argument("--window", type=positive_float, default=1.0, help="offset fade window W in seconds (default 1 s = 30 frames at 30 fps)")
    p.add_argument("--threshold", type=float_in(0.0, 1.0, lo_open=True), default=HOLD_THRESHOLD,
                   help=f"hold joints within this distance beyond the body surface, m (default {HOLD_THRESHOLD})")
    p.add_argument("--max-unreachable", type=fraction, default=0.1,
                   help="redraw a variation whose IK leaves more than this fraction of its contact frames "
                        "unreachable; skip it after 4 draws (default 0.1; 1.0 keeps every draw)")
    p.add_argument("--occupancy", action="store_true", help="also cache each new scene's occupancy grid")
    p.add_argument("--workers", type=nonneg_int, default=0,
                   help="worker processes (default 0: CPU count; never more than the sequences to do)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (same seed -> same outputs)")
    add_shard_argument(p, "source sequences (in index order, the --splits in turn)")
    add_no_progress_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line of stdout")


def run(args: argparse.Namespace) -> int:
    cfg = PipelineConfig(data=args.data, out=args.out, variations=args.variations, seed=args.seed,
                         splits=tuple(args.splits), kinds=tuple(args.kinds), workers=args.workers,
                         occupancy=args.occupancy, window_s=args.window, threshold=args.threshold,
                         max_unreachable=args.max_unreachable, source=args.source)
    try:
        summary = augment_dataset(cfg, progress=not (args.json or args.no_progress), overwrite=args.overwrite,
                                  shard=args.shard)
    except SourcesFailed as e:  # print what was done, then fail with the one error line
        _print(e.summary, args.json)
        raise
    warn_skipped(summary)
    _print(summary, args.json)
    return 0


def warn_skipped(summary: dict) -> None:
    """One ``trumans: warning:`` line on stderr when variations were not written (``skipped_outputs``),
    naming the objects and the sources, so a run that writes fewer outputs than asked never does so silently."""
    skipped = summary.get("skipped_outputs") or []
    if not skipped:
        return
    by_obj: dict[tuple[str, str], list[int]] = {}
    for s in skipped:
        by_obj.setdefault((s["object"], s["source"]), []).append(int(s["k"]))
    shown = "; ".join(f"{obj} v{','.join(map(str, ks))} of {src}" for (obj, src), ks in list(by_obj.items())[:5])
    more = f" and {len(by_obj) - 5} more" if len(by_obj) > 5 else ""
    print(f"trumans: warning: {len(skipped)} variation(s) not written: {shown}{more} ({skipped[0]['why']}); "
          f"raise --max-unreachable or check those objects' meshes (all in manifest.json, summary.skipped_outputs)",
          file=sys.stderr)


def _print(summary: dict, as_json: bool) -> None:
    summary = {k: v for k, v in summary.items() if k != "config"}
    if as_json:
        print_summary(summary)
    else:
        for k, v in summary.items():
            print(f"{k:>20}: {v}")
