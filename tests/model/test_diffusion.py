"""Diffusion: schedule closed forms, q-sample statistics, analytic sampling, exact inpainting, loss masking."""
from __future__ import annotations

import math

import pytest
import torch

from trumans.model.diffusion import DiffusionConfig, GaussianDiffusion, respaced_timesteps

torch.set_num_threads(1)


def test_schedule_closed_forms() -> None:
    d = GaussianDiffusion(DiffusionConfig(steps=100, beta_start=1e-4, beta_end=0.02))
    assert d.betas.dtype == torch.float64 and d.alphas_cumprod.dtype == torch.float64
    t = torch.arange(100, dtype=torch.float64)
    beta = 1e-4 + (0.02 - 1e-4) * t / 99
    assert torch.allclose(d.betas, beta, atol=1e-15)
    # ᾱ_t = prod_{s<=t} (1 - β_s), computed independently in log space
    ac = torch.exp(torch.cumsum(torch.log1p(-beta), 0))
    assert torch.allclose(d.alphas_cumprod, ac, rtol=1e-12)
    assert d.alphas_cumprod_prev[0] == 1.0 and torch.equal(d.alphas_cumprod_prev[1:], d.alphas_cumprod[:-1])
    assert torch.allclose(d.sqrt_alphas_cumprod ** 2 + d.sqrt_one_minus_alphas_cumprod ** 2, torch.ones(100, dtype=torch.float64))
    # β̃_t = β_t (1 - ᾱ_{t-1}) / (1 - ᾱ_t); β̃_0 = 0
    assert d.posterior_variance[0] == 0.0
    assert math.isclose(float(d.posterior_variance[50]), float(beta[50] * (1 - ac[49]) / (1 - ac[50])), rel_tol=1e-12)
    # final ᾱ_T for this schedule: ~0.364 (T = 100 is short: x_T still carries signal)
    assert 0.35 < float(d.alphas_cumprod[-1]) < 0.38


def test_respaced_timesteps() -> None:
    assert respaced_timesteps(100, 100).tolist() == list(range(99, -1, -1))
    ts = respaced_timesteps(100, 10)
    assert ts[0] == 99 and ts[-1] == 0 and len(ts) == 10 and bool((ts[1:] < ts[:-1]).all())
    with pytest.raises(ValueError, match="sampling steps"):
        respaced_timesteps(100, 0)


def test_q_sample_statistics() -> None:
    d = GaussianDiffusion()
    g = torch.Generator().manual_seed(0)
    x0 = torch.full((200_000, 1), 2.0)
    for ti in (0, 40, 99):
        t = torch.full((len(x0),), ti)
        xt = d.q_sample(x0, t, torch.randn(x0.shape, generator=g))
        ab = float(d.alphas_cumprod[ti])
        assert abs(xt.mean().item() - 2.0 * math.sqrt(ab)) < 0.01
        assert abs(xt.std().item() - math.sqrt(1 - ab)) < 0.01


def _gaussian_eps_model(d: GaussianDiffusion, s: float, c: float = 0.0):
    """Optimal ε̂ for data x0 ~ N(c, s²): E[ε | x_t] = sqrt(1-ᾱ)(x_t - sqrt(ᾱ)c) / (ᾱ s² + 1 - ᾱ)."""
    def model(x, t, mask=None):
        ab = d.alphas_cumprod[t].float().reshape(-1, 1)
        return (1 - ab).sqrt() * (x - ab.sqrt() * c) / (ab * s * s + 1 - ab)
    return model


@pytest.mark.parametrize("num_steps,eta", [(None, 1.0), (20, 1.0), (20, 0.0)])
def test_sampling_point_mass_is_exact(num_steps, eta) -> None:
    """For data = the constant c, the optimal model makes every sampler return c."""
    d = GaussianDiffusion()
    x = d.sample(_gaussian_eps_model(d, 0.0, 1.5), (64, 3), num_steps=num_steps, eta=eta,
                 generator=torch.Generator().manual_seed(1))
    assert torch.allclose(x, torch.full_like(x, 1.5), atol=1e-4)


