"""Shared network blocks: transformer encoder stacks, sinusoidal embeddings, MLPs."""
from __future__ import annotations

import math

import torch
from torch import nn

__all__ = ["encoder_stack", "sinusoidal_embedding", "mlp"]


def encoder_stack(d_model: int, layers: int, heads: int, ff: int, dropout: float, post_ln: bool = True) -> nn.TransformerEncoder:
    """A batch-first transformer encoder (GELU); post-LN (Vaswani et al.) unless ``post_ln`` is False."""
    if d_model % heads:
        raise ValueError(f"d_model ({d_model}) must be divisible by heads ({heads})")
    layer = nn.TransformerEncoderLayer(d_model, heads, ff, dropout, activation="gelu",
                                       batch_first=True, norm_first=not post_ln)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


def sinusoidal_embedding(t: torch.Tensor, dim: int, max_period: float = 10000.0) -> torch.Tensor:
    """t: (B,) step indices (any dtype) -> (B, dim) float32 sin/cos features (Vaswani et al. §3.5)."""
    half = dim // 2
    freqs = torch.exp(-math.log(max_period) * torch.arange(half, dtype=torch.float32, device=t.device) / half)
    args = t.float()[:, None] * freqs[None]
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
    return torch.nn.functional.pad(emb, (0, dim - 2 * half))


def mlp(d_in: int, d_hidden: int, d_out: int) -> nn.Sequential:
    """Linear -> SiLU -> Linear."""
    return nn.Sequential(nn.Linear(d_in, d_hidden), nn.SiLU(), nn.Linear(d_hidden, d_out))
