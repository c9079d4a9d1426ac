"""Networks: ViT scene perceiver, action encoder, denoiser (shapes, gradients, conditions, guidance, overfit)."""
from __future__ import annotations

import pytest
import torch

from trumans.model.diffusion import GaussianDiffusion
from trumans.model.nets import (ActionEncoder, ActionEncoderConfig, Denoiser, DenoiserConfig, GuidedDenoiser,
                          ScenePerceiver, ScenePerceiverConfig)

torch.set_num_threads(1)
SC = ScenePerceiverConfig(grid=32, patch=8, d_model=32, layers=1, heads=4, ff=64, dropout=0.0)
AC = ActionEncoderConfig(num_actions=5, frames=16, d_model=32, layers=1, heads=4, ff=64, dropout=0.0)


def _all_grads(module: torch.nn.Module) -> None:
    for name, p in module.named_parameters():
        assert p.grad is not None and torch.isfinite(p.grad).all(), name
        assert p.grad.abs().sum() > 0, f"no gradient reaches {name}"


def test_scene_perceiver_shapes_and_gradients() -> None:
    torch.manual_seed(0)
    vit = ScenePerceiver(SC, out_dim=24)
    grid = torch.rand(3, 32, 32, 32) > 0.7
    out = vit(grid)
    assert out.shape == (3, 24)
    out.square().sum().backward()
    _all_grads(vit)
    # height slices are channels: moving an obstacle up changes the embedding
    g2 = torch.zeros(1, 32, 32, 32, dtype=torch.bool)
    g3 = g2.clone()
    g2[0, 10:14, 10:14, 0:4] = True
    g3[0, 10:14, 10:14, 20:24] = True
    assert not torch.allclose(vit(g2), vit(g3))
    with pytest.raises(ValueError, match="forward, left, up"):
        vit(torch.zeros(1, 16, 32, 32, dtype=torch.bool))
    with pytest.raises(ValueError, match="divide"):
        ScenePerceiverConfig(grid=32, patch=5)


def test_action_encoder_shapes_and_gradients() -> None:
    torch.manual_seed(0)
    enc = ActionEncoder(AC, out_dim=20)
    a = torch.rand(4, 16, 5) + 1.0
    out = enc(a)
    assert out.shape == (4, 20)
    out.square().sum().backward()
    _all_grads(enc)
    b = a.clone()
    b[:, :, 2] = 0  # switch one action off
    assert not torch.allclose(enc(a), enc(b))
    with pytest.raises(ValueError, match=r"\(B, 16, 5\)"):
        enc(torch.zeros(4, 15, 5))


def _denoiser(**kw) -> Denoiser:
    cfg = DenoiserConfig(d_model=32, layers=2, heads=4, ff=64, dropout=0.0, scene=SC, action=AC, **kw)
    return Denoiser(cfg)


def test_denoiser_shapes_gradients_and_conditions() -> None:
    torch.manual_seed(0)
    m = _denoiser()
    x, t = torch.randn(2, 16, 72), torch.tensor([3, 70])
    scene, actions = torch.rand(2, 32, 32, 32) > 0.5, torch.rand(2, 16, 5)
    mask = torch.zeros(2, 16, 72, dtype=torch.bool)
    out = m(x, t, mask=mask, scene=scene, actions=actions)
    assert out.shape == (2, 16, 72)
    out.square().sum().backward()
    for name, p in m.named_parameters():
        if not name.startswith("null_"):  # null embeddings only get gradients when a condition is dropped
            assert p.grad is not None and torch.isfinite(p.grad).all() and p.grad.abs().sum() > 0, name
    with torch.no_grad():
        mask2 = mask.clone()
        mask2[:, :2] = True
        assert not torch.allclose(m(x, t, mask=mask2, scene=scene, actions=actions), out)  # the mask is an input
        assert not torch.allclose(m(x, t + 1, mask=mask, scene=scene, actions=actions), out)
        # a dropped condition is replaced by its null embedding: the scene then does not matter
        drop = torch.tensor([True, True])
        a = m(x, t, scene=scene, actions=actions, drop_scene=drop)
        b = m(x, t, scene=~scene, actions=actions, drop_scene=drop)
        c = m(x, t, scene=None, actions=actions)
        assert torch.allclose(a, b) and torch.allclose(a, c)
        assert not torch.allclose(m(x, t, scene=scene, actions=actions), m(x, t, scene=~scene, actions=actions))


