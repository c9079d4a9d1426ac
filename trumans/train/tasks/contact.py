"""Training the contact predictor (iReplica §4.2) as a ``trumans.train.tasks.Task``: ``trumans train --task contact``.

Labels per frame of a dataset sequence (at the model's fps): ``trumans.track.labels`` (hand
contact = wrist or index1 in contact; class = dof of the object moving near the frame).
Loss: binary cross-entropy on both hands' contacts over every frame of each window (the network
is sequence-to-sequence, §4.2) plus ``class_weight`` x cross-entropy on the class. Each window is
mirrored left/right with probability ``mirror_p`` (``mirror_rotations``; hand labels swapped).
The shared loop (``trumans.train.loop``) runs Adam, EMA, clipping, checkpoints and validation; the
validation loss is compared with a constant predictor of the training set's label frequencies.
Config: ``ContactTaskConfig`` (its defaults, or a TOML file whose [model], [data], [train] tables
override them; unknown keys are errors). Ablations: ``mirror`` (no mirroring), ``class`` (no class loss).
One model per dof class (iReplica supp. §10.1): ``[data] dof = "slide" | "hinge" | "free"`` (the
built-in configs ``--config slide|hinge|free``): hand labels kept only on frames of that class
(``per_dof.dof_hand_labels``; every other frame a negative), no class loss.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from trumans.track.labels import sequence_labels
from trumans.track.model_io import KIND, predictor_checkpoint
from trumans.track.per_dof import check_dof, dof_hand_labels
from trumans.track.predictor import (CLASSES, ContactPredictor, ContactPredictorConfig, mirror_rotations,
                                        pose_windows, window_indices)
from trumans.track.scores import binary_scores
from trumans.dataset import Dataset
from trumans.resample import resample_sequence
from trumans.model.checkpoint import Checkpoint

from trumans.config_data import config_from_dict
from trumans.train.config import TrainSection, load_toml, override_sections
from trumans.train.tasks import TaskLoss

__all__ = ["ContactDataSection", "ContactTaskConfig", "ContactTask", "ContactData", "load_contact_data",
           "sample_batch", "contact_loss", "evaluate_contacts", "ABLATIONS"]


@dataclass
class ContactData:
    """Sequences concatenated frame-wise: rotations (F, 24, 6), hands (F, 2) float {0, 1},
    classes (F,) int64 into CLASSES, lo / hi (F,) first / last frame of each frame's sequence."""

    rotations: torch.Tensor
    hands: torch.Tensor
    classes: torch.Tensor
    lo: np.ndarray
    hi: np.ndarray

    def __len__(self) -> int:
        return len(self.rotations)


def load_contact_data(dataset: Dataset, split: str, fps: float, dilate_s: float = 0.5, dof: str = "all") -> ContactData:
    """Every sequence of ``split`` with rotations and contacts, resampled to ``fps``; ``dof`` other
    than "all": the hand labels of that dof's model (``dof_hand_labels``)."""
    check_dof(dof)
    rots, hands, classes, lo, hi = [], [], [], [], []
    dofs_of: dict[str, dict[str, str]] = {}
    start = 0
    for path in dataset.split(split):
        seq = dataset.load(path)
        if seq.rotations is None or seq.contacts is None:
            continue
        if abs(seq.fps - fps) > 1e-6:
            seq = resample_sequence(seq, fps)
        if seq.scene not in dofs_of:
            scene = dataset.scene(seq.scene)
            dofs_of[seq.scene] = {n: o.dof for n, o in scene.objects.items()}
        h, c = sequence_labels(seq, dofs_of[seq.scene], dilate_s)
        if dof != "all":
            h = dof_hand_labels(h, c, dof)
        T = seq.num_frames
        rots.append(np.asarray(seq.rotations, np.float32))
        hands.append(h)
        classes.append(c)
        lo.append(np.full(T, start))
        hi.append(np.full(T, start + T - 1))
        start += T
    if not rots:
        raise ValueError(f"split {split!r} of {dataset.root} has no sequence with rotations and contacts")
    return ContactData(torch.from_numpy(np.concatenate(rots)), torch.from_numpy(np.concatenate(hands)).float(),
                       torch.from_numpy(np.concatenate(classes)), np.concatenate(lo), np.concatenate(hi))


def sample_batch(data: ContactData, centers: np.ndarray, window: int, mirror: np.ndarray) -> tuple[torch.Tensor, ...]:
    """Windows around ``centers`` (B,): x (B, W, 24, 6), hand labels (B, W, 2), classes (B, W);
    windows where ``mirror`` (B,) bool is True are mirrored with their hand labels swapped."""
    idx = window_indices(centers, data.lo[centers], data.hi[centers], window)
    x = pose_windows(data.rotations, idx)
    y = data.hands[torch.from_numpy(idx)]
    m = torch.from_numpy(np.asarray(mirror, dtype=bool))
    if m.any():
        x[m] = mirror_rotations(x[m])
        y[m] = y[m].flip(-1)
    return x, y, data.classes[torch.from_numpy(idx)]


