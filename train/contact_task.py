"""Training the contact predictor (iReplica §4.2): data windows, labels, loss, and a plain loop.

Labels per frame of a dataset sequence (at the model's fps): ``trumans.contacts.labels`` (hand
contact = wrist or index1 in contact; class = dof of the object moving near the frame).
Loss: binary cross-entropy on both hands' contacts over every frame of each window (the network
is sequence-to-sequence, §4.2) plus ``class_weight`` x cross-entropy on the class. Each window is
mirrored left/right with probability ``mirror_p`` (``mirror_rotations``; hand labels swapped).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from trumans.contacts.labels import sequence_labels
from trumans.contacts.model_io import save_predictor
from trumans.contacts.predictor import (CLASSES, ContactPredictor, ContactPredictorConfig, mirror_rotations,
                                        pose_windows, window_indices)
from trumans.contacts.scores import binary_scores
from trumans.dataset import Dataset
from trumans.resample import resample_sequence
from trumans.sequence import Sequence

__all__ = ["ContactTrainConfig", "ContactData", "load_contact_data", "sample_batch",
           "contact_loss", "evaluate_contacts", "train_contact"]


@dataclass(frozen=True)
class ContactTrainConfig:
    """steps, batch_size (windows), lr (Adam), mirror_p, class_weight, moving_dilate_s (s),
    val_every (steps), val_stride (frames between validated centres), time_limit_s (None = no
    limit), model: the predictor's config."""

    steps: int = 4000
    batch_size: int = 64
    lr: float = 1e-3
    mirror_p: float = 0.5
    class_weight: float = 0.5
    moving_dilate_s: float = 0.5
    val_every: int = 500
    val_stride: int = 3
    time_limit_s: float | None = None
    model: ContactPredictorConfig = field(default_factory=ContactPredictorConfig)

    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch_size < 1 or self.val_every < 1 or self.val_stride < 1:
            raise ValueError("steps, batch_size, val_every and val_stride must be >= 1, got "
                             f"{self.steps}, {self.batch_size}, {self.val_every}, {self.val_stride}")
        if not (self.lr > 0 and 0 <= self.mirror_p <= 1 and self.class_weight >= 0 and self.moving_dilate_s >= 0):
            raise ValueError("need lr > 0, 0 <= mirror_p <= 1, class_weight >= 0, moving_dilate_s >= 0")

    @classmethod
    def from_dict(cls, d: dict) -> "ContactTrainConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown contact training config keys {unknown}; known keys are {sorted(known)}")
        d = dict(d)
        if isinstance(d.get("model"), dict):
            d["model"] = ContactPredictorConfig.from_dict(d["model"])
        return cls(**d)


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


def load_contact_data(dataset: Dataset, split: str, fps: float, dilate_s: float = 0.5) -> ContactData:
    """Every sequence of ``split`` with rotations and contacts, resampled to ``fps``."""
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


def train_contact(data_dir: str | Path, out: str | Path, config: ContactTrainConfig = ContactTrainConfig(),
                  seed: int = 0, progress: bool = True) -> dict:
    """Train on the train split, validate on val, write ``out`` (a contact checkpoint). Returns a
    summary dict (steps, seconds, losses, val figures, parameter count)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    ds = Dataset(data_dir)
    mc = config.model
    train = load_contact_data(ds, "train", mc.fps, config.moving_dilate_s)
    val = load_contact_data(ds, "val", mc.fps, config.moving_dilate_s)
    model = ContactPredictor(mc)
    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: 0.5 * (1 + math.cos(math.pi * min(s / config.steps, 1.0))))
    t0, history, best = time.time(), [], None
    step = 0
    for step in range(1, config.steps + 1):
        model.train()
        centers = rng.integers(0, len(train), config.batch_size)
        x, y, c = sample_batch(train, centers, mc.window, rng.random(config.batch_size) < config.mirror_p)
        losses = contact_loss(model, x, y, c, config.class_weight)
        opt.zero_grad()
        losses["loss"].backward()
        opt.step()
        sched.step()
        history.append(losses["loss"].item())
        done = step == config.steps or (config.time_limit_s is not None and time.time() - t0 > config.time_limit_s)
        if step % config.val_every == 0 or done:
            fig = evaluate_contacts(model, val, config.val_stride)
            if progress:
                print(f"step {step}: train loss {np.mean(history[-config.val_every:]):.4f}, val ap {fig['ap']:.3f}, "
                      f"acc {fig['accuracy']:.3f}, class acc {fig['class_accuracy']:.3f} ({time.time() - t0:.0f} s)",
                      flush=True)
        if done:
            break
    n_params = sum(p.numel() for p in model.parameters())
    summary = {"steps": step, "seconds": time.time() - t0, "train_loss": float(np.mean(history[-100:])),
               "val": fig, "parameters": n_params, "train_frames": len(train), "val_frames": len(val)}
    cfg = asdict(config)
    save_predictor(model, out, data={"name": ds.name, "hash": ds.hash},
                   meta={"train_config": cfg, "summary": summary, "seed": seed})
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m train.contact_task --data DIR --out FILE [--steps N] [--time-limit S] [--seed S] [--json]``."""
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m train.contact_task", description="train the contact predictor")
    p.add_argument("--data", required=True, help="dataset folder (index.json; sequences with rotations and contacts)")
    p.add_argument("--out", required=True, help="checkpoint file to write (.pt)")
    p.add_argument("--steps", type=int, default=ContactTrainConfig.steps, help="optimisation steps")
    p.add_argument("--batch-size", type=int, default=ContactTrainConfig.batch_size, help="windows per step")
    p.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")
    args = p.parse_args(argv)
    cfg = ContactTrainConfig(steps=args.steps, batch_size=args.batch_size, time_limit_s=args.time_limit)
    summary = train_contact(args.data, args.out, cfg, seed=args.seed)
    print(f"{summary['steps']} steps in {summary['seconds']:.0f} s, val ap {summary['val']['ap']:.3f}; wrote {args.out}")
    if args.json:
        print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
