"""Where the posture-change labels sit on the motion, per take source (issue 35: do the real and the
procedural takes label a sit-down the same way?).

    python benchmarks/label_timing.py data/synth_v6 [--split train] [--json]
    python benchmarks/label_timing.py --corpus [--split train]    # the shipped mocap corpus' own states

For every interval of a transition label (``sit_down``, ``stand_up``, ``lie_down``, ``get_up``) in a
dataset's takes, split by source (the index's ``real`` takes against the procedural ones):

- the label's duration (s);
- how much of the posture change is done at label progress 0, 1/4, 1/2, 3/4 and 1: the pelvis height
  change from the label's first frame, as a fraction of the whole change to the settled pelvis (its
  median over the second that starts ``settle_s`` after the label ends: a drop for ``sit_down`` /
  ``lie_down``, a rise for the others);
- the pelvis' ground distance (m) to its settled place at the same progress.

Prints the medians per source and label. A label that covers the whole change ends near 100 %. Until
session 14 the corpus' motion labeller (``trumans.motion_labels``) ended ``sit_down`` where the ``sit``
state began (hips below 88 % of standing height): 8 % of the real takes' drop, against 100 % in the
procedural ones (docs/results.md, "How the sit-down label sits on the motion"); it now labels the whole
change. ``--corpus`` measures the corpus clips' stored states (source ``corpus``) and the states
``trumans.motion_labels`` gives them now (source ``relabelled``): equal once the corpus is rebuilt.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from trumans.motion_labels import segments  # noqa: E402
from trumans.skeleton import JOINT_INDEX  # noqa: E402

TRANSITIONS = ("sit_down", "stand_up", "lie_down", "get_up")
PROGRESS = np.linspace(0.0, 1.0, 5)


def transition_timing(joints: np.ndarray, fps: float, mask: np.ndarray, settle_s: float = 1.0,
                      min_change_m: float = 0.05) -> list[dict[str, object]]:
    """joints (T, 24, 3) z-up m at ``fps``; mask (T,) bool, the frames carrying one label -> one dict per
    run of the mask: ``seconds`` (the run's length), ``done`` (5,) the fraction of the pelvis height
    change done at run progress 0, 1/4, 1/2, 3/4, 1 (the change measured from the run's first frame to
    the settled pelvis: its median over the second starting ``settle_s`` after the run's last frame,
    clipped to the clip), ``distance_m`` (5,) the
    pelvis' ground distance to its settled place at the same progress. Runs shorter than 2 frames or
    whose pelvis moves less than ``min_change_m`` vertically are skipped."""
    J = np.asarray(joints, np.float64)
    m = np.asarray(mask, bool)
    if J.ndim != 3 or J.shape[1:] != (len(JOINT_INDEX), 3) or len(m) != len(J):
        raise ValueError(f"joints must be (T, {len(JOINT_INDEX)}, 3) and mask (T,), got {J.shape} and {m.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    pelvis = J[:, JOINT_INDEX["pelvis"]]
    out = []
    for s, e in segments(m):
        if e - s < 2:
            continue
        a = min(len(J) - 1, e - 1 + int(round(settle_s * fps)))
        settled = np.median(pelvis[a:a + max(1, int(round(fps)))], axis=0)
        change = settled[2] - pelvis[s, 2]
        if abs(change) < min_change_m:
            continue
        idx = np.rint(s + PROGRESS * (e - 1 - s)).astype(int)
        out.append({"seconds": (e - s) / fps,
                    "done": (pelvis[idx, 2] - pelvis[s, 2]) / change,
                    "distance_m": np.linalg.norm(pelvis[idx, :2] - settled[:2], axis=1)})
    return out


def dataset_timing(root: str | Path, split: str = "train") -> dict[str, dict[str, dict[str, object]]]:
    """source ('procedural' / 'real') -> label -> medians (``count``, ``seconds``, ``done`` (5,),
    ``distance_m`` (5,)) over the ``split`` takes of the dataset folder ``root``."""
    from trumans.dataset import load_index
    from trumans.sequence import load_sequence

    root = Path(root)
    if not (root / "index.json").is_file():
        raise FileNotFoundError(f"{root} is not a dataset folder (no index.json); pass one built by `trumans data synth`")
    index = load_index(root)
    if split not in index["splits"]:
        raise ValueError(f"{root} has no split {split!r}; its splits: {sorted(index['splits'])}")
    real = set(index.get("real", {}))
    rows: dict[str, dict[str, list[dict[str, object]]]] = {"procedural": {}, "real": {}}
    for rel in index["splits"][split]:
        seq = load_sequence(root / rel)
        if seq.actions is None or seq.action_names is None:
            continue
        names = list(seq.action_names)
        for label in TRANSITIONS:
            if label in names:
                mask = np.asarray(seq.actions)[:, names.index(label)] > 0
                rows["real" if rel in real else "procedural"].setdefault(label, []).extend(
                    transition_timing(seq.joints, float(seq.fps), mask))
    return _medians(rows)


def corpus_timing(split: str = "train", path: str | Path | None = None) -> dict[str, dict[str, dict[str, object]]]:
    """Like ``dataset_timing`` for the mocap corpus' clips of ``split``: source 'corpus' (their stored
    states) and 'relabelled' (``trumans.motion_labels.label_states`` run on them now)."""
    from trumans.mocap_corpus import load_corpus
    from trumans.motion_labels import MOTION_STATES, label_states

    rows: dict[str, dict[str, list[dict[str, object]]]] = {"corpus": {}, "relabelled": {}}
    for clip in load_corpus(path, split=split):
        for src, states in (("corpus", clip.states), ("relabelled", label_states(clip.joints, clip.fps))):
            for label in TRANSITIONS:
                rows[src].setdefault(label, []).extend(
                    transition_timing(clip.joints, clip.fps, states == MOTION_STATES.index(label)))
    return _medians(rows)


def _medians(rows: dict[str, dict[str, list[dict[str, object]]]]) -> dict[str, dict[str, dict[str, object]]]:
    return {src: {label: {"count": len(r), "seconds": float(np.median([x["seconds"] for x in r])),
                          "done": np.median([x["done"] for x in r], axis=0).round(3).tolist(),
                          "distance_m": np.median([x["distance_m"] for x in r], axis=0).round(3).tolist()}
                  for label, r in by.items() if r}
            for src, by in rows.items()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", nargs="?", help="dataset folder (index.json + sequences/)")
    p.add_argument("--corpus", action="store_true", help="measure the mocap corpus instead of a dataset")
    p.add_argument("--split", default="train")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.corpus == (a.dataset is not None):
        p.error("give a dataset folder or --corpus (one of them)")
    res = corpus_timing(a.split) if a.corpus else dataset_timing(a.dataset, a.split)
    if a.json:
        print(json.dumps(res))
        return 0
    for src, by in res.items():
        for label, r in by.items():
            done = " / ".join(f"{100 * v:.0f}" for v in r["done"])
            dist = " / ".join(f"{v:.2f}" for v in r["distance_m"])
            print(f"{src:10s} {label:9s} n={r['count']:4d}  {r['seconds']:.2f} s  done at 0..1: {done} %  "
                  f"to the settled place: {dist} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
