"""A minimal training loop for the HOI filter task (Adam, linear warm-up, EMA, clipping, sampled
validation, atomic checkpoint, time limit). Randomness is a pure function of (seed, step).
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, asdict
from pathlib import Path

import numpy as np
import torch

from trumans import __version__
from trumans.dataset import Dataset
from trumans.model.checkpoint import Checkpoint, save_checkpoint
from trumans.model.episodes import Normalizer

from trumans.hoi.data import load_filter_windows
from .filter_task import FilterConfig, FilterTask, make_batch, validate

__all__ = ["FilterResult", "train_filter", "fit_normalizer"]


@dataclass
class FilterResult:
    steps: int
    seconds: float
    train_loss: float
    val: dict
    val_input: dict
    train_windows: int
    val_windows: int
    parameters: int
    checkpoint: str

    def to_dict(self) -> dict:
        return asdict(self)


def fit_normalizer(data, cfg: FilterConfig, seed: int, n: int = 2048) -> Normalizer:
    """Statistics of clean canonical windows (canonical frames from corrupted copies, as in training)."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(data), size=min(n, len(data)), replace=False)
    ident = Normalizer(np.zeros(235), np.ones(235))
    b = make_batch(data, idx, ident, cfg.corruption, rng)
    return Normalizer.fit(b.clean.numpy())


def train_filter(cfg: FilterConfig, data_dir: str | Path, out: str | Path, *, steps: int | None = None,
                 seed: int = 0, progress: bool = True, export: bool = False) -> FilterResult:
    """Train into ``out/checkpoint.pt``; export=True stores only the EMA weights (float16, no
    optimiser state): the shipped-model form."""
    from tqdm import tqdm

    torch.manual_seed(seed)
    tc, net = cfg.train, cfg.net
    total = int(steps if steps is not None else tc.steps)
    out = Path(out)
    ckpt_path = out / "checkpoint.pt"
    if ckpt_path.exists():
        raise ValueError(f"{ckpt_path} exists; choose a new --out (this loop does not resume)")
    ds = Dataset(data_dir)
    cats = list(tc.categories) or None
    train = load_filter_windows(data_dir, "train", net.window, tc.stride, net.fps, cats)
    val = load_filter_windows(data_dir, "val", net.window, net.window, net.fps, train.category_names)
    normalizer = fit_normalizer(train, cfg, seed)
    task = FilterTask(cfg, train.category_names, normalizer)
    model = task.build_model()
    ema = copy.deepcopy(model).eval().requires_grad_(False)
    opt = torch.optim.Adam(model.parameters(), lr=tc.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: min(1.0, (s + 1) / max(tc.warmup_steps, 1)))
    vrng = np.random.default_rng(20240601)
    vidx = vrng.choice(len(val), size=min(tc.val_windows, len(val)), replace=False)
    vbatch = make_batch(val, vidx, normalizer, cfg.corruption, vrng)
    from .filter_task import filter_metrics

    tracked_filled = np.where(np.isnan(vbatch.tracked.numpy()), vbatch.clean.numpy(), vbatch.tracked.numpy())
    val_input = filter_metrics(tracked_filled, vbatch.clean.numpy())
    history: dict = {"train": [], "val_step": [], "val": []}
    t0 = time.perf_counter()
    bar = tqdm(total=total, desc=f"train[{cfg.name}]", disable=not progress, dynamic_ncols=True)
    step = 0
    while step < total:
        if tc.time_limit_s > 0 and time.perf_counter() - t0 > tc.time_limit_s:
            break
        rng = np.random.default_rng([seed, step])
        g = torch.Generator().manual_seed(int(rng.integers(2 ** 62)))
        torch.manual_seed(int(rng.integers(2 ** 62)))
        idx = rng.integers(0, len(train), tc.batch_size)
        b = make_batch(train, idx, normalizer, cfg.corruption, rng)
        model.train()
        progress_frac = max(step / total, (time.perf_counter() - t0) / tc.time_limit_s if tc.time_limit_s > 0 else 0.0)
        loss, terms = task.loss(model, b, progress_frac, g)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if tc.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), tc.grad_clip)
        opt.step()
        sched.step()
        step += 1
        decay = min(tc.ema_decay, (1 + step) / (10 + step))
        with torch.no_grad():
            for pe, pm in zip(ema.parameters(), model.parameters()):
                pe.lerp_(pm, 1.0 - decay)
        lv = float(loss.detach())
        if not math.isfinite(lv):
            raise FloatingPointError(f"filter training loss became {lv} at step {step}; lower train.lr")
        history["train"].append({"loss": lv, **terms})
        bar.update(1)
        bar.set_postfix(loss=f"{lv:.3f}", simple=f"{terms['simple']:.3f}")
        if step % tc.val_every == 0 or step == total:
            history["val_step"].append(step)
            history["val"].append(validate(task, ema, vbatch, tc.val_sampling_steps))
            bar.write(f"step {step}: val {history['val'][-1]} (input {val_input})")
    bar.close()
    if not history["val_step"] or history["val_step"][-1] != step:
        history["val_step"].append(step)
        history["val"].append(validate(task, ema, vbatch, tc.val_sampling_steps))
    f = task.checkpoint_fields()
    ema_state = {k: v.detach().clone() for k, v in ema.state_dict().items()}
    if export:
        model_state, ema_out, train_state = {k: v.half() for k, v in ema_state.items()}, None, None
    else:
        model_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
        ema_out, train_state = ema_state, {"step": step, "seed": seed, "config": cfg.to_dict(), "history": history}
    seconds = time.perf_counter() - t0
    f["meta"].update({"config_name": cfg.name, "step": step, "val": history["val"][-1], "val_input": val_input,
                      "seconds": seconds, "train_windows": len(train)})
    ck = Checkpoint(kind=f["kind"], model_config=f["model_config"], diffusion_config=f["diffusion_config"],
                    model_state=model_state, normalizer=f["normalizer"], fps=f["fps"],
                    L_epi=f["L_epi"], k=f["k"], extra=f["extra"], data={"name": ds.name, "hash": ds.hash,
                                                           "path": str(Path(data_dir).resolve())},
                    ema_state=ema_out, meta=f["meta"], train_state=train_state, code_version=__version__)
    save_checkpoint(ckpt_path, ck)
    tail = [h["loss"] for h in history["train"][-100:]]
    return FilterResult(steps=step, seconds=seconds, train_loss=float(np.mean(tail)) if tail else float("nan"),
                        val=history["val"][-1], val_input=val_input, train_windows=len(train), val_windows=len(vidx),
                        parameters=sum(p.numel() for p in model.parameters()), checkpoint=str(ckpt_path))
