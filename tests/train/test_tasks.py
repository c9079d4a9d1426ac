"""The trainer for several tasks: nested configs and their value checks, the task registry, the CLI's
errors, a second (non-generator) task through the same loop with exact resume, refused resumes."""
from __future__ import annotations

import json
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pytest
import torch

from helpers import TINY_TOML, make_tiny_dataset
from trumans.config_data import config_from_dict
from trumans.train.config import GeneratorConfig, TrainSection, load_config
from trumans.train.tasks import TASKS, TaskLoss, make_task, register_task
from trumans.model.checkpoint import KINDS, Checkpoint, KindSpec, load_checkpoint
from trumans.model.nets import DenoiserConfig

torch.set_num_threads(1)


def test_config_nests_component_configs(tmp_path: Path) -> None:
    cfg = load_config("cpu-small")
    assert isinstance(cfg.model, DenoiserConfig) and cfg.model.frames == cfg.data.episode_frames == 16
    assert cfg.model.scene == cfg.scene and cfg.scene.grid == cfg.data.grid and cfg.model.action.frames == 16
    assert (cfg.diffusion.schedule, cfg.diffusion.prediction) == ("cosine", "x0")  # reaches noise; x0 for the sampler
    assert cfg.denoiser_config(7).action.num_actions == 7
    assert GeneratorConfig.from_dict(cfg.to_dict()) == cfg and "frames" not in cfg.to_dict()["model"]
    p = tmp_path / "c.toml"
    p.write_text(TINY_TOML + '[diffusion]\nschedule = "cosine"\nprediction = "x0"\nloss = "l1"\n'
                 '[conditions]\nscene = false\n[data]\nepisode_frames = 12\nrotations = true\n')
    with pytest.raises(ValueError, match="data"):  # [data] twice is invalid TOML
        load_config(p)
    p.write_text(TINY_TOML.replace("[data]\n", "[data]\nepisode_frames = 12\nrotations = true\n") +
                 '[diffusion]\nschedule = "cosine"\nprediction = "x0"\nloss = "l1"\n[conditions]\nscene = false\n')
    c = load_config(p)
    assert (c.diffusion.schedule, c.diffusion.prediction, c.diffusion.loss) == ("cosine", "x0", "l1")
    assert c.model.scene is None and c.model.frames == 12 and c.model.action.frames == 12 and c.model.layout.rotations
    assert c.model.feature_dim == 24 * 9
    # a config saved before the nesting (checkpoints' train_state) reads as the same config
    legacy = c.to_dict()
    legacy["model"].update(scene_condition=False, action_condition=True)
    legacy.pop("conditions")
    legacy["action"]["patch"] = 8
    assert GeneratorConfig.from_dict(legacy) == c


@pytest.mark.parametrize("text,match", [
    ("[model]\nframes = 8\n", "model.frames is set by data.episode_frames"),
    ("[scene]\ngrid = 16\n", "scene.grid is set by data.grid"),
    ("[action]\nnum_actions = 3\n", "vocabulary"),
    ("[train]\ncheckpoint_every = 0\n", "checkpoint_every must be >= 1"),
    ("[train]\nval_every = 0\n", "val_every must be >= 1"),
    ("[train]\nema_decay = 1.0\n", r"ema_decay must be in \[0, 1\)"),
    ("[train]\nema_decay = -0.5\n", r"ema_decay must be in \[0, 1\)"),
    ("[train]\nlr = nan\n", "train.lr must be a finite number"),
    ("[train]\ntime_limit_s = -1\n", "time_limit_s must be >= 0"),
    ("[train]\np_drop_scene = 1.5\n", "p_drop_scene must be a probability"),
    ("[diffusion]\nbeta_end = inf\n", "finite"),
    ("[diffusion]\nschedule = \"sigmoid\"\n", "schedule must be"),
    ("[diffusion]\nprediction = \"score\"\n", "prediction must be"),
    ("[data]\nextent = [1.2, nan, 1.2]\n", "finite"),
    ("[data]\ntransition_frames = 16\n", "transition_frames"),
    ("[data]\nfps = 0\n", "fps must be > 0"),
    ("[model]\nheads = 5\n", "heads \\(5\\) must divide d_model \\(512\\)"),  # refused when read, before any weight
])
def test_config_value_errors(tmp_path: Path, text: str, match: str | None) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_config(p)


