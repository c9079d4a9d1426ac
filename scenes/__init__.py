"""Scenes: meshes + interactable objects, occupancy grids, local queries, rooms, planning."""
from .scene import Scene, SceneObject

__all__ = ["Scene", "SceneObject"]
