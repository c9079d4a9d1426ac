"""What the renderers draw of a sequence's scene (``SceneView``), found the way ``trumans view`` finds it:
an explicit ``--scene``, the scene spec a sampled npz records ('room:SEED', a scene folder or a mesh file,
``trumans.scenes.spec``), or a dataset sequence's scene id looked up in the dataset index."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from trumans.dataset import INDEX_FILE, load_index
from trumans.scenes.occupancy import OCCUPANCY_FILE, OccupancyGrid
from trumans.scenes.spec import SCENE_UP_KEY, procedural_seed
from trumans.viz.render import SceneView

if TYPE_CHECKING:
    from trumans.scenes.scene import Scene

__all__ = ["find_scene_dir", "scene_view", "sequence_scene_view", "load_scene_view"]


def find_scene_dir(seq_path: Path, scene_field: str, explicit: str | None) -> Path | None:
    """The scene folder of a sequence: ``explicit``, else ``scene_field`` as a path, else the dataset
    index (``index.json`` beside or above the sequence) mapping scene ids to folders."""
    if explicit:
        d = Path(explicit)
        if not d.is_dir():
            raise FileNotFoundError(f"scene folder {d} does not exist")
        return d
    if scene_field and Path(scene_field).is_dir():
        return Path(scene_field)
    for root in (seq_path.parent, seq_path.parent.parent):
        if (root / INDEX_FILE).is_file() and scene_field:
            scenes = load_index(root)["scenes"]
            if scene_field in scenes and (root / scenes[scene_field]).is_dir():
                return root / scenes[scene_field]
    return None


def scene_view(sc: Scene) -> SceneView:
    """What the renderer draws of a ``trumans.scenes.Scene``: static meshes and non-dynamic objects in world
    frame (an object found in the static mesh is drawn once, as part of it: ``SceneObject.part_of_static``),
    dynamic objects' meshes in their own frame (posed by the sequence) with their scene poses; no grid."""
    static = list(sc.static.values()) + [o.world_mesh() for o in sc.objects.values()
                                         if not o.dynamic and not o.part_of_static]
    dynamic = {name: o.mesh for name, o in sc.objects.items() if o.dynamic}
    return SceneView(static=static, dynamic=dynamic, dynamic_pose={n: sc.objects[n].pose for n in dynamic})


def sequence_scene_view(seq_path: Path, seq, explicit: str | None, up: str | None) -> SceneView | None:
    """The scene to draw under a sequence: ``explicit`` (--scene) or the sequence's own ``scene`` field,
    each a scene folder, a mesh file, 'default' or 'room:SEED' (a relative path is tried from the current
    folder, then beside the sequence); a dataset sequence's scene id is looked up in the dataset index.
    ``up``: a mesh file's up axis (default: the sequence's recorded ``scene_up``, else z). None when
    the sequence names no scene that can be found (only ``explicit`` must exist)."""
    spec = explicit if explicit else (seq.scene or "")
    if not spec:
        return None
    seed = procedural_seed(spec)
    if seed is not None:
        from trumans.scenes.procedural import make_room

        return scene_view(make_room(seed))
    candidates = [Path(spec)] + ([] if explicit or Path(spec).is_absolute() else [seq_path.parent / spec])
    for path in candidates:
        if path.is_dir():
            return load_scene_view(path)
        if path.is_file():
            from trumans.scenes.io import import_mesh

            axis = up or (str(seq.extra[SCENE_UP_KEY]) if SCENE_UP_KEY in seq.extra else "z")
            return SceneView(static=[import_mesh(path, up=axis)], dynamic={})
    if explicit:
        raise FileNotFoundError(f"--scene {explicit}: no such scene folder or mesh file; give a scene folder, a mesh "
                                f"file, 'default' or room:SEED")
    return load_scene_view(find_scene_dir(seq_path, seq.scene, None))


def load_scene_view(folder: Path | None) -> SceneView | None:
    """Meshes from ``scene.json`` (when present) and the grid from ``occupancy.npz`` (when present)."""
    if folder is None:
        return None
    static, dynamic, poses = [], {}, {}
    if (folder / "scene.json").is_file():
        from trumans.scenes.io import load_scene

        view = scene_view(load_scene(folder))
        static, dynamic, poses = view.static, view.dynamic, view.dynamic_pose
    grid = origin = voxel = None
    if (folder / OCCUPANCY_FILE).is_file():
        occ = OccupancyGrid.load(folder / OCCUPANCY_FILE)
        grid, origin, voxel = occ.grid, occ.origin, occ.voxel
    return SceneView(static=static, dynamic=dynamic, grid=grid, origin=origin, voxel=voxel, dynamic_pose=poses)
