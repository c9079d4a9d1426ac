"""Gaussian diffusion (DDPM, Ho et al. 2020) with inpainting masks; knows nothing about motion.

It calls ``model(x_t, t, mask=mask, **cond) -> eps_hat`` (same shape as ``x_t``) and returns
typed loss terms; masks and conditions are the caller's business. TRUMANS §4.2 / appendix A.2:
linear variance schedule, ε-prediction, Huber loss; the authors' code uses T = 100 steps with
betas 1e-4 -> 0.02. Given entries (``mask == True``, TRUMANS §4.1 ``M = M_trans ∪ M_goal``) are
never noised: in training they enter clean and are left out of the loss; in sampling they are
overwritten with their given values at every step, so the result holds them exactly.

Schedules are float64 buffers (``.to(device)`` moves them); per-step coefficients are cast to
the data's dtype when used.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable, Literal

import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["DiffusionConfig", "GaussianDiffusion", "DiffusionLoss", "respaced_timesteps"]

LossType = Literal["huber", "mse"]


@dataclass(frozen=True)
class DiffusionConfig:
    """steps: T; beta_start/beta_end: linear schedule ends; loss: 'huber' (delta ``huber_delta``) or 'mse'."""

    steps: int = 100
    beta_start: float = 1e-4
    beta_end: float = 0.02
    loss: LossType = "huber"
    huber_delta: float = 1.0

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")
        if not 0 < self.beta_start <= self.beta_end < 1:
            raise ValueError(f"need 0 < beta_start <= beta_end < 1, got {self.beta_start}, {self.beta_end}")
        if self.loss not in ("huber", "mse"):
            raise ValueError(f"loss must be 'huber' or 'mse', got {self.loss!r}")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class DiffusionLoss:
    """loss: scalar mean over free entries; per_sample: (B,) mean over each sample's free entries."""

    loss: torch.Tensor
    per_sample: torch.Tensor


def respaced_timesteps(steps: int, num: int) -> torch.Tensor:
    """``num`` timesteps from T-1 down to 0, evenly spaced (respaced / DDIM sampling): (num,) int64."""
    if not 1 <= num <= steps:
        raise ValueError(f"number of sampling steps must be in [1, {steps}], got {num}")
    return torch.linspace(steps - 1, 0, num, dtype=torch.float64).round().long().unique_consecutive()


