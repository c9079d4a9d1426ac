"""The motion denoiser (TRUMANS §4.2, Fig. 3b; appendix A.2): a post-LN transformer encoder.

Tokens: first the *condition token* = diffusion-step embedding + scene embedding (``ScenePerceiver``)
+ action embedding (``ActionEncoder``) (TRUMANS: "embeddings are added to the first token ... which
contains timestep information"), then one token per frame: a linear projection of the frame's
noisy features concatenated with the frame's inpainting mask (so the network knows which entries
are given, which the authors' code did not do), plus an optional per-frame condition (the HOI
filter's tracked input; ``in_proj(x) + cond_proj(c)`` is one linear map of the concatenation [x, c]).
In filter mode (``num_categories > 0``, I'm-HOI §3.2) an object-category embedding is added to the
first token as well. The frame tokens' outputs are projected back to the features: the
prediction (B, L, F) of the diffusion config's type (ε̂, x̂0 or v̂).

The condition encoders are separate from the per-step network: ``encode_conditions`` gives the
(B, d_model) condition embedding once per episode, and ``forward(..., cond_emb=...)`` takes it
instead of the raw conditions (same result), so a sampler does not rerun them at every step.

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
from trumans.limits import check_transformer

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
        check_transformer(self.d_model, self.layers, self.heads, self.ff, "the denoiser")

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


def _batch_size(scene: torch.Tensor | None, actions: torch.Tensor | None, batch: int | None) -> int:
    sizes = {len(v) for v in (scene, actions) if v is not None}
    if len(sizes) > 1:
        raise ValueError(f"scene and actions must have the same batch size, got {sorted(sizes)}")
    if sizes:
        return sizes.pop()
    if batch is None:
        raise ValueError("encoding conditions needs scene, actions or batch= to know the batch size")
    return batch


class Denoiser(nn.Module):
    """model(x_t, t, mask=..., scene=... | cond_emb=..., actions=..., frame_cond=...) -> prediction;
    shapes in ``forward``."""

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

    def condition_embedding(self, name: str, value: torch.Tensor | None, drop: torch.Tensor | None,
                            batch: int) -> torch.Tensor | None:
        """One condition's (batch, d_model) embedding: the encoder's output, or the learned null
        embedding where ``value`` is None or ``drop`` (B,) is True; None if the model lacks it."""
        if name not in ("scene", "actions"):
            raise ValueError(f"condition name must be 'scene' or 'actions', got {name!r}")
        encoder, null = ((self.scene_encoder, self.null_scene) if name == "scene"
                         else (self.action_encoder, self.null_action))
        if encoder is None:
            if value is not None:
                raise ValueError(f"this model has no {name} condition (its config has {name}=None); do not pass {name}")
            return None
        if value is None:
            return null.expand(batch, -1)
        emb = encoder(value)
        if drop is not None:
            emb = torch.where(drop.to(emb.device).reshape(-1, 1), null.expand(len(emb), -1), emb)
        return emb

    def encode_conditions(
        self,
        *,
        scene: torch.Tensor | None = None,
        actions: torch.Tensor | None = None,
        drop_scene: torch.Tensor | None = None,
        drop_action: torch.Tensor | None = None,
        batch: int | None = None,
    ) -> torch.Tensor:
        """The condition embedding added to the first token: (B, d_model) = scene + action embedding
        (null embeddings where absent or dropped; zeros if the model has no condition encoder).
        Compute it once per episode and pass it to every step as ``forward(..., cond_emb=...)``.
        scene: (B, n, n, n) bool; actions: (B, L, N_A); drop_*: (B,) bool; batch: B when neither
        scene nor actions is given."""
        B = _batch_size(scene, actions, batch)
        return self.sum_embeddings(self.condition_embedding("scene", scene, drop_scene, B),
                                   self.condition_embedding("actions", actions, drop_action, B), batch=B)

    def sum_embeddings(self, *parts: torch.Tensor | None, batch: int) -> torch.Tensor:
        """The sum of the (B, d_model) condition embeddings that are not None, in order (zeros if none)."""
        present = [p for p in parts if p is not None]
        if not present:
            return self.pos.new_zeros(batch, self.config.d_model)
        emb = present[0]
        for p in present[1:]:
            emb = emb + p
        return emb

    def category_embedding(self, category: torch.Tensor | None, batch: int) -> torch.Tensor:
        """(B, d_model) embeddings of the object categories (B,) int64 (filter mode)."""
        n = self.config.num_categories
        if category is None or tuple(category.shape) != (batch,):
            raise ValueError(f"category must be (B,) = ({batch},) int64 indices, got "
                             f"{None if category is None else tuple(category.shape)}")
        if bool((category < 0).any() or (category >= n).any()):
            raise ValueError(f"category indices must be in [0, {n}), got {category.tolist()}")
        return self.category_embed(category.to(self.pos.device))

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
        cond_emb: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """x: (B, L, F) noisy normalised features; t: (B,) or scalar int diffusion steps; mask:
        (B, L, F) bool, True = given; scene: (B, n, n, n) bool local grid; actions: (B, L, N_A)
        labels; frame_cond: (B, L, C); category: (B,) int64 object category indices (filter mode);
        drop_*: (B,) bool, True = use the null embedding;
        cond_emb: (B, d_model) from ``encode_conditions`` INSTEAD of scene / actions / drop_*
        (same result). -> the prediction (ε̂, x̂0 or v̂ per the diffusion config) (B, L, F)."""
        c = self.config
        if x.dim() != 3 or tuple(x.shape[1:]) != (c.frames, c.feature_dim):
            raise ValueError(f"x must be (B, {c.frames}, {c.feature_dim}), got {tuple(x.shape)}")
        B = x.shape[0]
        if cond_emb is None:
            cond_emb = self.encode_conditions(scene=scene, actions=actions, drop_scene=drop_scene,
                                              drop_action=drop_action, batch=B)
        elif any(v is not None for v in (scene, actions, drop_scene, drop_action)):
            raise ValueError("pass either cond_emb or the raw conditions (scene, actions, drop_*), not both")
        if tuple(cond_emb.shape) not in ((B, c.d_model), (1, c.d_model)):
            raise ValueError(f"cond_emb must be (B, d_model) = ({B}, {c.d_model}), got {tuple(cond_emb.shape)}; "
                             f"compute it with encode_conditions on the same batch")
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
        t = torch.as_tensor(t, device=x.device).reshape(-1).expand(B)
        first = self.step_embed(sinusoidal_embedding(t, c.d_model)) + cond_emb  # (B, d)
        if self.category_embed is not None:  # I'm-HOI filter: the object category enters the first token
            first = first + self.category_embedding(category, B)
        elif category is not None:
            raise ValueError("this model takes no category (num_categories = 0)")
        tokens = torch.cat([first[:, None], h], dim=1) + self.pos  # (B, 1 + L, d)
        return self.out_proj(self.encoder(tokens)[:, 1:])


class GuidedDenoiser(nn.Module):
    """Classifier-free guidance with separate scales (compositional form, Liu et al. 2022):
    ε = ε(∅,∅) + s_scene (ε(S,∅) - ε(∅,∅)) + s_action (ε(S,A) - ε(S,∅)).
    Scales 1, 1 give the plain conditional prediction in one pass; with s_scene = 1 the (∅,∅) term
    cancels, so two passes [(S,∅); (S,A)] suffice (ε = ε(S,∅) + s_action (ε(S,A) - ε(S,∅)); the
    default action guidance), else three. The combination is linear, so it applies to any
    prediction type (ε, x0, v)."""

    def __init__(self, model: Denoiser, scene_scale: float = 1.0, action_scale: float = 1.0) -> None:
        super().__init__()
        self.model, self.scene_scale, self.action_scale = model, float(scene_scale), float(action_scale)

    @property
    def guided(self) -> bool:
        return not (self.scene_scale == 1.0 and self.action_scale == 1.0)

    @property
    def passes(self) -> int:
        """Network passes per prediction: 1 (not guided), 2 (s_scene = 1) or 3."""
        return 1 if not self.guided else (2 if self.scene_scale == 1.0 else 3)

    def encode_conditions(self, *, scene: torch.Tensor | None = None, actions: torch.Tensor | None = None,
                          batch: int | None = None) -> torch.Tensor:
        """The embeddings ``forward(cond_emb=...)`` takes: (B, d_model) conditional when not guided;
        else (passes·B, d_model) = [(∅,∅);] (S,∅); (S,A) stacked, each encoder run once on B samples."""
        m = self.model
        if not self.guided:
            return m.encode_conditions(scene=scene, actions=actions, batch=batch)
        B = _batch_size(scene, actions, batch)
        s = m.condition_embedding("scene", scene, None, B)
        a = m.condition_embedding("actions", actions, None, B)
        null_a = m.condition_embedding("actions", None, None, B)
        parts = [m.sum_embeddings(s, null_a, batch=B), m.sum_embeddings(s, a, batch=B)]
        if self.passes == 3:
            parts.insert(0, m.sum_embeddings(m.condition_embedding("scene", None, None, B), null_a, batch=B))
        return torch.cat(parts)

    def forward(self, x: torch.Tensor, t: torch.Tensor, *, mask=None, scene=None, actions=None, frame_cond=None,
                cond_emb: torch.Tensor | None = None) -> torch.Tensor:
        """As ``Denoiser.forward``; cond_emb: the output of ``self.encode_conditions`` (instead of scene / actions)."""
        B = x.shape[0]
        if cond_emb is None:
            cond_emb = self.encode_conditions(scene=scene, actions=actions, batch=B)
        elif scene is not None or actions is not None:
            raise ValueError("pass either cond_emb or the raw conditions (scene, actions), not both")
        if not self.guided:
            return self.model(x, t, mask=mask, frame_cond=frame_cond, cond_emb=cond_emb)
        n = self.passes
        if len(cond_emb) != n * B:
            raise ValueError(f"guided cond_emb must be ({n}B, d_model) = ({n * B}, ...) from GuidedDenoiser.encode_conditions, "
                             f"got {tuple(cond_emb.shape)}")

        def rep(v):
            return None if v is None else torch.cat([v] * n)

        t = torch.as_tensor(t, device=x.device).reshape(-1).expand(B)
        out = self.model(rep(x), rep(t), mask=rep(None if mask is None else mask.expand_as(x)),
                         frame_cond=rep(frame_cond), cond_emb=cond_emb)
        if n == 2:
            es0, esa = out.chunk(2)
            return es0 + self.action_scale * (esa - es0)
        e00, es0, esa = out.chunk(3)
        return e00 + self.scene_scale * (es0 - e00) + self.action_scale * (esa - es0)
