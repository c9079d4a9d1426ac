"""The HOI filter as a training task (I'm-HOI §3.2, appendix A.2; ``trumans.train.tasks.Task``):
``trumans train --task filter``.

Loss: x₀-prediction with the L1 simple objective (eq. 6) on normalised frame vectors, plus the
regularisers of eq. 7 on the de-normalised prediction (``trumans.refine.losses``). Schedule
(appendix A.2): the first ``simple_only`` fraction of ``train.steps`` is the warm-up on every
category with the simple loss only; then L_off and L_vel join; from ``consist_imu_from`` L_consist
and L_imu join too. One shared model embeds the object category into its first token (the paper
fine-tunes one model per category; that variant is not measured here). EMA of the weights is the
loop's.

Data: clean windows (``trumans.refine.data``) corrupted on the fly by ``trumans.refine.corrupt`` with a
generator seeded by (seed, step, rank), so a run is a pure function of its seed; with a bone scale
range in ``[corruption]`` the clean windows get other proportions first (``vary_skeleton``). Validation: the
MPJPE (m) of the EMA model sampled from noise on fixed corrupted val windows, beside the MPJPE of
the tracked input with its gaps interpolated (the identity filter) as the baseline.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
from torch import nn

from trumans.version import __version__
from trumans.dataset import Dataset
from trumans.refine.corrupt import CorruptionConfig, corrupt, vary_skeleton
from trumans.refine.data import FilterWindows, load_filter_windows, window_motion_types
from trumans.refine.filter import (FilterModel, FilterNetConfig, build_filter_model, filter_denoiser_config, fit_normalizer,
                                prepare_windows, sample_x0)
from trumans.refine.frame import (FRAME_DIM, JOINTS, OBJ_R, OBJ_T, fill_missing, pack_frames, resample_frames, to_frame,
                               window_frame)
from trumans.refine.losses import loss_consist, loss_imu, loss_off, loss_pose, loss_residual, loss_vel
from trumans.refine.wiener import JointWiener, fit_joint_wiener
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import DiffusionConfig, GaussianDiffusion
from trumans.model.episodes import Normalizer
from trumans.rotations import sixd_to_matrix

from trumans.config_data import config_from_dict
from trumans.train.config import TrainSection, load_toml, override_sections
from trumans.train.tasks import TaskLoss

__all__ = ["FilterSection", "FilterConfig", "load_filter_config", "FilterTask", "FilterBatch", "make_batch",
           "phase_weights", "filter_metrics", "export_checkpoint", "real_motion_windows", "ABLATIONS", "DEFAULT_CONFIG",
           "CONFIG_DIR"]

CONFIG_DIR = Path(__file__).parents[1] / "configs" / "filter"
DEFAULT_CONFIG = "cpu"
VAL_SEED = 20240601
ABLATIONS = {  # --ablate NAME -> overrides
    "regularisers": {"filter": {"w_off": 0.0, "w_vel": 0.0, "w_consist": 0.0, "w_imu": 0.0, "w_pose": 0.0, "w_residual": 0.0}},
    "imu": {"corruption": {"p_no_imu": 1.0}},
    "wiener": {"net": {"wiener_radius": 0}},
}


@dataclass(frozen=True)
class FilterSection:
    """Windows, validation and the loss schedule. Paper weights: λ_off = λ_vel = λ_consist = 1,
    λ_imu = 100 on unnormalised SMPL-H vectors; ours act on metres beside an L1 loss on
    standardised features, so they are rescaled (at the start each weighted term is a fraction of
    the simple loss). simple_only / consist_imu_from: fractions of ``train.steps``; wiener_windows:
    corrupted train windows the joints' linear skip is fitted on (``trumans.refine.wiener``), and as
    many of the real-motion corpus's train split (other skeletons: the fit then relies less on the
    dataset's body proportions) with wiener_real_windows. w_pose: the joints relative to the pelvis
    (``loss_pose``, ours, on from the first step). w_residual: the joints after the input residual
    (``loss_residual``, ours: x̂ plus the Gaussian of ``residual_sigma`` frames of tracked minus x̂, as
    the first post-step returns them), on from the first step; 0 = off. categories: train and validate on windows of
    these object categories only (empty: all), e.g. to fine-tune a shared model for one category
    (``trumans train --task filter --init SHARED.pt --config chair.toml``); the vocabulary stays the data's."""

    stride: int = 16
    val_windows: int = 128
    val_sampling_steps: int = 5
    simple_only: float = 0.3
    consist_imu_from: float = 0.6
    w_off: float = 0.01
    w_vel: float = 0.1
    w_consist: float = 0.02
    w_imu: float = 0.1
    w_pose: float = 3.0  # 0.1 / 1 / 3 / 10 measured (README): from 3 the network beats its skip
    w_residual: float = 0.0
    residual_sigma: float = 3.0
    wiener_windows: int = 1500
    wiener_real_windows: int = 1500
    categories: tuple[str, ...] = ()
    balance_types: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.balance_types <= 1.0:
            raise ValueError(f"balance_types is a share of the batch in [0, 1], got {self.balance_types}")
        if self.stride < 1 or self.val_windows < 1 or self.val_sampling_steps < 1 or self.wiener_windows < 1:
            raise ValueError("stride, val_windows, val_sampling_steps and wiener_windows must be >= 1")
        if self.wiener_real_windows < 0:
            raise ValueError(f"wiener_real_windows must be >= 0, got {self.wiener_real_windows}")
        if not 0 <= self.simple_only <= self.consist_imu_from <= 1:
            raise ValueError(f"need 0 <= simple_only <= consist_imu_from <= 1, got {self.simple_only}, {self.consist_imu_from}")
        if min(self.w_off, self.w_vel, self.w_consist, self.w_imu, self.w_pose, self.w_residual) < 0:
            raise ValueError("regulariser weights must be >= 0")
        if not self.residual_sigma > 0:
            raise ValueError(f"residual_sigma must be > 0 frames, got {self.residual_sigma}")


