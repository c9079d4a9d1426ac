"""Occupancy grids: analytic volumes, overlaps, open meshes, queries, files and scene caching."""
import numpy as np
import pytest
import trimesh

from trumans.scenes import Scene, SceneObject
from trumans.scenes import occupancy as occmod
from trumans.scenes.occupancy import OccupancyGrid, compute_occupancy, scene_occupancy

V = 0.02
BOUNDS = np.array([[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]])


def volume(g: OccupancyGrid) -> float:
    return float(g.grid.sum()) * g.voxel**3


def offset_box(ext=(0.5, 0.4, 0.3), t=(0.013, 0.007, 0.003)) -> trimesh.Trimesh:
    b = trimesh.creation.box(ext)
    b.apply_translation(t)
    return b


def test_box_and_sphere_volumes():
    box = offset_box()
    assert volume(compute_occupancy([box], BOUNDS, V)) == pytest.approx(0.5 * 0.4 * 0.3, rel=0.02)
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    sphere.apply_translation([0.004, -0.006, 0.003])
    g = compute_occupancy({"s": sphere}, BOUNDS, V)
    assert volume(g) == pytest.approx(4 / 3 * np.pi * 0.3**3, rel=0.02)
    # every voxel centre is classified like the analytic sphere (away from the surface)
    r = np.linalg.norm(g.centers() - [0.004, -0.006, 0.003], axis=-1)
    far = np.abs(r - 0.3) > 0.01
    np.testing.assert_array_equal(g.grid[far], (r < 0.3)[far])


def test_grid_layout_and_query():
    g = compute_occupancy([offset_box()], BOUNDS, V)
    assert g.shape == (50, 50, 50)
    np.testing.assert_allclose(g.origin, [-0.49, -0.49, -0.49])
    np.testing.assert_allclose(g.bounds(), BOUNDS)
    q = g.query(np.array([[0.013, 0.007, 0.003], [0.4, 0.4, 0.4], [0.0, 0.0, 0.6], [-0.51, 0, 0]]))
    np.testing.assert_array_equal(q, [True, False, True, True])  # last two: outside the grid
    assert g.query(np.zeros((2, 3, 3))).shape == (2, 3)


def test_overlapping_bodies_do_not_cancel():
    a, b = offset_box(), offset_box()
    b.apply_translation([0.2, 0, 0])
    p = np.array([[0.1, 0.0, 0.0], [-0.2, 0.0, 0.0], [0.4, 0.0, 0.0]])
    for meshes in ([trimesh.util.concatenate([a, b])], [a, b]):
        for wt in ("auto", True):
            g = compute_occupancy(meshes, BOUNDS, V, watertight=wt)
            np.testing.assert_array_equal(g.query(p), True)
            assert volume(g) == pytest.approx(0.7 * 0.4 * 0.3, rel=0.02)


def test_open_box_majority_vote():
    box = offset_box()
    box.update_faces(box.face_normals[:, 2] < 0.5)  # remove the top face
    box.remove_unreferenced_vertices()
    assert not box.is_watertight
    for wt in ("auto", False):
        g = compute_occupancy([box], BOUNDS, V, watertight=wt)
        assert volume(g) == pytest.approx(0.06, rel=0.05)
        assert g.query(np.array([[0.013, 0.007, 0.003]]))[0]
        assert not g.query(np.array([[0.013, 0.007, 0.3]]))[0]


def test_save_load_and_bad_files(tmp_path):
    g = compute_occupancy([offset_box()], BOUNDS, V)
    g.save(tmp_path / "occupancy.npz")
    h = OccupancyGrid.load(tmp_path / "occupancy.npz")
    np.testing.assert_array_equal(h.grid, g.grid)
    np.testing.assert_array_equal(h.origin, g.origin)
    assert h.voxel == g.voxel
    with pytest.raises(FileNotFoundError, match="does not exist"):
        OccupancyGrid.load(tmp_path / "missing.npz")
    (tmp_path / "bad.npz").write_bytes(b"not a zip file at all")
    with pytest.raises(ValueError, match="corrupt"):
        OccupancyGrid.load(tmp_path / "bad.npz")
    np.savez(tmp_path / "partial.npz", grid=g.grid)
    with pytest.raises(ValueError, match="lacks"):
        OccupancyGrid.load(tmp_path / "partial.npz")


def test_bad_inputs():
    with pytest.raises(ValueError, match="empty"):
        compute_occupancy([trimesh.Trimesh()], BOUNDS, V)
    with pytest.raises(ValueError, match="no meshes"):
        compute_occupancy([], BOUNDS, V)
    with pytest.raises(ValueError, match="bounds"):
        compute_occupancy([offset_box()], BOUNDS[::-1], V)
    with pytest.raises(ValueError, match="voxel"):
        compute_occupancy([offset_box()], BOUNDS, 0.0)
    with pytest.raises(ValueError, match="bool"):
        OccupancyGrid(np.zeros((2, 2, 2)), np.zeros(3), V)


def small_scene(x: float = 0.6) -> Scene:
    floor = trimesh.creation.box((1.2, 1.0, 0.1))
    floor.apply_translation([0.6, 0.5, -0.05])
    pose = np.eye(4)
    pose[:3, 3] = [x, 0.5, 0.2]
    table = SceneObject("table", "table", trimesh.creation.box((0.3, 0.3, 0.4)), pose=pose, dynamic=True)
    return Scene("tiny", static={"floor": floor}, objects={"table": table})


def test_scene_occupancy_floor_and_cache(tmp_path, monkeypatch):
    g = scene_occupancy(small_scene(), tmp_path, voxel=0.04)
    assert (tmp_path / "occupancy.npz").is_file()
    assert g.query(np.array([[0.6, 0.5, 0.2]]))[0]  # the table
    assert not g.query(np.array([[0.2, 0.2, 0.3]]))[0]  # free air
    assert g.query(np.array([[0.2, 0.2, -0.03]]))[0]  # under the floor
    zc = g.origin[2] + g.voxel * np.arange(g.shape[2])
    assert g.grid[:, :, zc < 0].all()
    static_only = scene_occupancy(small_scene(), None, voxel=0.04, include_dynamic=False)
    assert not static_only.query(np.array([[0.6, 0.5, 0.2]]))[0]

    def boom(*a, **k):
        raise AssertionError("cache was not used")

    monkeypatch.setattr(occmod, "compute_occupancy", boom)
    again = scene_occupancy(small_scene(), tmp_path, voxel=0.04)
    np.testing.assert_array_equal(again.grid, g.grid)
    with pytest.raises(AssertionError, match="cache"):  # moved object -> stale cache
        scene_occupancy(small_scene(x=0.3), tmp_path, voxel=0.04)
    with pytest.raises(AssertionError, match="cache"):  # other voxel -> stale cache
        scene_occupancy(small_scene(), tmp_path, voxel=0.05)
    monkeypatch.undo()
    moved = scene_occupancy(small_scene(x=0.3), tmp_path, voxel=0.04)
    assert moved.query(np.array([[0.3, 0.5, 0.2]]))[0] and not moved.query(np.array([[0.7, 0.5, 0.2]]))[0]
