"""Autoregressive episode sampling (TRUMANS §4.1-4.2, appendix A.1).

Each episode of ``L`` frames is generated in the canonical frame of its first frame; its first
``k`` frames are the last ``k`` frames of the motion so far (``M_trans``) and its goal is the
pelvis xy at the last frame or a hand joint's 3D position (``M_goal``). The scene condition is the
local occupancy grid around the subgoal with the dynamic objects where they are now, the action
condition the frame-wise labels with the progress indicator; both are encoded once per episode
and reused by every denoising step. With ``goal_guidance`` > 0 every step is also steered by the
configured guidance terms (``trumans.sample.guidance``: goal, seat, penetration). ``episode``
returns the network's output; the corrections after it (pinned pelvis, seam, bone projection,
support lift, push-outs, feet, reach) are ``trumans.sample.cleanup.pipeline``, run by the rollout;
rotations for export are fitted afterwards (``trumans.ik.fit``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np
import torch

from trumans.scenes.scene_grids import SceneGrids
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import respaced_timesteps
from trumans.model.conditions import EpisodeCondition, episode_condition, episode_scene_grids, subgoal_to_canonical
from trumans.model.episodes import PELVIS, FeatureLayout, canonicalize, uncanonicalize
from trumans.model.masks import joint_goal_mask, pelvis_goal_mask, transition_mask
from trumans.model.nets import GuidedDenoiser
from trumans.skeleton import NUM_JOINTS

from trumans.sample.cleanup.bones import bone_lengths_of, project_bones
from trumans.sample.cleanup.pipeline import CleanupConfig
from trumans.sample.config_data import config_from_dict
from trumans.sample.guidance import GuidanceConfig, GuidanceInputs, GuidanceTerm, Prediction, build_terms
from trumans.sample.guidance.base import canonical_to_world
from trumans.sample.guidance.goal import GoalTermConfig
from trumans.sample.episode_goal import Goal
from trumans.scenes.sdf import SceneSDF

__all__ = ["SamplerConfig", "QUALITY_SCHEDULE", "Goal", "EpisodeSampler", "project_bones", "bone_lengths_of"]


@dataclass(frozen=True)
class SamplerConfig:
    """How ``trumans sample`` samples: the defaults here are the command's defaults.

    steps: denoising steps (respaced DDIM when < T); eta: DDIM noise (0 = deterministic);
    scene_scale / action_scale: classifier-free guidance scales (1 = plain conditional). Action
    guidance 2 raised action accuracy 0.78 -> 0.85 and lowered fid_matched 21.8 -> 18.5 on 5 plan
    seeds, at ~1.5x the sampling time and rougher seams (jerk ratio 1.24 -> 1.46; docs/sampling_log.md);
    naive: recompute the condition embeddings at every step (the reference sampler);
    goal_guidance: step size of the spatial guidance (0 = inpainting only, no guidance term runs;
    ``EpisodeSampler._guided_sample``); goal_iters: guidance updates per step, each a backward pass;
    guided_steps: guide only the last N denoising steps (0 = every step); the earlier ones are plain
    DDIM steps, one forward pass each (benchmarks/sampling_speed.py and docs/results.md weigh it);
    guidance_space: 'xt' (the gradient of the costs through the network, w.r.t. x_t: one backward
    pass per update) or 'x0' (the costs' gradient w.r.t. the predicted x0 itself, no backward pass
    through the network: one forward per step, ``goal_iters`` cheap updates of size
    ``goal_guidance * x0_guidance`` on x0 before the DDIM step).
    The default schedule (8 steps, the last 4 guided, 2 updates of size 45 each, with episodes
    overlapping by 5 frames: 12 network passes an episode, 7 of them backward, at 1.52x the
    episodes) makes motion at 0.85x the real-time factor of the earlier 10 steps / 5 guided without
    overlap (measured alternately: 7.6 / 8.5x against 9.0 / 9.7x real time), which was ~4x cheaper
    than 20 steps x 3 updates of size 20 every step (``QUALITY_SCHEDULE``; docs/results.md,
    "Sampling speed"); guiding only the last 3 of 10 steps was ~1.5x faster again but left bodies short of
    the 1 m gap of the safety benchmark's partition room (8 of 12 runs never finished their plan);
    guidance: the guidance terms (goal, seat, penetration; ``trumans.sample.guidance.terms``);
    cleanup: the steps after the network, in their order (``trumans.sample.cleanup.pipeline``);
    overlap: the last ``overlap`` new frames of every episode but the plan's last are not committed:
    the next episode makes them again, following them while it denoises and keeping their goals
    (``trumans.sample.rollout``, issue 35: the seams). 0 commits every new frame; 5 (the default)
    brings the folded seam peak from ~1.7 to ~1.2 and is no worse on any quality figure of 5 plan
    seeds, at 0.85x the speed (docs/results.md, "The default sampler since 2026-11-29").
    ``to_dict`` / ``from_dict`` give and take the whole config as plain data (unknown keys are
    errors); ``trumans sample`` saves it with every sequence (``extra/sampler_config``)."""

    steps: int = 8
    eta: float = 0.0
    scene_scale: float = 1.0
    action_scale: float = 2.0
    naive: bool = False
    goal_guidance: float = 45.0
    goal_iters: int = 2
    guided_steps: int = 4
    guidance_space: Literal["xt", "x0"] = "xt"
    x0_guidance: float = 1.0
    guidance: GuidanceConfig = field(default_factory=GuidanceConfig)
    cleanup: CleanupConfig = field(default_factory=CleanupConfig)
    overlap: int = 5

    def __post_init__(self) -> None:
        if self.overlap < 0:
            raise ValueError(f"overlap must be >= 0 frames (0 = none), got {self.overlap}")
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")
        if not self.eta >= 0:
            raise ValueError(f"eta must be >= 0, got {self.eta}")
        if self.goal_iters < 1:
            raise ValueError(f"goal_iters must be >= 1, got {self.goal_iters}")
        if self.guidance_space not in ("xt", "x0"):
            raise ValueError(f"guidance_space must be 'xt' or 'x0', got {self.guidance_space!r}")
        if not (np.isfinite(self.x0_guidance) and self.x0_guidance >= 0):
            raise ValueError(f"x0_guidance must be a finite number >= 0, got {self.x0_guidance}")
        if self.guided_steps < 0:
            raise ValueError(f"guided_steps must be >= 0 (0 = every step), got {self.guided_steps}")
        for name in ("scene_scale", "action_scale", "goal_guidance"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")

    def to_dict(self) -> dict:
        """Plain nested data (JSON-ready) of every field."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, where: str = "sampler config") -> SamplerConfig:
        """Inverse of ``to_dict``; keys left out keep their defaults, unknown keys and wrong types
        are errors naming the key (``trumans.sample.config_data.config_from_dict``)."""
        return config_from_dict(cls, d, where)