@dataclass(frozen=True)
class FilterConfig:
    """The filter's training config: [net] (``FilterNetConfig``), [diffusion], [train] (the shared
    ``TrainSection``), [filter] (``FilterSection``), [corruption] (``CorruptionConfig``)."""

    name: str = "filter-cpu"
    net: FilterNetConfig = field(default_factory=FilterNetConfig)
    diffusion: DiffusionConfig = field(default_factory=lambda: DiffusionConfig(steps=1000, loss="l1", prediction="x0"))
    train: TrainSection = field(default_factory=TrainSection)
    filter: FilterSection = field(default_factory=FilterSection)
    corruption: CorruptionConfig = field(default_factory=CorruptionConfig)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, source: str = "filter config") -> "FilterConfig":
        return config_from_dict(cls, d, source)

    def with_overrides(self, **sections: dict) -> "FilterConfig":
        return override_sections(self, sections)


def load_filter_config(name_or_path: str | Path) -> FilterConfig:
    """A built-in filter config (``train/configs/filter/<name>.toml``: cpu) or a TOML file."""
    d, p = load_toml(name_or_path, CONFIG_DIR)
    return FilterConfig.from_dict(d, str(p))


def phase_weights(cfg: FilterSection, frac: float) -> dict[str, float]:
    """Regulariser weights at training progress ``frac`` in [0, 1] (appendix A.2 schedule; the pose
    term, not the paper's, throughout)."""
    on1 = frac >= cfg.simple_only
    on2 = frac >= cfg.consist_imu_from
    return {"off": cfg.w_off * on1, "vel": cfg.w_vel * on1, "consist": cfg.w_consist * on2, "imu": cfg.w_imu * on2,
            "pose": cfg.w_pose, "residual": cfg.w_residual}


@dataclass
class FilterBatch:
    """x0: (B, L, 235) normalised clean canonical windows; clean: the same in metres; tracked:
    (B, L, 235) canonical tracked windows (NaN = missing); cond: (B, L, 261); offsets (B, 24, 3);
    category (B,) int64; progress: the training progress in [0, 1] that sets the loss schedule."""

    x0: torch.Tensor
    clean: torch.Tensor
    tracked: torch.Tensor
    cond: torch.Tensor
    offsets: torch.Tensor
    category: torch.Tensor
    progress: float = 1.0


