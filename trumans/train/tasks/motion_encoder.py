"""Train the motion encoder of the synthesis figures (``trumans.eval.motion_encoder``).

``python -m trumans.train.tasks.motion_encoder --data DATASET --out models/motion_encoder.pt`` trains on the
dataset's train split (dominant action of each window, softmax cross-entropy) and reports the
test-split accuracy and the real-vs-real reference figures (FID train vs test, diversity of test).
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from trumans.actions import remap_labels
from trumans.dataset import Dataset
from trumans.eval.motion_encoder import (MotionEncoder, MotionEncoderConfig, MotionEncoderNet, action_acc, diversity,
                                          dominant_action, fid, motion_windows, split_features, window_inputs)
from trumans.sequence import atomic_write
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["EncoderTrainConfig", "labelled_windows", "train_motion_encoder", "main"]


@dataclass(frozen=True)
class EncoderTrainConfig:
    """Optimisation settings; ``train_stride``: window stride (frames at the encoder's fps) in training."""

    epochs: int = 40
    batch_size: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-2
    train_stride: int = 4
    time_limit_s: float = 400.0


def labelled_windows(data: Dataset, split: str, cfg: MotionEncoderConfig,
                  stride: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Canonical windows (M, L, 24, 3) of a split and their dominant action (M,) in the dataset
    vocabulary; windows with no action on are dropped."""
    vocab = data.vocabulary
    xs, ys = [], []
    for path in data.split(split):
        seq = data.load(path)
        if seq.actions is None:
            raise ValueError(f"{path} has no action labels; the motion encoder needs labelled data")
        w, _ = motion_windows(seq.joints, seq.fps, cfg.window, cfg.fps, stride)
        y = dominant_action(remap_labels(seq.actions, seq.action_names, vocab), seq.fps, cfg.window, cfg.fps, stride)
        xs.append(w[y >= 0])
        ys.append(y[y >= 0])
    if not xs or sum(len(x) for x in xs) == 0:
        raise ValueError(f"split {split!r} of {data.root} gives no labelled {cfg.window}-frame windows")
    return np.concatenate(xs), np.concatenate(ys)


def _logits(net: MotionEncoderNet, x: np.ndarray) -> np.ndarray:
    net.eval()
    with torch.inference_mode():
        out = torch.cat([net(c)[1] for c in torch.from_numpy(x).split(512)]).softmax(-1).numpy()
    return out


def train_motion_encoder(data_root: str | Path, cfg: MotionEncoderConfig | None = None,
                         tcfg: EncoderTrainConfig = EncoderTrainConfig(), seed: int = 0,
                         log=print) -> tuple[MotionEncoder, dict]:
    """Train on the train split; returns the encoder and a report (accuracies, real-vs-real FID /
    diversity, window counts, seconds)."""
    t0 = time.time()
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    data = Dataset(data_root)
    vocab = data.vocabulary
    cfg = cfg or MotionEncoderConfig(num_actions=len(vocab))
    if cfg.num_actions != len(vocab):
        raise ValueError(f"config has {cfg.num_actions} actions but the dataset vocabulary {len(vocab)}")
    wx, y = labelled_windows(data, "train", cfg, tcfg.train_stride)
    x = window_inputs(wx, cfg.fps)
    mean = x.reshape(-1, x.shape[-1]).mean(0)
    std = np.maximum(x.reshape(-1, x.shape[-1]).std(0), 1e-2)
    x = (x - mean) / std
    wt, yt = labelled_windows(data, "test", cfg)
    xt = (window_inputs(wt, cfg.fps) - mean) / std
    log(f"motion encoder: {len(x)} train windows, {len(xt)} test windows, {len(vocab)} actions "
        f"({time.time() - t0:.0f} s loading)")
    net = MotionEncoderNet(cfg)
    opt = torch.optim.AdamW(net.parameters(), lr=tcfg.lr, weight_decay=tcfg.weight_decay)
    steps_per_epoch = int(np.ceil(len(x) / tcfg.batch_size))
    xtr, ytr = torch.from_numpy(x), torch.from_numpy(y)
    loss_fn = nn.CrossEntropyLoss()
    t_train, epochs_done, step, progress = time.time(), 0, 0, 0.0
    budget = max(tcfg.time_limit_s - (t_train - t0), 1.0)
    while progress < 1.0:
        net.train()
        perm = torch.from_numpy(rng.permutation(len(x)))
        total, seen = 0.0, 0
        for b in perm.split(tcfg.batch_size):
            # warm-up then cosine decay over whichever runs out first, the epochs or the time budget
            progress = max(step / (tcfg.epochs * steps_per_epoch), (time.time() - t_train) / budget)
            if progress >= 1.0:
                break
            for grp in opt.param_groups:
                grp["lr"] = tcfg.lr * min(1.0, progress / 0.03) * 0.5 * (1 + np.cos(np.pi * progress))
            _, logits = net(xtr[b])
            loss = loss_fn(logits, ytr[b])
            opt.zero_grad()
            loss.backward()
            opt.step()
            step += 1
            total += loss.item() * len(b)
            seen += len(b)
        epochs_done += 1
        if epochs_done % 5 == 0 or progress >= 1.0:
            acc = action_acc(_logits(net, xt), yt)
            log(f"epoch {epochs_done}: loss {total / max(seen, 1):.4f}, test acc {acc:.3f} ({time.time() - t0:.0f} s)")
    enc = MotionEncoder(cfg, net, mean, std, vocab)
    report = {
        "train_acc": action_acc(_logits(net, x), y),
        "test_acc": action_acc(_logits(net, xt), yt),
        "majority_baseline_acc": float((yt == np.bincount(y).argmax()).mean()),
        "train_windows": int(len(x)), "test_windows": int(len(xt)), "steps": step,
        "epochs": round(step / steps_per_epoch, 2),
        "data": data.name, "data_hash": data.hash, "seed": seed,
    }
    # real-vs-real reference figures: windows every window // 2 frames, all of them labelled or not
    f_train, f_test = split_features(enc, data, "train"), split_features(enc, data, "test")
    report.update(fid_train_vs_test=fid(f_train, f_test), diversity_test=diversity(f_test, seed=seed),
                  diversity_train=diversity(f_train, seed=seed), seconds=time.time() - t0)
    enc.info = dict(report)
    return enc, report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m trumans.train.tasks.motion_encoder", description="train the motion encoder")
    p.add_argument("--data", required=True, help="dataset folder (index.json with train and test splits)")
    p.add_argument("--out", default="models/motion_encoder.pt", help="checkpoint path (default models/motion_encoder.pt)")
    p.add_argument("--epochs", type=int, default=EncoderTrainConfig.epochs)
    p.add_argument("--time-limit", type=float, default=EncoderTrainConfig.time_limit_s, help="seconds for loading + training (default 400)")
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--json", action="store_true", help="print the report as JSON on the last line")
    args = p.parse_args(argv)
    try:
        enc, report = train_motion_encoder(args.data, tcfg=EncoderTrainConfig(epochs=args.epochs,
                                                                                time_limit_s=args.time_limit),
                                           seed=args.seed, log=lambda m: print(m, file=sys.stderr))
    except (ValueError, FileNotFoundError) as e:
        print(f"trumans: error: {e}", file=sys.stderr)
        return 2
    state = enc.state()
    atomic_write(args.out, lambda tmp: torch.save(state, tmp))
    print(f"test acc {report['test_acc']:.3f} (majority {report['majority_baseline_acc']:.3f}), "
          f"fid train vs test {report['fid_train_vs_test']:.3f}, diversity test {report['diversity_test']:.3f}; "
          f"wrote {args.out}")
    if args.json:
        print_summary(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
