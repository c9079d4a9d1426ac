"""The action encoder (TRUMANS §4.4, Fig. 3c): frame-wise action labels -> one action embedding.

Input: ``(B, L, N_A)`` labels with the progress indicator (``trumans.actions``: 0 off,
``1 + progress`` on). Each frame's label vector is a token (linear projection + learned position
embedding); a transformer encoder runs over the frames, and the LAST token's output goes through
an MLP to the action embedding ``(B, out_dim)``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from trumans.limits import check_transformer

from .blocks import encoder_stack, mlp

__all__ = ["ActionEncoderConfig", "ActionEncoder"]


@dataclass(frozen=True)
class ActionEncoderConfig:
    """num_actions: N_A (vocabulary size); frames: L; transformer sizes."""

    num_actions: int
    frames: int = 16
    d_model: int = 512
    layers: int = 6
    heads: int = 16
    ff: int = 1024
    dropout: float = 0.1

    def __post_init__(self) -> None:
        if self.num_actions < 1 or self.frames < 1:
            raise ValueError(f"num_actions and frames must be >= 1, got {self.num_actions}, {self.frames}")
        check_transformer(self.d_model, self.layers, self.heads, self.ff, "the action encoder")

    def to_dict(self) -> dict:
        return asdict(self)


class ActionEncoder(nn.Module):
    """(B, L, N_A) float labels -> (B, out_dim) action embedding."""

    def __init__(self, config: ActionEncoderConfig, out_dim: int) -> None:
        super().__init__()
        self.config = c = config
        self.to_tokens = nn.Linear(c.num_actions, c.d_model)
        self.pos = nn.Parameter(torch.randn(1, c.frames, c.d_model) * 0.02)
        self.encoder = encoder_stack(c.d_model, c.layers, c.heads, c.ff, c.dropout)
        self.head = mlp(c.d_model, c.d_model, out_dim)

    def forward(self, actions: torch.Tensor) -> torch.Tensor:
        c = self.config
        if actions.dim() != 3 or tuple(actions.shape[1:]) != (c.frames, c.num_actions):
            raise ValueError(f"actions must be (B, {c.frames}, {c.num_actions}), got {tuple(actions.shape)}")
        x = self.to_tokens(actions.float()) + self.pos
        return self.head(self.encoder(x)[:, -1])
