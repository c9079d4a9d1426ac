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
