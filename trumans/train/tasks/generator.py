"""The generator task (TRUMANS §4, appendix A.2): the motion denoiser trained as a masked diffusion
model on canonical episodes with scene and action conditions (``trumans.train.tasks.Task``).

Per step: a batch of episodes (``trumans.train.data.BatchStream``), random inpainting masks
(``MaskSampler``: M_trans, M_goal), random condition dropout for classifier-free guidance, and
``GaussianDiffusion.training_loss`` (its "simple" term is the loss), plus, with
``train.seam_weight`` > 0, the seam-continuity term ``seam_loss``. Validation: the same loss of
the EMA model on the val split with fixed noise, masks and steps, beside the loss of a model that
outputs 0.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
from torch import nn

from trumans.version import __version__
from trumans.dataset import Dataset
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import GaussianDiffusion
from trumans.model.episodes import Normalizer
from trumans.model.masks import MaskSampler
from trumans.model.nets import Denoiser, DenoiserConfig

from trumans.train.config import GeneratorConfig, load_config
from trumans.train.data import Batch, BatchStream, EpisodeSet, load_episodes
from trumans.train.tasks import TaskLoss

__all__ = ["GeneratorTask", "ABLATIONS", "seam_loss", "SEAM_WINDOW", "model_config", "mask_sampler", "condition_inputs", "validation_loss",
           "VAL_SEED", "DEFAULT_CONFIG"]

DEFAULT_CONFIG = "cpu-small"
VAL_SEED = 20240601  # validation noise/masks are fixed so val losses compare across runs
ABLATIONS = {  # --ablate NAME -> (section, key) set to False
    "progress": ("data", "progress_indicator"),
    "scene": ("conditions", "scene"),
    "action": ("conditions", "action"),
    "augmented": ("data", "augmented"),
}


SEAM_WINDOW = 3  # new frames after the context that the seam term covers


def seam_loss(x0_hat: torch.Tensor, x0: torch.Tensor, mask: torch.Tensor, k: int,
              window: int = SEAM_WINDOW) -> torch.Tensor:
    """The seam-continuity term: mean absolute error of the 1st, 2nd and 3rd time differences of the
    predicted episode against the clean one over its first ``k + window`` frames (the ``k`` context
    frames and the first new ones), on the samples whose transition frames are given.

    x0_hat, x0: (B, L, F) normalised features (x0_hat with the given entries at their clean values);
    mask: (B, L, F) bool, True = given; k: context frames -> scalar. Not in TRUMANS: its loss weighs
    the first new frame like any other, and generated motion jerked at every seam (the network's
    first new frames did not continue the context's velocity and acceleration; docs/sampling_log.md,
    "The seams, measured at their peak"). Velocity terms of this kind are MDM's geometric losses
    (Tevet et al. 2023, §3 eq. 4), here only across the seam."""
    if x0_hat.shape != x0.shape or x0.dim() != 3 or mask.shape != x0.shape:
        raise ValueError(f"need x0_hat, x0 and mask of one shape (B, L, F), got {tuple(x0_hat.shape)}, "
                         f"{tuple(x0.shape)}, {tuple(mask.shape)}")
    end = min(k + window, x0.shape[1])
    if k < 1 or end < 4:
        raise ValueError(f"the seam term needs k >= 1 and at least 4 frames from the context on, got k={k}, L={x0.shape[1]}")
    trans = mask[:, :k].flatten(1).all(dim=1).to(x0.dtype)  # (B,) the transition frames are given
    per = x0.new_zeros(x0.shape[0])
    for n in (1, 2, 3):
        err = torch.diff(x0_hat[:, :end], n=n, dim=1) - torch.diff(x0[:, :end], n=n, dim=1)
        per = per + err.abs().mean(dim=(1, 2))
    return (per * trans).sum() / trans.sum().clamp_min(1.0)


def model_config(cfg: GeneratorConfig, num_actions: int) -> DenoiserConfig:
    """The denoiser config of a training config for ``num_actions`` actions (ablations drop encoders)."""
    return cfg.denoiser_config(num_actions)


def mask_sampler(cfg: GeneratorConfig) -> MaskSampler:
    t, d = cfg.train, cfg.data
    return MaskSampler(d.episode_frames, cfg.model.layout, d.transition_frames, t.p_trans, t.p_goal_pelvis, t.p_goal_hand)


def condition_inputs(model_cfg: DenoiserConfig, scene: torch.Tensor, actions: torch.Tensor) -> dict:
    """The raw condition keyword arguments the denoiser takes (only those it has encoders for)."""
    cond = {}
    if model_cfg.scene is not None:
        cond["scene"] = scene
    if model_cfg.action is not None:
        cond["actions"] = actions
    return cond


@torch.no_grad()
def validation_loss(model: Denoiser, diffusion: GaussianDiffusion, stream: BatchStream, cfg: GeneratorConfig,
                    batch_size: int | None = None, max_episodes: int | None = None) -> tuple[float, float]:
    """(val_loss, zero baseline) over the first ``max_episodes`` episodes of ``stream``, with
    fixed diffusion steps, noise and masks (seed ``VAL_SEED``), every condition given. The baseline
    is the same loss for a model that outputs 0 (ε̂ = 0, x̂0 = 0 or v̂ = 0 per the prediction type)."""
    model.eval()
    n = min(len(stream.eps), max_episodes or cfg.data.max_val_episodes)
    bs = batch_size or cfg.train.val_batch_size
    g = torch.Generator().manual_seed(VAL_SEED)
    sampler = mask_sampler(cfg)
    dev = next(model.parameters()).device
    tot = zero = count = 0.0
    for s in range(0, n, bs):
        b = stream.get(np.arange(s, min(n, s + bs)))
        B = len(b.index)
        x0 = b.x.to(dev)
        mask = sampler(B, g).to(dev)
        t = torch.randint(0, diffusion.steps, (B,), generator=g).to(dev)
        noise = torch.randn(x0.shape, generator=g).to(dev)
        cond = condition_inputs(model.config, b.scene.to(dev), b.actions.to(dev))
        out = diffusion.training_loss(model, x0, mask=mask, t=t, noise=noise, **cond)
        free = (~mask).float()
        k = free.sum().item()
        tot += out.loss.item() * k
        target = diffusion.target(x0, noise, t)
        zero += (diffusion.elementwise_loss(torch.zeros_like(target), target) * free).sum().item()
        count += k
    return tot / max(count, 1.0), zero / max(count, 1.0)


class GeneratorTask:
    """The generator as a ``trumans.train.tasks.Task``. vocabulary: the action names (set by ``setup`` from
    the dataset; give it to build a model without data, e.g. for benchmarks)."""

    kind = "generator"

    def __init__(self, config: GeneratorConfig, vocabulary: Sequence[str] | None = None) -> None:
        self.config = config
        self.vocabulary = list(vocabulary) if vocabulary is not None else None
        self.diffusion = GaussianDiffusion(config.diffusion)
        self.sampler = mask_sampler(config)
        self.normalizer: Normalizer | None = None
        self.stream: BatchStream | None = None
        self.val_stream: BatchStream | None = None
        self.data_record: dict = {}

    @classmethod
    def from_config(cls, config: str | Path | None = None, *, overrides: dict[str, dict] | None = None,
                    ablate: Sequence[str] = ()) -> "GeneratorTask":
        """The task factory (``trumans.train.tasks.TASKS``): a config name or TOML path (default cpu-small)."""
        cfg = load_config(config or DEFAULT_CONFIG)
        over = {k: dict(v) for k, v in (overrides or {}).items()}
        for a in ablate:
            if a not in ABLATIONS:
                raise ValueError(f"unknown ablation {a!r} for the generator; ablations: {sorted(ABLATIONS)}")
            sec, key = ABLATIONS[a]
            over.setdefault(sec, {})[key] = False
        return cls(cfg.with_overrides(**over) if over else cfg)

    @property
    def model_config(self) -> DenoiserConfig:
        if self.vocabulary is None:
            raise ValueError("the generator's action vocabulary is unknown: call setup() with a dataset first")
        return self.config.denoiser_config(len(self.vocabulary))

    def setup(self, data_dir: str | Path, out_dir: Path, *, is_main: bool, barrier: Callable[[], None],
              prev: Checkpoint | None, seed: int = 0, extra_dirs: Sequence[str | Path] = (),
              progress: bool = True, fine_tune: bool = False) -> None:
        """Episodes of ``data_dir``'s train and val splits (+ the train splits of the augmented
        dataset folders ``extra_dirs`` unless ``data.augmented`` is False), cached in ``out_dir/cache``;
        ``prev``: the resumed run (same data) or, with ``fine_tune``, the --init checkpoint (any data
        with its action vocabulary)."""
        cfg = self.config
        ds = Dataset(data_dir)
        vocab = ds.vocabulary
        aug = [Dataset(d) for d in extra_dirs] if cfg.data.augmented else []
        for a in aug:
            if a.vocabulary != vocab:
                raise ValueError(f"augmented data {a.root} has vocabulary {a.vocabulary}, {data_dir} has {vocab}; "
                                 f"augment the same dataset")
        self.data_record = {"name": ds.name, "hash": ds.hash, "path": str(Path(data_dir).resolve()),
                            "augmented": [{"name": a.name, "hash": a.hash, "path": str(a.root.resolve())} for a in aug]}
        if prev is not None:
            if prev.vocabulary != vocab:
                what = "the --init checkpoint was" if fine_tune else f"the run in {out_dir} was"
                raise ValueError(f"{what} trained with the action vocabulary {prev.vocabulary}, but "
                                 f"{data_dir} has {vocab}; resume on the data it was trained on, or train a new run "
                                 f"(another --out)")
            old_h = [prev.data.get("hash")] + [a.get("hash") for a in prev.data.get("augmented", [])]
            new_h = [ds.hash] + [a.hash for a in aug]
            if old_h != new_h and not fine_tune:
                raise ValueError(f"the run in {out_dir} was trained on other data (hashes {[str(h)[:12] for h in old_h]}, "
                                 f"now {[str(h)[:12] for h in new_h]}); resume with the same --data / --augmented")
        self.vocabulary = vocab
        sources = [(ds, "train"), (ds, "val")] + [(a, "train") for a in aug]
        loaded: list[EpisodeSet] = []
        for rank_turn in (True, False):  # rank 0 builds and caches first, then the others read the cache
            if is_main == rank_turn:
                loaded = [load_episodes(d, split, cfg.data, vocab, out_dir / "cache", progress=progress and is_main,
                                        write_cache=is_main) for d, split in sources]
            barrier()
        train_eps = EpisodeSet.concat([loaded[0]] + loaded[2:]) if aug else loaded[0]
        self.normalizer = prev.normalizer if prev is not None else Normalizer.fit(train_eps.features)
        groups = shares = None
        if aug and cfg.data.augmented_share is not None:  # original vs augmented episodes, fixed batch shares
            groups = np.concatenate([np.zeros(len(loaded[0]), np.int64)] + [np.ones(len(e), np.int64) for e in loaded[2:]])
            shares = [1.0 - cfg.data.augmented_share, cfg.data.augmented_share]
        self.stream = BatchStream(train_eps, self.normalizer, cfg.train.batch_size, seed, groups, shares)
        self.val_stream = BatchStream(loaded[1], self.normalizer, cfg.train.val_batch_size, seed)

    def build_model(self) -> Denoiser:
        return Denoiser(self.model_config)

    def batch(self, step: int, rank: int, world: int) -> Batch:
        return self.stream.batch(step, rank, world)

    def random_batch(self, batch_size: int, generator: torch.Generator | None = None) -> Batch:
        """A batch of random inputs of the config's shapes (benchmarks: no dataset needed)."""
        c, n = self.config, self.config.data.grid
        L, F, A = c.data.episode_frames, self.model_config.feature_dim, len(self.vocabulary)
        return Batch(torch.randn(batch_size, L, F, generator=generator),
                     torch.rand(batch_size, L, A, generator=generator) + 1,
                     torch.rand(batch_size, n, n, n, generator=generator) > 0.7, np.arange(batch_size))

    def loss(self, model: nn.Module, batch: Batch, generator: torch.Generator, device: torch.device) -> TaskLoss:
        tc = self.config.train
        B = len(batch.index)
        mask = self.sampler(B, generator)
        cond = condition_inputs(self.model_config, batch.scene.to(device), batch.actions.to(device))
        if "scene" in cond:
            cond["drop_scene"] = (torch.rand(B, generator=generator) < tc.p_drop_scene).to(device)
        if "actions" in cond:
            cond["drop_action"] = (torch.rand(B, generator=generator) < tc.p_drop_action).to(device)
        x0, mask = batch.x.to(device), mask.to(device)
        out = self._diffusion(device).training_loss(model, x0, mask=mask, generator=generator, **cond)
        if tc.seam_weight == 0:
            return TaskLoss(out.loss, out.terms)
        seam = seam_loss(out.x0_hat, x0, mask, self.config.data.transition_frames)
        return TaskLoss(out.loss + tc.seam_weight * seam, {**out.terms, "seam": seam})

    def validate(self, model: nn.Module) -> tuple[float, float]:
        dev = next(model.parameters()).device
        return validation_loss(model, self._diffusion(dev), self.val_stream, self.config)

    def _diffusion(self, device: torch.device) -> GaussianDiffusion:
        if self.diffusion.betas.device != torch.device(device):
            self.diffusion.to(device)
        return self.diffusion

    def sizes(self) -> tuple[int, int]:
        return len(self.stream.eps), len(self.val_stream.eps)

    def checkpoint(self, *, model_state: dict, ema_state: dict, meta: dict, train_state: dict) -> Checkpoint:
        d = self.config.data
        return Checkpoint(
            kind="generator", model_config=self.model_config, diffusion_config=self.config.diffusion,
            model_state=model_state, ema_state=ema_state, normalizer=self.normalizer, vocabulary=self.vocabulary,
            fps=d.fps, L_epi=d.episode_frames, k=d.transition_frames, grid={"n": d.grid, "extent": list(d.extent)},
            extra={"progress_indicator": bool(d.progress_indicator)},  # the sampler builds labels the same way
            data=self.data_record, meta=meta, train_state=train_state, code_version=__version__)
