"""The denoiser in filter mode (I'm-HOI §3.2, appendix A.2) and the window inputs it takes; shared
by training (``trumans.train.tasks.filter``) and inference (``trumans.refine.pipeline``).

Filter mode of ``trumans.model.nets.Denoiser``: the noisy frame vectors x_n (B, L, 235) are the
tokens' input, the tracked window enters as a per-frame condition (``frame_cond``: the normalised
tracked frame vectors with missing entries 0, plus observed flags, 261 wide) added to each frame
token (the tracked values, missing ones interpolated in time, plus observed flags), and the object category is embedded into the first token with the diffusion step. The
network predicts x₀ itself (the paper follows [65]; ``prediction = "x0"``). Windows are put in a
canonical frame computed from the *tracked* input (``trumans.refine.frame.window_frame``), since at
inference nothing else is known.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
import torch

from trumans.model.checkpoint import Checkpoint, KindSpec
from trumans.model.episodes import FeatureLayout, Normalizer
from trumans.model.nets.denoiser import Denoiser, DenoiserConfig

from trumans.refine.frame import COND_DIM, FRAME_DIM, IMU_FLAG, IMU_R, JOINTS, condition_features, to_frame, window_frame
from trumans.refine.residual_basis import BASIS_KEY, ResidualBasis
from trumans.refine.wiener import WIENER_RADIUS, JointWiener

__all__ = ["FilterNetConfig", "filter_denoiser_config", "WindowInputs", "prepare_windows", "category_indices", "sample_x0", "FilterModel", "fit_normalizer",
           "build_filter_model", "configure_skip"]


SKIP_SIGMA_FRAMES = 2.0  # the default Gaussian low-pass of FilterModel's skip, in frames at the filter's fps


@dataclass(frozen=True)
class FilterNetConfig:
    """Network and window sizes. Paper: 4 layers, 4 heads, d = 1024, T = 64 frames; ours is
    narrower for a 2-core CPU. overlap: frames shared by neighbouring windows at inference; fps: the
    rate the filter works at (input is resampled); skip_sigma: the low-pass of ``FilterModel``'s skip;
    wiener_radius: frames each side of the fitted linear estimate that is the joints' skip
    (``trumans.refine.wiener``; 0 = the low-pass for the joints too)."""

    d_model: int = 128
    layers: int = 4
    heads: int = 4
    ff: int = 256
    dropout: float = 0.0
    window: int = 64
    overlap: int = 16
    fps: float = 30.0
    skip_sigma: float = SKIP_SIGMA_FRAMES
    wiener_radius: int = WIENER_RADIUS

    def __post_init__(self) -> None:
        if self.window < 8 or not 0 <= self.overlap < self.window // 2 + 1:
            raise ValueError(f"need window >= 8 and 0 <= overlap <= window / 2, got {self.window}, {self.overlap}")
        if not self.fps > 0 or self.skip_sigma < 0:
            raise ValueError(f"fps must be positive and skip_sigma >= 0, got {self.fps}, {self.skip_sigma}")
        if not 0 <= 2 * self.wiener_radius < self.window:
            raise ValueError(f"need 0 <= 2 wiener_radius < window (a window must hold a full neighbourhood), "
                             f"got {self.wiener_radius}, {self.window}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "FilterNetConfig":
        unknown = set(d) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown filter config keys {sorted(unknown)}")
        return cls(**d)


_LAYOUT = FeatureLayout(rotations=True)  # joints (72) + rotations (144); the object and IMU part is extra


def filter_denoiser_config(net: FilterNetConfig, num_categories: int) -> DenoiserConfig:
    """The ``DenoiserConfig`` of the filter: 235 features, no inpainting mask, a 261-wide per-frame
    condition, ``num_categories`` category embeddings."""
    if num_categories < 1:
        raise ValueError(f"the filter needs at least one object category, got {num_categories}")
    return DenoiserConfig(layout=_LAYOUT, extra_features=FRAME_DIM - _LAYOUT.dim, frames=net.window,
                          d_model=net.d_model, layers=net.layers, heads=net.heads, ff=net.ff, dropout=net.dropout,
                          mask_input=False, frame_cond_dim=COND_DIM, num_categories=num_categories)


@dataclass
class WindowInputs:
    """cond: (B, L, 261) float32 torch condition; origin (B, 3), yaw (B,): the windows' canonical
    frames; tracked: (B, L, 235) float32 canonical tracked frame vectors (NaN = missing)."""

    cond: torch.Tensor
    origin: np.ndarray
    yaw: np.ndarray
    tracked: np.ndarray


def prepare_windows(tracked_world: np.ndarray, normalizer: Normalizer,
                    filled_world: np.ndarray | None = None) -> WindowInputs:
    """Tracked world windows (B, L, 235) (NaN = missing) -> the filter's inputs. filled_world: the
    same windows with gaps filled over the whole sequence (``fill_missing`` before cutting); default:
    filled within each window. (Rigid transforms and normalising commute with the linear filling.)"""
    tw = np.asarray(tracked_world, dtype=np.float32)
    if tw.ndim != 3 or tw.shape[-1] != FRAME_DIM:
        raise ValueError(f"tracked windows must be (B, L, {FRAME_DIM}), got {tw.shape}")
    origin, yaw = window_frame(tw)
    tc = to_frame(tw, origin, yaw)
    filled = None if filled_world is None else normalizer.normalize(to_frame(filled_world, origin, yaw))
    cond = condition_features(normalizer.normalize(tc), filled)
    return WindowInputs(cond=torch.from_numpy(cond), origin=origin, yaw=yaw, tracked=tc)


def fit_normalizer(clean: np.ndarray) -> Normalizer:
    """Standardisation of clean canonical frame vectors (..., 235); the IMU flag keeps its 0 / 1
    values (mean 0, std 1): clean windows all have an IMU, so its fitted std would be 0."""
    n = Normalizer.fit(clean)
    n.mean[IMU_FLAG], n.std[IMU_FLAG] = 0.0, 1.0
    return n


def category_indices(names: list[str] | str, categories: list[str]) -> np.ndarray:
    """Category names -> (n,) int64 indices into ``categories``; an unknown name is a ValueError
    listing the known ones."""
    names = [names] if isinstance(names, str) else list(names)
    lut = {c: i for i, c in enumerate(categories)}
    bad = sorted({n for n in names if n not in lut})
    if bad:
        raise ValueError(f"object category {bad[0]!r} is unknown to this filter; it knows {list(categories)} "
                         f"(pass --category with one of them)")
    return np.array([lut[n] for n in names], dtype=np.int64)


@torch.inference_mode()
def sample_x0(model: torch.nn.Module, diffusion, cond: torch.Tensor, category: torch.Tensor, *,
              num_steps: int = 5, eta: float = 0.0, generator: torch.Generator | None = None,
              start: torch.Tensor | None = None, strength: float = 1.0,
              noise: torch.Tensor | None = None) -> torch.Tensor:
    """Reverse diffusion for a batch of windows: -> x̂0 (B, L, 235) normalised.

    From noise (``start`` None; the paper's filter): DDIM over ``num_steps`` respaced steps from
    T-1 (``GaussianDiffusion.step``). SDEdit-style (Meng et al. 2022): ``start`` (B, L, 235), the
    normalised tracked windows (missing = 0), is noised to step ``round(strength * (T-1))`` and
    denoised from there. cond: (B, L, 261); category: (B,) int64; noise: the starting noise
    (B, L, 235) (default: drawn from ``generator``, a CPU generator). The work runs on ``cond``'s device
    (the model and ``category`` must be there too); x̂0 comes back on that device.
    """
    from trumans.model.diffusion import respaced_timesteps

    if not 0.0 < strength <= 1.0:
        raise ValueError(f"strength must be in (0, 1], got {strength}")
    B, L = cond.shape[:2]
    shape = (B, L, FRAME_DIM)
    dev = cond.device  # the model's device (the caller moves cond, category and the model there)
    if noise is None:
        noise = torch.randn(shape, generator=generator)  # drawn on the CPU: the same noise on every device
    elif tuple(noise.shape) != shape:
        raise ValueError(f"noise must be {shape}, got {tuple(noise.shape)}")
    noise = noise.to(dev)
    T = diffusion.steps
    if start is None:
        t0 = T - 1
        x = noise
    else:
        if tuple(start.shape) != shape:
            raise ValueError(f"start must be {shape}, got {tuple(start.shape)}")
        t0 = int(round(strength * (T - 1)))
        x = diffusion.q_sample(start.to(dev), torch.full((B,), t0, dtype=torch.long, device=dev), noise)
    ts = [int(t) for t in respaced_timesteps(t0 + 1, min(num_steps, t0 + 1))]
    # the skip S(c) depends on the condition alone: computed once, not at every step
    extra = {"skip": model.skip(cond)} if isinstance(model, FilterModel) else {}
    for i, t in enumerate(ts):
        out = model(x, torch.full((B,), t, dtype=torch.long, device=dev), frame_cond=cond, category=category, **extra)
        x, x0 = diffusion.step(out, t, x, t_prev=ts[i + 1] if i + 1 < len(ts) else -1, eta=eta, generator=generator)
    return x0


def smooth_time(x: torch.Tensor, sigma: float = SKIP_SIGMA_FRAMES) -> torch.Tensor:
    """Gaussian low-pass of x (B, L, D) along time (edges replicated); sigma in frames (0 = none).
    One (L, L) banded matrix (the kernel, truncated at 3 sigma, with the replicated edges folded in)
    times x: a few times faster than a convolution over B·D channels of one."""
    if sigma <= 0:
        return x
    r = int(np.ceil(3 * sigma))
    k = torch.exp(-0.5 * (torch.arange(-r, r + 1, dtype=x.dtype, device=x.device) / sigma) ** 2)
    k = k / k.sum()
    L = x.shape[-2]
    cols = (torch.arange(L, device=x.device)[:, None] + torch.arange(-r, r + 1, device=x.device)[None]).clamp(0, L - 1)
    M = torch.zeros(L, L, dtype=x.dtype, device=x.device).scatter_add_(1, cols, k.expand(L, -1).contiguous())
    return M @ x


class FilterModel(torch.nn.Module):
    """The filter-mode denoiser with a skip from the tracked input: x̂0 = S(c) + D(x_n, n, c, category)
    on the human and object features (the IMU part is D's alone: an absent IMU has no value to
    pass on), where c is the normalised tracked frame vector part of the condition (missing values
    interpolated in time) and S a fixed filter of it: a Gaussian low-pass in time (σ = ``skip_sigma``
    frames, kept in the checkpoint's ``extra``; 0 = no smoothing) and, once ``set_wiener`` gave it
    one, the fitted linear estimate of the joints (``trumans.refine.wiener``, ``extra['wiener']``) in
    place of the low-pass on the joint positions. The network learns the correction of that estimate
    instead of re-deriving the sequence (our addition for a CPU training budget; the paper's network
    outputs x̂0 directly). Its learned weights are ``denoiser``'s; the skip is set from the checkpoint."""

    def __init__(self, denoiser: torch.nn.Module, skip_sigma: float = SKIP_SIGMA_FRAMES) -> None:
        super().__init__()
        self.denoiser = denoiser
        self.skip_sigma = float(skip_sigma)
        self.wiener: JointWiener | None = None
        self._joint_mean = self._joint_std = None

    def set_wiener(self, wiener: JointWiener | None, normalizer: Normalizer | None = None) -> None:
        """Use ``wiener`` for the joints' skip (None: the Gaussian low-pass); ``normalizer``: the
        checkpoint's, to take the condition's joints to metres and back."""
        if wiener is not None and normalizer is None:
            raise ValueError("set_wiener needs the filter's normalizer to work in metres")
        self.wiener = wiener
        if wiener is not None:
            self._joint_mean = torch.as_tensor(normalizer.mean[JOINTS], dtype=torch.float32)
            self._joint_std = torch.as_tensor(normalizer.std[JOINTS], dtype=torch.float32)

    def skip(self, frame_cond: torch.Tensor) -> torch.Tensor:
        """S(c): (B, L, 261) condition -> (B, L, IMU_R.start) normalised human and object features."""
        if self.wiener is None:
            return smooth_time(frame_cond[..., :IMU_R.start], self.skip_sigma)  # human and object only
        rest = smooth_time(frame_cond[..., JOINTS.stop:IMU_R.start], self.skip_sigma)  # the joints are the Wiener's
        mean, std = self._joint_mean.to(frame_cond), self._joint_std.to(frame_cond)
        joints = self.wiener(frame_cond[..., JOINTS] * std + mean)
        return torch.cat([(joints - mean) / std, rest], dim=-1)

    def forward(self, x: torch.Tensor, t: torch.Tensor, *, frame_cond: torch.Tensor, category: torch.Tensor,
                mask: torch.Tensor | None = None, skip: torch.Tensor | None = None) -> torch.Tensor:
        """x̂0 (B, L, 235) normalised. skip: ``self.skip(frame_cond)`` when the caller already has it
        (it depends on the condition alone, so a sampler computes it once for all its steps)."""
        out = self.denoiser(x, t, mask=mask, frame_cond=frame_cond, category=category)
        if skip is None:
            skip = self.skip(frame_cond)
        return torch.cat([out[..., :IMU_R.start] + skip, out[..., IMU_R.start:]], dim=-1)


def build_filter_model(config: DenoiserConfig) -> FilterModel:
    """The checkpoint kind's builder: the filter-mode denoiser behind the tracked-input skip."""
    return FilterModel(Denoiser(config))


def configure_skip(model: FilterModel, ck: Checkpoint) -> FilterModel:
    """Set ``model``'s skip from the checkpoint's ``extra``: ``skip_sigma`` and, if present, ``wiener``."""
    model.skip_sigma = float(ck.extra.get("skip_sigma", SKIP_SIGMA_FRAMES))
    w = ck.extra.get("wiener")
    model.set_wiener(None if w is None else JointWiener.from_extra(w), ck.normalizer)
    return model


def filter_window(ck: Checkpoint) -> tuple[int, int]:
    """(window, overlap) in frames of a filter checkpoint: ``extra["window"]`` / ``extra["overlap"]``
    (files written before they had their own names kept them in the generator's ``L_epi`` / ``k``)."""
    if "window" in ck.extra:
        return int(ck.extra["window"]), int(ck.extra.get("overlap", -1))
    if ck.L_epi is None or ck.k is None:
        raise ValueError("the filter checkpoint has no window / overlap (extra['window'], extra['overlap']); "
                         "retrain or re-export it")
    return int(ck.L_epi), int(ck.k)


def _check_filter(ck: Checkpoint) -> None:
    cfg: DenoiserConfig = ck.model_config
    cats = ck.extra.get("categories")
    if not isinstance(cats, list) or not cats or cfg.num_categories != len(cats):
        raise ValueError(f"the filter embeds {cfg.num_categories} categories but extra['categories'] is {cats!r}; "
                         f"the checkpoint is inconsistent")
    if cfg.feature_dim != FRAME_DIM or cfg.frame_cond_dim != COND_DIM or ck.normalizer.mean.shape[0] != FRAME_DIM:
        raise ValueError(f"a filter takes {FRAME_DIM} features and a {COND_DIM}-wide condition, this one "
                         f"{cfg.feature_dim} / {cfg.frame_cond_dim} (normalisation {ck.normalizer.mean.shape[0]})")
    window, overlap = filter_window(ck)
    if cfg.frames != window or not 0 <= overlap < window:
        raise ValueError(f"window {window} / overlap {overlap} do not fit the model's {cfg.frames} frames")
    if ck.diffusion_config.prediction != "x0":
        raise ValueError(f"the filter predicts x0, this checkpoint {ck.diffusion_config.prediction!r}")
    if ck.extra.get("wiener") is not None:
        JointWiener.from_extra(ck.extra["wiener"])  # shapes and finite values
    if ck.extra.get(BASIS_KEY) is not None:
        ResidualBasis.from_extra(ck.extra[BASIS_KEY])  # shape, finite, orthonormal


# I'm-HOI filter checkpoints: fps; categories, window and overlap (frames) in extra
FILTER_KIND = KindSpec(config_from_dict=DenoiserConfig.from_dict, build=build_filter_model,
                       required=("diffusion_config", "norm", "fps"), required_extra=("categories",),
                       check=_check_filter)
