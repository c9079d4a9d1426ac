"""`trumans train` / `python -m trumans.train`: train a task (default: the generator) from a config.

Bad input (unknown task, config or ablation, bad values, missing data) raises ValueError /
FileNotFoundError; the console script prints it as the one line ``trumans: error: ...`` (exit 2).
"""
from __future__ import annotations

import argparse
import math
import os
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_device_argument, add_hidden_alias, add_no_progress_argument, out_help

__all__ = ["add_arguments", "run", "main"]

DEVICES = ("cpu", "cuda")


def _builtin_configs() -> str:
    """'generator: cpu-small, paper, ...; contact: free, hinge, slide; ...' from the config folders."""
    from pathlib import Path

    root = Path(__file__).resolve().parent / "configs"
    tasks = {"generator": sorted(p.stem for p in root.glob("*.toml"))}
    tasks.update({d.name: sorted(p.stem for p in d.glob("*.toml")) for d in sorted(root.iterdir()) if d.is_dir()})
    return "; ".join(f"{task}: {', '.join(names)}" for task, names in tasks.items() if names)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--task", default="generator",
                   help="what to train: a registered task (generator, filter, contact, motion_encoder)")
    p.add_argument("--config", default=None,
                   help=f"built-in config of the task ({_builtin_configs()}; contact: one model per dof class) or a "
                        f"TOML file")
    p.add_argument("--data", required=True, help="dataset folder (with index.json)")
    p.add_argument("--out", required=True, help=out_help("folder", "the run (checkpoint.pt, loss.png, cache/); "
                   "--resume continues it"))
    p.add_argument("--augmented", action="append", default=[], metavar="DIR",
                   help="augmented dataset folder (`trumans augment` output) added to the train split; repeatable")
    p.add_argument("--max-steps", dest="steps", type=int, default=None, metavar="N",
                   help="total optimiser steps (default: the config's; --steps is the denoising steps of sample / refine)")
    add_hidden_alias(p, "--steps", "steps", type=int)  # the spelling before issue 37
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    p.add_argument("--init", default=None, metavar="CHECKPOINT",
                   help="fine-tune: start from this checkpoint's weights and normalisation (same task and model; "
                        "its data or other data with the same action vocabulary), fresh optimiser")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (data order, noise, init)")
    p.add_argument("--ablate", action="append", default=[], metavar="NAME",
                   help="switch off a part (generator: progress (indicator), scene / action (condition), "
                        "augmented (data)); repeatable")
    p.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds (overrides config)")
    p.add_argument("--precision", choices=("fp32", "bf16"), default=None,
                   help="bf16: mixed precision (autocast forward and loss, float32 weights; for GPUs); "
                        "default: the config's train.precision (fp32)")
    add_device_argument(p, default=None)
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    add_no_progress_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    import torch

    from trumans.train.loop import train
    from trumans.train.tasks import make_task

    from trumans.out_paths import check_out

    check_out(args.out, "folder")
    if args.init is not None and args.resume:
        raise ValueError("--init starts a new run from a checkpoint's weights and --resume continues the run in "
                         "--out; give one of them")
    if args.threads is not None:
        if args.threads < 1:
            raise ValueError(f"--threads must be >= 1, got {args.threads}")
        torch.set_num_threads(args.threads)
    if args.steps is not None and args.steps < 0:
        raise ValueError(f"--max-steps must be >= 0, got {args.steps}")
    over: dict[str, dict] = {}
    if args.time_limit is not None:
        if not (math.isfinite(args.time_limit) and args.time_limit >= 0):
            raise ValueError(f"--time-limit must be >= 0 seconds (0 = none), got {args.time_limit}")
        over["train"] = {"time_limit_s": float(args.time_limit)}
    if args.precision is not None:
        over.setdefault("train", {})["precision"] = args.precision
    task = make_task(args.task, args.config, overrides=over, ablate=args.ablate)
    res = train(task, args.data, args.out, steps=args.steps, resume=args.resume, seed=args.seed,
                progress=not args.no_progress, device=args.device, augmented_dirs=args.augmented, init=args.init)
    if int(os.environ.get("RANK", "0")) != 0:
        return 0
    print(f"{res.steps} steps, {res.samples_per_s:.1f} samples/s, train loss {res.train_loss:.4f}, "
          f"val loss {res.val_loss:.4f} (zero baseline {res.val_loss_zero_baseline:.4f}, ratio {res.val_ratio:.3f}); "
          f"checkpoint {res.checkpoint}")
    if args.json:
        print_summary(res.to_dict())
    return 0


def main(argv: list[str] | None = None) -> int:
    """`python -m trumans.train ARGS` (also under torchrun) = `trumans train ARGS`, errors on the same channel."""
    import sys

    from trumans.cli import console_main

    return console_main(["train", *(sys.argv[1:] if argv is None else argv)])
