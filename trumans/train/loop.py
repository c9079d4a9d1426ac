"""The training loop (TRUMANS §4, appendix A.2), shared by every task (``trumans.train.tasks.Task``):
Adam (or AdamW, ``train.optimizer``) with linear warm-up, EMA, gradient clipping, validation and
atomic checkpoints at their cadence, exact resume, the loss curve, DDP.

Randomness is a pure function of (seed, step, rank): the task's batch, its diffusion steps, noise,
masks and condition dropout come from a generator seeded per step, and the global torch seed
(dropout) is reset per step; the model is initialised right after ``torch.manual_seed(seed)``.
With the optimizer, scheduler and EMA states in the checkpoint, ``resume`` continues to exactly
the weights of an uninterrupted run.
"""
from __future__ import annotations

import copy
import gc
import hashlib
import json
import math
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch import nn
from torch.nn.parallel import DistributedDataParallel

from trumans.io_lock import FolderLock, sweep_temp_files
from trumans.model.checkpoint import load_checkpoint, save_checkpoint
from trumans.sequence import atomic_write

from trumans.train import ddp
from trumans.train.config import GeneratorConfig
from trumans.train.tasks.generator import GeneratorTask, model_config, validation_loss  # noqa: F401  (public names of train.loop)
from trumans.train.tasks import Task

__all__ = ["TrainResult", "train", "initial_model", "model_config", "validation_loss", "weights_digest",
           "CHECKPOINT_NAME", "LOSS_PNG"]

CHECKPOINT_NAME = "checkpoint.pt"
LOSS_PNG = "loss.png"


@dataclass
class TrainResult:
    """The summary figures of a run (``--json`` prints them). val_loss_zero_baseline: the task's
    validation loss of a trivial model (the generator: one that outputs 0); *_episodes: the task's
    training / validation examples."""

    steps: int
    samples_per_s: float
    loader_samples_per_s: float
    train_loss: float
    val_loss: float
    val_loss_zero_baseline: float
    val_ratio: float
    seconds: float
    train_episodes: int
    val_episodes: int
    parameters: int
    world_size: int
    weights_sha256: str
    ranks_in_sync: bool
    checkpoint: str
    loss_png: str

    def to_dict(self) -> dict:
        return asdict(self)


