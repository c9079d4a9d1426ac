"""`trumans train --task motion_encoder`: the motion encoder through the shared training loop."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from trumans.dataset import content_hash, write_index
from trumans.eval.motion_encoder import load_motion_encoder
from trumans.train.tasks import make_task, task_names
from trumans.train.tasks.motion_encoder import MotionEncoderTask, MotionEncoderTaskConfig

from helpers import DATASET_VOCAB, make_tiny_dataset

TINY = {"model": {"window": 8, "channels": [8, 8, 8], "feature_dim": 6},
        "train": {"batch_size": 8, "val_every": 100, "checkpoint_every": 100, "warmup_steps": 1}}  # one save per run


def _with_test_split(root: Path) -> Path:
    """The tiny dataset (4 train, 2 val clips) with its first val clip also as the test split."""
    index = json.loads((root / "index.json").read_text())
    index["splits"]["test"] = index["splits"]["val"][:1]
    files = [p for s in ("train", "val") for p in index["splits"][s]]
    write_index(root, {**index, "hash": content_hash(root, files)})
    return root


def test_built_in_config_round_trip_and_errors(tmp_path):
    task = make_task("motion_encoder")
    t = task.config.train
    # the settings of the private trainer it replaced (40 epochs of 19,669 windows at 128 = 6,160 steps)
    assert (t.optimizer, t.lr, t.weight_decay, t.batch_size, t.steps, t.warmup_steps, t.time_limit_s) == \
        ("adamw", 2e-3, 1e-2, 128, 6160, 185, 400.0)
    assert task.config.data.train_stride == 4 and task.config.model.window == 32 and "motion_encoder" in task_names()
    cfg = task.config
    assert MotionEncoderTaskConfig.from_dict(cfg.to_dict()) == cfg and "num_actions" not in cfg.to_dict()["model"]
    toml = tmp_path / "m.toml"
    toml.write_text("[model]\nnum_actions = 5\n")
    with pytest.raises(ValueError, match="num_actions is set by the dataset's vocabulary"):
        make_task("motion_encoder", str(toml))
    toml.write_text("[data]\ntrain_strid = 2\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['train_strid'\]"):
        make_task("motion_encoder", str(toml))
    with pytest.raises(ValueError, match="has no ablations"):
        make_task("motion_encoder", ablate=["scene"])


def test_a_few_steps_through_the_loop_and_the_checkpoint_loads(tmp_path):
    from trumans.train.loop import train

    data = _with_test_split(make_tiny_dataset(tmp_path / "data"))
    task = MotionEncoderTask.from_config(None, overrides=TINY)
    res = train(task, data, tmp_path / "run", steps=3, progress=False)
    assert res.steps == 3 and np.isfinite(res.val_loss) and res.val_loss_zero_baseline > 0
    assert res.train_episodes == len(task.train_set.y) > 8 and res.val_episodes == len(task.val_set.y) > 0
    enc = load_motion_encoder(tmp_path / "run" / "checkpoint.pt")
    assert enc.vocabulary == DATASET_VOCAB and enc.cfg.num_actions == 3 and enc.cfg.window == 8
    fig = enc.info
    for key in ("train_acc", "val_acc", "test_acc", "majority_baseline_acc", "fid_train_vs_test", "diversity_test",
                "diversity_train"):
        assert np.isfinite(fig[key]), key
    assert fig["steps"] == 3 and fig["data_hash"] and 0 <= fig["test_acc"] <= 1
    # the loaded encoder is the run's EMA weights and normalisation: its classification of the test
    # windows gives the recorded accuracy
    from trumans.dataset import Dataset

    ds = Dataset(data)
    seq = ds.load(ds.split("test")[0])
    probs = enc.classify(seq.joints, seq.fps)
    labels = enc.window_labels(seq.actions, list(seq.action_names), seq.fps)
    keep = labels >= 0
    assert fig["test_acc"] == pytest.approx(float((probs.argmax(-1)[keep] == labels[keep]).mean()))
    with pytest.raises(ValueError, match="exists"):
        train(task, data, tmp_path / "run", steps=3, progress=False)
    # exact resume: 2 steps, then resumed to 3 = the 3 steps above (batches: seeded epoch permutations)
    train(MotionEncoderTask.from_config(None, overrides=TINY), data, tmp_path / "two", steps=2, progress=False)
    again = train(MotionEncoderTask.from_config(None, overrides=TINY), data, tmp_path / "two", steps=3, resume=True,
                  progress=False)
    assert again.weights_sha256 == res.weights_sha256


def test_bad_data_is_refused_before_training(tmp_path):
    from trumans.train.loop import train

    data = make_tiny_dataset(tmp_path / "data", num_seqs=3)
    task = MotionEncoderTask.from_config(None, overrides={**TINY, "model": {"window": 200}})  # 20 s windows
    with pytest.raises(ValueError, match="split 'train' of .* gives no labelled 200-frame windows"):
        train(task, data, tmp_path / "run", steps=1, progress=False)
    assert not (tmp_path / "run").exists()
    with pytest.raises(ValueError, match="--augmented is not supported"):
        train(MotionEncoderTask.from_config(None, overrides=TINY), data, tmp_path / "run", steps=1,
              progress=False, augmented_dirs=[data])
