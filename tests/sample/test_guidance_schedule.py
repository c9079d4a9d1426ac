"""Where and how the sampler guides (``SamplerConfig.guided_steps``, ``guidance_space``): the cheaper
schedules are exact special cases of the full ones, and they still pull the body toward its goal."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.sample.rollout import start_context
from trumans.sample.sampler import EpisodeSampler, Goal, SamplerConfig

from helpers import tiny_checkpoint


def _episode(config: SamplerConfig, seed: int = 0, goal=(1.0, 0.0)) -> np.ndarray:
    ck = tiny_checkpoint()
    s = EpisodeSampler(ck, None, config)
    ctx = start_context(ck, np.array([0.0, 0.0]), 0.0)
    labels = np.zeros((1, ck.L_epi, len(ck.vocabulary)), np.float32)
    labels[..., ck.vocabulary.index("walk")] = 1.0
    return s.episode(ctx, labels, [Goal(goal)], generator=torch.Generator().manual_seed(seed))


def test_bad_schedules_are_refused():
    with pytest.raises(ValueError, match="guided_steps"):
        SamplerConfig(guided_steps=-1)
    with pytest.raises(ValueError, match="guidance_space"):
        SamplerConfig(guidance_space="eps")
    with pytest.raises(ValueError, match="x0_guidance"):
        SamplerConfig(x0_guidance=float("nan"))


def test_guiding_the_last_all_steps_is_guiding_every_step():
    a = _episode(SamplerConfig(steps=4, guided_steps=0))
    b = _episode(SamplerConfig(steps=4, guided_steps=4))
    np.testing.assert_array_equal(a, b)
    c = _episode(SamplerConfig(steps=4, guided_steps=1))
    assert np.abs(c - a).max() > 1e-4  # fewer guided steps is another sampler


def test_unguided_steps_are_plain_ddim():
    """Guiding 0 of the steps in x0 space with a zero step size is the unguided sampler, exactly."""
    plain = _episode(SamplerConfig(steps=4, goal_guidance=0.0))
    x0_zero = _episode(SamplerConfig(steps=4, guidance_space="x0", x0_guidance=0.0))
    np.testing.assert_allclose(x0_zero, plain, atol=1e-5)


@pytest.mark.parametrize("config", [SamplerConfig(steps=4, guided_steps=2),
                                    SamplerConfig(steps=4, guidance_space="x0", x0_guidance=0.1)])
def test_cheaper_guidance_still_guides(config):
    """The goal itself is inpainted (exact in every sampler); guidance moves the rest of the body."""
    free = _episode(SamplerConfig(steps=4, goal_guidance=0.0))
    guided = _episode(config)
    np.testing.assert_allclose(guided[0, -1, 0, :2], free[0, -1, 0, :2], atol=1e-5)
    assert np.abs(guided - free).max() > 1e-3


def test_last_step_runs_no_backward_pass_its_result_cannot_use(monkeypatch):
    """The last step's final guidance update would only move x_{t-1} after the last step: it is not
    computed (one backward pass fewer an episode), and the episode is what it was."""
    calls = []
    real = torch.autograd.grad
    monkeypatch.setattr(torch.autograd, "grad", lambda *a, **k: calls.append(1) or real(*a, **k))
    _episode(SamplerConfig(steps=4, guided_steps=2, goal_iters=3))
    assert len(calls) == 2 * 3 - 1
    calls.clear()
    _episode(SamplerConfig(steps=4, guided_steps=1, goal_iters=1))
    assert calls == []