@pytest.mark.parametrize("num_steps,eta", [(None, 1.0), (25, 0.0)])
def test_sampling_gaussian_statistics(num_steps, eta) -> None:
    """Data N(1, 0.5²), started from its exact terminal marginal q(x_T): samples have its statistics."""
    d = GaussianDiffusion()
    g = torch.Generator().manual_seed(2)
    abT = float(d.alphas_cumprod[-1])
    x_T = math.sqrt(abT) * 1.0 + math.sqrt(abT * 0.25 + 1 - abT) * torch.randn(40_000, 1, generator=g)
    x = d.sample(_gaussian_eps_model(d, 0.5, 1.0), (40_000, 1), num_steps=num_steps, eta=eta, generator=g, x_T=x_T)
    assert abs(x.mean().item() - 1.0) < 0.02
    assert abs(x.std().item() - 0.5) < 0.03


def test_unit_gaussian_prior_matches_terminal_marginal() -> None:
    """For zero-mean unit-variance data, N(0, I) is exactly q(x_T) (var = ᾱ + 1 - ᾱ): sampling from it is unbiased."""
    d = GaussianDiffusion()
    x = d.sample(_gaussian_eps_model(d, 1.0, 0.0), (40_000, 1), generator=torch.Generator().manual_seed(4))
    assert abs(x.mean().item()) < 0.02 and abs(x.std().item() - 1.0) < 0.02


def test_ddim_eta1_full_schedule_is_ddpm_posterior() -> None:
    """σ² of the DDIM update with η = 1 on all steps equals the DDPM posterior variance β̃_t."""
    d = GaussianDiffusion()
    ab, abp = d.alphas_cumprod[1:], d.alphas_cumprod[:-1]
    var = (1 - abp) / (1 - ab) * (1 - ab / abp)
    assert torch.allclose(var, d.posterior_variance[1:], rtol=1e-10)


def test_masked_entries_come_out_exactly_as_given() -> None:
    d = GaussianDiffusion()
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(5, 16), torch.nn.Tanh(), torch.nn.Linear(16, 5))
    seen = []

    def model(x, t, mask=None):
        seen.append(torch.equal(x[mask], given[mask]))  # the model sees the given entries, clean
        return net(x)

    given = torch.randn(4, 7, 5) * 3
    mask = torch.rand(4, 7, 5) > 0.6
    for steps, eta in ((None, 1.0), (10, 0.0), (10, 0.5)):
        seen.clear()
        x = d.sample(model, (4, 7, 5), mask=mask, given=given, num_steps=steps, eta=eta,
                     generator=torch.Generator().manual_seed(3))
        assert torch.equal(x[mask], given[mask])
        assert all(seen) and len(seen) == (steps or 100)
        assert not torch.allclose(x[~mask], given[~mask])


def test_training_loss_masks_given_entries() -> None:
    d = GaussianDiffusion()
    x0 = torch.randn(3, 4, 6)
    mask = torch.zeros(3, 4, 6, dtype=torch.bool)
    mask[:, :2] = True
    noise = torch.randn_like(x0)
    t = torch.tensor([0, 50, 99])

    def perfect_on_free(x, t_, mask=None):
        assert torch.equal(x[mask], x0[mask])  # given entries enter clean
        return torch.where(mask, torch.full_like(x, 100.0), noise)  # wrong only where given

    out = d.training_loss(perfect_on_free, x0, mask=mask, t=t, noise=noise)
    assert out.loss.item() == 0.0 and out.per_sample.shape == (3,)
    zero = d.training_loss(lambda x, t_, mask=None: torch.zeros_like(x), x0, mask=mask, t=t, noise=noise)
    free = noise[~mask]
    expected = torch.nn.functional.huber_loss(torch.zeros_like(free), free)
    assert torch.allclose(zero.loss, expected)