# ``SamplerConfig(**QUALITY_SCHEDULE)``: the default until the speed issue (38), 20 steps, every one guided by
# 3 updates of size 20, heading weight 3 (~4x slower; a little closer to the goals: docs/results.md, "Sampling speed")
QUALITY_SCHEDULE: dict = {"steps": 20, "goal_guidance": 20.0, "goal_iters": 3, "guided_steps": 0,
                          "guidance": GuidanceConfig(goal=GoalTermConfig(heading_weight=3.0))}


class EpisodeSampler:
    """One episode at a time for a batch of B variations; see the module doc.

    ckpt: a generator checkpoint; grids: the scene's ``SceneGrids`` (None = open floor)."""

    def __init__(self, ckpt: Checkpoint, grids: SceneGrids | None, config: SamplerConfig = SamplerConfig(),
                 device: str = "cpu") -> None:
        self.ckpt, self.grids, self.config, self.device = ckpt, grids, config, torch.device(device)
        self.model = ckpt.build_model().to(self.device)
        self.diffusion = ckpt.build_diffusion().to(self.device)
        if config.steps > self.diffusion.steps:
            raise ValueError(f"steps must be <= the model's {self.diffusion.steps} diffusion steps, got {config.steps}")
        self.layout: FeatureLayout = ckpt.model_config.layout
        self.L, self.k = ckpt.L_epi, ckpt.k
        self.norm = ckpt.normalizer
        self.n = int(ckpt.grid.get("n", 32))
        self.extent = tuple(ckpt.grid.get("extent", (1.2, 1.2, 1.2)))
        self.guided = GuidedDenoiser(self.model, config.scene_scale, config.action_scale)
        self.hip_width = 0.12  # m, the start pose's hip line length (set by the rollout for its body)
        guide_sdf = config.guidance.penetration.enabled and config.goal_guidance > 0
        # the scene's signed distance: for the penetration guidance and the cleanup (trumans.sample.rollout)
        cleanup_sdf = config.cleanup.uses_scene
        self.scene_sdf = SceneSDF(grids.static) if grids is not None and (guide_sdf or cleanup_sdf) else None
        self.sdf = self.scene_sdf if guide_sdf else None
        # with the dynamic objects (chairs, stools, doors) at their scene poses: the cleanup's field
        # while the plan has moved none of them (``trumans.sample.rollout``)
        full = getattr(grids, "occ", None) if grids is not None and getattr(grids, "points", None) else None
        self.scene_sdf_all = SceneSDF(full) if cleanup_sdf and full is not None else self.scene_sdf
        if cleanup_sdf:  # the cleanup reads the enclosed fields and their gradients: built with the scene, not in
            for field_ in {id(f): f for f in (self.scene_sdf, self.scene_sdf_all) if f is not None}.values():
                field_.enclosed().gradient_volume()  # an episode's time (``seconds_per_episode``)

    # ------------------------------------------------------------------ one episode
    def condition(self, context: np.ndarray, labels: np.ndarray, goals: list[Goal]) -> EpisodeCondition:
        """The episode's frame, subgoal and labels by the training definition (``episode_condition``):
        the subgoal is the pelvis goal, or where the body stands now for a hand goal."""
        sub = np.zeros((len(goals), 3))
        for b, g in enumerate(goals):
            sub[b, :2] = g.point[:2] if g.joint == "pelvis" else context[b, -1, PELVIS, :2]
        # a model trained without the progress indicator (the §5 ablation) gets plain 0/1 labels, as in training
        progress = bool(self.ckpt.extra.get("progress_indicator", True))
        return episode_condition(context, labels, subgoal=sub, progress_indicator=progress)

    def _given(self, context: np.ndarray, cond: EpisodeCondition, goals: list[Goal]):
        """Normalised given values and the mask, both (B, L, F): M_trans (the context frames) and
        M_goal (pelvis x, y at the last frame, or a joint's 3D position at its frame)."""
        B, L, lay = context.shape[0], self.L, self.layout
        feats = np.zeros((B, L, lay.dim), np.float32)
        feats[:, : self.k, : NUM_JOINTS * 3] = canonicalize(context, cond.origin, cond.yaw).reshape(B, self.k, -1)
        masks = []
        for b, g in enumerate(goals):
            m = transition_mask(L, lay, self.k)
            if g.joint == "pelvis":
                local = cond.subgoal_canonical()[b]
                feats[b, L - 1, lay.position_index(PELVIS, (0, 1))] = local[:2]
                m = m | pelvis_goal_mask(L, lay)
            else:
                local = subgoal_to_canonical(np.asarray(g.point, np.float64), cond.origin[b], cond.yaw[b])
                frame = g.frame % L
                feats[b, frame, lay.position_index(g.joint)] = local
                m = m | joint_goal_mask(L, lay, g.joint, frame)
            masks.append(m)
        x = torch.from_numpy(self.norm.normalize(feats)).to(self.device)
        return x, torch.stack(masks).to(self.device)

    @torch.no_grad()
    def episode(self, context: np.ndarray, labels: np.ndarray, goals: list[Goal],
                object_poses: dict | None = None, generator: torch.Generator | None = None,
                lead: np.ndarray | None = None, lead_weight: np.ndarray | None = None,
                carried: tuple[tuple[Goal, ...], ...] = ()) -> np.ndarray:
        """context: (B, k, 24, 3) world m, the last k frames so far; labels: (B, L, N_A) action
        labels; goals: one ``Goal`` per sample -> (B, L, 24, 3) float32 world joints (first k =
        context): the network's output, before the cleanup (``trumans.sample.cleanup.pipeline``).
        lead (B, D, 24, 3) world m, lead_weight (D,) in [0, 1]: frames the first D new frames should
        follow (the previous episode's uncommitted end, ``SamplerConfig.overlap``); after every
        denoising step x0's lead joints move that share of the way to them (``_follow_lead``);
        carried: per sample, the earlier episode's goals due in this episode's frames (guided only,
        ``GuidanceInputs.carried``)."""
        B = context.shape[0]
        if context.ndim != 4 or context.shape[1:] != (self.k, NUM_JOINTS, 3):
            raise ValueError(f"context must be (B, {self.k}, 24, 3), got {context.shape}")
        if len(goals) != B or labels.shape[:2] != (B, self.L):
            raise ValueError(f"need {B} goals and labels (B, {self.L}, N_A), got {len(goals)} and {labels.shape}")
        cond = self.condition(context, labels, goals)
        x_given, mask = self._given(context, cond, goals)
        follow = None if lead is None else self._lead(lead, lead_weight, cond)
        if self.grids is None:
            grid = np.zeros((B, self.n, self.n, self.n), dtype=bool)
        else:
            grid = episode_scene_grids(self.grids, cond, object_poses, n=self.n, extent=self.extent)
        scene = torch.from_numpy(grid).to(self.device)
        acts = torch.as_tensor(cond.actions, dtype=torch.float32, device=self.device)
        emb = self._conditions(scene, acts)
        if self.config.goal_guidance > 0 or follow is not None:
            terms = self._terms(cond, goals, carried) if self.config.goal_guidance > 0 else []
            x0 = self._guided_sample(self._model_fn(emb), mask, x_given, terms, generator, cond, follow)
        else:
            x0 = self.diffusion.sample(self._model_fn(emb), (B, self.L, self.layout.dim), mask=mask, given=x_given,
                                       num_steps=self.config.steps, eta=self.config.eta, generator=generator,
                                       device=self.device)
        feats = self.norm.denormalize(x0.cpu().numpy())
        cj, _ = self.layout.unpack(feats)
        world = uncanonicalize(cj, cond.origin, cond.yaw)
        world[:, : self.k] = context
        return world

    def _lead(self, lead: np.ndarray, weight: np.ndarray, cond: EpisodeCondition) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised lead frames and per-entry weights, both (B, L, F): frames k..k+D-1, joint positions."""
        lead = np.asarray(lead, np.float64)
        B, D = lead.shape[:2]
        if lead.shape != (B, D, NUM_JOINTS, 3) or D > self.L - self.k or B != len(cond.origin):
            raise ValueError(f"lead must be (B={len(cond.origin)}, D <= {self.L - self.k}, 24, 3), got {lead.shape}")
        weight = np.asarray(weight if weight is not None else np.ones(D), np.float32)
        if weight.shape != (D,) or not ((weight >= 0) & (weight <= 1)).all():
            raise ValueError(f"lead_weight must be (D={D},) in [0, 1], got {weight}")
        feats = np.zeros((B, self.L, self.layout.dim), np.float32)
        feats[:, self.k:self.k + D, :NUM_JOINTS * 3] = canonicalize(lead, cond.origin, cond.yaw).reshape(B, D, -1)
        w = np.zeros((B, self.L, self.layout.dim), np.float32)
        w[:, self.k:self.k + D, :NUM_JOINTS * 3] = weight[None, :, None]
        return (torch.from_numpy(self.norm.normalize(feats)).to(self.device), torch.from_numpy(w).to(self.device))

    def _follow_lead(self, x_prev: torch.Tensor, x0_hat: torch.Tensor, t_prev: int,
                     follow: tuple[torch.Tensor, torch.Tensor] | None) -> torch.Tensor:
        """x_{t-1} with x0's lead entries moved w of the way to the lead (DDIM's x_{t-1} =
        sqrt(abar_{t-1}) x0 + c eps, the network's eps kept): replacement inpainting of the overlap
        (as in MDM's in-betweening), so the new frames after it continue the lead's motion."""
        if follow is None:
            return x_prev
        given, w = follow
        ab_prev = float(self.diffusion.alphas_cumprod[t_prev]) if t_prev >= 0 else 1.0
        return x_prev + ab_prev ** 0.5 * w * (given - x0_hat)

    def _terms(self, cond: EpisodeCondition, goals: list[Goal],
               carried: tuple[tuple[Goal, ...], ...] = ()) -> list[GuidanceTerm]:
        """The configured guidance terms (``SamplerConfig.guidance``) that act in this episode."""
        return build_terms(self.config.guidance, GuidanceInputs(cond, tuple(goals), self.layout, self.L, self.k,
                                                                self.hip_width, self.sdf, tuple(carried), self.device))

    def _guided_sample(self, model_fn, mask: torch.Tensor, given: torch.Tensor, terms: list[GuidanceTerm],
                       generator, cond: EpisodeCondition,
                       follow: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """Respaced DDIM (``GaussianDiffusion.step``) with spatial guidance (OmniControl, Xie et al.
        2024, "spatial guidance"): a sparse inpainted goal (2 of L x F entries) is weakly followed, so
        after each step x_{t-1} moves against the gradient of the summed costs (m^2) of the
        guidance ``terms`` on the body's predicted x0: x_{t-1} <- x_{t-1} - s grad_{x_t}, ``goal_iters``
        updates of step size s = ``goal_guidance`` per step. ``follow``: the lead (``_follow_lead``);
        with no ``terms`` no step is guided."""
        d = self.diffusion
        B, L, F = given.shape
        mean = torch.as_tensor(self.norm.mean, dtype=torch.float32, device=self.device)
        std = torch.as_tensor(self.norm.std, dtype=torch.float32, device=self.device)
        x = torch.randn((B, L, F), generator=generator, dtype=torch.float32).to(self.device)
        rotation, origin = (m.to(self.device) for m in canonical_to_world(cond))
        ts = respaced_timesteps(d.steps, self.config.steps).tolist()
        first_guided = len(ts) - self.config.guided_steps if self.config.guided_steps else 0
        if not terms:
            first_guided = len(ts)
        for i, t_i in enumerate(ts):
            x = torch.where(mask, given, x)
            t = torch.full((B,), t_i, dtype=torch.long, device=x.device)
            t_prev = ts[i + 1] if i + 1 < len(ts) else -1
            if i < first_guided:  # an unguided step: the network once, no backward pass
                out = model_fn(x, t, mask=mask)
                x, x0_hat = d.step(out, t, x, t_prev=t_prev, eta=self.config.eta, generator=generator)
                x = self._follow_lead(x, x0_hat, t_prev, follow)
                continue
            if self.config.guidance_space == "x0":
                x = self._x0_guided_step(model_fn, x, t, mask, terms, mean, std, rotation, origin,
                                         t_prev, generator, follow)
                continue
            grad = torch.zeros_like(x)
            last = i + 1 == len(ts)
            with torch.enable_grad():
                for it in range(self.config.goal_iters):
                    xg = (x - grad).detach().requires_grad_(True)
                    if last and it + 1 == self.config.goal_iters:  # its gradient would move nothing: the
                        with torch.no_grad():  # last step's x0 comes from this prediction, no x - grad follows
                            out = model_fn(xg, t, mask=mask)
                        break
                    out = model_fn(xg, t, mask=mask)
                    x0_hat, _ = d.x0_and_eps(out, t, xg)
                    prediction = Prediction(x0_hat, mean, std, self.k, rotation, origin)
                    loss = xg.new_zeros(())
                    for term in terms:
                        loss = loss + term.loss(prediction)
                    g, = torch.autograd.grad(loss, xg, allow_unused=True) if loss.requires_grad else (None,)
                    if g is None:
                        break
                    grad = grad + self.config.goal_guidance * g
            x, x0_hat = d.step(out.detach(), t, xg.detach(), t_prev=t_prev, eta=self.config.eta, generator=generator)
            x = self._follow_lead(x, x0_hat, t_prev, follow)
            if i + 1 < len(ts):
                x = x - grad
        return torch.where(mask, given, x)

    def _x0_guided_step(self, model_fn, x: torch.Tensor, t: torch.Tensor, mask: torch.Tensor,
                        terms: list[GuidanceTerm], mean, std, rotation, origin, t_prev: int, generator,
                        follow: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """One DDIM step guided in x0 space: the network once (no gradient), then ``goal_iters``
        updates x0 <- x0 - s grad_x0(sum of the terms' costs) with s = goal_guidance * x0_guidance, then
        the DDIM step from the updated x0 (its epsilon recomputed from x_t, DDIM eq. 12)."""
        d = self.diffusion
        out = model_fn(x, t, mask=mask)
        x0, _ = d.x0_and_eps(out, t, x)
        step = self.config.goal_guidance * self.config.x0_guidance
        with torch.enable_grad():
            for _ in range(self.config.goal_iters):
                x0g = x0.detach().requires_grad_(True)
                prediction = Prediction(x0g, mean, std, self.k, rotation, origin)
                loss = x0g.new_zeros(())
                for term in terms:
                    loss = loss + term.loss(prediction)
                if not loss.requires_grad:
                    break
                g, = torch.autograd.grad(loss, x0g, allow_unused=True)
                if g is None:
                    break
                x0 = x0.detach() - step * g
        eps = d.predict_eps(x, t, x0)
        x_prev, x0_hat = d.step(d.target(x0, eps, t), t, x, t_prev=t_prev, eta=self.config.eta, generator=generator)
        return self._follow_lead(x_prev, x0_hat, t_prev, follow)

    def _conditions(self, scene: torch.Tensor, actions: torch.Tensor) -> dict:
        """Condition embeddings once per episode (or the raw conditions for the naive sampler)."""
        if self.config.naive:
            return {"scene": scene, "actions": actions}
        return {"cond_emb": self.guided.encode_conditions(scene=scene, actions=actions)}

    def _model_fn(self, cond: dict):
        guided = self.guided

        def fn(x, t, mask=None):
            return guided(x, t, mask=mask, **cond)
        return fn