def test_denoiser_options_and_errors() -> None:
    m = Denoiser(DenoiserConfig(d_model=32, layers=1, heads=4, ff=64, frame_cond_dim=7, extra_features=9))
    x = torch.randn(2, 16, 81)
    assert m(x, torch.tensor([1, 2]), frame_cond=torch.randn(2, 16, 7)).shape == (2, 16, 81)
    with pytest.raises(ValueError, match="frame_cond"):
        m(x, torch.tensor([1, 2]))
    with pytest.raises(ValueError, match="no scene condition"):
        m(x, torch.tensor([1, 2]), frame_cond=torch.randn(2, 16, 7), scene=torch.zeros(2, 32, 32, 32, dtype=torch.bool))
    with pytest.raises(ValueError, match=r"\(B, 16, 81\)"):
        m(torch.randn(2, 16, 72), torch.tensor([1, 2]))
    cfg = _denoiser().config
    assert DenoiserConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError, match="unknown"):
        DenoiserConfig.from_dict({**cfg.to_dict(), "depth": 3})


def test_guidance_scales() -> None:
    torch.manual_seed(1)
    m = _denoiser().eval()
    x, t = torch.randn(2, 16, 72), torch.tensor([5, 50])
    s, a = torch.rand(2, 32, 32, 32) > 0.5, torch.rand(2, 16, 5)
    with torch.no_grad():
        full = m(x, t, scene=s, actions=a)
        assert torch.allclose(GuidedDenoiser(m, 1.0, 1.0)(x, t, scene=s, actions=a), full)
        uncond = m(x, t)
        assert torch.allclose(GuidedDenoiser(m, 0.0, 0.0)(x, t, scene=s, actions=a), uncond, atol=1e-5)
        scene_only = m(x, t, scene=s)
        g = GuidedDenoiser(m, 2.5, 3.0)(x, t, scene=s, actions=a)
        ref = uncond + 2.5 * (scene_only - uncond) + 3.0 * (full - scene_only)
        assert torch.allclose(g, ref, atol=1e-5)


def test_tiny_model_overfits_one_batch() -> None:
    """A tiny denoiser drives the ε loss of one fixed batch (fixed t and noise) far below the zero-ε baseline."""
    torch.manual_seed(0)
    m = Denoiser(DenoiserConfig(d_model=64, layers=2, heads=4, ff=128, dropout=0.0, action=AC))
    d = GaussianDiffusion()
    g = torch.Generator().manual_seed(0)
    x0 = torch.randn(4, 16, 72, generator=g).cumsum(1) / 4  # smooth-ish trajectories
    t, noise = torch.randint(0, 100, (4,), generator=g), torch.randn(4, 16, 72, generator=g)
    acts = torch.rand(4, 16, 5, generator=g)
    mask = torch.zeros(4, 16, 72, dtype=torch.bool)
    mask[:, :2] = True
    opt = torch.optim.Adam(m.parameters(), lr=2e-3)
    first = None
    for _ in range(150):
        loss = d.training_loss(m, x0, mask=mask, t=t, noise=noise, actions=acts).loss
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.05 * first, (first, loss.item())


