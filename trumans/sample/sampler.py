"""Autoregressive episode sampling (TRUMANS §4.1-4.2, appendix A.1).

Each episode of ``L`` frames is generated in the canonical frame of its first frame; its first
``k`` frames are the last ``k`` frames of the motion so far (``M_trans``) and its goal is the
pelvis xy at the last frame or a hand joint's 3D position (``M_goal``). The scene condition is the
local occupancy grid around the subgoal with the dynamic objects where they are now, the action
condition the frame-wise labels with the progress indicator; both are encoded once per episode
and reused by every denoising step. After each episode the joints are projected onto the
skeleton's bone lengths (the body keeps its proportions over minutes); rotations for export are
fitted afterwards (``trumans.ik.fit``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from einops import rearrange

from trumans.scenes.scene_grids import SceneGrids
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import respaced_timesteps
from trumans.model.conditions import EpisodeCondition, episode_condition, episode_scene_grids, subgoal_to_canonical
from trumans.model.episodes import PELVIS, FeatureLayout, canonicalize, uncanonicalize
from trumans.model.masks import joint_goal_mask, pelvis_goal_mask, transition_mask
from trumans.model.nets import GuidedDenoiser
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS, PARENTS

from trumans.sample.guidance.penetration import penetration_loss
from trumans.sample.scene_sdf import SceneSDF

__all__ = ["SamplerConfig", "Goal", "EpisodeSampler", "project_bones", "bone_lengths_of"]

HEADING_WEIGHT = 3.0  # the hip-line (heading) term against the position term of the goal guidance
HEIGHT_WEIGHT = 1.0  # the seated pelvis height term (per frame) against the position term
PENETRATION_WEIGHT = 1.0  # the scene-penetration term (trumans.sample.guidance.penetration) against the position term


@dataclass(frozen=True)
class Goal:
    """An episode goal (M_goal): ``joint`` 'pelvis' with ``point`` (2,) world xy at the last
    frame, or a joint name with ``point`` (3,) world m at episode frame ``frame``."""

    point: tuple[float, ...]
    joint: str = "pelvis"
    frame: int = -1
    guide: bool = True  # goal guidance applies (``SamplerConfig.goal_guidance``); else inpainting only
    heading: float | None = None  # world heading (rad) the body should have at the goal (sitting down)
    pelvis_z: tuple[tuple[int, float], ...] = ()  # (episode frame, world pelvis height m): seated frames


@dataclass(frozen=True)
class SamplerConfig:
    """steps: denoising steps (respaced DDIM when < T); eta: DDIM noise (0 = deterministic);
    scene_scale / action_scale: classifier-free guidance scales (1 = plain conditional);
    naive: recompute the condition embeddings at every step (the reference sampler);
    goal_guidance: step size of the spatial guidance that pulls the predicted body onto its goal
    (0 = inpainting only; see ``EpisodeSampler._guided_sample``); goal_iters: guidance updates per step;
    foot_cleanup: lock planted feet on the floor and re-solve the legs after each episode
    (``trumans.sample.cleanup.foot``; applied by ``trumans.sample.rollout``); seam_blend: frames over which the
    jump at an episode seam is blended out (``trumans.sample.cleanup.seam``; 0 = off); seat_guidance: the goal
    guidance also pulls a seated pelvis to its seat's height (``trumans.sample.guidance.seat``);
    penetration_guidance: the goal guidance also pushes the joints out of the scene
    (``trumans.sample.guidance.penetration``; needs grids); scene_pushout: after each episode a smooth
    root offset moves the new frames' body out of the scene (``trumans.sample.cleanup.scene_pushout``; applied by
    ``trumans.sample.rollout``; needs grids); arm_pushout: then a hand still in the scene is moved out by
    arm IK (``trumans.sample.cleanup.arm_pushout``; needs grids); reach_cleanup: after each episode the acting arm (and, out of
    reach, the upper body) is moved onto the hand target of the plan's hand phases
    (``trumans.sample.cleanup.reach``; applied by ``trumans.sample.rollout``); support_lift: after the projection
    onto the body's bones the body is raised until its lowest foot is back on the floor, where the
    feet carry it (``trumans.sample.cleanup.support_lift``; applied by ``trumans.sample.rollout``)."""

    steps: int = 20
    eta: float = 0.0
    scene_scale: float = 1.0
    action_scale: float = 1.0
    naive: bool = False
    goal_guidance: float = 0.0
    goal_iters: int = 1
    foot_cleanup: bool = True
    seam_blend: int = 3
    seat_guidance: bool = True
    penetration_guidance: bool = True
    scene_pushout: bool = True
    arm_pushout: bool = True
    reach_cleanup: bool = True
    support_lift: bool = True

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")
        if not self.eta >= 0:
            raise ValueError(f"eta must be >= 0, got {self.eta}")
        if self.seam_blend < 0:
            raise ValueError(f"seam_blend must be >= 0 frames, got {self.seam_blend}")
        if self.goal_iters < 1:
            raise ValueError(f"goal_iters must be >= 1, got {self.goal_iters}")
        for name in ("scene_scale", "action_scale", "goal_guidance"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")


def bone_lengths_of(joints: np.ndarray) -> np.ndarray:
    """joints (..., 24, 3) -> (..., 24) length of each joint's bone to its parent (root 0), m."""
    par = np.asarray(PARENTS)
    d = joints[..., 1:, :] - joints[..., par[1:], :]
    return np.concatenate([np.zeros(joints.shape[:-2] + (1,)), np.linalg.norm(d, axis=-1)], axis=-1)


