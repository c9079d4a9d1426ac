"""Objects found in a raw mesh (seats, beds, tables: ``trumans.scenes.affordances``) are parts of its static
mesh: a GLB (and what the other renderers draw) has each of the mesh's triangles once, not once in the room
and again in the found object."""
from __future__ import annotations

import numpy as np
import trimesh

from helpers import REPO_ROOT
from trumans.sequence import Sequence
from trumans.skeleton import REST_JOINTS

MESH = REPO_ROOT / "examples" / "room_mesh.obj"


def _triangle_keys(tris: np.ndarray) -> np.ndarray:
    """(n, 3, 3) world triangles -> (n, 9) keys in mm, the corners sorted (the same triangle, any order); the
    corners as float32 first, as a GLB stores them (a value on a half millimetre rounds the same way)."""
    k = np.round(np.asarray(tris, np.float32).astype(np.float64) * 1000).astype(np.int64)
    order = np.lexsort((k[..., 2], k[..., 1], k[..., 0]), axis=-1)
    return np.take_along_axis(k, order[..., None], axis=1).reshape(len(k), 9)


def test_glb_of_a_mesh_scene_has_each_triangle_once(tmp_path):
    from trumans.sample.scene_input import load_sample_scene
    from trumans.viz.export import export
    from trumans.viz.scene_view import scene_view

    sc = load_sample_scene(str(MESH))
    found = [o for o in sc.scene.objects.values() if o.meta.get("found_by")]
    assert len(found) >= 4 and all(o.part_of_static for o in found)  # seats, bed and tables of the room mesh
    j = REST_JOINTS.astype(np.float32)
    j[:, :2] += np.array([2.4, 2.44], np.float32) - j[0, :2]
    seq = Sequence(joints=np.repeat(j[None], 8, 0), fps=30.0, scene=str(MESH))
    glb = export(seq, tmp_path / "s", {"glb"}, scene=sc.scene)["glb"]

    static = sc.scene.static["mesh"]
    room = _triangle_keys(static.triangles)
    assert len(np.unique(room, axis=0)) == len(room)  # the input itself has no duplicate triangle
    from scipy.spatial.transform import Rotation
    from trumans.viz.glb import Z_UP_TO_Y_UP

    back = np.eye(4)
    back[:3, :3] = Rotation.from_quat(Z_UP_TO_Y_UP).inv().as_matrix()  # glTF y-up -> our z-up
    loaded = trimesh.load(glb, force="scene", process=False)
    tris = []
    for node in loaded.graph.nodes_geometry:
        T, name = loaded.graph[node]
        g = loaded.geometry[name]
        if isinstance(g, trimesh.Trimesh) and len(g.faces):
            tris.append(trimesh.transform_points(g.vertices, back @ T)[g.faces])
    keys = _triangle_keys(np.concatenate(tris))
    room_set = {tuple(r) for r in room}
    in_room = np.array([tuple(k) in room_set for k in keys])
    assert in_room.sum() == len(room), (in_room.sum(), len(room))  # every room triangle drawn, and once
    _, counts = np.unique(keys, axis=0, return_counts=True)
    assert counts.max() == 1
    view = scene_view(sc.scene)  # the gif / png / html renderers draw the same: the room once
    assert sum(len(m.faces) for m in view.static) == len(static.faces) and not view.dynamic
