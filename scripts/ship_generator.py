"""Export a trained generator run as the shipped sampling checkpoint (models/generator.pt).

    python scripts/ship_generator.py runs/small/checkpoint.pt --data data/synth --out models/generator.pt \
        --command "trumans train --config cpu-small --data data/synth --augmented data/synth_aug --out runs/small"

Keeps the EMA weights only (no optimiser state: the file is a few MB), adds the sampling
statistics of the training split (``trumans.model.motion_stats``: walking speed, action durations,
a standing start pose; from the procedural takes) to ``meta``, or copies them from another
generator (``--stats-from``), and records the training command and the data hash.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from trumans.dataset import Dataset
from trumans.model.checkpoint import load_checkpoint, save_checkpoint, shipped_data_record
from trumans.model.motion_stats import sampling_stats


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint")
    p.add_argument("--data", required=True, help="the dataset the run was trained on")
    p.add_argument("--out", default="models/generator.pt")
    p.add_argument("--command", default="", help="the training command, recorded in meta")
    p.add_argument("--stats-from", metavar="CHECKPOINT", default=None,
                   help="copy the sampling statistics (walk speed, action durations, start body) from this "
                        "generator checkpoint instead of measuring them on --data: a retrained network with the "
                        "planner of the model it replaces")
    a = p.parse_args(argv)
    ck = load_checkpoint(a.checkpoint, kind="generator")
    ds = Dataset(a.data)
    if a.stats_from:
        src = load_checkpoint(a.stats_from, kind="generator")
        if list(src.vocabulary) != list(ck.vocabulary):
            raise SystemExit(f"--stats-from {a.stats_from} has another action vocabulary than {a.checkpoint}")
        stats = {k: src.meta[k] for k in ("walk_speed", "action_seconds", "start_pose") if k in src.meta}
    else:
        stats = sampling_stats(ds, "train", ck.vocabulary, ck.fps)
    meta = dict(ck.meta)
    meta.update(stats)
    meta["train_command"] = a.command
    weights = ck.ema_state if ck.ema_state is not None else ck.model_state
    out = replace(ck, model_state=weights, ema_state=None, train_state=None, meta=meta, data=shipped_data_record(ck.data))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    save_checkpoint(a.out, out)
    print(json.dumps({"out": a.out, "bytes": Path(a.out).stat().st_size, "data": ck.data,
                      **{k: v for k, v in stats.items() if k != "start_pose"}}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