def test_bad_inputs() -> None:
    d = GaussianDiffusion()
    x0 = torch.randn(2, 3)
    with pytest.raises(ValueError, match="bool"):
        d.training_loss(lambda x, t, mask=None: x, x0, mask=torch.ones(2, 3))
    with pytest.raises(ValueError, match="broadcast"):
        d.training_loss(lambda x, t, mask=None: x, x0, mask=torch.ones(4, 3, dtype=torch.bool))
    with pytest.raises(ValueError, match="given"):
        d.sample(lambda x, t, mask=None: x, (2, 3), mask=torch.ones(2, 3, dtype=torch.bool))
    with pytest.raises(ValueError, match="beta"):
        DiffusionConfig(beta_start=0.1, beta_end=0.01)
    with pytest.raises(ValueError, match="model returned"):
        d.training_loss(lambda x, t, mask=None: x[:, :2], x0)


# --- schedules that reach noise, prediction types, the public step ---------------------------------------

def test_cosine_schedule_reaches_noise_and_linear_does_not() -> None:
    """Nichol & Dhariwal 2021 eq. 17: ᾱ_t = f(t+1)/f(0) with f(u) = cos²((u/T + s)/(1 + s) π/2), β ≤ 0.999."""
    d = GaussianDiffusion(DiffusionConfig(schedule="cosine"))
    assert d.betas.dtype == torch.float64 and d.alphas_cumprod.dtype == torch.float64
    T, s = 100, 0.008
    f = torch.cos((torch.arange(T + 1, dtype=torch.float64) / T + s) / (1 + s) * math.pi / 2) ** 2
    assert torch.allclose(d.alphas_cumprod[:-1], f[1:-1] / f[0], rtol=1e-10)  # no clipping before the last step
    assert float(d.betas.max()) == 0.999 and bool((d.alphas_cumprod[1:] < d.alphas_cumprod[:-1]).all())
    assert float(d.alphas_cumprod[-1]) < 1e-3  # x_T is noise: N(0, I) is the terminal marginal
    # the authors' linear 1e-4 -> 0.02 at T = 100 does NOT reach noise (the sampling issue's collapse)
    assert float(GaussianDiffusion(DiffusionConfig(beta_start=1e-4, beta_end=0.02)).alphas_cumprod[-1]) > 1e-3
    assert GaussianDiffusion(DiffusionConfig(schedule="cosine", beta_end=0.5)).betas.equal(d.betas)  # betas unused


@pytest.mark.parametrize("schedule", ["linear", "cosine"])
def test_prediction_conversions_agree(schedule) -> None:
    """The target of each prediction type converts back to the true (x0, ε)."""
    g = torch.Generator().manual_seed(5)
    x0, noise = torch.randn(6, 4, 3, generator=g, dtype=torch.float64), torch.randn(6, 4, 3, generator=g, dtype=torch.float64)
    t = torch.tensor([0, 1, 30, 60, 98, 99])
    for pred in ("eps", "x0", "v"):
        d = GaussianDiffusion(DiffusionConfig(schedule=schedule, prediction=pred))
        x_t = d.q_sample(x0, t, noise)
        x0_hat, eps_hat = d.x0_and_eps(d.target(x0, noise, t), t, x_t)
        assert torch.allclose(x0_hat, x0, atol=1e-6) and torch.allclose(eps_hat, noise, atol=1e-6), pred
    d = GaussianDiffusion(DiffusionConfig(schedule=schedule, prediction="v"))
    ab = d.alphas_cumprod[t].reshape(-1, 1, 1)
    assert torch.allclose(d.target(x0, noise, t), ab.sqrt() * noise - (1 - ab).sqrt() * x0)


