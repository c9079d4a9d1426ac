"""Training the motion encoder of the synthesis figures (``trumans.eval.motion_encoder``) as a
``trumans.train.tasks.Task``: ``trumans train --task motion_encoder --data DATASET --out RUN``.

Examples: canonical windows of the train split (``window`` frames at the encoder's fps, one every
``data.train_stride`` frames) labelled with their dominant action in the dataset vocabulary
(windows with no action on are dropped); loss: softmax cross-entropy (the HumanML3D evaluator's
recipe, Guo et al. 2022 §5). Batches walk through seeded permutations of the windows (epochs).
Validation: the cross-entropy on the val split's windows (one every ``window // 2`` frames) against
a constant predictor of the training set's action frequencies. The shared loop
(``trumans.train.loop``) runs the optimiser, warm-up, EMA, checkpoints and validation.

Every checkpoint's ``meta["figures"]`` (the EMA weights; ``MotionEncoder.info`` once loaded) holds
the report: ``train_acc``, ``val_acc`` / ``val_majority_baseline_acc``, and with a test split
``test_acc``, ``majority_baseline_acc`` (the train split's most frequent action, scored on test),
``fid_train_vs_test`` and ``diversity_test`` (real-vs-real reference figures over every window of
the train and test clips, as ``split_features``), plus ``diversity_train``, window counts, epochs,
the data name / hash and the seed. Config: the built-in ``train/configs/motion_encoder/default.toml``
(or a TOML file with [model] (``MotionEncoderConfig``; ``num_actions`` is the dataset's vocabulary),
[data] (``EncoderDataSection``), [train] (``TrainSection``)).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from trumans.actions import remap_labels
from trumans.config_data import config_from_dict
from trumans.dataset import Dataset
from trumans.eval.motion_encoder import (INPUT_DIM, KIND, MotionEncoderConfig, MotionEncoderNet, action_acc,
                                          diversity, dominant_action, encoder_checkpoint, fid, motion_windows,
                                          window_inputs)
from trumans.model.checkpoint import Checkpoint
from trumans.model.episodes import Normalizer
from trumans.train.config import TrainSection, load_toml, override_sections
from trumans.train.tasks import TaskLoss

__all__ = ["EncoderDataSection", "MotionEncoderTaskConfig", "MotionEncoderTask", "SplitWindows", "split_windows",
           "fit_normalizer", "CONFIG_DIR", "DEFAULT_CONFIG"]

CONFIG_DIR = Path(__file__).parents[1] / "configs" / "motion_encoder"
DEFAULT_CONFIG = "default"
MIN_STD = 1e-2  # floor of the input standard deviations (features that barely vary are not blown up)

# keys the data decide: refused in a file, filled in by the task
_DERIVED = {"model": {"num_actions": "the dataset's vocabulary"}}


@dataclass(frozen=True)
class EncoderDataSection:
    """train_stride: frames (at the encoder's fps) between the starts of training windows; val and
    test windows start every ``window // 2`` frames, as the synthesis figures cut them."""

    train_stride: int = 4

    def __post_init__(self) -> None:
        if self.train_stride < 1:
            raise ValueError(f"train_stride must be >= 1 frame, got {self.train_stride}")


@dataclass(frozen=True)
class MotionEncoderTaskConfig:
    """name; model: the network (its ``num_actions`` comes from the dataset); data: windows; train:
    the shared optimiser section (the built-in default.toml holds the values of a run)."""

    name: str = "motion_encoder"
    model: MotionEncoderConfig = field(default_factory=lambda: MotionEncoderConfig(num_actions=1))
    data: EncoderDataSection = field(default_factory=EncoderDataSection)
    train: TrainSection = field(default_factory=TrainSection)

    def to_dict(self) -> dict:
        """Plain data without the derived ``model.num_actions`` (``from_dict`` inverts it)."""
        d = asdict(self)
        d["model"].pop("num_actions")
        return d

    @classmethod
    def from_dict(cls, d: dict, source: str = "motion encoder config") -> "MotionEncoderTaskConfig":
        return config_from_dict(cls, d, source, derived=_DERIVED)

    def with_overrides(self, **sections: dict) -> "MotionEncoderTaskConfig":
        return override_sections(self, sections)


@dataclass
class SplitWindows:
    """One split's windows as network inputs (``window_inputs``, un-normalised until ``fit``):
    x (M, L, 144) float32 and y (M,) int64 the labelled windows (dominant action, dataset
    vocabulary) at the requested stride; ref (R, L, 144) every window (labelled or not) one every
    ``window // 2`` frames of clips at least a window long (the windows ``split_features`` encodes)."""

    x: np.ndarray
    y: np.ndarray
    ref: np.ndarray


def split_windows(data: Dataset, split: str, cfg: MotionEncoderConfig, stride: int | None = None) -> SplitWindows:
    """The windows of ``split`` (``SplitWindows``); every clip must have action labels."""
    vocab = data.vocabulary
    xs, ys, refs = [], [], []
    for path in data.split(split):
        seq = data.load(path)
        if seq.actions is None:
            raise ValueError(f"{path} has no action labels; the motion encoder needs labelled data")
        labels = remap_labels(seq.actions, seq.action_names, vocab)
        w, _ = motion_windows(seq.joints, seq.fps, cfg.window, cfg.fps, stride)
        y = dominant_action(labels, seq.fps, cfg.window, cfg.fps, stride)
        xs.append(window_inputs(w[y >= 0], cfg.fps))
        ys.append(y[y >= 0])
        ref = w if stride is None else motion_windows(seq.joints, seq.fps, cfg.window, cfg.fps)[0]
        refs.append(window_inputs(ref, cfg.fps))
    empty = np.zeros((0, cfg.window, INPUT_DIM), np.float32)
    return SplitWindows(np.concatenate([empty, *xs]), np.concatenate([np.zeros(0, np.int64), *ys]),
                        np.concatenate([empty, *refs]))


def fit_normalizer(x: np.ndarray, min_std: float = MIN_STD) -> Normalizer:
    """Mean and standard deviation (floored at ``min_std``) of inputs (..., F) over every leading
    axis, accumulated in float64 chunks (the train split's windows take hundreds of MB as float32)."""
    flat = x.reshape(-1, x.shape[-1])
    if len(flat) == 0:
        raise ValueError("cannot fit the input normalisation on zero windows")
    chunks = range(0, len(flat), 1 << 16)
    mean = sum(flat[i:i + (1 << 16)].sum(0, dtype=np.float64) for i in chunks) / len(flat)
    var = sum(((flat[i:i + (1 << 16)] - mean) ** 2).sum(0) for i in chunks) / len(flat)
    return Normalizer(mean, np.maximum(np.sqrt(var), min_std))


class MotionEncoderTask:
    """The motion encoder as a ``trumans.train.tasks.Task`` (kind "motion_encoder")."""

    kind = KIND

    def __init__(self, config: MotionEncoderTaskConfig) -> None:
        self.config = config
        self.model_config: MotionEncoderConfig | None = None  # with the dataset's num_actions, after setup
        self.vocabulary: list[str] = []
        self.normalizer: Normalizer | None = None
        self.train_set: SplitWindows | None = None
        self.val_set: SplitWindows | None = None
        self.test_set: SplitWindows | None = None  # None: the dataset has no labelled test window
        self.data_record: dict = {}
        self.seed = 0
        self._perm: tuple[int, np.ndarray] | None = None  # (epoch, its permutation)

    @classmethod
    def from_config(cls, config: str | Path | None = None, *, overrides: dict[str, dict] | None = None,
                    ablate: Sequence[str] = ()) -> "MotionEncoderTask":
        """The task factory (``trumans.train.tasks.TASKS``): a built-in config name or TOML file (None = default)."""
        if ablate:
            raise ValueError(f"the motion_encoder task has no ablations, got {list(ablate)}; drop --ablate")
        d, p = load_toml(config or DEFAULT_CONFIG, CONFIG_DIR)
        cfg = MotionEncoderTaskConfig.from_dict(d, source=str(p))
        return cls(cfg.with_overrides(**overrides) if overrides else cfg)

    def setup(self, data_dir: str | Path, out_dir: Path, *, is_main: bool, barrier: Callable[[], None],
              prev: Checkpoint | None, seed: int = 0, extra_dirs: Sequence[str | Path] = (),
              progress: bool = True, fine_tune: bool = False) -> None:
        """The train, val and (if any) test windows of ``data_dir``; the input normalisation fitted on
        the train windows, or ``prev``'s (same vocabulary; a resumed run also the same data)."""
        if extra_dirs:
            raise ValueError("the motion_encoder task trains on one dataset; --augmented is not supported for it")
        ds = Dataset(data_dir)
        vocab = ds.vocabulary
        if not vocab:
            raise ValueError(f"dataset {ds.root} has no action vocabulary; the motion encoder classifies actions - "
                             f"train it on a dataset with action labels")
        if prev is not None:
            if list(prev.vocabulary or []) != vocab:
                raise ValueError(f"the checkpoint classifies {len(prev.vocabulary or [])} actions {prev.vocabulary}, "
                                 f"the dataset {ds.root} has the vocabulary {vocab}; use data with the same vocabulary")
            if not fine_tune and prev.data.get("hash") != ds.hash:
                raise ValueError(f"the run in {out_dir} was trained on other data (hash {str(prev.data.get('hash'))[:12]}, "
                                 f"now {ds.hash[:12]}); resume with the same --data")
        cfg = replace(self.config.model, num_actions=len(vocab))
        self.model_config, self.vocabulary, self.seed = cfg, vocab, seed
        self.data_record = {"name": ds.name, "hash": ds.hash, "path": str(Path(data_dir).resolve())}
        self.train_set = split_windows(ds, "train", cfg, self.config.data.train_stride)
        self.val_set = split_windows(ds, "val", cfg) if "val" in ds.split_names else None
        for name, s in (("train", self.train_set), ("val", self.val_set)):
            if s is None or len(s.y) == 0:
                raise ValueError(f"split {name!r} of {ds.root} gives no labelled {cfg.window}-frame windows "
                                 f"({cfg.window / cfg.fps:g} s); the motion encoder needs train and val clips with actions")
        test = split_windows(ds, "test", cfg) if "test" in ds.split_names else None
        self.test_set = test if test is not None and len(test.y) and len(test.ref) >= 2 else None
        self.normalizer = prev.normalizer if prev is not None else fit_normalizer(self.train_set.x)
        m, s = self.normalizer.mean, self.normalizer.std
        for part in (self.train_set, self.val_set, self.test_set):
            if part is not None:
                for a in (part.x, part.ref):
                    a -= m
                    a /= s
        self._perm = None
        barrier()

    def build_model(self) -> MotionEncoderNet:
        if self.model_config is None:
            raise ValueError("the motion encoder's vocabulary is unknown: call setup() with a dataset first")
        return MotionEncoderNet(self.model_config)

    def _steps_per_epoch(self) -> int:
        return math.ceil(len(self.train_set.y) / self.config.train.batch_size)

    def batch(self, step: int, rank: int, world: int) -> tuple[torch.Tensor, torch.Tensor]:
        """This rank's share of global batch ``step``: the ``step``-th slice of ``batch_size`` windows
        of its epoch's seeded permutation (a pure function of seed and step); x (B, L, 144), y (B,)."""
        epoch, i = divmod(step, self._steps_per_epoch())
        if self._perm is None or self._perm[0] != epoch:
            self._perm = (epoch, np.random.default_rng([self.seed, epoch, 23]).permutation(len(self.train_set.y)))
        b = self.config.train.batch_size
        chunk = self._perm[1][i * b:(i + 1) * b]
        idx = chunk[rank::world] if len(chunk) >= world else chunk[rank % len(chunk):][:1]
        return torch.from_numpy(self.train_set.x[idx]), torch.from_numpy(self.train_set.y[idx])

    def loss(self, model: nn.Module, batch: tuple[torch.Tensor, torch.Tensor], generator: torch.Generator,
             device: torch.device) -> TaskLoss:
        x, y = (t.to(device) for t in batch)
        ce = F.cross_entropy(model(x)[1], y)
        return TaskLoss(ce, {"ce": ce})

    def _prior(self) -> torch.Tensor:
        """(A,) the training windows' action frequencies (an absent action counts once)."""
        counts = np.bincount(self.train_set.y, minlength=self.model_config.num_actions).astype(np.float64)
        counts = np.maximum(counts, 1.0)
        return torch.from_numpy(counts / counts.sum())

    @torch.no_grad()
    def validate(self, model: nn.Module) -> tuple[float, float]:
        """(cross-entropy of the val windows, that of the constant predictor of the training
        windows' action frequencies)."""
        dev = next(model.parameters()).device
        model.eval()
        x, y = torch.from_numpy(self.val_set.x), torch.from_numpy(self.val_set.y)
        total = 0.0
        for s in range(0, len(y), self.config.train.val_batch_size):
            e = s + self.config.train.val_batch_size
            total += float(F.cross_entropy(model(x[s:e].to(dev))[1], y[s:e].to(dev), reduction="sum"))
        base = float(-self._prior().log()[y].mean())
        return total / len(y), base

    def sizes(self) -> tuple[int, int]:
        return len(self.train_set.y), len(self.val_set.y)

    @torch.no_grad()
    def figures(self, state: dict[str, torch.Tensor], step: int = 0) -> dict:
        """The report of weights ``state`` (module doc): accuracies, baselines, real-vs-real FID / diversity."""
        net = MotionEncoderNet(self.model_config)
        net.load_state_dict(state)
        net.eval()

        def run(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # (features (M, D), probabilities (M, A))
            out = [net(c) for c in torch.from_numpy(x).split(512)]
            return (torch.cat([f for f, _ in out]).numpy(), torch.cat([lg for _, lg in out]).softmax(-1).numpy())

        majority = int(np.bincount(self.train_set.y).argmax())
        f_train = run(self.train_set.ref)[0]
        out = {"train_acc": action_acc(run(self.train_set.x)[1], self.train_set.y),
               "val_acc": action_acc(run(self.val_set.x)[1], self.val_set.y),
               "val_majority_baseline_acc": float((self.val_set.y == majority).mean())}
        if self.test_set is not None:
            f_test = run(self.test_set.ref)[0]
            out.update(test_acc=action_acc(run(self.test_set.x)[1], self.test_set.y),
                       majority_baseline_acc=float((self.test_set.y == majority).mean()),
                       diversity_test=diversity(f_test, seed=self.seed))
            if len(f_train) >= 2:
                out["fid_train_vs_test"] = fid(f_train, f_test)
        if len(f_train) >= 2:
            out["diversity_train"] = diversity(f_train, seed=self.seed)
        out.update(train_windows=int(len(self.train_set.y)), val_windows=int(len(self.val_set.y)),
                   test_windows=int(len(self.test_set.y)) if self.test_set is not None else 0, steps=int(step),
                   epochs=round(step / self._steps_per_epoch(), 2), data=self.data_record["name"],
                   data_hash=self.data_record["hash"], seed=self.seed)
        return out

    def checkpoint(self, *, model_state: dict, ema_state: dict, meta: dict, train_state: dict) -> Checkpoint:
        meta = dict(meta)
        if ema_state:
            meta["figures"] = self.figures(ema_state, int(meta.get("step", 0)))
        return encoder_checkpoint(self.model_config, model_state, self.normalizer, self.vocabulary, ema_state=ema_state,
                                  data=self.data_record, meta=meta, train_state=train_state)
