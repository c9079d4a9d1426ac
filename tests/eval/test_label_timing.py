"""benchmarks/label_timing.py: where a transition label sits on the pelvis' posture change."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import sit_stand_take, standing_body
from trumans.actions import ActionInterval, labels_from_intervals
from trumans.dataset import content_hash, write_index
from trumans.sequence import Sequence, save_sequence

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "label_timing.py"
_spec = importlib.util.spec_from_file_location("label_timing", SCRIPT)
label_timing = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(label_timing)

FPS = 30.0


def sitting_body(T: int = 120, drop: tuple[int, int] = (30, 70), depth: float = 0.45, back: float = 0.3) -> np.ndarray:
    """(T, 24, 3): a standing body lowered by ``depth`` m and moved ``back`` m along -x, both linearly over
    the frames ``drop`` [start, end), still before and after."""
    J = standing_body(T)[0]
    s, e = drop
    f = np.clip((np.arange(T) - s) / (e - 1 - s), 0.0, 1.0)
    J[..., 2] -= depth * f[:, None]
    J[..., 0] -= back * f[:, None]
    return J


def test_a_label_over_the_whole_change_ends_done_and_a_short_one_part_way():
    J = sitting_body()
    whole = np.zeros(len(J), bool)
    whole[30:70] = True
    (r,) = label_timing.transition_timing(J, FPS, whole)
    assert r["seconds"] == pytest.approx(40 / FPS)
    np.testing.assert_allclose(r["done"], [0.0, 0.25, 0.5, 0.75, 1.0], atol=0.02)
    np.testing.assert_allclose(r["distance_m"], 0.3 * (1 - np.array([0.0, 0.25, 0.5, 0.75, 1.0])), atol=0.01)
    short = np.zeros(len(J), bool)
    short[30:40] = True  # the first quarter of the drop only
    (r,) = label_timing.transition_timing(J, FPS, short)
    assert r["done"][-1] == pytest.approx(9 / 39, abs=1e-6)  # frame 39 of a drop over frames 30..69
    assert r["distance_m"][0] == pytest.approx(0.3, abs=1e-6)


def test_still_runs_and_single_frames_are_skipped_and_bad_input_refused():
    J = sitting_body()
    m = np.zeros(len(J), bool)
    m[[5, 80]] = True  # two 1-frame runs
    m[90:110] = True  # seated, still: no posture change
    assert label_timing.transition_timing(J, FPS, m) == []
    with pytest.raises(ValueError, match="joints must be"):
        label_timing.transition_timing(J[:, :10], FPS, m)
    with pytest.raises(ValueError, match="mask"):
        label_timing.transition_timing(J, FPS, m[:-1])
    with pytest.raises(ValueError, match="fps"):
        label_timing.transition_timing(J, 0.0, m)


def test_a_dataset_splits_real_and_procedural_takes(tmp_path):
    vocab = ["stand", "sit_down", "sit"]
    rels = []
    for name, label_end in (("proc", 70), ("real", 40)):
        J = sitting_body()
        acts = labels_from_intervals([ActionInterval("stand", 0, 30), ActionInterval("sit_down", 30, label_end),
                                      ActionInterval("sit", label_end, len(J))], vocab, len(J))
        rel = f"sequences/{name}.npz"
        save_sequence(Sequence(joints=J, fps=FPS, actions=acts, action_names=vocab), tmp_path / rel)
        rels.append(rel)
    write_index(tmp_path, {"name": "t", "version": "1", "fps": 30, "vocabulary": vocab,
                           "splits": {"train": rels, "val": [], "test": []}, "scenes": {}, "real": {rels[1]: "cmu:x"},
                           "hash": content_hash(tmp_path, rels)})
    res = label_timing.dataset_timing(tmp_path)
    assert res["procedural"]["sit_down"]["count"] == 1 and res["real"]["sit_down"]["count"] == 1
    assert res["procedural"]["sit_down"]["done"][-1] == pytest.approx(1.0, abs=0.01)
    assert res["real"]["sit_down"]["done"][-1] < 0.3
    out = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--json"], capture_output=True, text=True,
                         check=True)
    assert json.loads(out.stdout)["real"]["sit_down"]["seconds"] == pytest.approx(10 / FPS)
    with pytest.raises(ValueError, match="no split"):
        label_timing.dataset_timing(tmp_path, "nope")
    with pytest.raises(FileNotFoundError, match="index.json"):
        label_timing.dataset_timing(tmp_path / "sequences")


def test_the_corpus_stored_states_against_the_labeller(tmp_path):
    from trumans.mocap_corpus import MocapClip, write_corpus
    from trumans.motion_labels import MOTION_STATES

    J = sit_stand_take(FPS)
    old = np.zeros(len(J), np.int64)  # a corpus written with a short sit_down: 4 frames at the drop's start
    old[49:53] = MOTION_STATES.index("sit_down")
    old[53:-60] = MOTION_STATES.index("sit")
    path = tmp_path / "corpus.npz"
    write_corpus(path, [MocapClip("01_01", "01", "sit", "train", FPS, J, old)], {})
    res = label_timing.corpus_timing("train", path)
    assert res["corpus"]["sit_down"]["done"][-1] < 0.5
    assert res["relabelled"]["sit_down"]["done"][-1] > 0.85 and res["relabelled"]["stand_up"]["count"] == 1
    assert label_timing.corpus_timing("test", path) == {"corpus": {}, "relabelled": {}}
