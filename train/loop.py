"""The training loop of the generator (TRUMANS §4, appendix A.2): Adam, EMA, clipping, validation,
atomic checkpoints, exact resume, loss curve, DDP.

Randomness is a pure function of (seed, step, rank): the batch (``train.data.BatchStream``), the
diffusion steps, noise, masks and condition dropout come from a generator seeded per step, and
the global torch seed (dropout) is reset per step. With the optimizer, scheduler and EMA states
in the checkpoint, ``resume`` continues to exactly the weights of an uninterrupted run.
"""
from __future__ import annotations

import copy
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch.nn.parallel import DistributedDataParallel

from trumans import __version__
from trumans.model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from trumans.dataset import Dataset
from trumans.model.diffusion import GaussianDiffusion
from trumans.model.episodes import FeatureLayout, Normalizer
from trumans.model.masks import MaskSampler
from trumans.model.nets import ActionEncoderConfig, Denoiser, DenoiserConfig, ScenePerceiverConfig
from trumans.sequence import atomic_write

from . import ddp
from .config import TrainConfig
from .data import BatchStream, EpisodeSet, load_episodes

__all__ = ["TrainResult", "train", "model_config", "validation_loss", "weights_digest", "CHECKPOINT_NAME", "LOSS_PNG"]

CHECKPOINT_NAME = "checkpoint.pt"
LOSS_PNG = "loss.png"
VAL_SEED = 20240601  # validation noise/masks are fixed so val losses compare across runs


@dataclass
class TrainResult:
    """The summary figures of a run (``--json`` prints them)."""

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


def model_config(cfg: TrainConfig, num_actions: int) -> DenoiserConfig:
    """The denoiser config of a training config (ablation switches drop encoders)."""
    m, d = cfg.model, cfg.data
    scene = (ScenePerceiverConfig(grid=d.grid, patch=cfg.scene.patch, d_model=cfg.scene.d_model, layers=cfg.scene.layers,
                                  heads=cfg.scene.heads, ff=cfg.scene.ff, dropout=cfg.scene.dropout)
             if m.scene_condition else None)
    action = (ActionEncoderConfig(num_actions=num_actions, frames=d.episode_frames, d_model=cfg.action.d_model,
                                  layers=cfg.action.layers, heads=cfg.action.heads, ff=cfg.action.ff,
                                  dropout=cfg.action.dropout)
              if m.action_condition else None)
    return DenoiserConfig(layout=FeatureLayout(rotations=d.rotations), frames=d.episode_frames, d_model=m.d_model,
                          layers=m.layers, heads=m.heads, ff=m.ff, dropout=m.dropout, mask_input=m.mask_input,
                          scene=scene, action=action)


def _mask_sampler(cfg: TrainConfig) -> MaskSampler:
    t, d = cfg.train, cfg.data
    return MaskSampler(d.episode_frames, FeatureLayout(rotations=d.rotations), d.transition_frames,
                       t.p_trans, t.p_goal_pelvis, t.p_goal_hand)


def _cond(model_cfg: DenoiserConfig, scene: torch.Tensor, actions: torch.Tensor) -> dict:
    cond = {}
    if model_cfg.scene is not None:
        cond["scene"] = scene
    if model_cfg.action is not None:
        cond["actions"] = actions
    return cond


@torch.no_grad()
def validation_loss(model: Denoiser, diffusion: GaussianDiffusion, stream: BatchStream, cfg: TrainConfig,
                    batch_size: int | None = None, max_episodes: int | None = None) -> tuple[float, float]:
    """(val_loss, zero-noise baseline) over the first ``max_episodes`` episodes of ``stream``, with
    fixed diffusion steps, noise and masks (seed ``VAL_SEED``), every condition given. The baseline
    is the same loss for a model that outputs 0 (ε̂ = 0, x̂0 = 0 or v̂ = 0 per the prediction type)."""
    model.eval()
    n = min(len(stream.eps), max_episodes or cfg.data.max_val_episodes)
    bs = batch_size or cfg.train.val_batch_size
    g = torch.Generator().manual_seed(VAL_SEED)
    sampler = _mask_sampler(cfg)
    dev = next(model.parameters()).device
    tot = zero = count = 0.0
    for s in range(0, n, bs):
        b = stream.get(np.arange(s, min(n, s + bs)))
        B = len(b.index)
        x0 = b.x.to(dev)
        mask = sampler(B, g).to(dev)
        t = torch.randint(0, diffusion.steps, (B,), generator=g).to(dev)
        noise = torch.randn(x0.shape, generator=g).to(dev)
        cond = _cond(model.config, b.scene.to(dev), b.actions.to(dev))
        out = diffusion.training_loss(model, x0, mask=mask, t=t, noise=noise, **cond)
        free = (~mask).float()
        k = free.sum().item()
        tot += out.loss.item() * k
        target = diffusion.target(x0, noise, t)
        zero += (diffusion.elementwise_loss(torch.zeros_like(target), target) * free).sum().item()
        count += k
    return tot / max(count, 1.0), zero / max(count, 1.0)


