"""Body penetration of the real takes (issue 9 §1): every train clip of the corpus placed in its
room (``trumans.synth.real_takes.real_sequence``, the same seed for every clip), its deepest body
penetration into the room (``ContactResult.penetration``: fitted seats / beds / supports, carried
objects at their per-frame poses, procedural furniture, the floor) and the piece, joint and frame
there. Prints one line per clip and, last, one JSON object: median / p90 / max over the takes,
over the takes with fitted pieces, the pieces at the maxima and the fitted object counts. Usage::

    python benchmarks/real_takes_penetration.py [--seed 0] [--clips 13_04 139_18 ...] [--out per_clip.json]
"""
from __future__ import annotations

import argparse
import collections
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from trumans.contacts.rule import ContactScene  # noqa: E402
from trumans.mocap_corpus import load_corpus  # noqa: E402
from trumans.skeleton import JOINT_NAMES  # noqa: E402
from trumans.synth.real_takes import real_sequence  # noqa: E402


def clip_penetration(clip, seed: int) -> dict:
    """The deepest penetration (cm) of one placed clip and where it is."""
    made = real_sequence(clip, seed)
    if made is None:
        return {"clip": clip.name, "skipped": "fits no room"}
    seq, terms = made
    pen = terms["penetration"]
    f, j = np.unravel_index(np.argmax(pen), pen.shape)
    scene = ContactScene(terms["placement"].scene)
    res = scene.query(seq.joints[f:f + 1].astype(np.float64),
                      {n: t.pose[f:f + 1].astype(np.float64) for n, t in seq.objects.items()})
    k = int(res.mesh_index[0, j])
    return {"clip": clip.name, "max_cm": float(100 * pen.max()), "frame": int(f), "joint": JOINT_NAMES[j],
            "piece": scene.names[k] if k >= 0 else "", "fitted": terms["placement"].fitted}


def summary(rows: list[dict]) -> dict:
    placed = [r for r in rows if "max_cm" in r]

    def stats(rs: list[dict]) -> dict:
        p = np.array([r["max_cm"] for r in rs]) if rs else np.zeros(1)
        return {"takes": len(rs), "median_cm": float(np.median(p)), "p90_cm": float(np.percentile(p, 90)),
                "max_cm": float(p.max())}

    kind = lambda name: name.rsplit("_", 1)[0] if name.startswith("fit_") else name  # noqa: E731
    return {"all": stats(placed), "with_fitted": stats([r for r in placed if r["fitted"]]),
            "skipped": len(rows) - len(placed),
            "piece_at_max": dict(collections.Counter(kind(r["piece"]) for r in placed)),
            "fitted": dict(collections.Counter(kind(n) for r in placed for n in r["fitted"])),
            "worst": sorted(placed, key=lambda r: -r["max_cm"])[:5]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0, help="placement seed of every clip (default 0)")
    ap.add_argument("--clips", nargs="*", default=None, help="only these corpus train clips (default: all)")
    ap.add_argument("--out", default=None, help="write the per-clip rows here (JSON)")
    a = ap.parse_args()
    clips = load_corpus(split="train")
    if a.clips:
        unknown = sorted(set(a.clips) - {c.name for c in clips})
        if unknown:
            sys.exit(f"real_takes_penetration: error: clips {unknown} are not corpus train clips")
        clips = [c for c in clips if c.name in a.clips]
    rows = []
    for c in clips:
        rows.append(clip_penetration(c, a.seed))
        print(json.dumps(rows[-1]), flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(rows, indent=1))
    print(json.dumps(summary(rows)))


if __name__ == "__main__":
    main()