def project_bones(joints: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Put joints (..., 24, 3) on a skeleton with bone ``lengths`` (24,) m: from the root down, each
    joint moves along its bone's direction to the right distance from its (already moved) parent."""
    out = np.array(joints, dtype=np.float64, copy=True)
    for j in range(1, NUM_JOINTS):  # topological order (parents come first)
        p = PARENTS[j]
        d = joints[..., j, :] - joints[..., p, :]
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        out[..., j, :] = out[..., p, :] + lengths[j] * d / np.maximum(n, 1e-9)
    return out.astype(np.float32)


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
        guide_sdf = config.penetration_guidance and config.goal_guidance > 0
        # the scene's signed distance: for the penetration guidance and the push-outs (trumans.sample.rollout)
        pushout = config.scene_pushout or config.arm_pushout
        self.scene_sdf = SceneSDF(grids.static) if grids is not None and (guide_sdf or pushout) else None
        self.sdf = self.scene_sdf if guide_sdf else None
        # with the dynamic objects (chairs, stools, doors) at their scene poses: the push-out's field
        # while the plan has moved none of them (``trumans.sample.rollout``)
        full = getattr(grids, "occ", None) if grids is not None and getattr(grids, "points", None) else None
        self.scene_sdf_all = SceneSDF(full) if pushout and full is not None else self.scene_sdf

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
                attach_pelvis: bool = True) -> np.ndarray:
        """context: (B, k, 24, 3) world m, the last k frames so far; labels: (B, L, N_A) action
        labels; goals: one ``Goal`` per sample -> (B, L, 24, 3) world joints (first k = context).
        attach_pelvis: put a pinned pelvis back on the generated body (``_attach_pinned_pelvis``)."""
        B = context.shape[0]
        if context.ndim != 4 or context.shape[1:] != (self.k, NUM_JOINTS, 3):
            raise ValueError(f"context must be (B, {self.k}, 24, 3), got {context.shape}")
        if len(goals) != B or labels.shape[:2] != (B, self.L):
            raise ValueError(f"need {B} goals and labels (B, {self.L}, N_A), got {len(goals)} and {labels.shape}")
        cond = self.condition(context, labels, goals)
        x_given, mask = self._given(context, cond, goals)
        if self.grids is None:
            grid = np.zeros((B, self.n, self.n, self.n), dtype=bool)
        else:
            grid = episode_scene_grids(self.grids, cond, object_poses, n=self.n, extent=self.extent)
        scene = torch.from_numpy(grid).to(self.device)
        acts = torch.as_tensor(cond.actions, dtype=torch.float32, device=self.device)
        emb = self._conditions(scene, acts)
        if self.config.goal_guidance > 0:
            x0 = self._guided_sample(self._model_fn(emb), mask, x_given, self._goal_targets(cond, goals), generator,
                                     cond)
        else:
            x0 = self.diffusion.sample(self._model_fn(emb), (B, self.L, self.layout.dim), mask=mask, given=x_given,
                                       num_steps=self.config.steps, eta=self.config.eta, generator=generator,
                                       device=self.device)
        feats = self.norm.denormalize(x0.cpu().numpy())
        cj, _ = self.layout.unpack(feats)
        world = uncanonicalize(cj, cond.origin, cond.yaw)
        world[:, : self.k] = context
        return _attach_pinned_pelvis(world, goals) if attach_pelvis else world

    def _goal_targets(self, cond: EpisodeCondition, goals: list[Goal]) -> list[list[tuple]]:
        """Per sample, the guidance terms (frame, feature columns, W, target): the loss is
        |W x0[frame, columns] - target|^2 in metres (denormalised, canonical frame). A pelvis goal
        pulls the hip midpoint's x, y (W averages the hips) and, with a heading, the hip line
        (left minus right hip) onto the heading's left direction; a joint goal pulls that joint;
        ``Goal.pelvis_z`` pulls the pelvis height at those frames (seated frames, frames as a tensor)."""
        lay = self.layout
        hips = lay.position_index("left_hip", (0, 1)) + lay.position_index("right_hip", (0, 1))
        mean_w = torch.tensor([[0.5, 0, 0.5, 0], [0, 0.5, 0, 0.5]])
        diff_w = torch.tensor([[1.0, 0, -1.0, 0], [0, 1.0, 0, -1.0]])
        out = []
        for b, g in enumerate(goals):
            terms = []
            if g.guide and g.joint == "pelvis":
                goal = torch.as_tensor(cond.subgoal_canonical()[b, :2], dtype=torch.float32)
                terms.append((self.L - 1, hips, mean_w, goal))
                if g.heading is not None:
                    h = g.heading - float(cond.yaw[b])  # canonical heading
                    left = torch.tensor([-np.sin(h), np.cos(h)], dtype=torch.float32) * self.hip_width
                    terms.append((self.L - 1, hips, HEADING_WEIGHT * diff_w, HEADING_WEIGHT * left))
            elif g.guide:
                local = subgoal_to_canonical(np.asarray(g.point, np.float64), cond.origin[b], cond.yaw[b])
                terms.append((g.frame % self.L, lay.position_index(g.joint), torch.eye(3),
                              torch.as_tensor(local, dtype=torch.float32)))
            if g.pelvis_z:  # seated frames: the pelvis at its height above the seat (canonical z = world z)
                frames = torch.as_tensor([f % self.L for f, _ in g.pelvis_z], dtype=torch.long)
                z = torch.as_tensor([h for _, h in g.pelvis_z], dtype=torch.float32)
                terms.append((frames, lay.position_index(PELVIS, (2,)), HEIGHT_WEIGHT * torch.eye(len(z)),
                              HEIGHT_WEIGHT * z))
            out.append(terms)
        return out

    def _guided_sample(self, model_fn, mask: torch.Tensor, given: torch.Tensor, targets, generator,
                       cond: EpisodeCondition | None = None) -> torch.Tensor:
        """Respaced DDIM (``GaussianDiffusion.step``) with spatial guidance (OmniControl, Xie et al.
        2024, "spatial guidance"): a sparse inpainted goal (2 of L x F entries) is weakly followed, so
        after each step x_{t-1} moves against the gradient of the squared distance (m^2) between the
        body's predicted x0 at the goal frame and the goal: x_{t-1} <- x_{t-1} - s grad_{x_t}."""
        d = self.diffusion
        B, L, F = given.shape
        mean = torch.as_tensor(self.norm.mean, dtype=torch.float32)
        std = torch.as_tensor(self.norm.std, dtype=torch.float32)
        x = torch.randn((B, L, F), generator=generator, dtype=torch.float32).to(self.device)
        if self.sdf is not None and cond is not None:  # canonical -> world of the new frames' joints
            c, s_ = np.cos(cond.yaw), np.sin(cond.yaw)
            Rt = torch.as_tensor(np.stack([np.stack([c, s_, 0 * c], -1), np.stack([-s_, c, 0 * c], -1),
                                           np.stack([0 * c, 0 * c, 1 + 0 * c], -1)], 1), dtype=torch.float32)
            org = torch.as_tensor(cond.origin, dtype=torch.float32)
        ts = respaced_timesteps(d.steps, self.config.steps).tolist()
        for i, t_i in enumerate(ts):
            x = torch.where(mask, given, x)
            t = torch.full((B,), t_i, dtype=torch.long, device=x.device)
            grad = torch.zeros_like(x)
            with torch.enable_grad():
                for it in range(self.config.goal_iters):
                    xg = (x - grad).detach().requires_grad_(True)
                    out = model_fn(xg, t, mask=mask)
                    x0_hat, _ = d.x0_and_eps(out, t, xg)
                    loss = xg.new_zeros(())
                    for b, terms in enumerate(targets):
                        for f, cols, W, target in terms:
                            pred = W @ (x0_hat[b, f, cols] * std[cols] + mean[cols])
                            loss = loss + ((pred - target) ** 2).sum()
                    if self.sdf is not None and cond is not None:
                        pos = (x0_hat[:, self.k:, :NUM_JOINTS * 3] * std[:NUM_JOINTS * 3] + mean[:NUM_JOINTS * 3])
                        pos = rearrange(pos, "b l (j c) -> b l j c", c=3) @ Rt[:, None] + org[:, None, None]
                        loss = loss + PENETRATION_WEIGHT * penetration_loss(self.sdf, pos)
                    g, = torch.autograd.grad(loss, xg, allow_unused=True) if loss.requires_grad else (None,)
                    if g is None:
                        break
                    grad = grad + self.config.goal_guidance * g
            x, _ = d.step(out.detach(), t, xg.detach(), t_prev=ts[i + 1] if i + 1 < len(ts) else -1,
                          eta=self.config.eta, generator=generator)
            if i + 1 < len(ts):
                x = x - grad
        return torch.where(mask, given, x)

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


def _attach_pinned_pelvis(world: np.ndarray, goals: list[Goal]) -> np.ndarray:
    """The pinned pelvis x, y at the last frame is the goal, not necessarily where the generated
    body is (a model that lags leaves it torn from the hips; that frame would become the next
    episode's context). Put it back on the body: the last frame's pelvis keeps the previous
    frame's offset from the hip midpoint (the goal error is then measured on the body)."""
    hips = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]
    for b, g in enumerate(goals):
        if g.joint == "pelvis":
            mid = world[b][:, hips].mean(axis=1)  # (L, 3)
            world[b, -1, PELVIS, :2] = mid[-1, :2] + world[b, -2, PELVIS, :2] - mid[-2, :2]
    return world


def pelvis_of(joints: np.ndarray) -> np.ndarray:
    """(..., 24, 3) -> (..., 3) pelvis position."""
    return joints[..., JOINT_INDEX["pelvis"], :]