def weights_digest(model: torch.nn.Module) -> str:
    """SHA-256 of every parameter's bytes (in state-dict order): equal digests = identical weights."""
    import hashlib

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
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)


def _comparable(cfg: dict) -> dict:
    d = json.loads(json.dumps(cfg))
    for k in ("steps", "time_limit_s", "checkpoint_every", "val_every"):
        d["train"].pop(k, None)
    return d


def train(cfg: TrainConfig, data_dir: str | Path, out_dir: str | Path, *, steps: int | None = None,
          resume: bool = False, seed: int = 0, progress: bool = True, device: str | None = None,
          augmented_dirs: list[str | Path] = ()) -> TrainResult:
    """Train the generator on ``data_dir`` into ``out_dir`` (``checkpoint.pt``, ``loss.png``).

    steps: total optimisation steps (default ``cfg.train.steps``); resume: continue from
    ``out_dir/checkpoint.pt``; augmented_dirs: augmented dataset folders (``trumans augment``
    output) whose train split joins the training episodes unless ``cfg.data.augmented`` is False
    (validation always uses ``data_dir``'s val split). Under torchrun every process calls this;
    rank 0 writes the files.
    """
    from tqdm import tqdm

    info = ddp.setup(device)
    try:
        torch.manual_seed(seed)
        out = Path(out_dir)
        ckpt_path = out / CHECKPOINT_NAME
        total = int(steps if steps is not None else cfg.train.steps)
        if total < 0:
            raise ValueError(f"steps must be >= 0, got {total}")
        prev = None
        if ckpt_path.is_file():
            if not resume:
                raise ValueError(f"{ckpt_path} exists; pass --resume to continue that run or choose a new --out")
            prev = load_checkpoint(ckpt_path)
            if prev.train_state is None:
                raise ValueError(f"{ckpt_path} has no training state (an export); it cannot be resumed")
            if _comparable(prev.train_state["config"]) != _comparable(cfg.to_dict()):
                raise ValueError(f"{ckpt_path} was trained with a different config; resume with the same --config")
            if int(prev.train_state["seed"]) != seed:
                raise ValueError(f"{ckpt_path} was trained with --seed {prev.train_state['seed']}, not {seed}")
        ds = Dataset(data_dir)
        vocab = ds.vocabulary
        aug = [Dataset(d) for d in augmented_dirs] if cfg.data.augmented else []
        for a in aug:
            if a.vocabulary != vocab:
                raise ValueError(f"augmented data {a.root} has vocabulary {a.vocabulary}, {data_dir} has {vocab}; "
                                 f"augment the same dataset")
        data_record = {"name": ds.name, "hash": ds.hash, "path": str(Path(data_dir).resolve()),
                       "augmented": [{"name": a.name, "hash": a.hash, "path": str(a.root.resolve())} for a in aug]}
        if prev is not None:
            old_h = [prev.data.get("hash")] + [a.get("hash") for a in prev.data.get("augmented", [])]
            new_h = [ds.hash] + [a.hash for a in aug]
            if old_h != new_h:
                raise ValueError(f"{ckpt_path} was trained on other data (hashes {[str(h)[:12] for h in old_h]}, now "
                                 f"{[str(h)[:12] for h in new_h]}); resume with the same --data / --augmented")
        cache = out / "cache"
        t0 = time.perf_counter()
        episodes: dict[str, EpisodeSet] = {}
        sources = [(ds, "train"), (ds, "val")] + [(a, "train") for a in aug]
        loaded: list[EpisodeSet] = []
        for rank_turn in (True, False):  # rank 0 builds and caches first, then the others read the cache
            if info.is_main == rank_turn:
                loaded = [load_episodes(d, split, cfg.data, vocab, cache, progress=progress and info.is_main,
                                        write_cache=info.is_main) for d, split in sources]
            ddp.barrier(info)
        episodes["train"] = EpisodeSet.concat([loaded[0]] + loaded[2:]) if aug else loaded[0]
        episodes["val"] = loaded[1]
        data_seconds = time.perf_counter() - t0
        normalizer = prev.normalizer if prev is not None else Normalizer.fit(episodes["train"].features)
        stream = BatchStream(episodes["train"], normalizer, cfg.train.batch_size, seed)
        val_stream = BatchStream(episodes["val"], normalizer, cfg.train.val_batch_size, seed)

        mcfg = model_config(cfg, len(vocab))
        diffusion = GaussianDiffusion(cfg.diffusion).to(info.device)
        model = Denoiser(mcfg).to(info.device)
        ema = copy.deepcopy(model).eval().requires_grad_(False)
        opt = torch.optim.Adam(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
        sched = torch.optim.lr_scheduler.LambdaLR(opt, _lr_lambda(cfg.train.warmup_steps))
        history = {"train": [], "val_step": [], "val": [], "zero": []}
        step, elapsed_before = 0, 0.0
        if prev is not None:
            model.load_state_dict(prev.model_state)
            ema.load_state_dict(prev.ema_state)
            opt.load_state_dict(prev.train_state["optimizer"])
            sched.load_state_dict(prev.train_state["scheduler"])
            history = {k: list(v) for k, v in prev.train_state["history"].items()}
            step = int(prev.train_state["step"])
            elapsed_before = float(prev.train_state.get("seconds", 0.0))
        net = DistributedDataParallel(model) if info.enabled else model
        sampler = _mask_sampler(cfg)
        n_params = sum(p.numel() for p in model.parameters())

        def save() -> None:
            if not info.is_main:
                return
            val_last = history["val"][-1] if history["val"] else float("nan")
            ck = Checkpoint(
                kind="generator", model_config=mcfg, diffusion_config=cfg.diffusion,
                model_state={k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
                ema_state={k: v.detach().cpu().clone() for k, v in ema.state_dict().items()},
                normalizer=normalizer, vocabulary=vocab, fps=cfg.data.fps, L_epi=cfg.data.episode_frames,
                k=cfg.data.transition_frames, grid={"n": cfg.data.grid, "extent": list(cfg.data.extent)},
                data=data_record,
                meta={"config_name": cfg.name, "val_loss": val_last, "step": step},
                train_state={"step": step, "seed": seed, "config": cfg.to_dict(), "optimizer": opt.state_dict(),
                             "scheduler": sched.state_dict(), "history": history,
                             "seconds": elapsed_before + (time.perf_counter() - t_start)},
                code_version=__version__)
            save_checkpoint(ckpt_path, ck)
            _plot(history, out / LOSS_PNG, f"{cfg.name}: step {step}", f"{cfg.diffusion.prediction} loss ({cfg.diffusion.loss})")

        def validate() -> None:
            if info.is_main:
                v, z = validation_loss(ema, diffusion, val_stream, cfg)
                history["val_step"].append(step)
                history["val"].append(v)
                history["zero"].append(z)

        t_start = time.perf_counter()
        train_time = load_time = 0.0
        done_here = 0
        bar = tqdm(total=total, initial=min(step, total), desc=f"train[{cfg.name}]",
                   disable=not (progress and info.is_main), dynamic_ncols=True)
        tc = cfg.train
        while step < total:
            if tc.time_limit_s > 0 and time.perf_counter() - t_start > tc.time_limit_s:
                break
            ts = time.perf_counter()
            torch.manual_seed(_step_seed(seed, step, info.rank))  # dropout
            g = torch.Generator().manual_seed(_step_seed(seed, step, info.rank) + 1)
            b = stream.batch(step, info.rank, info.world)
            load_time += time.perf_counter() - ts
            B = len(b.index)
            mask = sampler(B, g)
            cond = _cond(mcfg, b.scene.to(info.device), b.actions.to(info.device))
            if "scene" in cond:
                cond["drop_scene"] = (torch.rand(B, generator=g) < tc.p_drop_scene).to(info.device)
            if "actions" in cond:
                cond["drop_action"] = (torch.rand(B, generator=g) < tc.p_drop_action).to(info.device)
            model.train()
            loss = diffusion.training_loss(net, b.x.to(info.device), mask=mask.to(info.device), generator=g, **cond).loss
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
                raise FloatingPointError(f"training loss became {lv} at step {step}; lower train.lr or check the data")
            history["train"].append(lv)
            train_time += time.perf_counter() - ts
            done_here += 1
            bar.update(1)
            bar.set_postfix(loss=f"{lv:.4f}", val=f"{history['val'][-1]:.4f}" if history["val"] else "-")
            if step % tc.val_every == 0 or step == total:
                validate()
            if step % tc.checkpoint_every == 0 or step == total:
                save()
            if step % tc.checkpoint_every == 0:
                ddp.barrier(info)
        bar.close()
        if not history["val_step"] or history["val_step"][-1] != step:
            validate()
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
        tail = history["train"][-100:]
        v = history["val"][-1] if history["val"] else float("nan")
        z = history["zero"][-1] if history["zero"] else float("nan")
        return TrainResult(
            steps=step, samples_per_s=done_here * cfg.train.batch_size / train_time if train_time > 0 else 0.0,
            loader_samples_per_s=done_here * cfg.train.batch_size / load_time if load_time > 0 else 0.0,
            train_loss=float(np.mean(tail)) if tail else float("nan"), val_loss=v, val_loss_zero_baseline=z,
            val_ratio=v / z if z > 0 else float("nan"), seconds=elapsed_before + time.perf_counter() - t_start + data_seconds,
            train_episodes=len(episodes["train"]), val_episodes=len(episodes["val"]), parameters=n_params,
            world_size=info.world, weights_sha256=digest, ranks_in_sync=in_sync, checkpoint=str(ckpt_path), loss_png=str(out / LOSS_PNG))
    finally:
        ddp.cleanup(info)
