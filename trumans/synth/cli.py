"""`trumans data synth`: build the embedded synthetic HSI dataset (rooms + motions + actions + contacts)."""
from __future__ import annotations

import argparse

from trumans.argtypes import float_in, int_in, nonneg_int
from trumans.limits import MAX_ROOMS, MAX_SYNTH_HOURS
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_no_progress_argument, out_help
from trumans.shards import add_shard_argument


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help=out_help("folder", "the dataset (scenes/, sequences/, index.json; with "
                   "--shard: the shard's files and shard.json); new, empty, or an interrupted build of the same "
                   "settings (it resumes)"))
    p.add_argument("--overwrite", action="store_true", help="replace the dataset already in --out")
    p.add_argument("--hours", type=float_in(0.0, MAX_SYNTH_HOURS, lo_open=True, limit="MAX_SYNTH_HOURS"), default=2.0,
                   help=f"hours of motion at 30 fps (default 2, at most {MAX_SYNTH_HOURS:g})")
    p.add_argument("--rooms", type=int_in(1, MAX_ROOMS, limit="MAX_ROOMS"), default=50,
                   help=f"number of procedural rooms (default 50, at most {MAX_ROOMS:,})")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (same seed -> same data)")
    p.add_argument("--workers", type=nonneg_int, default=0, help="worker processes, rooms in parallel (default: CPU count)")
    p.add_argument("--real-share", type=float_in(0.0, 1.0), default=1.0,
                   help="share of the mocap corpus's train clips added as real takes, each in a procedural room "
                        "that leaves its path free (default 1 = all that fit a room; 0 = procedural only)")
    add_shard_argument(p, "rooms (then real clips)")
    add_no_progress_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line of stdout")


def run(args: argparse.Namespace) -> int:
    from .build import SynthConfig, build_dataset

    cfg = SynthConfig(out=args.out, hours=args.hours, rooms=args.rooms, seed=args.seed, workers=args.workers,
                      real_share=args.real_share)
    summary = build_dataset(cfg, progress=not args.no_progress, overwrite=args.overwrite, shard=args.shard)
    if args.json:
        print_summary(summary)
    elif args.shard is not None:
        print(f"wrote shard {summary['shard']} ({summary['items']} of {summary['total']} rooms and real clips, "
              f"{summary['files']} files) to {summary['out']}; join all shards with `trumans data merge`")
    else:
        print(f"wrote {summary['sequences']} sequences, {summary['hours']:.2f} h over {summary['rooms']} rooms "
              f"to {summary['out']} in {summary['seconds']:.0f} s")
        for k in ("bone_length_dev_mm", "foot_skate_per_step_cm", "penetration_max_cm", "grasp_dist_cm"):
            print(f"  {k}: {summary[k]:.3f}")
        if "real" in summary:
            r = summary["real"]
            print(f"  real takes: {r['takes']} of {r['clips']} corpus train clips ({r['hours']:.2f} h), "
                  f"{r['skipped']} fit no room")
        if summary["actions_missing"]:
            print(f"  actions missing: {summary['actions_missing']}")
    return 0
