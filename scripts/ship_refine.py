"""Export a trained filter run as the shipped refine checkpoint (models/refine.pt).

    python scripts/ship_refine.py runs/filter/checkpoint.pt --out models/refine.pt \
        --command "trumans train --task filter --data data/synth_v5 --out runs/filter --steps 3000"

Keeps the EMA weights only, in float16 (``trumans.train.tasks.filter.export_checkpoint``; the fitted joint
skip in ``extra['wiener']`` stays float32), no optimiser state, and records the training command.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from trumans.train.tasks.filter import export_checkpoint
from trumans.model.checkpoint import load_checkpoint, save_checkpoint, shipped_data_record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint")
    p.add_argument("--out", default="models/refine.pt")
    p.add_argument("--command", default="", help="the training command, recorded in meta")
    a = p.parse_args(argv)
    ck = export_checkpoint(load_checkpoint(a.checkpoint, kind="filter"))
    out = replace(ck, meta={**ck.meta, "train_command": a.command}, data=shipped_data_record(ck.data))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    save_checkpoint(a.out, out)
    n = sum(v.numel() for v in out.model_state.values())
    print(json.dumps({"out": a.out, "bytes": Path(a.out).stat().st_size, "parameters": n, "data": ck.data,
                      "wiener": "wiener" in ck.extra}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