def test_task_registry_and_cli_errors(tmp_path: Path, capsys) -> None:
    from trumans.cli import console_main

    with pytest.raises(ValueError, match=r"unknown task 'dance'; registered tasks: \[.*'generator'"):
        make_task("dance")
    task = make_task("generator", None, overrides={"train": {"time_limit_s": 5.0}}, ablate=["scene", "progress"])
    assert task.config.name == "cpu-small" and task.config.train.time_limit_s == 5.0
    assert task.config.model.scene is None and not task.config.data.progress_indicator
    with pytest.raises(ValueError, match=r"unknown ablation 'legs'.*'augmented'"):
        make_task("generator", ablate=["legs"])
    with pytest.raises(ValueError, match="a task name is a word"):
        register_task("bad name", lambda *a, **k: None)
    base = ["train", "--data", str(tmp_path), "--out", str(tmp_path / "run")]
    for extra, msg in ((["--task", "dance"], "unknown task 'dance'"), (["--device", "gpu0"], "is not a device; give cpu, cuda or cuda:N"),
                       (["--time-limit", "-5"], "--time-limit must be >= 0"), (["--max-steps", "-1"], "--max-steps must be >= 0"),
                       (["--steps", "-1"], "--max-steps must be >= 0"),
                       (["--ablate", "legs"], "unknown ablation")):
        assert console_main(base + extra) == 2
        err = capsys.readouterr().err
        assert err.startswith("trumans: error: ") and msg in err and err.count("\n") == 1, err


# --- a second task through the same loop -------------------------------------------------------------------

@dataclass(frozen=True)
class RegressionConfig:
    name: str = "regression"
    width: int = 4
    train: TrainSection = field(default_factory=lambda: TrainSection(
        steps=60, batch_size=16, lr=0.1, grad_clip=0.0, ema_decay=0.5, checkpoint_every=30, val_every=10,
        val_batch_size=64))

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "RegressionConfig":
        return config_from_dict(cls, d)


@dataclass(frozen=True)
class LinearConfig:
    width: int = 4

    def to_dict(self) -> dict:
        return asdict(self)


class RegressionTask:
    """y = x w on random data: the smallest task that uses every hook of the protocol."""

    kind = "contact"

    def __init__(self, config: RegressionConfig) -> None:
        self.config = config

    def setup(self, data_dir, out_dir, *, is_main, barrier, prev, seed=0, extra_dirs=(), progress=True) -> None:
        g = torch.Generator().manual_seed(123)
        self.x = torch.randn(256, self.config.width, generator=g)
        self.y = self.x @ torch.arange(1.0, self.config.width + 1)
        self.seed = seed
        barrier()

    def build_model(self) -> torch.nn.Module:
        return torch.nn.Linear(self.config.width, 1, bias=False)

    def batch(self, step, rank, world):
        b = self.config.train.batch_size // world
        idx = (step * self.config.train.batch_size + rank * b + torch.arange(b)) % 192
        return self.x[idx], self.y[idx]

    def loss(self, model, batch, generator, device) -> TaskLoss:
        x, y = batch
        noise = 0.01 * torch.randn(y.shape, generator=generator)
        mse = (model(x)[:, 0] - y - noise).square().mean()
        l2 = 1e-4 * model.weight.square().sum()
        return TaskLoss(mse + l2, {"mse": mse, "l2": l2})

    def validate(self, model) -> tuple[float, float]:
        with torch.no_grad():
            x, y = self.x[192:], self.y[192:]
            return float((model(x)[:, 0] - y).square().mean()), float(y.square().mean())

    def sizes(self) -> tuple[int, int]:
        return 192, 64

    def checkpoint(self, *, model_state, ema_state, meta, train_state) -> Checkpoint:
        return Checkpoint(kind="contact", model_config=LinearConfig(self.config.width), model_state=model_state,
                          ema_state=ema_state, meta=meta, train_state=train_state, extra={"target": "y = x w"})


