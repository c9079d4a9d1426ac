"""`trumans refine tracked.npz --out refined.npz [--category C]`: the HOI filter (I'm-HOI §3.2).

``trumans refine --interactions ...`` is the older spelling of ``trumans track ...`` (the iReplica
tracker, its own job in ``trumans.track``): the console script's front door (``trumans.cli.main``)
hands it to ``track`` before this module is read, so the filter does not depend on the tracker.
"""
from __future__ import annotations

import argparse
import time

from trumans.threads import add_threads_argument, set_threads
from trumans.refine.post_args import add_post_step_arguments, post_steps_config
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["add_arguments", "run", "main"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.common_args import add_device_argument, out_help

    p.add_argument("input", metavar="tracked.npz",
                   help="tracked sequence .npz: joints (T, 24, 3) m z-up, optional rotations (T, 24, 6), one object's "
                        "pose (T, 4, 4) and category, optional object IMU imu_rot (T, 6) / imu_acc (T, 3); NaN marks "
                        "a missing frame or joint (docs/refine.md 'Input and output'; example: "
                        "examples/tracked_carry.npz, its clean truth examples/tracked_carry_truth.npz)")
    p.add_argument("--out", required=True, help=out_help("file", "the refined sequence .npz (same frames and fps)"))
    p.add_argument("--category", default=None,
                   help="object category (default: the object's own); must be one the filter knows")
    p.add_argument("--object", default=None, help="object to refine with the human (default: the only one, "
                                                  "else the one that moves most); others pass through")
    p.add_argument("--checkpoint", default=None, help="filter checkpoint (default: the shipped models/refine.pt)")
    p.add_argument("--steps", type=int, default=2, help="DDIM sampling steps (default 2; 1, 2 and 5 give the same errors, benchmarks/refine_diagnosis.py)")
    p.add_argument("--mode", choices=("noise", "sdedit"), default="noise",
                   help="start from noise conditioned on the input (the paper) or from the noised input (SDEdit)")
    p.add_argument("--strength", type=float, default=0.5, help="SDEdit noise level in (0, 1] (default 0.5)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="sampling seed")
    add_device_argument(p, runs="the filter network; windowing, blending and the post-steps are numpy on the CPU")
    add_threads_argument(p)
    add_post_step_arguments(p)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")
    p.add_argument("--interactions", action="store_true",
                   help="the older spelling of `trumans track` (contact-driven interaction tracking, iReplica): "
                        "`trumans refine X --interactions ...` runs `trumans track X ...`; see `trumans track --help`")


def run(args: argparse.Namespace) -> int:
    if args.interactions:  # reached only when called without the front door (trumans.cli.main rewrites it)
        raise ValueError("--interactions is `trumans track`: run `trumans track INPUT --scene SCENE --out OUT`")
    from trumans.out_paths import check_out, refuse_dataset_file

    check_out(args.out, "file")
    refuse_dataset_file(args.out)
    set_threads(args.threads)
    from trumans.sequence import load_sequence, save_sequence

    from trumans.refine.pipeline import HOIFilter, RefineOptions

    opts = RefineOptions(num_steps=args.steps, mode=args.mode, strength=args.strength, seed=args.seed,
                         post=post_steps_config(args))
    seq = load_sequence(args.input, allow_missing=True)
    filt = HOIFilter.load(args.checkpoint, device=args.device)
    t0 = time.perf_counter()
    out, name = filt.refine_sequence(seq, category=args.category, object_name=args.object, options=opts)
    seconds = time.perf_counter() - t0
    save_sequence(out, args.out)
    import numpy as np

    summary = {"out": str(args.out), "frames": seq.num_frames, "fps": seq.fps, "object": name,
               "category": out.objects[name].category,
               "missing_frames_in": int(np.isnan(seq.joints).any(axis=(1, 2)).sum()),
               "seconds": round(seconds, 3), "frames_per_s": round(seq.num_frames / max(seconds, 1e-9), 1),
               "post_steps": opts.post_steps(out.objects[name].category), "device": str(args.device)}
    print(f"refined {summary['frames']} frames ({summary['missing_frames_in']} with a missing joint) with object "
          f"{name!r} ({summary['category']}) in {seconds:.2f} s -> {args.out}; after the filter: "
          f"{', '.join(summary['post_steps']) or 'nothing'}")
    if args.json:
        print_summary(summary)
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="trumans refine", description="refine a tracked HOI sequence with the diffusion filter")
    add_arguments(p)
    return run(p.parse_args(argv))