def weights_digest(model: torch.nn.Module) -> str:
    """SHA-256 of every parameter's bytes (in state-dict order): equal digests = identical weights."""
    h = hashlib.sha256()
    for k, v in model.state_dict().items():
        h.update(k.encode())
        h.update(v.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def _step_seed(seed: int, step: int, rank: int) -> int:
    return (seed * 1_000_003 + step * 7919 + rank * 104_729 + 17) % (2 ** 63 - 1)


def _lr_lambda(warmup: int):
    return lambda step: min(1.0, (step + 1) / warmup) if warmup > 0 else 1.0


def _plot(history: dict, path: Path, title: str, ylabel: str = "loss") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    tr = np.asarray(history["train"], dtype=np.float64)
    if len(tr):
        w = max(1, min(100, len(tr) // 20))
        smooth = np.convolve(tr, np.ones(w) / w, mode="valid")
        ax.plot(np.arange(len(tr)), tr, color="C0", alpha=0.2, lw=0.5)
        ax.plot(np.arange(w - 1, len(tr)), smooth, color="C0", label=f"train (mean of {w})")
    if history["val_step"]:
        ax.plot(history["val_step"], history["val"], "o-", color="C1", label="val (EMA)")
        ax.plot(history["val_step"], history["zero"], "--", color="gray", label="val, zero-noise baseline")
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.13, top=0.9)
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)


def _comparable(task: Task, cfg: dict) -> dict:
    """A config as plain data without the keys a resumed run may change (length, cadence, time limit)."""
    d = json.loads(json.dumps(type(task.config).from_dict(cfg).to_dict()))
    for k in ("steps", "time_limit_s", "checkpoint_every", "val_every"):
        d["train"].pop(k, None)
    return d


def initial_model(task: Task, seed: int) -> nn.Module:
    """The task's model as the loop initialises it for ``seed`` (before any step)."""
    torch.manual_seed(seed)
    return task.build_model()


def train(task: Task | GeneratorConfig, data_dir: str | Path, out_dir: str | Path, *, steps: int | None = None,
          resume: bool = False, seed: int = 0, progress: bool = True, device: str | None = None,
          augmented_dirs: Sequence[str | Path] = (), init: str | Path | None = None) -> TrainResult:
    """Train ``task`` (a generator config means ``GeneratorTask(config)``) on ``data_dir`` into
    ``out_dir`` (``checkpoint.pt``, ``loss.png``, ``cache/``).

    steps: total optimisation steps (default ``config.train.steps``); resume: continue from
    ``out_dir/checkpoint.pt``; augmented_dirs: extra data folders handed to the task (the
    generator: augmented datasets whose train split joins training unless ``data.augmented`` is
    False); init: a checkpoint of the same kind to fine-tune, on its data or other data the task can
    read (the same action vocabulary): its weights (EMA if present), normalisation and task state
    start the run, with a fresh optimiser and step 0 (ignored when resuming). Under torchrun every process calls this; rank 0 writes the files.
    """
    from tqdm import tqdm

    if isinstance(task, GeneratorConfig):
        task = GeneratorTask(task)
    cfg = task.config
    tc = cfg.train
    total = int(steps if steps is not None else tc.steps)
    if total < 0:
        raise ValueError(f"steps must be >= 0, got {total}")
    info = ddp.setup(device)
    lock = None
    net = None  # the DDP wrapper: its reducer holds the process group and must go before it
    finished = False  # every rank reached the end: cleanup may meet at a barrier
    out = Path(out_dir)
    created = info.is_main and not out.exists()  # a refused run removes the run folder it made
    try:
        if info.is_main:  # one writer per run folder; a killed run's temp files (.checkpoint.pt.*.tmp) go
            lock = FolderLock(out, "trumans train").acquire()
            sweep_temp_files(out)
        ckpt_path = out / CHECKPOINT_NAME
        prev = None
        if ckpt_path.is_file():
            if not resume:
                raise ValueError(f"{ckpt_path} exists; pass --resume to continue that run or choose a new --out")
            prev = load_checkpoint(ckpt_path, kind=task.kind)
            if prev.train_state is None:
                raise ValueError(f"{ckpt_path} has no training state (an export); it cannot be resumed")
            try:
                same = _comparable(task, prev.train_state["config"]) == _comparable(task, cfg.to_dict())
            except ValueError as e:
                raise ValueError(f"{ckpt_path} holds a config this code cannot read ({e}); start a new run") from e
            if not same:
                raise ValueError(f"{ckpt_path} was trained with a different config; resume with the same --config")
            if int(prev.train_state["seed"]) != seed:
                raise ValueError(f"{ckpt_path} was trained with --seed {prev.train_state['seed']}, not {seed}")
        start = None
        if init is not None and prev is None:
            start = load_checkpoint(init, kind=task.kind)
        init_name = str(init) if start is not None else (prev.meta.get("init") if prev is not None else None)
        t0 = time.perf_counter()
        task.setup(data_dir, out, is_main=info.is_main, barrier=lambda: ddp.barrier(info), prev=prev or start,
                   seed=seed, extra_dirs=augmented_dirs, progress=progress,
                   **({"fine_tune": True} if start is not None else {}))  # only then: older tasks lack the keyword
        data_seconds = time.perf_counter() - t0

        model = initial_model(task, seed).to(info.device)
        ema = copy.deepcopy(model).eval().requires_grad_(False)
        optimizer = torch.optim.AdamW if tc.optimizer == "adamw" else torch.optim.Adam
        opt = optimizer(model.parameters(), lr=tc.lr, weight_decay=tc.weight_decay)
        sched = torch.optim.lr_scheduler.LambdaLR(opt, _lr_lambda(tc.warmup_steps))
        history: dict = {"train": [], "val_step": [], "val": [], "zero": [], "terms": {}}
        step, elapsed_before = 0, 0.0
        if start is not None:  # fine-tuning: the init's weights in the model and its EMA
            weights = start.ema_state if start.ema_state is not None else start.model_state
            try:
                model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in weights.items()})
            except RuntimeError as e:
                raise ValueError(f"--init {init} does not fit this config's model ({str(e).splitlines()[0]}); "
                                 f"fine-tune with the config it was trained with") from e
            ema.load_state_dict(model.state_dict())
        if prev is not None:
            model.load_state_dict(prev.model_state)
            ema.load_state_dict(prev.ema_state)
            opt.load_state_dict(prev.train_state["optimizer"])
            sched.load_state_dict(prev.train_state["scheduler"])
            history = {k: (dict(v) if isinstance(v, dict) else list(v)) for k, v in prev.train_state["history"].items()}
            history.setdefault("terms", {})
            step = int(prev.train_state["step"])
            elapsed_before = float(prev.train_state.get("seconds", 0.0))
        net = DistributedDataParallel(model) if info.enabled else model
        n_params = sum(p.numel() for p in model.parameters())

        def save() -> None:
            if not info.is_main:
                return
            val_last = history["val"][-1] if history["val"] else float("nan")
            ck = task.checkpoint(
                model_state={k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
                ema_state={k: v.detach().cpu().clone() for k, v in ema.state_dict().items()},
                meta={"config_name": cfg.name, "val_loss": val_last, "step": step,
                      **({"init": init_name} if init_name else {})},
                train_state={"step": step, "seed": seed, "config": cfg.to_dict(), "optimizer": opt.state_dict(),
                             "scheduler": sched.state_dict(), "history": history,
                             "seconds": elapsed_before + (time.perf_counter() - t_start)})
            save_checkpoint(ckpt_path, ck)
            _plot(history, out / LOSS_PNG, f"{cfg.name}: step {step}", _loss_label(cfg))

        def validate() -> None:
            if info.is_main:
                v, z = task.validate(ema)
                history["val_step"].append(step)
                history["val"].append(v)
                history["zero"].append(z)

        t_start = time.perf_counter()
        saved_at = step if prev is not None else -1  # the step of the checkpoint on disk
        train_time = load_time = 0.0
        done_here = 0
        bar = tqdm(total=total, initial=min(step, total), desc=f"train[{cfg.name}]",
                   disable=not (progress and info.is_main), dynamic_ncols=True)
        while step < total:
            if tc.time_limit_s > 0 and time.perf_counter() - t_start > tc.time_limit_s:
                break
            ts = time.perf_counter()
            torch.manual_seed(_step_seed(seed, step, info.rank))  # dropout
            g = torch.Generator().manual_seed(_step_seed(seed, step, info.rank) + 1)
            batch = task.batch(step, info.rank, info.world)
            load_time += time.perf_counter() - ts
            model.train()
            with torch.autocast(info.device.type, dtype=torch.bfloat16, enabled=tc.precision == "bf16"):
                out_loss = task.loss(net, batch, g, info.device)
            loss = out_loss.loss.float()
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
                for be, bm in zip(ema.buffers(), model.buffers()):
                    be.copy_(bm)
            lv = ddp.all_mean(loss.item(), info)
            if not math.isfinite(lv):
                kept = f"the checkpoint of step {saved_at} is kept" if saved_at >= 0 else "no checkpoint was written"
                raise ValueError(f"training loss became {lv} at step {step} ({kept}); lower train.lr or check the data")
            history["train"].append(lv)
            if len(out_loss.terms) > 1:  # a single term is the loss itself
                for name, v in out_loss.terms.items():
                    history["terms"].setdefault(name, []).append(float(v.detach()))
            train_time += time.perf_counter() - ts
            done_here += 1
            bar.update(1)
            bar.set_postfix(loss=f"{lv:.4f}", val=f"{history['val'][-1]:.4f}" if history["val"] else "-")
            if step % tc.val_every == 0 or step == total:
                validate()
            if step % tc.checkpoint_every == 0 or step == total:
                save()
                saved_at = step
            if step % tc.checkpoint_every == 0:
                ddp.barrier(info)
        bar.close()
        validated_now = not history["val_step"] or history["val_step"][-1] != step
        if validated_now:
            validate()
        if validated_now or saved_at != step:  # else the checkpoint of this step is already written
            save()
        ddp.barrier(info)
        digest = weights_digest(model)
        if info.enabled:
            import torch.distributed as dist

            digests: list = [None] * info.world
            dist.all_gather_object(digests, digest)
            in_sync = all(d == digest for d in digests)
        else:
            in_sync = True
        finished = True
        tail = history["train"][-100:]
        v = history["val"][-1] if history["val"] else float("nan")
        z = history["zero"][-1] if history["zero"] else float("nan")
        n_train, n_val = task.sizes()
        return TrainResult(
            steps=step, samples_per_s=done_here * tc.batch_size / train_time if train_time > 0 else 0.0,
            loader_samples_per_s=done_here * tc.batch_size / load_time if load_time > 0 else 0.0,
            train_loss=float(np.mean(tail)) if tail else float("nan"), val_loss=v, val_loss_zero_baseline=z,
            val_ratio=v / z if z > 0 else float("nan"), seconds=elapsed_before + time.perf_counter() - t_start + data_seconds,
            train_episodes=n_train, val_episodes=n_val, parameters=n_params,
            world_size=info.world, weights_sha256=digest, ranks_in_sync=in_sync, checkpoint=str(ckpt_path),
            loss_png=str(out / LOSS_PNG))
    except BaseException:
        if lock is not None:
            lock.release()
            lock = None
        if created and not (out / CHECKPOINT_NAME).exists():
            shutil.rmtree(out, ignore_errors=True)
        raise
    finally:
        if lock is not None:
            lock.release()
        # drop DDP's reducer (it holds the gloo group) now, not at interpreter exit: a gloo group torn
        # down by the exit's static destructors aborted rank 1 now and then ("terminate called
        # without an active exception", about 1 run in 20)
        del net
        gc.collect()
        ddp.cleanup(info, finished)


def _loss_label(cfg) -> str:
    diffusion = getattr(cfg, "diffusion", None)
    return f"{diffusion.prediction} loss ({diffusion.loss})" if diffusion is not None else "loss"
