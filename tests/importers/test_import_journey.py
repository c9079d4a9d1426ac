"""A newcomer's journey with their own BVH files: import (labels read from the motion, splits with a
validation set, the converter's T-pose frame dropped) -> train a few steps -> sample with that checkpoint."""
from __future__ import annotations

import json
import shutil

import numpy as np

from trumans.cli import console_main
from trumans.importers.cli import split_by_group
from trumans.importers.labels import motion_labels
from trumans.sequence import load_sequence
from trumans.synth.vocab import SYNTH_ACTIONS

from helpers import CMU_WALK_BVH, TEST_DATA

DAZ_BVH = TEST_DATA / "cmu_13_10_daz_first56.bvh"  # a Daz conversion: frame 0 is a synthetic T-pose


def _last_json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_splits_always_hold_a_validation_set():
    assert split_by_group(["a"], 0) == ["train"]
    assert sorted(split_by_group(["a", "b"], 0)) == ["train", "val"]
    four = split_by_group(list("abcd"), 0)
    assert four.count("val") == 1 and four.count("test") == 1 and four.count("train") == 2


def test_motion_labels_follow_a_walk(tmp_path):
    from trumans.importers.bvh import import_bvh

    seq = import_bvh(CMU_WALK_BVH, fps=30, feet_on_floor=True, refine_steps=0)  # start, walk, stop
    labels = motion_labels(seq.joints, seq.fps)
    assert labels.shape == (seq.num_frames, len(SYNTH_ACTIONS))
    on = labels > 0
    assert (on.sum(1) == 1).all()  # one body state per frame
    walk = on[:, SYNTH_ACTIONS.index("walk")]
    assert 0.3 < walk.mean() < 0.95 and not walk[0]  # it starts standing, then walks
    assert ((labels[on] >= 1) & (labels[on] <= 2)).all()  # 1 + progress


def test_import_drops_the_converters_tpose_frame_unless_asked(tmp_path, capsys):
    for flag, name in (([], "dropped"), (["--keep-first-frame"], "kept")):
        assert console_main(["data", "import", str(DAZ_BVH), "--format", "bvh", "--out", str(tmp_path / name),
                             "--feet-on-floor", *flag]) == 0
    dropped, kept = (load_sequence(tmp_path / n / "sequences" / f"{DAZ_BVH.stem}.npz") for n in ("dropped", "kept"))
    assert kept.num_frames == 56 and dropped.num_frames == 55
    span = lambda s: np.linalg.norm(s.joints[0, 20] - s.joints[0, 21])  # noqa: E731  wrist to wrist, m
    assert span(kept) > 1.2 > span(dropped)  # arms straight out in the T-pose only
    np.testing.assert_allclose(dropped.joints[..., :2], kept.joints[1:, :, :2], atol=1e-5)
    dz = dropped.joints[..., 2] - kept.joints[1:, :, 2]  # the same motion, put on the floor without the T-pose
    assert np.ptp(dz) < 1e-5


def test_import_train_sample_journey(tmp_path, capsys):
    src = tmp_path / "mine"
    src.mkdir()
    for i in range(4):
        shutil.copy(CMU_WALK_BVH, src / f"take{i}.bvh")
    files = sorted(str(p) for p in src.glob("*.bvh"))
    assert console_main(["data", "import", *files, "--format", "bvh", "--out", str(tmp_path / "ds"), "--fps", "30",
                         "--feet-on-floor", "--json"]) == 0
    capsys.readouterr()
    index = json.loads((tmp_path / "ds" / "index.json").read_text())
    assert index["splits"]["val"] and index["splits"]["train"] and index["vocabulary"] == list(SYNTH_ACTIONS)
    assert console_main(["train", "--config", "cpu-small", "--data", str(tmp_path / "ds"), "--out",
                         str(tmp_path / "run"), "--steps", "2", "--threads", "1", "--json"]) == 0
    figs = _last_json(capsys)
    assert figs["steps"] == 2 and np.isfinite(figs["val_loss"])
    assert console_main(["sample", "--checkpoint", str(tmp_path / "run" / "checkpoint.pt"), "--scene", "room:2",
                         "--start", "2.4,2.5", "--act", "stand:1.5", "--steps", "2", "--out", str(tmp_path / "stand"),
                         "--formats", "npz", "--no-progress", "--json"]) == 0
    seq = load_sequence(tmp_path / "stand.npz")
    assert seq.num_frames >= 15 and list(seq.action_names) == list(SYNTH_ACTIONS)