def make_batch(data: FilterWindows, idx: np.ndarray, normalizer: Normalizer, cfg: CorruptionConfig,
               rng: np.random.Generator, progress: float = 1.0) -> FilterBatch:
    """Assemble, corrupt and canonicalise windows ``idx`` of ``data`` (with ``cfg``'s skeleton
    variation, if any, on the clean windows and their rest offsets first)."""
    clean, offsets, cat = data.batch(idx)
    clean, offsets = vary_skeleton(clean, offsets, rng, cfg)
    tracked = corrupt(clean, data.fps, rng, cfg)
    inp = prepare_windows(tracked, normalizer)
    clean_c = to_frame(clean, inp.origin, inp.yaw)
    t = torch.from_numpy
    return FilterBatch(x0=t(normalizer.normalize(clean_c).astype(np.float32)), clean=t(clean_c), tracked=t(inp.tracked),
                       cond=inp.cond, offsets=t(offsets.astype(np.float32)), category=t(cat), progress=progress)


class FilterTask:
    """The filter as a ``trumans.train.tasks.Task``: windows and normalisation from ``setup``, the
    filter-mode denoiser, eq. 6 + eq. 7 loss, sampled validation, the 'filter' checkpoint."""

    kind = "filter"

    def __init__(self, config: FilterConfig) -> None:
        if config.diffusion.prediction != "x0":
            raise ValueError(f"the filter predicts x0 (I'm-HOI §3.2); diffusion.prediction is {config.diffusion.prediction!r}")
        self.config = config
        self.diffusion = GaussianDiffusion(config.diffusion)
        self.categories: list[str] | None = None
        self.normalizer: Normalizer | None = None
        self.train_data: FilterWindows | None = None
        self.val_batch: FilterBatch | None = None
        self.wiener: JointWiener | None = None
        self.seed = 0
        self.data_record: dict = {}

    @classmethod
    def from_config(cls, config: str | Path | None = None, *, overrides: dict[str, dict] | None = None,
                    ablate: Sequence[str] = ()) -> "FilterTask":
        """The task factory (``trumans.train.tasks.TASKS``): a config name or TOML path (default cpu);
        ablations: regularisers (all λ = 0), imu (no window has an IMU), wiener (the Gaussian skip
        for the joints too)."""
        cfg = load_filter_config(config or DEFAULT_CONFIG)
        over = {k: dict(v) for k, v in (overrides or {}).items()}
        for a in ablate:
            if a not in ABLATIONS:
                raise ValueError(f"unknown ablation {a!r} for the filter; ablations: {sorted(ABLATIONS)}")
            for sec, vals in ABLATIONS[a].items():
                over.setdefault(sec, {}).update(vals)
        return cls(cfg.with_overrides(**over) if over else cfg)

    @property
    def model_config(self):
        if self.categories is None:
            raise ValueError("the filter's categories are unknown: call setup() with a dataset first")
        return filter_denoiser_config(self.config.net, len(self.categories))

    def setup(self, data_dir: str | Path, out_dir: Path, *, is_main: bool, barrier: Callable[[], None],
              prev: Checkpoint | None, seed: int = 0, extra_dirs: Sequence[str | Path] = (),
              progress: bool = True, fine_tune: bool = False) -> None:
        """Windows of the train and val splits; normalisation fitted on clean canonical train
        windows and the joints' linear skip on corrupted ones (or ``prev``'s: the resumed run, on the
        same data, or with ``fine_tune`` the --init checkpoint, on any data); a fixed corrupted
        validation batch."""
        if extra_dirs:
            raise ValueError("the filter trains on one dataset; --augmented is not supported for --task filter")
        net, fc = self.config.net, self.config.filter
        ds = Dataset(data_dir)
        self.data_record = {"name": ds.name, "hash": ds.hash, "path": str(Path(data_dir).resolve())}
        cats = None
        if prev is not None:
            if prev.data.get("hash") != ds.hash and not fine_tune:
                raise ValueError(f"the run in {out_dir} was trained on other data; resume with the same --data")
            cats = list(prev.extra["categories"])
        self.train_data = load_filter_windows(data_dir, "train", net.window, fc.stride, net.fps, cats)
        self.categories = self.train_data.category_names
        val = load_filter_windows(data_dir, "val", net.window, net.window, net.fps, self.categories)
        if fc.categories:
            self.train_data, val = self.train_data.only(fc.categories), val.only(fc.categories)
        self.type_pools = ([np.flatnonzero(col) for col in window_motion_types(self.train_data).T if col.any()]
                           if fc.balance_types > 0 else [])
        self.seed = seed
        if prev is not None:
            self.normalizer = prev.normalizer
        else:
            rng = np.random.default_rng(seed)
            idx = rng.choice(len(self.train_data), size=min(2048, len(self.train_data)), replace=False)
            ident = Normalizer(np.zeros(FRAME_DIM), np.ones(FRAME_DIM))
            self.normalizer = fit_normalizer(make_batch(self.train_data, idx, ident, self.config.corruption, rng).clean.numpy())
        self.wiener = self._fit_wiener(prev, seed)
        vrng = np.random.default_rng(VAL_SEED)
        vidx = vrng.choice(len(val), size=min(fc.val_windows, len(val)), replace=False)
        self.val_batch = make_batch(val, vidx, self.normalizer, self.config.corruption, vrng)

    def _fit_wiener(self, prev: Checkpoint | None, seed: int) -> JointWiener | None:
        """The joints' linear skip: the resumed run's, else fitted on ``wiener_windows`` corrupted
        train windows and ``wiener_real_windows`` corrupted windows of the mocap corpus's train split
        (``real_motion_windows``), drawn by ``seed`` (None when ``net.wiener_radius`` is 0)."""
        net, fc = self.config.net, self.config.filter
        if net.wiener_radius == 0:
            return None
        if prev is not None and prev.extra.get("wiener") is not None:
            return JointWiener.from_extra(prev.extra["wiener"])
        rng = np.random.default_rng([seed, 1])
        n = min(fc.wiener_windows, len(self.train_data))
        clean, _, _ = self.train_data.batch(rng.choice(len(self.train_data), size=n, replace=False))
        if fc.wiener_real_windows:
            real = real_motion_windows(net.window, net.fps)
            pick = rng.choice(len(real), size=min(fc.wiener_real_windows, len(real)), replace=False)
            clean = np.concatenate([clean, real[pick]])
        clean, _ = vary_skeleton(clean, np.zeros((len(clean), 24, 3), np.float32), rng, self.config.corruption)
        tracked = corrupt(clean, net.fps, rng, self.config.corruption)
        origin, yaw = window_frame(tracked)
        return fit_joint_wiener(fill_missing(to_frame(tracked, origin, yaw))[..., JOINTS],
                                to_frame(clean, origin, yaw)[..., JOINTS], net.wiener_radius)

    def build_model(self) -> FilterModel:
        """The filter-mode denoiser behind the tracked-input skip; its output layer starts at zero,
        so training starts from x̂0 = the skip of the tracked input (gaps interpolated)."""
        model = build_filter_model(self.model_config)
        model.skip_sigma = self.config.net.skip_sigma
        model.set_wiener(self.wiener, self.normalizer)
        nn.init.zeros_(model.denoiser.out_proj.weight)
        nn.init.zeros_(model.denoiser.out_proj.bias)
        return model

    def batch(self, step: int, rank: int, world: int) -> FilterBatch:
        """This rank's share of batch ``step``: windows drawn and corrupted by (seed, step, rank)."""
        rng = np.random.default_rng([self.seed, step, rank])
        per = max(1, self.config.train.batch_size // world)
        idx = rng.integers(0, len(self.train_data), per)
        if self.type_pools:  # balance_types: this share drawn type by type (no extra draws when 0)
            for b in np.flatnonzero(rng.random(per) < self.config.filter.balance_types):
                pool = self.type_pools[rng.integers(len(self.type_pools))]
                idx[b] = pool[rng.integers(len(pool))]
        return make_batch(self.train_data, idx, self.normalizer, self.config.corruption, rng,
                          progress=step / max(self.config.train.steps, 1))

    def loss(self, model: nn.Module, b: FilterBatch, generator: torch.Generator, device: torch.device) -> TaskLoss:
        """Eq. 6 + eq. 7 with the schedule's weights at the batch's training progress."""
        dev = torch.device(device)
        if self.diffusion.betas.device != dev:
            self.diffusion = self.diffusion.to(dev)
        to = lambda v: v.to(dev)
        out = self.diffusion.training_loss(model, to(b.x0), generator=generator, frame_cond=to(b.cond),
                                           category=to(b.category))
        x_hat = self.normalizer.denormalize(out.x0_hat)
        clean = to(b.clean)
        w = phase_weights(self.config.filter, b.progress)
        terms = {"simple": out.terms["simple"], "off": loss_off(x_hat, clean), "vel": loss_vel(x_hat, clean),
                 "consist": loss_consist(x_hat, to(b.offsets)),
                 "imu": loss_imu(x_hat, clean, to(b.tracked), self.config.net.fps), "pose": loss_pose(x_hat, clean)}
        if w["residual"] > 0:
            filled = self.normalizer.denormalize(to(b.cond[..., :FRAME_DIM]))
            terms["residual"] = loss_residual(x_hat, clean, filled, self.config.filter.residual_sigma)
        total = terms["simple"] + sum(w[k] * terms[k] for k in w if w[k] > 0)
        return TaskLoss(total, terms)

    @torch.no_grad()
    def validate(self, model: nn.Module) -> tuple[float, float]:
        """(MPJPE in m of x̂0 sampled from noise, MPJPE of the gap-interpolated tracked input) on the
        fixed validation windows."""
        m = self.val_metrics(model)
        return m["mpjpe_mm"] / 1000, m["mpjpe_in_mm"] / 1000

    @torch.no_grad()
    def val_metrics(self, model: nn.Module) -> dict[str, float]:
        model.eval()
        dev = next(model.parameters()).device
        v = self.val_batch
        g = torch.Generator().manual_seed(VAL_SEED)
        x0 = sample_x0(model, self.diffusion.to(dev), v.cond.to(dev), v.category.to(dev),
                       num_steps=self.config.filter.val_sampling_steps, generator=g)
        clean = v.clean.numpy()
        out = filter_metrics(self.normalizer.denormalize(x0.cpu().numpy()), clean)
        inp = filter_metrics(fill_missing(v.tracked.numpy()), clean)
        out.update({"mpjpe_in_mm": inp["mpjpe_mm"], "obj_t_err_in_cm": inp["obj_t_err_cm"],
                    "obj_rot_err_in_deg": inp["obj_rot_err_deg"]})
        return out

    def sizes(self) -> tuple[int, int]:
        return len(self.train_data), len(self.val_batch.x0)

    def checkpoint(self, *, model_state: dict, ema_state: dict, meta: dict, train_state: dict) -> Checkpoint:
        net = self.config.net
        extra = {"categories": list(self.categories), "skip_sigma": net.skip_sigma, "window": net.window,
                 "overlap": net.overlap}
        if self.wiener is not None:
            extra["wiener"] = self.wiener.to_extra()
        return Checkpoint(kind="filter", model_config=self.model_config, model_state=model_state,
                          diffusion_config=self.config.diffusion, normalizer=self.normalizer, fps=net.fps,
                          extra=extra,
                          data=dict(self.data_record), ema_state=ema_state,
                          meta={**meta, "net": net.to_dict(), "corruption": self.config.corruption.to_dict()},
                          train_state=train_state, code_version=__version__)


def real_motion_windows(window: int, fps: float, stride: int = 16) -> np.ndarray:
    """Clean world frame vectors (N, window, 235) of the mocap corpus's train split
    (``trumans.mocap_corpus``), joints only: rotations and object missing (NaN), no IMU."""
    from trumans.mocap_corpus import load_corpus

    out = []
    for c in load_corpus(split="train"):
        f = pack_frames(c.joints, None, np.full((len(c.joints), 4, 4), np.nan))
        if abs(c.fps - fps) > 1e-6:
            f = resample_frames(f, c.fps, fps)
        out.extend(f[s:s + window] for s in range(0, len(f) - window + 1, stride))
    if not out:
        raise ValueError(f"the mocap corpus's train split has no clip of {window} frames; set "
                         f"filter.wiener_real_windows = 0")
    return np.stack(out)


def export_checkpoint(src: Checkpoint, half: bool = True) -> Checkpoint:
    """The shipped form of a trained filter: the EMA weights only (float16 if ``half``), no
    optimiser state."""
    state = src.ema_state if src.ema_state is not None else src.model_state
    state = {k: (v.half() if half and v.is_floating_point() else v).clone() for k, v in state.items()}
    return Checkpoint(kind=src.kind, model_config=src.model_config, model_state=state,
                      diffusion_config=src.diffusion_config, normalizer=src.normalizer, fps=src.fps, L_epi=src.L_epi,
                      k=src.k, extra=dict(src.extra), data=dict(src.data), ema_state=None, meta=dict(src.meta),
                      train_state=None, code_version=src.code_version)


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