@pytest.mark.parametrize("pred", ["x0", "v", "eps"])
def test_true_prediction_recovers_x0_in_one_step(pred) -> None:
    """A model that outputs the true target of its type gives x0 in one step to the end (t_prev = -1)."""
    d = GaussianDiffusion(DiffusionConfig(prediction=pred))
    g = torch.Generator().manual_seed(6)
    x0, noise = torch.randn(3, 5, generator=g), torch.randn(3, 5, generator=g)
    t = torch.full((3,), 99)
    x_t = d.q_sample(x0, t, noise)
    x_prev, x0_hat = d.step(d.target(x0, noise, t), 99, x_t, t_prev=-1, generator=g)
    assert torch.equal(x_prev, x0_hat) and torch.allclose(x0_hat, x0, atol=1e-5)
    if pred == "x0":
        assert torch.equal(x0_hat, x0)  # exactly
        out = d.sample(lambda x, t_, mask=None: x0, (3, 5), num_steps=1, generator=g)
        assert torch.equal(out, x0)


def test_step_is_the_ddpm_posterior_and_ddim() -> None:
    """η = 1, t_prev = t - 1: mean μ̃_t(x_t, x0) (Ho et al. eq. 7), noise scaled by sqrt(β̃_t); η = 0: DDIM eq. 12."""
    d = GaussianDiffusion(DiffusionConfig(prediction="x0", schedule="cosine"))
    g = torch.Generator().manual_seed(7)
    x0, x_t, n = (torch.randn(4, 6, generator=g, dtype=torch.float64) for _ in range(3))
    ti = 40
    b, ab, abp = d.betas[ti], d.alphas_cumprod[ti], d.alphas_cumprod[ti - 1]
    mean = abp.sqrt() * b / (1 - ab) * x0 + (1 - b).sqrt() * (1 - abp) / (1 - ab) * x_t
    x_mean, x0_hat = d.step(x0, ti, x_t, noise=torch.zeros_like(x_t))
    assert torch.equal(x0_hat, x0) and torch.allclose(x_mean, mean, atol=1e-12)
    x_noisy, _ = d.step(x0, ti, x_t, noise=n)
    assert torch.allclose(x_noisy - x_mean, d.posterior_variance[ti].sqrt() * n, atol=1e-12)
    # DDIM η = 0 from 40 to 10: sqrt(ᾱ_10) x0 + sqrt(1 - ᾱ_10) ε̂, no noise drawn
    eps = (x_t - ab.sqrt() * x0) / (1 - ab).sqrt()
    x_ddim, _ = d.step(x0, torch.full((4,), ti), x_t, t_prev=10, eta=0.0)
    a10 = d.alphas_cumprod[10]
    assert torch.allclose(x_ddim, a10.sqrt() * x0 + (1 - a10).sqrt() * eps, atol=1e-12)
    # per-sample steps and clipping
    x_prev, x0c = d.step(torch.full_like(x_t, 5.0), torch.tensor([40, 30, 20, 10]), x_t,
                         t_prev=torch.tensor([39, -1, 0, 9]), eta=0.0, clip_x0=1.0)
    assert bool((x0c == 1.0).all()) and torch.equal(x_prev[1], x0c[1])


def _gaussian_x0_model(d: GaussianDiffusion, s: float, c: float):
    """Optimal x̂0 for data x0 ~ N(c, s²): E[x0 | x_t] = c + sqrt(ᾱ) s² (x_t - sqrt(ᾱ) c) / (ᾱ s² + 1 - ᾱ),
    returned as the config's prediction type."""
    def model(x, t, mask=None):
        ab = d.alphas_cumprod[t].float().reshape(-1, 1)
        x0 = c + ab.sqrt() * s * s * (x - ab.sqrt() * c) / (ab * s * s + 1 - ab)
        if d.prediction == "x0":
            return x0
        eps = (x - ab.sqrt() * x0) / (1 - ab).sqrt()
        return ab.sqrt() * eps - (1 - ab).sqrt() * x0  # v
    return model


@pytest.mark.parametrize("pred,num_steps,eta,std_tol", [("x0", None, 1.0, 0.025), ("v", None, 1.0, 0.025),
                                                         ("x0", 20, 0.0, 0.045), ("v", 20, 0.0, 0.045)])
