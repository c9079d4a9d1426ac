"""Scene folder save/load round trips, error messages, and y-up mesh import."""
import json

import numpy as np
import pytest
import trimesh

from trumans.scenes import Scene, SceneObject
from trumans.scenes.io import Y_UP_TO_Z_UP, import_mesh, load_scene, save_scene
from trumans.scenes.occupancy import scene_occupancy


def make_scene() -> Scene:
    rng = np.random.default_rng(0)
    floor = trimesh.creation.box((4.0, 3.0, 0.1))
    floor.apply_translation([2.0, 1.5, -0.05])
    pose = trimesh.transformations.rotation_matrix(0.3, [0, 0, 1])
    pose[:3, 3] = [1.234567891234, 0.5, 0.0]
    door = SceneObject("door", "door", trimesh.creation.box((0.05, 0.9, 2.0)), pose=pose, dof="hinge",
                       hinge_point=[0.0, -0.45, 0.0], axis=[0, 0, 1], meta={"handle": [0.0, 0.4, 1.0]})
    chair = SceneObject("chair/1", "chair", trimesh.creation.box((0.4, 0.4, 0.9)), dof="slide", dynamic=True,
                        meta={"seat_height": 0.45, "tags": ["wood", "red"], "nested": {"a": 1}})
    cup = trimesh.creation.icosphere(2, radius=0.05)
    cup.vertices += rng.normal(scale=1e-3, size=cup.vertices.shape)
    return Scene("room 1", static={"floor": floor}, meta={"source": "test"},
                 objects={"door": door, "chair/1": chair,
                          "cup": SceneObject("cup", "cup", cup, dof="free", dynamic=True)})


def test_round_trip(tmp_path):
    s = make_scene()
    save_scene(s, tmp_path / "scene")
    t = load_scene(tmp_path / "scene")
    assert t.name == s.name and t.meta == s.meta
    assert list(t.static) == ["floor"] and list(t.objects) == list(s.objects)
    np.testing.assert_allclose(t.static["floor"].vertices, s.static["floor"].vertices, atol=1e-6)
    for name, o in s.objects.items():
        p = t.objects[name]
        assert (p.category, p.dof, p.dynamic, p.meta) == (o.category, o.dof, o.dynamic, o.meta)
        np.testing.assert_array_equal(p.pose, o.pose)  # float64 JSON round trip is exact
        np.testing.assert_allclose(p.mesh.vertices, o.mesh.vertices, atol=1e-6)
        np.testing.assert_array_equal(p.mesh.faces, o.mesh.faces)
        for key in ("hinge_point", "axis"):
            a, b = getattr(o, key), getattr(p, key)
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a, b)


def test_overwrite_keeps_occupancy_cache_and_refuses_foreign_folder(tmp_path):
    s = make_scene()
    folder = tmp_path / "scene"
    save_scene(s, folder)
    occ = scene_occupancy(load_scene(folder), folder, voxel=0.1)
    mtime = (folder / "occupancy.npz").stat().st_mtime_ns
    save_scene(s, folder)
    assert (folder / "occupancy.npz").stat().st_mtime_ns == mtime
    again = scene_occupancy(load_scene(folder), folder, voxel=0.1)  # the key survives save/load
    assert (folder / "occupancy.npz").stat().st_mtime_ns == mtime
    np.testing.assert_array_equal(again.grid, occ.grid)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp leftovers
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "a.jpg").write_bytes(b"x")
    with pytest.raises(ValueError, match="not a scene folder"):
        save_scene(s, foreign)


def edit_json(folder, fn):
    doc = json.loads((folder / "scene.json").read_text())
    fn(doc)
    (folder / "scene.json").write_text(json.dumps(doc))


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_scene(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="scene.json"):
        load_scene(tmp_path / "empty")
    folder = tmp_path / "scene"
    save_scene(make_scene(), folder)
    cases = [
        (lambda d: d["objects"][0].update(dof="wobble"), ValueError, "unknown dof"),
        (lambda d: d["objects"][0].update(pose=[[1, 0, 0], [0, 1, 0]]), ValueError, "pose must be"),
        (lambda d: d["objects"][1].update(mesh="objects/missing.ply"), FileNotFoundError, "missing"),
        (lambda d: d["objects"][0].update(axis=[0, 1]), ValueError, "axis"),
        (lambda d: d["objects"][0].pop("name"), ValueError, "missing field 'name'"),
    ]
    original = (folder / "scene.json").read_text()
    for edit, exc, msg in cases:
        (folder / "scene.json").write_text(original)
        edit_json(folder, edit)
        with pytest.raises(exc, match=msg):
            load_scene(folder)
    (folder / "scene.json").write_text(original)
    (folder / "static" / "floor.ply").write_text("ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\n"
                                                 "property list uchar int vertex_indices\nend_header\n")
    with pytest.raises(ValueError, match="no triangles|empty"):
        load_scene(folder)
    (folder / "scene.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_scene(folder)


def test_import_y_up(tmp_path):
    tall_y = trimesh.creation.box((0.2, 2.0, 0.4))  # y-up: 2 m tall
    tall_y.apply_translation([0.3, 1.0, -0.5])
    tall_y.export(tmp_path / "tall.obj")
    z = import_mesh(tmp_path / "tall.obj", up="y")
    np.testing.assert_allclose(z.extents, [0.2, 0.4, 2.0], atol=1e-6)
    np.testing.assert_allclose(z.bounds, [[0.2, 0.3, 0.0], [0.4, 0.7, 2.0]], atol=1e-6)
    assert z.volume > 0  # orientation kept: a proper rotation, not a mirror
    assert np.linalg.det(Y_UP_TO_Z_UP) == pytest.approx(1.0)
    np.testing.assert_allclose(Y_UP_TO_Z_UP @ [0, 1, 0], [0, 0, 1])
    same = import_mesh(tmp_path / "tall.obj", up="z", scale=0.5)
    np.testing.assert_allclose(same.extents, [0.1, 1.0, 0.2], atol=1e-6)


def test_import_scene_file_flattened(tmp_path):
    sc = trimesh.Scene()
    sc.add_geometry(trimesh.creation.box((1, 1, 1)), transform=trimesh.transformations.translation_matrix([2, 0, 0]))
    sc.add_geometry(trimesh.creation.box((1, 1, 1)))
    sc.export(tmp_path / "two.glb")
    m = import_mesh(tmp_path / "two.glb")
    assert len(m.faces) == 24
    np.testing.assert_allclose(m.bounds, [[-0.5, -0.5, -0.5], [2.5, 0.5, 0.5]], atol=1e-6)
    with pytest.raises(FileNotFoundError):
        import_mesh(tmp_path / "missing.obj")
    with pytest.raises(ValueError, match="up must be"):
        import_mesh(tmp_path / "two.glb", up="x")


def test_scene_mesh_paths_stay_inside_the_scene_folder(tmp_path):
    import json as _json
    import os

    room = tmp_path / "room"
    save_scene(make_scene(), room)
    doc = _json.loads((room / "scene.json").read_text())
    outside = tmp_path / "secret.ply"
    trimesh.creation.box((1, 1, 1)).export(outside)
    os.symlink(outside, room / "link.ply")
    for bad in (str(outside), "../secret.ply", "link.ply", "../nowhere.ply"):
        d = _json.loads(_json.dumps(doc))
        d["static"][0]["mesh"] = bad
        (room / "scene.json").write_text(_json.dumps(d))
        with pytest.raises(ValueError, match="leaves the scene folder"):
            load_scene(room)