def test_a_second_task_trains_and_resumes_exactly(tmp_path: Path, monkeypatch) -> None:
    from trumans.train.loop import train

    monkeypatch.setitem(KINDS, "contact", KindSpec(config_from_dict=lambda d: LinearConfig(**d),
                                                   build=lambda c: torch.nn.Linear(c.width, 1, bias=False)))
    monkeypatch.setitem(TASKS, "regression", lambda config, overrides, ablate: RegressionTask(RegressionConfig()))
    task = make_task("regression")
    full = train(task, tmp_path, tmp_path / "full", seed=4, progress=False)
    assert full.steps == 60 and full.val_loss < 0.01 * full.val_loss_zero_baseline
    ck = load_checkpoint(full.checkpoint, kind="contact")
    assert ck.extra == {"target": "y = x w"} and ck.normalizer is None
    assert torch.allclose(ck.build_model().weight, torch.arange(1.0, 5.0)[None], atol=0.25)  # EMA weights near w
    hist = ck.train_state["history"]
    assert len(hist["terms"]["mse"]) == 60 and len(hist["terms"]["l2"]) == 60 and hist["val_step"] == [10, 20, 30, 40, 50, 60]
    part = train(make_task("regression"), tmp_path, tmp_path / "part", steps=15, seed=4, progress=False)
    assert part.steps == 15
    resumed = train(make_task("regression"), tmp_path, tmp_path / "part", resume=True, seed=4, progress=False)
    assert resumed.weights_sha256 == full.weights_sha256
    assert load_checkpoint(resumed.checkpoint, kind="contact").train_state["history"]["train"] == hist["train"]
    with pytest.raises(ValueError, match="'contact' checkpoint, but a 'generator'"):
        train(load_config("cpu-small"), tmp_path, tmp_path / "full", resume=True, seed=4, progress=False)


def test_generator_with_cosine_v_and_refused_resumes(tmp_path: Path) -> None:
    from trumans.train.loop import train

    data = make_tiny_dataset(tmp_path / "data", num_seqs=3, frames=90)
    p = tmp_path / "t.toml"
    p.write_text(TINY_TOML + '[diffusion]\nschedule = "cosine"\nprediction = "v"\n')
    cfg = load_config(p)
    res = train(cfg, data, tmp_path / "run", steps=1, progress=False)
    ck = load_checkpoint(res.checkpoint)
    assert (ck.diffusion_config.schedule, ck.diffusion_config.prediction) == ("cosine", "v")
    assert np.isfinite(res.val_loss) and res.val_loss_zero_baseline > 0
    with pytest.raises(ValueError, match="different config"):
        train(load_config(p).with_overrides(diffusion={"prediction": "eps"}), data, tmp_path / "run", steps=2,
              resume=True, progress=False)
    # the same data under another vocabulary (the content hash covers the sequences, not the names)
    index = json.loads((data / "index.json").read_text())
    index["vocabulary"] = index["vocabulary"][::-1]
    other = tmp_path / "other"
    shutil.copytree(data, other)
    (other / "index.json").write_text(json.dumps(index))
    with pytest.raises(ValueError, match=r"trained with the action vocabulary \['walk', 'sit', 'reach'\], but .* has "
                                         r"\['reach', 'sit', 'walk'\]"):
        train(cfg, other, tmp_path / "run", steps=2, resume=True, progress=False)


class DivergingTask(RegressionTask):
    def loss(self, model, batch, generator, device) -> TaskLoss:
        self.calls = getattr(self, "calls", 0) + 1
        out = super().loss(model, batch, generator, device)
        return TaskLoss(out.loss * (float("nan") if self.calls > 35 else 1.0), out.terms)


def test_a_diverging_run_stops_with_a_clear_error_and_keeps_its_checkpoint(tmp_path: Path, monkeypatch) -> None:
    from trumans.train.loop import train

    monkeypatch.setitem(KINDS, "contact", KindSpec(config_from_dict=lambda d: LinearConfig(**d),
                                                   build=lambda c: torch.nn.Linear(c.width, 1, bias=False)))
    with pytest.raises(ValueError, match=r"loss became nan at step 36 \(the checkpoint of step 30 is kept\)"):
        train(DivergingTask(RegressionConfig()), tmp_path, tmp_path / "run", progress=False)
    assert load_checkpoint(tmp_path / "run" / "checkpoint.pt", kind="contact").train_state["step"] == 30
