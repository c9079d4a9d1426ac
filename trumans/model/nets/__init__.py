"""Networks: the motion denoiser, the scene perceiver (voxel ViT) and the action encoder."""
from .action_encoder import ActionEncoder, ActionEncoderConfig
from .denoiser import Denoiser, DenoiserConfig, GuidedDenoiser
from .vit import ScenePerceiver, ScenePerceiverConfig

__all__ = ["ActionEncoder", "ActionEncoderConfig", "Denoiser", "DenoiserConfig", "GuidedDenoiser",
           "ScenePerceiver", "ScenePerceiverConfig"]
