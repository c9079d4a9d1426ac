"""`trumans train --task contact`: the contact predictor through the shared training loop."""
from __future__ import annotations

import pytest

from trumans.train.tasks.contact import ContactTask, ContactTaskConfig
from trumans.train.tasks import make_task, task_names
from trumans.track.model_io import load_predictor
from trumans.track.predictor import ContactPredictorConfig

from helpers import tiny_contact_dataset


def test_config_round_trip_and_errors(tmp_path):
    cfg = ContactTaskConfig()
    assert ContactTaskConfig.from_dict(cfg.to_dict()) == cfg
    assert cfg.model == ContactPredictorConfig() and cfg.train.lr == 1e-3
    with pytest.raises(ValueError, match="unknown key"):
        ContactTaskConfig.from_dict({"model": {"widnow": 61}})
    toml = tmp_path / "c.toml"
    toml.write_text("[model]\nd_model = 16\nheads = 2\n[train]\nsteps = 7\n")
    task = make_task("contact", str(toml), ablate=["mirror"])
    assert task.config.model.d_model == 16 and task.config.train.steps == 7 and task.config.data.mirror_p == 0.0
    assert "contact" in task_names()
    with pytest.raises(ValueError, match="ablation"):
        make_task("contact", ablate=["scene"])


def test_a_few_steps_through_the_loop(tmp_path):
    from trumans.train.loop import train

    data = tiny_contact_dataset(tmp_path / "data")
    task = ContactTask.from_config(None, overrides={"model": {"d_model": 8, "hidden": 8, "heads": 2, "layers": 1,
                                                              "ff": 8, "window": 15},
                                                    "train": {"batch_size": 4, "val_every": 2, "checkpoint_every": 2},
                                                    "data": {"val_stride": 10}})
    res = train(task, data, tmp_path / "run", steps=3, progress=False)
    assert res.steps == 3 and res.val_loss > 0 and res.val_loss_zero_baseline > 0
    model, info = load_predictor(tmp_path / "run" / "checkpoint.pt")
    assert model.config.window == 15 and info["data"]["hash"] and "ap" in info["meta"]["val_figures"]
    with pytest.raises(ValueError, match="exists"):
        train(task, data, tmp_path / "run", steps=3, progress=False)
