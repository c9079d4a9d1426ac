"""The TRUMANS model family: diffusion, episode features, conditions, masks, networks and checkpoints."""
from .episodes import FeatureLayout, Normalizer, canonical_frame, canonicalize, uncanonicalize
from .diffusion import DiffusionConfig, DiffusionLoss, GaussianDiffusion, respaced_timesteps
from .masks import MaskSampler, joint_goal_mask, pelvis_goal_mask, transition_mask
from .conditions import EpisodeCondition, episode_condition, episode_scene_grids, subgoal_to_canonical, subgoal_to_world
from .nets import Denoiser, DenoiserConfig, GuidedDenoiser
from .checkpoint import Checkpoint, CheckpointKind, KindSpec, load_checkpoint, register_kind, save_checkpoint

__all__ = ["FeatureLayout", "Normalizer", "canonical_frame", "canonicalize", "uncanonicalize", "DiffusionConfig",
           "DiffusionLoss", "GaussianDiffusion", "respaced_timesteps", "MaskSampler", "joint_goal_mask",
           "pelvis_goal_mask", "transition_mask", "EpisodeCondition", "episode_condition", "episode_scene_grids",
           "subgoal_to_canonical", "subgoal_to_world", "Denoiser", "DenoiserConfig", "GuidedDenoiser", "Checkpoint",
           "CheckpointKind", "KindSpec", "load_checkpoint", "register_kind", "save_checkpoint"]
