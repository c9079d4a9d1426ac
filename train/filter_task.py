"""Training the HOI filter (I'm-HOI §3.2, appendix A.2): the task (model, loss, checkpoint) and
its config.

Loss: x₀-prediction with the L1 simple objective (eq. 6) on normalised frame vectors, plus the
regularisers of eq. 7 on the de-normalised prediction (``trumans.hoi.losses``). Schedule
(appendix A.2): the first ``simple_only`` fraction of the steps is the warm-up on every category
with the simple loss only; then L_off and L_vel join; after ``consist_imu_from`` L_consist and L_imu
join too. One shared model embeds the object category into its first token (the paper fine-tunes
one model per category; ``categories`` in the config restricts training to a subset, which is how a
per-category fine-tune from a shared checkpoint is run). EMA of the weights.

Data: clean windows (``trumans.hoi.data``) corrupted on the fly by ``trumans.hoi.corrupt`` with a
generator seeded per step, so a run is a pure function of its seed.
"""
from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from pathlib import Path

import numpy as np
import torch

from trumans.hoi.corrupt import CorruptionConfig, corrupt
from trumans.hoi.filter import FilterModel, FilterNetConfig, filter_denoiser_config, prepare_windows, sample_x0
from trumans.hoi.frame import JOINTS, OBJ_R, OBJ_T, to_frame
from trumans.hoi.losses import loss_consist, loss_imu, loss_off, loss_vel
from trumans.model.diffusion import DiffusionConfig, GaussianDiffusion
from trumans.model.episodes import Normalizer
from trumans.model.nets.denoiser import Denoiser
from trumans.rotations import sixd_to_matrix

from trumans.hoi.data import FilterWindows

__all__ = ["FilterTrainSection", "FilterConfig", "load_filter_config", "FilterTask", "filter_metrics", "KIND"]

KIND = "filter"
CONFIG_DIR = Path(__file__).parent / "configs"


@dataclass(frozen=True)
class FilterTrainSection:
    """Optimiser, schedule and loss weights. Paper weights: λ_off = λ_vel = λ_consist = 1,
    λ_imu = 100 on unnormalised SMPL-H vectors; ours act on metres next to an L1 loss on
    standardised features, so they are rescaled (at the start each weighted term is a fraction of the simple loss)."""

    steps: int = 3000
    batch_size: int = 32
    lr: float = 5e-4
    warmup_steps: int = 100
    ema_decay: float = 0.995
    grad_clip: float = 1.0
    stride: int = 16
    val_every: int = 500
    val_windows: int = 256
    val_sampling_steps: int = 5
    time_limit_s: float = 0.0
    simple_only: float = 0.3
    consist_imu_from: float = 0.6
    w_off: float = 0.01
    w_vel: float = 0.1
    w_consist: float = 0.02
    w_imu: float = 0.1
    categories: tuple[str, ...] = ()


@dataclass(frozen=True)
class FilterConfig:
    name: str = "filter-cpu"
    net: FilterNetConfig = field(default_factory=FilterNetConfig)
    diffusion: DiffusionConfig = field(default_factory=lambda: DiffusionConfig(steps=1000, loss="l1", prediction="x0"))
    train: FilterTrainSection = field(default_factory=FilterTrainSection)
    corruption: CorruptionConfig = field(default_factory=CorruptionConfig)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, where: str = "filter config") -> "FilterConfig":
        return _build(cls, d, where)


def _build(cls, d, where: str):
    if not isinstance(d, dict):
        raise ValueError(f"{where} must be a table, got {type(d).__name__}")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; known keys: {sorted(known)}")
    defaults = cls()
    kw = {}
    for k, v in d.items():
        dv = getattr(defaults, k)
        if is_dataclass(dv):
            kw[k] = _build(type(dv), v, f"{where}.{k}")
        elif isinstance(dv, tuple):
            kw[k] = tuple(v)
        else:
            kw[k] = v
    try:
        return cls(**kw)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from e


def load_filter_config(name_or_path: str | Path) -> FilterConfig:
    """A built-in config name (``filter-cpu``) or a TOML file -> FilterConfig (unknown keys are errors)."""
    p = Path(name_or_path)
    if not p.suffix and (CONFIG_DIR / f"{p.name}.toml").is_file():
        p = CONFIG_DIR / f"{p.name}.toml"
    if not p.is_file():
        raise FileNotFoundError(f"filter config {name_or_path!r} is neither a built-in config nor a TOML file")
    try:
        d = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{p} is not valid TOML: {e}") from e
    d.setdefault("name", p.stem)
    return FilterConfig.from_dict(d, str(p))


def _phase_weights(cfg: FilterTrainSection, frac: float) -> dict[str, float]:
    """Regulariser weights at training progress ``frac`` in [0, 1] (appendix A.2 schedule)."""
    on1 = frac >= cfg.simple_only
    on2 = frac >= cfg.consist_imu_from
    return {"off": cfg.w_off * on1, "vel": cfg.w_vel * on1, "consist": cfg.w_consist * on2, "imu": cfg.w_imu * on2}


