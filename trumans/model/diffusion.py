"""Gaussian diffusion (DDPM, Ho et al. 2020) with inpainting masks; knows nothing about motion.

It calls ``model(x_t, t, mask=mask, **cond) -> output`` (same shape as ``x_t``), where the output
is the prediction of the config's ``prediction`` type, and returns typed loss terms; masks and
conditions are the caller's business. TRUMANS §4.2 / appendix A.2: linear variance schedule,
ε-prediction, Huber loss; the authors' code uses T = 100 steps with betas 1e-4 -> 0.02 (which
ends at ᾱ_T ≈ 0.36, so x_T keeps signal; the cosine schedule reaches noise). Given entries
(``mask == True``, TRUMANS §4.1 ``M = M_trans ∪ M_goal``) are never noised: in training they enter
clean and are left out of the loss; in sampling they are overwritten with their given values at
every step, so the result holds them exactly.

Prediction types (the diffusers ``prediction_type``): ``eps`` the noise ε (Ho et al.), ``x0`` the
clean sample, ``v`` = sqrt(ᾱ) ε - sqrt(1 - ᾱ) x0 (Salimans & Ho 2022, §4 eq. 9).

Schedules are float64 buffers (``.to(device)`` moves them); per-step coefficients are cast to
the data's dtype when used.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Callable, Literal

import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["DiffusionConfig", "GaussianDiffusion", "DiffusionLoss", "respaced_timesteps", "beta_schedule",
           "LossType", "ScheduleType", "PredictionType"]

LossType = Literal["huber", "mse", "l1"]
ScheduleType = Literal["linear", "cosine"]
PredictionType = Literal["eps", "x0", "v"]
COSINE_S = 0.008  # Nichol & Dhariwal 2021, §3.2 eq. 17: the offset s
MAX_BETA = 0.999  # ... and the clip on β_t that keeps the end of the schedule from being singular


@dataclass(frozen=True)
class DiffusionConfig:
    """steps: T; schedule: 'linear' (beta_start -> beta_end) or 'cosine' (Nichol & Dhariwal 2021;
    the betas are then unused); prediction: what the model outputs ('eps', 'x0' or 'v'); loss:
    'huber' (delta ``huber_delta``), 'mse' or 'l1'."""

    steps: int = 100
    beta_start: float = 1e-4
    beta_end: float = 0.02
    loss: LossType = "huber"
    huber_delta: float = 1.0
    schedule: ScheduleType = "linear"
    prediction: PredictionType = "eps"

    def __post_init__(self) -> None:
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 1:
            raise ValueError(f"steps must be an integer >= 1, got {self.steps!r}")
        if not 0 < self.beta_start <= self.beta_end < 1:  # also refuses nan
            raise ValueError(f"need 0 < beta_start <= beta_end < 1, got {self.beta_start}, {self.beta_end}")
        if self.loss not in ("huber", "mse", "l1"):
            raise ValueError(f"loss must be 'huber', 'mse' or 'l1', got {self.loss!r}")
        if not self.huber_delta > 0:
            raise ValueError(f"huber_delta must be > 0, got {self.huber_delta}")
        if self.schedule not in ("linear", "cosine"):
            raise ValueError(f"schedule must be 'linear' or 'cosine', got {self.schedule!r}")
        if self.prediction not in ("eps", "x0", "v"):
            raise ValueError(f"prediction must be 'eps', 'x0' or 'v', got {self.prediction!r}")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class DiffusionLoss:
    """loss: scalar mean of the terms' sum over free entries; per_sample: (B,) the same per sample;
    terms: named scalar terms ("simple": the prediction loss); x0_hat: (B, ...) the predicted clean
    sample (given entries replaced by their clean values; carries gradients); t: (B,) the steps."""

    loss: torch.Tensor
    per_sample: torch.Tensor
    terms: dict[str, torch.Tensor] = field(default_factory=dict)
    x0_hat: torch.Tensor | None = None
    t: torch.Tensor | None = None


def beta_schedule(config: DiffusionConfig) -> torch.Tensor:
    """(T,) float64 betas of ``config``'s schedule."""
    T = config.steps
    if config.schedule == "linear":
        return torch.linspace(config.beta_start, config.beta_end, T, dtype=torch.float64)
    # cosine (Nichol & Dhariwal 2021, eq. 17): ᾱ(t) = f(t) / f(0), f(t) = cos²((t/T + s) / (1 + s) · π/2),
    # β_t = 1 - ᾱ(t+1) / ᾱ(t) clipped at 0.999
    u = torch.arange(T + 1, dtype=torch.float64) / T
    f = torch.cos((u + COSINE_S) / (1 + COSINE_S) * math.pi / 2) ** 2
    return (1 - f[1:] / f[:-1]).clamp(max=MAX_BETA)


