"""Rebuild data/mocap/cmu_corpus.npz from the raw CMU clips (deterministic: same files, same bytes).

    tar xJf ../shared/data/mocap/cmu_subset.tar.xz -C /tmp/mocap
    python scripts/build_mocap_corpus.py --raw /tmp/mocap --clips ../shared/data/mocap/clips.csv

Every clip of clips.csv is converted with ``trumans.mocap_corpus.convert_clip`` (FBX 6.1 Daz-style
or BVH, the first-frame T-pose dropped, resampled once from the raw keys to 30 fps by
``trumans.resample.resample_smooth``: a zero-phase 6 Hz Butterworth low-pass and a cubic spline;
feet on the floor, per-frame states). Duplicate
captures are skipped (77_xx = 139_xx, per the INDEX). Clips of ``HELD_OUT_SUBJECTS`` form the test
split.
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
import warnings
from pathlib import Path

from trumans.mocap_corpus import CORPUS_PATH, HELD_OUT_SUBJECTS, convert_clip, write_corpus


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--raw", required=True, help="folder the tarball was extracted into (holds raw/)")
    p.add_argument("--clips", required=True, help="clips.csv of the raw files")
    p.add_argument("--out", default=str(CORPUS_PATH), help=f"npz to write (default {CORPUS_PATH})")
    p.add_argument("--limit", type=int, help="convert only the first N clips (a quick check)")
    args = p.parse_args(argv)
    rows = list(csv.DictReader(open(args.clips, newline="")))
    if args.limit:
        rows = rows[:args.limit]
    clips, t = [], time.time()
    for r in rows:
        path = Path(args.raw) / r["local_path"]
        if not path.is_file():
            raise FileNotFoundError(f"{path} (clip {r['clip']}) does not exist; extract the tarball into --raw")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            clips.append(convert_clip(path, r["clip"], r["cmu_description"]))
        print(f"{r['clip']:>7} {clips[-1].split:5} {len(clips[-1].joints):6d} frames  {time.time() - t:6.1f} s",
              file=sys.stderr)
    meta = {"source": "CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu), see data/mocap/LICENSE.md",
            "held_out_subjects": list(HELD_OUT_SUBJECTS), "fps": 30.0, "quantum_m": 1e-4,
            "clips_csv_rows": len(rows)}
    write_corpus(args.out, clips, meta)
    n_test = sum(c.split == "test" for c in clips)
    print(f"wrote {args.out}: {len(clips)} clips ({n_test} held out), "
          f"{sum(len(c.joints) for c in clips) / 30 / 60:.1f} min", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
