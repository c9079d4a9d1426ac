"""Visualisation: animated skeleton + scene (GIF/MP4) and top-down maps."""
from .render import SceneView, render_animation, render_still, render_topdown

__all__ = ["SceneView", "render_animation", "render_still", "render_topdown"]