def test_cosine_sampling_from_unit_noise_matches_data(pred, num_steps, eta, std_tol) -> None:
    """With the cosine schedule N(0, I) is the terminal marginal for any data: samples of N(1, 0.5²) from it
    are unbiased (the std is a little low from the discretisation: 0.48 at T = 100 ancestral, 0.46 with 20
    DDIM steps). With the linear 1e-4..0.02 schedule the same prior biases the mean by > 0.1."""
    g = torch.Generator().manual_seed(8)
    d = GaussianDiffusion(DiffusionConfig(schedule="cosine", prediction=pred))
    x = d.sample(_gaussian_x0_model(d, 0.5, 1.0), (40_000, 1), num_steps=num_steps, eta=eta, generator=g)
    assert abs(x.mean().item() - 1.0) < 0.01 and abs(x.std().item() - 0.5) < std_tol
    lin = GaussianDiffusion(DiffusionConfig(schedule="linear", prediction=pred))
    x = lin.sample(_gaussian_x0_model(lin, 0.5, 1.0), (40_000, 1), num_steps=num_steps, eta=eta, generator=g)
    assert abs(x.mean().item() - 1.0) > 0.1


def test_training_loss_terms_and_x0_hat() -> None:
    g = torch.Generator().manual_seed(9)
    x0, noise = torch.randn(3, 4, 6, generator=g), torch.randn(3, 4, 6, generator=g)
    mask = torch.zeros(3, 4, 6, dtype=torch.bool)
    mask[:, 0] = True
    t = torch.tensor([2, 50, 97])
    for pred in ("eps", "x0", "v"):
        d = GaussianDiffusion(DiffusionConfig(prediction=pred, schedule="cosine", loss="l1"))
        target = d.target(x0, noise, t)
        out = d.training_loss(lambda x, t_, mask=None: torch.where(mask, torch.full_like(x, 9.0), target),
                              x0, mask=mask, t=t, noise=noise)
        assert out.loss.item() == 0.0 and set(out.terms) == {"simple"} and torch.equal(out.t, t)
        assert torch.equal(out.x0_hat[mask], x0[mask])  # given entries are their clean values
        assert torch.allclose(out.x0_hat, x0, atol=1e-4), pred
        zero = d.training_loss(lambda x, t_, mask=None: torch.zeros_like(x), x0, mask=mask, t=t, noise=noise)
        assert torch.allclose(zero.loss, target[~mask].abs().mean())  # L1
        assert torch.allclose(zero.per_sample, (target.abs() * ~mask).sum((1, 2)) / (~mask).sum((1, 2)))
    # x0_hat carries gradients (task regularisers use it)
    w = torch.ones((), requires_grad=True)
    d = GaussianDiffusion(DiffusionConfig(prediction="x0"))
    out = d.training_loss(lambda x, t_, mask=None: x * w, x0, t=t, noise=noise)
    out.x0_hat.square().sum().backward()
    assert w.grad is not None and w.grad.abs() > 0


def test_new_bad_inputs() -> None:
    for kw, match in (({"schedule": "quadratic"}, "schedule"), ({"prediction": "y"}, "prediction"),
                      ({"loss": "l2"}, "loss"), ({"beta_end": float("nan")}, "beta"),
                      ({"huber_delta": float("nan")}, "huber_delta"), ({"steps": 0}, "steps")):
        with pytest.raises(ValueError, match=match):
            DiffusionConfig(**kw)
    d = GaussianDiffusion()
    x = torch.randn(2, 3)
    with pytest.raises(ValueError, match="t_prev must be < t"):
        d.step(x, 5, x, t_prev=5)
    with pytest.raises(ValueError, match=r"t must lie in \[0, 100\)"):
        d.step(x, 100, x)
    with pytest.raises(ValueError, match="clip_x0"):
        d.step(x, 5, x, clip_x0=0.0)
    with pytest.raises(ValueError, match="shape"):
        d.step(x[:, :2], 5, x)
    with pytest.raises(ValueError, match="eta"):
        d.step(x, 5, x, eta=-1.0)