def contact_loss(model: ContactPredictor, x: torch.Tensor, y: torch.Tensor, cls: torch.Tensor,
                 class_weight: float) -> dict[str, torch.Tensor]:
    """{'loss', 'bce', 'ce'} for a batch (``sample_batch``)."""
    logit, class_logit = model(x)
    bce = F.binary_cross_entropy_with_logits(logit, y)
    ce = F.cross_entropy(class_logit.reshape(-1, len(CLASSES)), cls.reshape(-1))
    return {"loss": bce + class_weight * ce, "bce": bce, "ce": ce}


def evaluate_contacts(model: ContactPredictor, data: ContactData, stride: int = 1) -> dict[str, float]:
    """Centre-frame figures on every ``stride``-th frame: ap/precision/recall/accuracy (both hands
    pooled, threshold 0.5) and class_accuracy."""
    centers = np.arange(0, len(data), stride)
    probs, cprobs = [], []
    for s in range(0, len(centers), 4096):
        c = centers[s:s + 4096]
        with torch.no_grad():
            model.eval()
            logit, class_logit = model(pose_windows(data.rotations, window_indices(c, data.lo[c], data.hi[c],
                                                                                   model.config.window)))
        W = model.config.window
        probs.append(torch.sigmoid(logit[:, W // 2]))
        cprobs.append(class_logit[:, W // 2].argmax(-1))
    p = torch.cat(probs).numpy()
    out = binary_scores(p, data.hands[centers].numpy() > 0.5)
    out["class_accuracy"] = float((torch.cat(cprobs) == data.classes[centers]).float().mean())
    return out


ABLATIONS = {"mirror": ("data", "mirror_p", 0.0), "class": ("data", "class_weight", 0.0)}


@dataclass(frozen=True)
class ContactDataSection:
    """mirror_p: probability of mirroring a window; class_weight: weight of the class loss;
    moving_dilate_s (s): class labels reach this far around object motion; val_stride: frames
    between validated window centres; dof: "all" (one model, class head) or the dof class of a
    per-dof model (module doc; needs class_weight 0)."""

    mirror_p: float = 0.5
    class_weight: float = 0.5
    moving_dilate_s: float = 0.5
    val_stride: int = 3
    dof: str = "all"

    def __post_init__(self) -> None:
        if not (0 <= self.mirror_p <= 1 and self.class_weight >= 0 and self.moving_dilate_s >= 0 and self.val_stride >= 1):
            raise ValueError(f"need 0 <= mirror_p <= 1, class_weight >= 0, moving_dilate_s >= 0, val_stride >= 1; got "
                             f"{self.mirror_p}, {self.class_weight}, {self.moving_dilate_s}, {self.val_stride}")
        check_dof(self.dof)
        if self.dof != "all" and self.class_weight != 0:
            raise ValueError(f"a per-dof contact model (dof {self.dof!r}) has no class to learn; set class_weight = 0 "
                             f"(got {self.class_weight}) or use the built-in config --config {self.dof}")


def _contact_train() -> TrainSection:
    return TrainSection(steps=1500, batch_size=64, lr=1e-3, ema_decay=0.99, grad_clip=1.0, checkpoint_every=500,
                        val_every=500)


@dataclass(frozen=True)
class ContactTaskConfig:
    """name; model: the predictor; data: labels / augmentation; train: the shared optimiser section."""

    name: str = "contact"
    model: ContactPredictorConfig = field(default_factory=ContactPredictorConfig)
    data: ContactDataSection = field(default_factory=ContactDataSection)
    train: TrainSection = field(default_factory=_contact_train)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, source: str = "config") -> "ContactTaskConfig":
        return config_from_dict(cls, d, source)

    def with_overrides(self, **sections: dict) -> "ContactTaskConfig":
        return override_sections(self, sections)


class ContactTask:
    """The contact predictor as a ``trumans.train.tasks.Task`` (kind "contact")."""

    kind = KIND

    def __init__(self, config: ContactTaskConfig) -> None:
        self.config = config
        self.train_data: ContactData | None = None
        self.val_data: ContactData | None = None
        self.data_record: dict = {}
        self.seed = 0

    @classmethod
    def from_config(cls, config: str | Path | None = None, *, overrides: dict[str, dict] | None = None,
                    ablate: Sequence[str] = ()) -> "ContactTask":
        """The task factory (``trumans.train.tasks.TASKS``): None = the defaults, else a TOML file."""
        if config is None:
            cfg = ContactTaskConfig()
        else:
            d, p = load_toml(config, config_dir=Path(__file__).parents[1] / "configs" / "contact")
            cfg = ContactTaskConfig.from_dict(d, source=str(p))
        over = {k: dict(v) for k, v in (overrides or {}).items()}
        for a in ablate:
            if a not in ABLATIONS:
                raise ValueError(f"unknown ablation {a!r} for the contact task; ablations: {sorted(ABLATIONS)}")
            sec, key, value = ABLATIONS[a]
            over.setdefault(sec, {})[key] = value
        return cls(cfg.with_overrides(**over) if over else cfg)

    def setup(self, data_dir: str | Path, out_dir: Path, *, is_main: bool, barrier: Callable[[], None],
              prev: Checkpoint | None, seed: int = 0, extra_dirs: Sequence[str | Path] = (),
              progress: bool = True, fine_tune: bool = False) -> None:
        """The train and val splits of ``data_dir`` (sequences with rotations and contacts); a resumed
        run (``prev``, not ``fine_tune``) refuses other data."""
        if extra_dirs:
            raise ValueError("the contact task trains on one dataset; --augmented is not supported for it")
        ds = Dataset(data_dir)
        if prev is not None and prev.data.get("hash") != ds.hash and not fine_tune:
            raise ValueError(f"the run in {out_dir} was trained on other data (hash {str(prev.data.get('hash'))[:12]}, "
                             f"now {ds.hash[:12]}); resume with the same --data")
        self.data_record = {"name": ds.name, "hash": ds.hash, "path": str(Path(data_dir).resolve())}
        c = self.config
        self.train_data = load_contact_data(ds, "train", c.model.fps, c.data.moving_dilate_s, c.data.dof)
        self.val_data = load_contact_data(ds, "val", c.model.fps, c.data.moving_dilate_s, c.data.dof)
        self.seed = seed
        barrier()

    def build_model(self) -> ContactPredictor:
        return ContactPredictor(self.config.model)

    def batch(self, step: int, rank: int, world: int) -> tuple[torch.Tensor, ...]:
        """This rank's windows of step ``step``: a pure function of (seed, step, rank)."""
        rng = np.random.default_rng([self.seed, step, rank, 11])
        n = max(1, self.config.train.batch_size // world)
        centers = rng.integers(0, len(self.train_data), n)
        return sample_batch(self.train_data, centers, self.config.model.window, rng.random(n) < self.config.data.mirror_p)

    def loss(self, model: nn.Module, batch: tuple[torch.Tensor, ...], generator: torch.Generator,
             device: torch.device) -> TaskLoss:
        x, y, c = (t.to(device) for t in batch)
        out = contact_loss(model, x, y, c, self.config.data.class_weight)
        return TaskLoss(out["loss"], {"bce": out["bce"], "ce": out["ce"]})

    @torch.no_grad()
    def validate(self, model: nn.Module) -> tuple[float, float]:
        """(loss on every ``val_stride``-th val window, no mirroring; the same loss of a constant
        predictor of the training label frequencies)."""
        d, W = self.val_data, self.config.model.window
        centers = np.arange(0, len(d), self.config.data.val_stride)
        dev = next(model.parameters()).device
        total, n = 0.0, 0
        for s in range(0, len(centers), 2048):
            x, y, c = (t.to(dev) for t in sample_batch(d, centers[s:s + 2048], W, np.zeros(len(centers[s:s + 2048]), bool)))
            total += float(contact_loss(model.eval(), x, y, c, self.config.data.class_weight)["loss"]) * len(x)
            n += len(x)
        p = self.train_data.hands.mean(0).clamp(1e-4, 1 - 1e-4)  # (2,)
        q = torch.bincount(self.train_data.classes, minlength=len(CLASSES)).float().clamp_min(1)
        q = q / q.sum()
        yv, cv = d.hands[centers], d.classes[centers]
        bce0 = F.binary_cross_entropy(p.expand_as(yv), yv)
        ce0 = F.nll_loss(q.log().expand(len(cv), -1), cv)
        return total / max(n, 1), float(bce0 + self.config.data.class_weight * ce0)

    def sizes(self) -> tuple[int, int]:
        return len(self.train_data), len(self.val_data)

    def checkpoint(self, *, model_state: dict, ema_state: dict, meta: dict, train_state: dict) -> Checkpoint:
        meta = dict(meta)
        if self.val_data is not None and ema_state:
            model = ContactPredictor(self.config.model)
            model.load_state_dict(ema_state)
            meta["val_figures"] = evaluate_contacts(model, self.val_data, self.config.data.val_stride)
            if self.config.data.dof != "all":
                del meta["val_figures"]["class_accuracy"]  # a per-dof model's class head is untrained
        return predictor_checkpoint(self.config.model, model_state, ema_state=ema_state, data=self.data_record,
                                    meta=meta, train_state=train_state, dof=self.config.data.dof)