def test_precomputed_condition_embedding_gives_identical_outputs() -> None:
    """forward(cond_emb=encode_conditions(...)) == forward(raw conditions), bit for bit, also under inference_mode."""
    torch.manual_seed(2)
    m = _denoiser().eval()
    x, t = torch.randn(3, 16, 72), torch.tensor([0, 40, 99])
    s, a = torch.rand(3, 32, 32, 32) > 0.5, torch.rand(3, 16, 5)
    mask = torch.rand(3, 16, 72) > 0.7
    drop = torch.tensor([True, False, True])
    with torch.no_grad():
        for kw in ({"scene": s, "actions": a}, {"scene": s}, {}, {"scene": s, "actions": a, "drop_scene": drop},
                   {"actions": a, "drop_action": drop}):
            ref = m(x, t, mask=mask, **kw)
            emb = m.encode_conditions(batch=3, **kw)
            assert emb.shape == (3, 32)
            assert torch.equal(m(x, t, mask=mask, cond_emb=emb), ref), kw
        ref = m(x, t, mask=mask, scene=s, actions=a)
    with torch.inference_mode():
        emb = m.encode_conditions(scene=s, actions=a)
        assert torch.equal(m(x, t, mask=mask, cond_emb=emb), ref)
        assert torch.equal(m(x, 7, cond_emb=emb[:1].expand(3, -1)), m(x, torch.full((3,), 7), scene=s[:1].expand(3, -1, -1, -1),
                                                                       actions=a[:1].expand(3, -1, -1)))
    # a model without condition encoders: the embedding is zeros and changes nothing
    plain = Denoiser(DenoiserConfig(d_model=32, layers=1, heads=4, ff=64, dropout=0.0)).eval()
    with torch.no_grad():
        z = plain.encode_conditions(batch=3)
        assert torch.equal(z, torch.zeros(3, 32)) and torch.equal(plain(x, t, cond_emb=z), plain(x, t))
    with pytest.raises(ValueError, match="not both"):
        m(x, t, scene=s, cond_emb=emb)
    with pytest.raises(ValueError, match="cond_emb must be"):
        m(x, t, cond_emb=torch.zeros(2, 32))
    with pytest.raises(ValueError, match="same batch size"):
        m.encode_conditions(scene=s, actions=a[:2])
    with pytest.raises(ValueError, match="batch"):
        m.encode_conditions()


def test_guidance_with_precomputed_embeddings() -> None:
    torch.manual_seed(3)
    m = _denoiser().eval()
    x, t = torch.randn(2, 16, 72), torch.tensor([5, 50])
    s, a = torch.rand(2, 32, 32, 32) > 0.5, torch.rand(2, 16, 5)
    with torch.inference_mode():
        for scales, rows in (((1.0, 1.0), 2), ((2.5, 3.0), 6), ((0.0, 0.0), 6), ((1.0, 2.0), 4)):
            g = GuidedDenoiser(m, *scales)
            emb = g.encode_conditions(scene=s, actions=a)
            assert emb.shape == (rows, 32) and g.passes * 2 == rows
            assert torch.equal(g(x, t, cond_emb=emb), g(x, t, scene=s, actions=a))
        # scene scale 1 (the default action guidance): the (∅,∅) pass cancels and is not run
        g = GuidedDenoiser(m, 1.0, 2.0)
        emb = g.encode_conditions(scene=s, actions=a)
        assert torch.equal(emb[:2], m.encode_conditions(scene=s))
        assert torch.equal(emb[2:], m.encode_conditions(scene=s, actions=a))
        three = m(x, t) + 1.0 * (m(x, t, scene=s) - m(x, t)) + 2.0 * (m(x, t, scene=s, actions=a) - m(x, t, scene=s))
        assert torch.allclose(g(x, t, cond_emb=emb), three, atol=1e-5)
        with pytest.raises(ValueError, match="2B"):
            g(x, t, cond_emb=m.encode_conditions(scene=s, actions=a))
        g = GuidedDenoiser(m, 2.5, 3.0)
        emb = g.encode_conditions(scene=s, actions=a)
        # the stacked embeddings are the model's own for (∅,∅), (S,∅), (S,A)
        assert torch.equal(emb[:2], m.encode_conditions(batch=2))
        assert torch.equal(emb[2:4], m.encode_conditions(scene=s))
        assert torch.equal(emb[4:], m.encode_conditions(scene=s, actions=a))
        ref = m(x, t) + 2.5 * (m(x, t, scene=s) - m(x, t)) + 3.0 * (m(x, t, scene=s, actions=a) - m(x, t, scene=s))
        assert torch.allclose(g(x, t, cond_emb=emb), ref, atol=1e-5)
        with pytest.raises(ValueError, match="3B"):
            g(x, t, cond_emb=m.encode_conditions(scene=s, actions=a))
