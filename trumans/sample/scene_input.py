"""The scene a motion is sampled in: a scene folder, a single mesh file, or the default room.

``load_sample_scene`` returns the scene, its occupancy grid (cached: ``occupancy.npz`` in a scene
folder, ``<mesh>.occupancy.npz`` beside a mesh file when that folder is writable), the walkable
floor map, and the dynamic-object local grids the sampler queries. A mesh file's seats, beds and tables
are found from its geometry or its part names (``trumans.scenes.affordances``) and added as static objects
(``seat_0``, ``bed_0``, ``table_0`` ...; the mesh itself stays the static mesh).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable
from pathlib import Path

import numpy as np

from trumans.scenes.affordances import mesh_affordances
from trumans.scenes.io import import_mesh, load_scene
from trumans.scenes.occupancy import OccupancyGrid, scene_occupancy
from trumans.scenes.procedural import make_room
from trumans.scenes.scene import Scene
from trumans.scenes.scene_grids import SceneGrids
from trumans.scenes.spec import DEFAULT_ROOM_SEED, procedural_seed, procedural_spec
from trumans.scenes.walkability import WalkMap, nearest_walkable, walkable_map

__all__ = ["SampleScene", "load_sample_scene", "DEFAULT_ROOM_SEED"]


@dataclass
class SampleScene:
    scene: Scene
    occupancy: OccupancyGrid
    walkmap: WalkMap
    grids: SceneGrids
    source: str  # the scene's spec, loadable again: 'room:SEED', a scene folder or a mesh file

    def free_point(self) -> np.ndarray:
        """(2,) a walkable floor point near the room's centre, m."""
        b = self.scene.bounds()
        return nearest_walkable(self.walkmap, 0.5 * (b[0, :2] + b[1, :2]))


def _writable(folder: Path) -> bool:
    return folder.is_dir() and os.access(folder, os.W_OK)


def load_sample_scene(spec: str | None, voxel: float = 0.02, up: str = "z", default_seed: int = DEFAULT_ROOM_SEED,
                      cache_dir: str | Path | None = None, check: Callable[[Scene], None] | None = None) -> SampleScene:
    """spec: None / 'default' (the default procedural room), 'room:SEED' (another procedural room),
    a scene folder (scene.json), or a mesh file trimesh reads (a scan or room model; ``up`` 'y'
    converts a y-up file). Raises FileNotFoundError / ValueError naming the problem.
    ``check(scene)`` runs on the scene as soon as it is read, before the occupancy grid (the slow part):
    a caller's checks that need only the geometry refuse bad input before any heavy work."""
    seed = procedural_seed(spec)
    found_in = None
    if seed is not None:
        seed = default_seed if spec in (None, "", "default") else seed
        scene = make_room(seed)
        if check is not None:
            check(scene)
        folder = Path(cache_dir) / scene.name if cache_dir is not None else None
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)
        occ = scene_occupancy(scene, folder, voxel=voxel)
        source = procedural_spec(seed)  # a spec this function loads again (``trumans view`` reads it from the npz)
    else:
        path = Path(spec)
        if path.is_dir():
            if not (path / "scene.json").is_file():
                raise FileNotFoundError(f"scene folder {path} has no scene.json; give a scene folder written by "
                                        f"trumans (trumans.scenes.io.save_scene), a mesh file, or 'default'")
            scene = load_scene(path)
            if check is not None:
                check(scene)
            occ = scene_occupancy(scene, path if _writable(path) else None, voxel=voxel)
        elif path.is_file():
            mesh = import_mesh(path, up=up)
            found_in = path  # seats, beds and tables are found after the occupancy (its cache key is the mesh's)
            scene = Scene(name=path.stem, static={"mesh": mesh})
            if check is not None:
                check(scene)
            cache = path.parent / f"{path.stem}.occupancy" if _writable(path.parent) else None
            if cache is not None:
                cache.mkdir(exist_ok=True)
            occ = scene_occupancy(scene, cache, voxel=voxel)
        else:
            raise FileNotFoundError(f"scene {spec} does not exist; give a scene folder, a mesh file (.obj .ply .glb "
                                    f"...) or 'default'")
        source = str(path)
    wm = walkable_map(occ)
    if not wm.walkable.any():
        raise ValueError(f"scene {source} has no walkable floor (no free area at z = 0 that a person fits in); "
                         f"is the mesh z-up (use --up y for a y-up file) and in metres?")
    if found_in is not None:  # a raw mesh: its seats, beds and tables as static objects (trumans.scenes.affordances)
        for obj in mesh_affordances(found_in, scene.static["mesh"], up=up):
            scene.objects[obj.name] = obj
    return SampleScene(scene, occ, wm, SceneGrids(occ, scene), source)

