"""The local scene perceiver (TRUMANS §4.3, Fig. 3d): a ViT over a local occupancy grid.

Input: ``(B, n, n, n)`` bool local grids, axes (forward, left, up), True = occupied (from
``trumans.scenes.local_grid.local_grids``). The up axis becomes image channels (one per height slice),
the ground plane is cut into ``patch x patch`` patches (Dosovitskiy et al. 2021), a class token
plus learned position embeddings go through a transformer encoder, and the class token's output
is projected to one scene embedding ``(B, out_dim)``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from einops import rearrange
from torch import nn

from trumans.limits import check_grid, check_transformer

from .blocks import encoder_stack

__all__ = ["ScenePerceiverConfig", "ScenePerceiver"]


@dataclass(frozen=True)
class ScenePerceiverConfig:
    """grid: n voxels per side; patch: ground-plane patch size (divides n); transformer sizes."""

    grid: int = 32
    patch: int = 8
    d_model: int = 512
    layers: int = 6
    heads: int = 16
    ff: int = 1024
    dropout: float = 0.1

    def __post_init__(self) -> None:
        check_grid(self.grid)
        check_transformer(self.d_model, self.layers, self.heads, self.ff, "the scene perceiver")
        if self.grid < 1 or self.patch < 1 or self.grid % self.patch:
            raise ValueError(f"patch ({self.patch}) must divide grid ({self.grid})")

    def to_dict(self) -> dict:
        return asdict(self)


class ScenePerceiver(nn.Module):
    """(B, n, n, n) bool local grid -> (B, out_dim) scene embedding."""

    def __init__(self, config: ScenePerceiverConfig, out_dim: int) -> None:
        super().__init__()
        self.config = c = config
        num_patches = (c.grid // c.patch) ** 2
        self.to_tokens = nn.Linear(c.patch * c.patch * c.grid, c.d_model)
        self.cls = nn.Parameter(torch.zeros(1, 1, c.d_model))
        self.pos = nn.Parameter(torch.randn(1, num_patches + 1, c.d_model) * 0.02)
        self.encoder = encoder_stack(c.d_model, c.layers, c.heads, c.ff, c.dropout, post_ln=False)
        self.head = nn.Sequential(nn.LayerNorm(c.d_model), nn.Linear(c.d_model, out_dim))

    def forward(self, grid: torch.Tensor) -> torch.Tensor:
        n = self.config.grid
        if grid.dim() != 4 or tuple(grid.shape[1:]) != (n, n, n):
            raise ValueError(f"scene grid must be (B, {n}, {n}, {n}) (forward, left, up), got {tuple(grid.shape)}")
        img = rearrange(grid.float(), "b x y z -> b z x y")  # height slices as channels
        p = self.config.patch
        tokens = rearrange(img, "b c (h p1) (w p2) -> b (h w) (p1 p2 c)", p1=p, p2=p)
        x = self.to_tokens(tokens * 2.0 - 1.0)  # occupied +1, free -1
        x = torch.cat([self.cls.expand(len(x), -1, -1), x], dim=1) + self.pos
        return self.head(self.encoder(x)[:, 0])
