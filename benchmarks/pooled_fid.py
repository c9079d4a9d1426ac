"""fid of generated windows pooled over several `trumans eval synthesis --save-windows` runs (seeds).

One seed's ~130 windows give a noisy Fréchet distance (the same sampler moves by ±10 % between
seeds); pooling the seeds' windows compares samplers or models on a set several times larger, with
the real values taken at the pooled size and action mix (``trumans.sample.eval_synthesis.fid_figures``).

    python benchmarks/pooled_fid.py naive=out/naive_s0.npz,out/naive_s1.npz fast=out/fast_s0.npz,out/fast_s1.npz

Prints one JSON object: per name, the pooled figures and each file's own; with two names, the
first name's fid and fid_matched ÷ the second's (``ratio_<a>_over_<b>``). The reference is the
shipped one (`models/synthesis_reference.npz`) unless --data gives a dataset.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from trumans.sample.eval_synthesis import fid_figures, load_reference, read_windows, reference_windows  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sets", nargs="+", metavar="NAME=FILE[,FILE...]")
    p.add_argument("--data", default=None, help="dataset whose test split is the reference (default: the shipped one)")
    a = p.parse_args(argv)
    if a.data is not None:
        from trumans.eval.motion_encoder import load_motion_encoder

        ref = reference_windows(load_motion_encoder(None), a.data)
    else:
        ref = load_reference()
        if ref is None:
            raise SystemExit("no shipped reference features (models/synthesis_reference.npz); give --data DATASET")
    out, names = {}, []
    for spec in a.sets:
        name, _, files = spec.partition("=")
        if not name or not files:
            raise SystemExit(f"each set is NAME=FILE[,FILE...], got {spec!r}")
        parts = [read_windows(f) for f in files.split(",")]
        feats = np.concatenate([f for f, _ in parts])
        labels = np.concatenate([y for _, y in parts])
        out[name] = {"pooled": fid_figures(feats, labels, ref),
                     "each": [fid_figures(f, y, ref)["fid"] for f, y in parts]}
        names.append(name)
    if len(names) == 2:
        x, y = (out[n]["pooled"] for n in names)
        for key in ("fid", "fid_matched"):
            if key in x and key in y:
                out[f"ratio_{names[0]}_over_{names[1]}_{key}"] = round(x[key] / y[key], 4)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
