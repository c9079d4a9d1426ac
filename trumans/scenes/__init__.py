"""Scenes: meshes + interactable objects, occupancy grids, local queries, rooms, planning.

Public names are imported lazily (PEP 562) so that ``import trumans.scenes.atomic`` pulls in neither
trimesh nor open3d (``import trumans`` stays light); ``from trumans.scenes import Scene`` works as usual.
"""
from __future__ import annotations

import importlib

_LAZY = {
    "Scene": "scene", "SceneObject": "scene",
    "SceneDistance": "distance", "DistanceResult": "distance",
    "OccupancyGrid": "occupancy", "compute_occupancy": "occupancy", "scene_occupancy": "occupancy",
    "local_grids": "local_grid", "local_points": "local_grid",
    "WalkMap": "walkability", "NoPathError": "walkability", "walkable_map": "walkability",
    "plan_path": "walkability", "nearest_walkable": "walkability",
    "save_scene": "io", "load_scene": "io", "import_mesh": "io",
    "make_room": "procedural", "list_categories": "procedural",
}

__all__ = [*_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
