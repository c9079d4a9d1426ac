"""LeanTransformerEncoder: the functional forward equals torch's TransformerEncoder (values and
gradients), keeps its state-dict keys and dropout sites, and refuses what it does not implement."""
from __future__ import annotations

import pytest
import torch
from torch import nn

from trumans.model.nets.blocks import LeanTransformerEncoder, encoder_stack


def _reference(lean: LeanTransformerEncoder) -> nn.TransformerEncoder:
    """torch's own encoder with the same weights."""
    layer = lean.layers[0]
    ref_layer = nn.TransformerEncoderLayer(layer.self_attn.embed_dim, layer.self_attn.num_heads,
                                           layer.linear1.out_features, layer.dropout.p, activation="gelu",
                                           batch_first=True, norm_first=layer.norm_first)
    ref = nn.TransformerEncoder(ref_layer, len(lean.layers), enable_nested_tensor=False)
    ref.load_state_dict(lean.state_dict())
    return ref


@pytest.mark.parametrize("post_ln", [True, False])
def test_lean_encoder_matches_torch_values_and_gradients(post_ln):
    torch.manual_seed(0)
    lean = encoder_stack(32, 3, 4, 48, dropout=0.1, post_ln=post_ln).eval()
    ref = _reference(lean).eval()
    x = torch.randn(3, 9, 32)
    xa, xb = x.clone().requires_grad_(True), x.clone().requires_grad_(True)
    ya, yb = lean(xa), ref(xb)
    assert ya.shape == (3, 9, 32)
    torch.testing.assert_close(ya, yb, atol=1e-5, rtol=1e-5)
    w = torch.randn_like(ya)
    ga, = torch.autograd.grad((ya * w).sum(), xa)
    gb, = torch.autograd.grad((yb * w).sum(), xb)
    torch.testing.assert_close(ga, gb, atol=1e-5, rtol=1e-4)
    with torch.no_grad():  # torch's fused inference path too
        torch.testing.assert_close(lean(x), ref(x), atol=1e-5, rtol=1e-5)


def test_lean_encoder_parameter_gradients_match_torch():
    torch.manual_seed(1)
    lean = encoder_stack(16, 2, 2, 24, dropout=0.0).train()
    ref = _reference(lean).train()
    x = torch.randn(2, 5, 16)
    lean(x).square().sum().backward()
    ref(x).square().sum().backward()
    grads = dict(ref.named_parameters())
    for name, p in lean.named_parameters():
        torch.testing.assert_close(p.grad, grads[name].grad, atol=1e-5, rtol=1e-4, msg=name)


def test_lean_encoder_state_dict_keys_are_torchs():
    lean = encoder_stack(16, 2, 2, 24, dropout=0.1)
    assert list(lean.state_dict()) == list(_reference(lean).state_dict())


def test_lean_encoder_dropout_only_in_training():
    torch.manual_seed(2)
    lean = encoder_stack(16, 2, 2, 24, dropout=0.5)
    x = torch.randn(2, 6, 16)
    lean.train()
    a, b = lean(x), lean(x)
    assert not torch.allclose(a, b)  # dropout draws differ between calls
    lean.eval()
    torch.testing.assert_close(lean(x), lean(x))


def test_lean_encoder_refuses_masks_and_other_layers():
    lean = encoder_stack(16, 1, 2, 24, dropout=0.0)
    x = torch.randn(1, 4, 16)
    with pytest.raises(ValueError, match="masks"):
        lean(x, mask=torch.zeros(4, 4, dtype=torch.bool))
    with pytest.raises(ValueError, match="masks"):
        lean(x, src_key_padding_mask=torch.zeros(1, 4, dtype=torch.bool))
    relu = nn.TransformerEncoderLayer(16, 2, 24, batch_first=True)
    with pytest.raises(ValueError, match="gelu"):
        LeanTransformerEncoder(relu, 2)