@dataclass
class FilterBatch:
    """x0: (B, L, 235) normalised clean canonical windows; clean: the same in metres; tracked:
    (B, L, 235) canonical tracked windows (NaN = missing); cond: (B, L, 261); offsets (B, 24, 3);
    category (B,) int64."""

    x0: torch.Tensor
    clean: torch.Tensor
    tracked: torch.Tensor
    cond: torch.Tensor
    offsets: torch.Tensor
    category: torch.Tensor


def make_batch(data: FilterWindows, idx: np.ndarray, normalizer: Normalizer, cfg: CorruptionConfig,
               rng: np.random.Generator) -> FilterBatch:
    """Assemble, corrupt and canonicalise windows ``idx`` of ``data``."""
    clean, offsets, cat = data.batch(idx)
    tracked = corrupt(clean, data.fps, rng, cfg)
    inp = prepare_windows(tracked, normalizer)
    clean_c = to_frame(clean, inp.origin, inp.yaw)
    t = torch.from_numpy
    return FilterBatch(x0=t(normalizer.normalize(clean_c).astype(np.float32)), clean=t(clean_c), tracked=t(inp.tracked),
                       cond=inp.cond, offsets=t(offsets.astype(np.float32)), category=t(cat))


class FilterTask:
    """The filter as a training task: build the model, the loss on a batch, the checkpoint fields."""

    kind = KIND

    def __init__(self, cfg: FilterConfig, categories: list[str], normalizer: Normalizer) -> None:
        self.cfg, self.categories, self.normalizer = cfg, list(categories), normalizer
        self.model_config = filter_denoiser_config(cfg.net, len(categories))
        self.diffusion = GaussianDiffusion(cfg.diffusion)
        if cfg.diffusion.prediction != "x0":
            raise ValueError(f"the filter predicts x0 (I'm-HOI §3.2); diffusion.prediction is {cfg.diffusion.prediction!r}")

    def build_model(self) -> FilterModel:
        """The filter-mode denoiser behind the tracked-input skip; ``.denoiser`` holds the weights.
        Its output layer starts at zero, so training starts from x̂0 = the tracked input."""
        net = Denoiser(self.model_config)
        torch.nn.init.zeros_(net.out_proj.weight)
        torch.nn.init.zeros_(net.out_proj.bias)
        return FilterModel(net)

    def loss(self, model, b: FilterBatch, progress: float,
             generator: torch.Generator) -> tuple[torch.Tensor, dict[str, float]]:
        """Eq. 6 + eq. 7 with the schedule's weights at training ``progress`` in [0, 1] (the larger of
        the step and the time-limit fractions) -> (total loss, {term: value})."""
        out = self.diffusion.training_loss(model, b.x0, generator=generator, frame_cond=b.cond, category=b.category)
        x_hat = self.normalizer.denormalize(out.x0_hat)
        w = _phase_weights(self.cfg.train, progress)
        terms = {"simple": out.terms["simple"], "off": loss_off(x_hat, b.clean), "vel": loss_vel(x_hat, b.clean),
                 "consist": loss_consist(x_hat, b.offsets), "imu": loss_imu(x_hat, b.clean, b.tracked, self.cfg.net.fps)}
        total_loss = terms["simple"] + sum(w[k] * terms[k] for k in w if w[k] > 0)
        return total_loss, {k: float(v.detach()) for k, v in terms.items()}

    def checkpoint_fields(self) -> dict:
        """Everything ``sample.refine`` needs beside the weights."""
        return {"kind": KIND, "model_config": self.model_config, "diffusion_config": self.cfg.diffusion,
                "normalizer": self.normalizer, "fps": self.cfg.net.fps, "L_epi": self.cfg.net.window,
                "k": self.cfg.net.overlap, "extra": {"categories": self.categories},
                "meta": {"net": self.cfg.net.to_dict(), "corruption": self.cfg.corruption.to_dict()}}


def _rot_err_deg(a6: np.ndarray, b6: np.ndarray) -> np.ndarray:
    Ra, Rb = sixd_to_matrix(np.asarray(a6, np.float64)), sixd_to_matrix(np.asarray(b6, np.float64))
    c = (np.einsum("...ij,...ij->...", Ra, Rb) - 1) / 2
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def filter_metrics(pred: np.ndarray, clean: np.ndarray) -> dict[str, float]:
    """MPJPE (mm), object translation (cm) and rotation (deg) errors of frame vectors (..., 235)."""
    J = lambda v: v[..., JOINTS].reshape(*v.shape[:-1], 24, 3)
    return {"mpjpe_mm": float(1000 * np.linalg.norm(J(pred) - J(clean), axis=-1).mean()),
            "obj_t_err_cm": float(100 * np.linalg.norm(pred[..., OBJ_T] - clean[..., OBJ_T], axis=-1).mean()),
            "obj_rot_err_deg": float(_rot_err_deg(pred[..., OBJ_R], clean[..., OBJ_R]).mean())}


@torch.no_grad()
def validate(task: FilterTask, model, val: FilterBatch, num_steps: int, seed: int = 0) -> dict[str, float]:
    """Sampled (from noise, ``num_steps`` DDIM steps) metrics on fixed validation windows."""
    model.eval()
    g = torch.Generator().manual_seed(seed)
    x0 = sample_x0(model, task.diffusion, val.cond, val.category, num_steps=num_steps, generator=g)
    pred = task.normalizer.denormalize(x0.numpy())
    return filter_metrics(pred, val.clean.numpy())
