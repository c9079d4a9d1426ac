"""`trumans train` / `python -m train`: train the generator from a config (CLI module contract)."""
from __future__ import annotations

import argparse
import json
import sys

__all__ = ["add_arguments", "run", "main"]

ABLATIONS = {
    "progress": ("data", "progress_indicator"),
    "scene": ("model", "scene_condition"),
    "augmented": ("data", "augmented"),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", default="cpu-small", help="built-in config (cpu-small, paper) or a TOML file")
    p.add_argument("--data", required=True, help="dataset folder (with index.json)")
    p.add_argument("--out", required=True, help="run folder: checkpoint.pt, loss.png, cache/")
    p.add_argument("--augmented", action="append", default=[], metavar="DIR",
                   help="augmented dataset folder (`trumans augment` output) added to the train split; repeatable")
    p.add_argument("--steps", type=int, default=None, help="total optimisation steps (default: the config's)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    p.add_argument("--seed", type=int, default=0, help="random seed (data order, noise, init)")
    p.add_argument("--ablate", action="append", default=[], choices=sorted(ABLATIONS),
                   help="switch off: progress (indicator), scene (condition), augmented (data); repeatable")
    p.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds (overrides config)")
    p.add_argument("--device", default=None, help="cpu or cuda (default: cuda if available)")
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    import torch

    from .config import load_config
    from .loop import train

    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        cfg = load_config(args.config)
        over: dict[str, dict] = {}
        for a in args.ablate:
            sec, key = ABLATIONS[a]
            over.setdefault(sec, {})[key] = False
        if args.time_limit is not None:
            over.setdefault("train", {})["time_limit_s"] = float(args.time_limit)
        if over:
            cfg = cfg.with_overrides(**over)
        res = train(cfg, args.data, args.out, steps=args.steps, resume=args.resume, seed=args.seed,
                    progress=not args.no_progress, device=args.device,
                    augmented_dirs=args.augmented)
    except (ValueError, FileNotFoundError) as e:
        print(f"trumans train: {e}", file=sys.stderr)
        return 2
    d = res.to_dict()
    import os
    if int(os.environ.get("RANK", "0")) != 0:
        return 0
    print(f"{res.steps} steps, {res.samples_per_s:.1f} samples/s, train loss {res.train_loss:.4f}, "
          f"val loss {res.val_loss:.4f} (zero baseline {res.val_loss_zero_baseline:.4f}, ratio {res.val_ratio:.3f}); "
          f"checkpoint {res.checkpoint}")
    if args.json:
        print(json.dumps(d))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train", description="train the TRUMANS generator")
    add_arguments(p)
    return run(p.parse_args(argv))
