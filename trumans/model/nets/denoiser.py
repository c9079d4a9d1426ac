"""The motion denoiser (TRUMANS §4.2, Fig. 3b; appendix A.2): a post-LN transformer encoder.

Tokens: first the *condition token* = diffusion-step embedding + scene embedding (``ScenePerceiver``)
+ action embedding (``ActionEncoder``) (TRUMANS: "embeddings are added to the first token ... which
contains timestep information"), then one token per frame: a linear projection of the frame's
noisy features concatenated with the frame's inpainting mask (so the network knows which entries
are given, which the authors' code did not do), plus an optional per-frame condition (the HOI
filter's tracked input). The frame tokens' outputs are projected back to the features: the
predicted noise ε̂ (B, L, F).

Classifier-free guidance (Ho & Salimans 2022): each condition can be replaced by a learned null
embedding (``drop_scene`` / ``drop_action`` per sample, or by passing ``None``);
``GuidedDenoiser`` combines the conditional and unconditional predictions with separate scales.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import torch
from torch import nn

from trumans.model.episodes import FeatureLayout
from .action_encoder import ActionEncoder, ActionEncoderConfig
from .blocks import encoder_stack, mlp, sinusoidal_embedding
from .vit import ScenePerceiver, ScenePerceiverConfig

__all__ = ["DenoiserConfig", "Denoiser", "GuidedDenoiser"]


@dataclass(frozen=True)
class DenoiserConfig:
    """layout: per-frame feature layout (+ ``extra_features`` appended, e.g. object pose);
    frames: L; transformer sizes; mask_input: feed the given-entry mask; frame_cond_dim: width of a
    per-frame condition (0 = none); num_categories: object categories embedded into the first token
    (the HOI filter's filter mode; 0 = none); scene / action: encoder configs (None = that condition is off)."""

    layout: FeatureLayout = field(default_factory=FeatureLayout)
    extra_features: int = 0
    frames: int = 16
    d_model: int = 512
    layers: int = 8
    heads: int = 16
    ff: int = 1024
    dropout: float = 0.1
    mask_input: bool = True
    frame_cond_dim: int = 0
    num_categories: int = 0
    scene: ScenePerceiverConfig | None = None
    action: ActionEncoderConfig | None = None

    def __post_init__(self) -> None:
        if self.frames < 1 or self.extra_features < 0 or self.frame_cond_dim < 0 or self.num_categories < 0:
            raise ValueError("frames must be >= 1, extra_features, frame_cond_dim and num_categories >= 0")
        if self.action is not None and self.action.frames != self.frames:
            raise ValueError(f"action.frames ({self.action.frames}) must equal frames ({self.frames})")

    @property
    def feature_dim(self) -> int:
        return self.layout.dim + self.extra_features

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "DenoiserConfig":
        """Inverse of ``to_dict``; unknown keys are errors."""
        d = dict(d)
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown denoiser config keys {sorted(unknown)}; known: {sorted(known)}")
        d["layout"] = FeatureLayout(**d.get("layout", {}))
        if d.get("scene") is not None:
            d["scene"] = ScenePerceiverConfig(**d["scene"])
        if d.get("action") is not None:
            d["action"] = ActionEncoderConfig(**d["action"])
        return cls(**d)


class Denoiser(nn.Module):
    """model(x_t, t, mask=..., scene=..., actions=..., frame_cond=...) -> ε̂; shapes in ``forward``."""

    def __init__(self, config: DenoiserConfig) -> None:
        super().__init__()
        self.config = c = config
        F = c.feature_dim
        self.in_proj = nn.Linear(2 * F if c.mask_input else F, c.d_model)
        self.cond_proj = nn.Linear(c.frame_cond_dim, c.d_model) if c.frame_cond_dim else None
        self.step_embed = mlp(c.d_model, c.d_model, c.d_model)
        self.pos = nn.Parameter(torch.randn(1, c.frames + 1, c.d_model) * 0.02)
        self.scene_encoder = ScenePerceiver(c.scene, c.d_model) if c.scene is not None else None
        self.action_encoder = ActionEncoder(c.action, c.d_model) if c.action is not None else None
        self.null_scene = nn.Parameter(torch.zeros(c.d_model)) if c.scene is not None else None
        self.null_action = nn.Parameter(torch.zeros(c.d_model)) if c.action is not None else None
        self.category_embed = nn.Embedding(c.num_categories, c.d_model) if c.num_categories else None
        self.encoder = encoder_stack(c.d_model, c.layers, c.heads, c.ff, c.dropout, post_ln=True)
        self.out_proj = nn.Linear(c.d_model, F)

    def _condition(self, name: str, encoder, null, value, drop, B: int) -> torch.Tensor | None:
        if encoder is None:
            if value is not None:
                raise ValueError(f"this model has no {name} condition (its config has {name}=None); do not pass {name}")
            return None
        if value is None:
            return null.expand(B, -1)
        emb = encoder(value)
        if drop is not None:
            emb = torch.where(drop.to(emb.device).reshape(B, 1), null.expand(B, -1), emb)
        return emb

    def forward(
        self,
        x: torch.Tensor,
        t: torch.Tensor,
        *,
        mask: torch.Tensor | None = None,
        scene: torch.Tensor | None = None,
        actions: torch.Tensor | None = None,
        frame_cond: torch.Tensor | None = None,
        category: torch.Tensor | None = None,
        drop_scene: torch.Tensor | None = None,
        drop_action: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """x: (B, L, F) noisy normalised features; t: (B,) int diffusion steps; mask: (B, L, F)
        bool, True = given; scene: (B, n, n, n) bool local grid; actions: (B, L, N_A) labels;
        frame_cond: (B, L, C); category: (B,) int64 object category indices (filter mode);
        drop_*: (B,) bool, True = use the null embedding. -> ε̂ (B, L, F)."""
        c = self.config
        if x.dim() != 3 or tuple(x.shape[1:]) != (c.frames, c.feature_dim):
            raise ValueError(f"x must be (B, {c.frames}, {c.feature_dim}), got {tuple(x.shape)}")
        B = x.shape[0]
        h = x
        if c.mask_input:
            m = torch.zeros_like(x) if mask is None else mask.expand_as(x).to(x.dtype)
            h = torch.cat([x, m], dim=-1)
        h = self.in_proj(h)  # (B, L, d)
        if self.cond_proj is not None:
            if frame_cond is None or tuple(frame_cond.shape) != (B, c.frames, c.frame_cond_dim):
                raise ValueError(f"frame_cond must be (B, {c.frames}, {c.frame_cond_dim}), got "
                                 f"{None if frame_cond is None else tuple(frame_cond.shape)}")
            h = h + self.cond_proj(frame_cond)
        elif frame_cond is not None:
            raise ValueError("this model takes no frame_cond (frame_cond_dim = 0)")
        first = self.step_embed(sinusoidal_embedding(t.reshape(-1).expand(B), c.d_model))  # (B, d)
        for emb in (self._condition("scene", self.scene_encoder, self.null_scene, scene, drop_scene, B),
                    self._condition("actions", self.action_encoder, self.null_action, actions, drop_action, B)):
            if emb is not None:
                first = first + emb
        if self.category_embed is not None:  # I'm-HOI filter: the object category enters the first token
            if category is None or tuple(category.shape) != (B,):
                raise ValueError(f"category must be (B,) = ({B},) int64 indices, got "
                                 f"{None if category is None else tuple(category.shape)}")
            if category.min() < 0 or category.max() >= c.num_categories:
                raise ValueError(f"category indices must be in [0, {c.num_categories}), got {category.tolist()}")
            first = first + self.category_embed(category.to(first.device))
        elif category is not None:
            raise ValueError("this model takes no category (num_categories = 0)")
        tokens = torch.cat([first[:, None], h], dim=1) + self.pos  # (B, 1 + L, d)
        return self.out_proj(self.encoder(tokens)[:, 1:])


class GuidedDenoiser(nn.Module):
    """Classifier-free guidance with separate scales (compositional form, Liu et al. 2022):
    ε = ε(∅,∅) + s_scene (ε(S,∅) - ε(∅,∅)) + s_action (ε(S,A) - ε(S,∅)).
    Scales 1, 1 give the plain conditional prediction in one pass."""

    def __init__(self, model: Denoiser, scene_scale: float = 1.0, action_scale: float = 1.0) -> None:
        super().__init__()
        self.model, self.scene_scale, self.action_scale = model, float(scene_scale), float(action_scale)

    def forward(self, x: torch.Tensor, t: torch.Tensor, *, mask=None, scene=None, actions=None, frame_cond=None) -> torch.Tensor:
        if self.scene_scale == 1.0 and self.action_scale == 1.0:
            return self.model(x, t, mask=mask, scene=scene, actions=actions, frame_cond=frame_cond)
        B = x.shape[0]

        def rep(v):
            return None if v is None else torch.cat([v] * 3)

        ones, zeros = torch.ones(B, dtype=torch.bool), torch.zeros(B, dtype=torch.bool)
        drop_s = torch.cat([ones, zeros, zeros]) if scene is not None else None
        drop_a = torch.cat([ones, ones, zeros]) if actions is not None else None
        eps = self.model(rep(x), rep(t.reshape(-1).expand(B)), mask=rep(None if mask is None else mask.expand_as(x)),
                         scene=rep(scene), actions=rep(actions), frame_cond=rep(frame_cond),
                         drop_scene=drop_s, drop_action=drop_a)
        e00, es0, esa = eps.chunk(3)
        return e00 + self.scene_scale * (es0 - e00) + self.action_scale * (esa - es0)
