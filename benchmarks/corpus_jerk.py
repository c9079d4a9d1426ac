"""Jerk of the mocap corpus against the jerk of its raw keys (issue 35: does the resampling add jerk?).

    mkdir -p /tmp/mocap && tar xJf ../shared/data/mocap/cmu_subset.tar.xz -C /tmp/mocap
    python benchmarks/corpus_jerk.py --raw /tmp/mocap --clips ../shared/data/mocap/clips.csv \
        data/mocap/cmu_corpus.npz [OTHER_CORPUS.npz ...] [--json]

Per clip, the median joint jerk (third difference x fps^3, m/s^3, all joints) over its walking
frames and over its seated frames (the states of the first corpus given), measured

- on the raw keys without any interpolation: 24 fps FBX keys taken every 3rd (8 fps) and every
  2nd key (12 fps), which bracket 10 fps; 120 fps BVH frames every 12th (10 fps) and as they are;
- on each corpus: at its 30 fps and taken every 3rd frame (10 fps, what ``trumans.resample``
  gives the 10 fps generator).

Prints the median over the clips (with the 10th-90th percentile) per split and source rate.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def state_jerk(joints: np.ndarray, fps: float, states30: np.ndarray, state: int, min_windows: int = 6) -> float:
    """Median jerk (m/s^3) over the jerk windows of joints (T, 24, 3) at ``fps`` whose centre falls on
    a frame of ``state`` (the 30 fps ``states30``); NaN with fewer than ``min_windows``."""
    jerk = np.linalg.norm(np.diff(np.asarray(joints, np.float64), n=3, axis=0), axis=-1) * fps ** 3  # (T-3, 24)
    centre = (np.arange(len(jerk)) + 1.5) / fps
    on = states30[np.clip(np.round(centre * 30.0).astype(int), 0, len(states30) - 1)] == state
    return float(np.median(jerk[on])) if on.sum() >= min_windows else float("nan")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("corpora", nargs="+", help="corpus .npz files (the first one's states select the frames)")
    p.add_argument("--raw", required=True, help="folder the raw tarball was extracted into (holds raw/)")
    p.add_argument("--clips", required=True, help="clips.csv of the raw files")
    p.add_argument("--min-seconds", type=float, default=3.0, help="clips with at least this much of the state")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()

    from trumans.mocap_corpus import load_corpus, source_joints
    from trumans.motion_labels import MOTION_STATES

    corpora = [{c.name: c for c in load_corpus(path)} for path in args.corpora]
    rows = {r["clip"]: r for r in csv.DictReader(open(args.clips, newline=""))}
    states = {"walk": MOTION_STATES.index("walk"), "sit": MOTION_STATES.index("sit")}
    per: dict[tuple, list[float]] = {}
    for name, first in corpora[0].items():
        st = first.states
        want = {s: i for s, i in states.items() if (st == i).sum() >= args.min_seconds * 30}
        if not want:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            keys, fps = source_joints(Path(args.raw) / rows[name]["local_path"])
        raw = {"raw keys, every 3rd (8 fps)": (keys[::3], fps / 3), "raw keys, every 2nd (12 fps)": (keys[::2], fps / 2)} \
            if fps < 60 else {"raw frames, every 12th (10 fps)": (keys[::12], fps / 12), "raw frames (120 fps)": (keys, fps)}
        for s, i in want.items():
            for label, (j, f) in raw.items():
                per.setdefault((first.split, fps, s, label), []).append(state_jerk(j, f, st, i))
            for path, corpus in zip(args.corpora, corpora):
                c = corpus[name]
                for label, (j, f) in ((f"{Path(path).name} 30 fps", (c.joints, 30.0)),
                                      (f"{Path(path).name} 10 fps", (c.joints[::3], 10.0))):
                    per.setdefault((first.split, fps, s, label), []).append(state_jerk(j, f, st, i))
    out = []
    for (split, fps, s, label), v in sorted(per.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2])):
        v = np.asarray(v)
        v = v[np.isfinite(v)]
        if len(v):
            out.append({"split": split, "source_fps": fps, "state": s, "measured_on": label, "clips": len(v),
                        "median": round(float(np.median(v)), 2), "p10": round(float(np.percentile(v, 10)), 2),
                        "p90": round(float(np.percentile(v, 90)), 2)})
    if args.json:
        print(json.dumps(out))
    else:
        for r in out:
            print(f"{r['split']:5} {r['source_fps']:5.0f} fps {r['state']:4}  {r['measured_on']:42} n={r['clips']:3d}  "
                  f"median {r['median']:7.2f}  (p10 {r['p10']:7.2f}, p90 {r['p90']:7.2f}) m/s^3")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