def respaced_timesteps(steps: int, num: int) -> torch.Tensor:
    """``num`` timesteps from T-1 down to 0, evenly spaced (respaced / DDIM sampling): (num,) int64."""
    if not 1 <= num <= steps:
        raise ValueError(f"number of sampling steps must be in [1, {steps}], got {num}")
    return torch.linspace(steps - 1, 0, num, dtype=torch.float64).round().long().unique_consecutive()


class GaussianDiffusion(nn.Module):
    """DDPM with a linear or cosine schedule, ε / x0 / v prediction, masked training loss, and the
    DDPM / DDIM update ``step`` on which ``sample`` (ancestral or respaced) is a driver."""

    def __init__(self, config: DiffusionConfig = DiffusionConfig()) -> None:
        super().__init__()
        self.config = config
        betas = beta_schedule(config)
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

    @property
    def prediction(self) -> PredictionType:
        return self.config.prediction

    @staticmethod
    def _at(buf: torch.Tensor, t: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """buf[t] shaped (B, 1, ..., 1) in x's dtype."""
        return buf[t].to(x.dtype).reshape(-1, *([1] * (x.dim() - 1)))

    def _steps_of(self, t: int | torch.Tensor, x: torch.Tensor, name: str, low: int = 0) -> torch.Tensor:
        """t as a (B,) int64 tensor on x's device, checked to lie in [low, T)."""
        t = torch.as_tensor(t, device=x.device)
        if t.is_floating_point() or t.dim() > 1:
            raise ValueError(f"{name} must be an integer step or a (B,) integer tensor, got {t.dtype} {tuple(t.shape)}")
        t = t.long().reshape(-1).expand(x.shape[0]) if t.numel() == 1 else t.long()
        if t.shape != (x.shape[0],):
            raise ValueError(f"{name} must be a scalar or (B,) = ({x.shape[0]},), got {tuple(t.shape)}")
        if bool(((t < low) | (t >= self.steps)).any()):
            raise ValueError(f"{name} must lie in [{low}, {self.steps}), got {t.tolist()}")
        return t

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """x_t = sqrt(ᾱ_t) x0 + sqrt(1 - ᾱ_t) ε.  x0, noise: (B, ...); t: (B,) int in [0, T)."""
        return self._at(self.sqrt_alphas_cumprod, t, x0) * x0 + self._at(self.sqrt_one_minus_alphas_cumprod, t, x0) * noise

    def predict_x0(self, x_t: torch.Tensor, t: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
        """x0 = (x_t - sqrt(1 - ᾱ_t) ε) / sqrt(ᾱ_t)."""
        return (x_t - self._at(self.sqrt_one_minus_alphas_cumprod, t, x_t) * eps) / self._at(self.sqrt_alphas_cumprod, t, x_t)

    def predict_eps(self, x_t: torch.Tensor, t: torch.Tensor, x0: torch.Tensor) -> torch.Tensor:
        """ε = (x_t - sqrt(ᾱ_t) x0) / sqrt(1 - ᾱ_t)."""
        return (x_t - self._at(self.sqrt_alphas_cumprod, t, x_t) * x0) / self._at(self.sqrt_one_minus_alphas_cumprod, t, x_t)

    def target(self, x0: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """What the model should output for x_t = q_sample(x0, t, noise): ε, x0 or v = sqrt(ᾱ) ε - sqrt(1-ᾱ) x0."""
        if self.prediction == "eps":
            return noise
        if self.prediction == "x0":
            return x0
        return self._at(self.sqrt_alphas_cumprod, t, x0) * noise - self._at(self.sqrt_one_minus_alphas_cumprod, t, x0) * x0

    def x0_and_eps(self, model_output: torch.Tensor, t: torch.Tensor, x_t: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(x0_hat, eps_hat) from a model output of the config's prediction type. t: (B,) int."""
        if self.prediction == "eps":
            return self.predict_x0(x_t, t, model_output), model_output
        if self.prediction == "x0":
            return model_output, self.predict_eps(x_t, t, model_output)
        a, s = self._at(self.sqrt_alphas_cumprod, t, x_t), self._at(self.sqrt_one_minus_alphas_cumprod, t, x_t)
        return a * x_t - s * model_output, s * x_t + a * model_output  # Salimans & Ho 2022, appendix D

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
        if self.config.loss == "l1":
            return (pred - target).abs()
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
        """The "simple" loss (model output vs the prediction type's target) on the free entries
        (mask False). x0: (B, ...) clean data; mask: bool like x0 (True = given, enters clean);
        t: (B,) (uniform if None); noise: like x0 (N(0, I) if None); cond: passed on to the model."""
        mask = self._check(x0, mask)
        B = x0.shape[0]
        if t is None:
            t = torch.randint(0, self.steps, (B,), generator=generator).to(x0.device)
        if noise is None:
            noise = torch.randn(x0.shape, generator=generator, dtype=x0.dtype).to(x0.device)
        x_t = torch.where(mask, x0, self.q_sample(x0, t, noise))
        out = model(x_t, t, mask=mask, **cond)
        if out.shape != x0.shape:
            raise ValueError(f"model returned {tuple(out.shape)}, expected {tuple(x0.shape)}")
        free = (~mask).to(x0.dtype)
        el = self.elementwise_loss(out, self.target(x0, noise, t)) * free
        dims = tuple(range(1, x0.dim()))
        per = el.sum(dims) / free.sum(dims).clamp_min(1.0)
        simple = el.sum() / free.sum().clamp_min(1.0)
        x0_hat = torch.where(mask, x0, self.x0_and_eps(out, t, x_t)[0])
        return DiffusionLoss(loss=simple, per_sample=per, terms={"simple": simple}, x0_hat=x0_hat, t=t)

    def step(
        self,
        model_output: torch.Tensor,
        t: int | torch.Tensor,
        x_t: torch.Tensor,
        *,
        t_prev: int | torch.Tensor | None = None,
        eta: float = 1.0,
        generator: torch.Generator | None = None,
        noise: torch.Tensor | None = None,
        clip_x0: float | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One reverse step from t to t_prev: -> (x_prev, x0_hat), both like x_t.

        model_output: the model's prediction at (x_t, t) of the config's type; t: int or (B,);
        t_prev: int or (B,) in [-1, t) (None = t - 1; -1 = the end: x_prev = x0_hat). The update is
        DDIM (Song et al. 2021, eq. 12) with σ² = η² (1 - ᾱ_prev) / (1 - ᾱ_t) (1 - ᾱ_t / ᾱ_prev);
        η = 1 with t_prev = t - 1 is exactly ancestral DDPM (σ² = β̃_t), η = 0 is deterministic.
        noise: the fresh noise (default N(0, I) from ``generator``, drawn only when σ > 0);
        clip_x0: clamp x0_hat to [-c, c] (ε is then recomputed from the clamped x0_hat).
        """
        if model_output.shape != x_t.shape:
            raise ValueError(f"model_output {tuple(model_output.shape)} must have x_t's shape {tuple(x_t.shape)}")
        if not eta >= 0:
            raise ValueError(f"eta must be >= 0, got {eta}")
        t = self._steps_of(t, x_t, "t")
        t_prev = t - 1 if t_prev is None else self._steps_of(t_prev, x_t, "t_prev", low=-1)
        if bool((t_prev >= t).any()):
            raise ValueError(f"t_prev must be < t, got t={t.tolist()}, t_prev={t_prev.tolist()}")
        x0_hat, eps = self.x0_and_eps(model_output, t, x_t)
        if clip_x0 is not None:
            if not clip_x0 > 0:
                raise ValueError(f"clip_x0 must be > 0 (or None), got {clip_x0}")
            x0_hat = x0_hat.clamp(-clip_x0, clip_x0)
            eps = self.predict_eps(x_t, t, x0_hat)
        ab = self.alphas_cumprod[t]
        ab_prev = torch.where(t_prev >= 0, self.alphas_cumprod[t_prev.clamp_min(0)], torch.ones_like(ab))
        var = eta ** 2 * (1 - ab_prev) / (1 - ab) * (1 - ab / ab_prev)  # float64; 0 where t_prev = -1

        def col(v: torch.Tensor) -> torch.Tensor:
            return v.to(x_t.dtype).reshape(-1, *([1] * (x_t.dim() - 1)))

        x_prev = col(ab_prev.sqrt()) * x0_hat + col((1 - ab_prev - var).clamp_min(0).sqrt()) * eps
        if eta > 0 and bool((var > 0).any()):
            if noise is None:
                noise = torch.randn(x_t.shape, generator=generator, dtype=x_t.dtype).to(x_t.device)
            x_prev = x_prev + col(var.sqrt()) * noise
        return x_prev, x0_hat

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
        clip_x0: float | None = None,
        **cond,
    ) -> torch.Tensor:
        """Draw x0 of ``shape`` by reverse diffusion (``step`` over ``respaced_timesteps``),
        inpainting ``given`` where ``mask``.

        num_steps None (all T) with eta = 1 is ancestral DDPM sampling (posterior variance β̃_t);
        fewer steps use the respaced DDIM update (Song et al. 2021, eq. 12), eta = 0 deterministic.
        Given entries are set to ``given`` before every model call and in the result (exactly).
        x_T: the starting sample (default N(0, I)); with T = 100 linear betas ᾱ_T ≈ 0.36, so N(0, I)
        is the exact terminal marginal only for zero-mean unit-variance data (the cosine schedule
        reaches noise: ᾱ_T < 1e-3).
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
        ts = respaced_timesteps(self.steps, num_steps or self.steps).tolist()
        for i, t_i in enumerate(ts):
            if mask is not None:
                x = torch.where(mask, given, x)
            t = torch.full((shape[0],), t_i, dtype=torch.long, device=x.device)
            out = model(x, t, mask=mask, **cond)
            x, _ = self.step(out, t, x, t_prev=ts[i + 1] if i + 1 < len(ts) else -1, eta=eta,
                             generator=generator, clip_x0=clip_x0)
        if mask is not None:
            x = torch.where(mask, given, x)
        return x