class GaussianDiffusion(nn.Module):
    """Linear-beta DDPM with ε-prediction, masked training loss, ancestral and respaced sampling."""

    def __init__(self, config: DiffusionConfig = DiffusionConfig()) -> None:
        super().__init__()
        self.config = config
        betas = torch.linspace(config.beta_start, config.beta_end, config.steps, dtype=torch.float64)
        alphas = 1.0 - betas
        ac = torch.cumprod(alphas, 0)
        ac_prev = torch.cat([torch.ones(1, dtype=torch.float64), ac[:-1]])
        self.register_buffer("betas", betas, persistent=False)
        self.register_buffer("alphas_cumprod", ac, persistent=False)
        self.register_buffer("alphas_cumprod_prev", ac_prev, persistent=False)
        self.register_buffer("sqrt_alphas_cumprod", ac.sqrt(), persistent=False)
        self.register_buffer("sqrt_one_minus_alphas_cumprod", (1.0 - ac).sqrt(), persistent=False)
        # posterior q(x_{t-1} | x_t, x_0) (Ho et al. eq. 6-7)
        self.register_buffer("posterior_variance", betas * (1.0 - ac_prev) / (1.0 - ac), persistent=False)

    @property
    def steps(self) -> int:
        return self.config.steps

    @staticmethod
    def _at(buf: torch.Tensor, t: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """buf[t] shaped (B, 1, ..., 1) in x's dtype."""
        return buf[t].to(x.dtype).reshape(-1, *([1] * (x.dim() - 1)))

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """x_t = sqrt(ᾱ_t) x0 + sqrt(1 - ᾱ_t) ε.  x0, noise: (B, ...); t: (B,) int in [0, T)."""
        return self._at(self.sqrt_alphas_cumprod, t, x0) * x0 + self._at(self.sqrt_one_minus_alphas_cumprod, t, x0) * noise

    def predict_x0(self, x_t: torch.Tensor, t: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
        """x0 = (x_t - sqrt(1 - ᾱ_t) ε) / sqrt(ᾱ_t)."""
        return (x_t - self._at(self.sqrt_one_minus_alphas_cumprod, t, x_t) * eps) / self._at(self.sqrt_alphas_cumprod, t, x_t)

    def _check(self, x0: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        if mask is None:
            return torch.zeros_like(x0, dtype=torch.bool)
        if mask.dtype != torch.bool:
            raise ValueError(f"mask must be bool (True = given), got {mask.dtype}")
        try:
            return mask.expand_as(x0)
        except RuntimeError:
            raise ValueError(f"mask must broadcast to the data's shape {tuple(x0.shape)}, "
                             f"got {tuple(mask.shape)}") from None

    def elementwise_loss(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        if self.config.loss == "huber":
            return F.huber_loss(pred, target, reduction="none", delta=self.config.huber_delta)
        return (pred - target) ** 2

    def training_loss(
        self,
        model: Callable[..., torch.Tensor],
        x0: torch.Tensor,
        *,
        mask: torch.Tensor | None = None,
        t: torch.Tensor | None = None,
        noise: torch.Tensor | None = None,
        generator: torch.Generator | None = None,
        **cond,
    ) -> DiffusionLoss:
        """ε-prediction loss on the free entries (mask False). x0: (B, ...) clean data;
        mask: bool like x0 (True = given, enters clean); t: (B,) (uniform if None); cond: passed on."""
        mask = self._check(x0, mask)
        B = x0.shape[0]
        if t is None:
            t = torch.randint(0, self.steps, (B,), generator=generator).to(x0.device)
        if noise is None:
            noise = torch.randn(x0.shape, generator=generator, dtype=x0.dtype).to(x0.device)
        x_t = torch.where(mask, x0, self.q_sample(x0, t, noise))
        eps = model(x_t, t, mask=mask, **cond)
        if eps.shape != x0.shape:
            raise ValueError(f"model returned {tuple(eps.shape)}, expected {tuple(x0.shape)}")
        free = (~mask).to(x0.dtype)
        el = self.elementwise_loss(eps, noise) * free
        dims = tuple(range(1, x0.dim()))
        per = el.sum(dims) / free.sum(dims).clamp_min(1.0)
        return DiffusionLoss(loss=el.sum() / free.sum().clamp_min(1.0), per_sample=per)

    @torch.no_grad()
    def sample(
        self,
        model: Callable[..., torch.Tensor],
        shape: tuple[int, ...],
        *,
        mask: torch.Tensor | None = None,
        given: torch.Tensor | None = None,
        num_steps: int | None = None,
        eta: float = 1.0,
        generator: torch.Generator | None = None,
        device: torch.device | str = "cpu",
        dtype: torch.dtype = torch.float32,
        x_T: torch.Tensor | None = None,
        **cond,
    ) -> torch.Tensor:
        """Draw x0 of ``shape`` by reverse diffusion, inpainting ``given`` where ``mask``.

        num_steps None (all T) with eta = 1 is ancestral DDPM sampling (posterior variance β̃_t);
        fewer steps use the respaced DDIM update (Song et al. 2021, eq. 12), eta = 0 deterministic.
        Given entries are set to ``given`` before every model call and in the result (exactly).
        x_T: the starting sample (default N(0, I)); note that with T = 100 linear betas ᾱ_T ≈ 0.36,
        so N(0, I) is the exact terminal marginal only for zero-mean unit-variance data (normalise!).
        """
        if x_T is not None:
            if tuple(x_T.shape) != tuple(shape):
                raise ValueError(f"x_T must have shape {tuple(shape)}, got {tuple(x_T.shape)}")
            x = x_T.to(device=device, dtype=dtype)
        else:
            x = torch.randn(shape, generator=generator, dtype=dtype).to(device)
        if mask is not None:
            if given is None or given.shape != x.shape:
                raise ValueError(f"with a mask, given must be a tensor of shape {tuple(shape)}, "
                                 f"got {None if given is None else tuple(given.shape)}")
            mask = self._check(x, mask.to(device))
            given = given.to(device=device, dtype=dtype)
        if not eta >= 0:
            raise ValueError(f"eta must be >= 0, got {eta}")
        ts = respaced_timesteps(self.steps, num_steps or self.steps).to(device)
        for i, t_i in enumerate(ts):
            if mask is not None:
                x = torch.where(mask, given, x)
            t = t_i.expand(shape[0])
            eps = model(x, t, mask=mask, **cond)
            ab = self.alphas_cumprod[t_i]
            ab_prev = self.alphas_cumprod[ts[i + 1]] if i + 1 < len(ts) else torch.ones((), dtype=ab.dtype, device=ab.device)
            x0 = self.predict_x0(x, t, eps)
            # DDIM (eq. 12): sigma^2 = eta^2 (1 - ab_prev) / (1 - ab) (1 - ab / ab_prev); eta = 1 on
            # the full schedule gives exactly the DDPM posterior variance β̃_t.
            var = eta ** 2 * (1 - ab_prev) / (1 - ab) * (1 - ab / ab_prev)
            dir_coef = (1 - ab_prev - var).clamp_min(0).sqrt()
            x = ab_prev.sqrt().to(dtype) * x0 + dir_coef.to(dtype) * eps
            if i + 1 < len(ts) and eta > 0:
                x = x + var.sqrt().to(dtype) * torch.randn(shape, generator=generator, dtype=dtype).to(device)
        if mask is not None:
            x = torch.where(mask, given, x)
        return x
