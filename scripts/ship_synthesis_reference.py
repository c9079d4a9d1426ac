"""Write the fid reference of ``trumans eval synthesis`` (models/synthesis_reference.npz).

    python scripts/ship_synthesis_reference.py --data data/synth_v3 --out models/synthesis_reference.npz

Stores, for the shipped motion encoder (or ``--encoder``), the features and window labels of the
dataset's test split and of 3,000 seeded windows of its train split (``trumans.sample.eval_synthesis.
reference_windows``). Re-run it whenever the shipped motion encoder changes.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from trumans.sample.eval_synthesis import reference_windows
from trumans.eval.motion_encoder import load_motion_encoder


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, help="the dataset the motion encoder was trained on")
    p.add_argument("--encoder", default=None, help="motion encoder (default: the shipped one)")
    p.add_argument("--out", default="models/synthesis_reference.npz")
    a = p.parse_args(argv)
    ref = reference_windows(load_motion_encoder(a.encoder), a.data)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(a.out).with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **ref)
    tmp.replace(a.out)
    print(json.dumps({"out": a.out, "bytes": Path(a.out).stat().st_size, "test_windows": len(ref["features"]),
                      "train_windows": len(ref["train_features"]), "data_hash": str(ref["data_hash"])}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
