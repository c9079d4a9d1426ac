"""Rotated, floor-anchored local occupancy grids vs a slow per-point reference."""

import numpy as np
import pytest
import trimesh

from trumans.scenes.local_grid import local_grids, local_points
from trumans.scenes.occupancy import OccupancyGrid, compute_occupancy

V = 0.02


def reference(occ: OccupancyGrid, center, yaw, n, extent):
    """Slow float64 per-cell loop; also returns a mask of cells far from voxel-boundary ties."""
    out = np.zeros((n, n, n), bool)
    safe = np.ones((n, n, n), bool)
    ex, ey, ez = extent
    c, s = np.cos(yaw), np.sin(yaw)
    for i in range(n):
        for j in range(n):
            for k in range(n):
                u, v, w = -ex / 2 + (i + 0.5) * ex / n, -ey / 2 + (j + 0.5) * ey / n, (k + 0.5) * ez / n
                p = np.array([center[0] + c * u - s * v, center[1] + s * u + c * v, center[2] + w])
                f = (p - occ.origin) / occ.voxel + 0.5
                idx = np.floor(f).astype(int)
                safe[i, j, k] = np.all(np.abs(f - np.round(f)) > 1e-3)
                inside = np.all((idx >= 0) & (idx < occ.grid.shape))
                out[i, j, k] = occ.grid[tuple(idx)] if inside else True
    return out, safe


@pytest.fixture(scope="module")
def random_grid():
    rng = np.random.default_rng(0)
    return OccupancyGrid(rng.random((60, 50, 40)) < 0.3, np.array([0.01, 0.01, 0.01]), V)


def test_matches_slow_reference(random_grid):
    rng = np.random.default_rng(1)
    n, extent = 8, (0.5, 0.4, 0.6)
    centers = np.array([[0.6, 0.5, 0.0], [1.1, 0.9, 0.13], [0.05, 0.1, 0.5], [1.15, 0.3, -0.2]])
    yaw = rng.uniform(-np.pi, np.pi, len(centers))
    fast = local_grids(random_grid, centers, yaw, n=n, extent=extent)
    assert fast.shape == (4, n, n, n) and fast.dtype == bool
    for b in range(len(centers)):
        ref, safe = reference(random_grid, centers[b], yaw[b], n, extent)
        assert safe.mean() > 0.9
        np.testing.assert_array_equal(fast[b][safe], ref[safe])
    # one shared floor height takes the layer-slicing path; it must agree with the general one
    flat_c = centers * [1, 1, 0] + [0, 0, 0.13]
    flat = local_grids(random_grid, flat_c, yaw, n=n, extent=extent)
    mixed = local_grids(random_grid, np.r_[flat_c, [[0.3, 0.3, 0.5]]], np.r_[yaw, 0.0], n=n, extent=extent)
    np.testing.assert_array_equal(flat, mixed[:-1])
    for b in range(len(centers)):
        ref, safe = reference(random_grid, flat_c[b], yaw[b], n, extent)
        np.testing.assert_array_equal(flat[b][safe], ref[safe])
    # cells outside the scene grid (the last query pokes below and past it) are occupied
    pts = local_points(centers, yaw, n=n, extent=extent)
    outside = np.any((pts < 0) | (pts > np.array(random_grid.shape) * V), axis=-1)
    assert outside.any() and fast[outside].all()


def test_box_in_front_for_any_yaw():
    box = trimesh.creation.box((0.3, 0.3, 0.5))
    box.apply_translation([1.0, 1.0, 0.25])
    occ = compute_occupancy([box], np.array([[-0.2, -0.2, 0.0], [2.2, 2.2, 1.4]]), V)
    n = 16
    for yaw in np.linspace(-np.pi, np.pi, 9):
        fwd = np.array([np.cos(yaw), np.sin(yaw)])
        c = np.r_[np.array([1.0, 1.0]) - 0.4 * fwd, 0.0]
        g = local_grids(occ, c[None], np.array([yaw]), n=n)[0]  # axes (forward, left, up)
        front = g[12:14, 7:9, :4]  # 0.34-0.41 m ahead, within 0.04 m of the axis, low
        assert front.all(), yaw
        assert not g[: n // 2].any(), yaw  # nothing behind
        assert not g[:, :, 8:].any(), yaw  # the box is 0.5 m tall; the grid reaches 1.2 m


def test_ninety_degrees_permutes_axes(random_grid):
    n = 16
    c = np.array([[0.603, 0.503, 0.0]])  # off voxel boundaries: no rounding ties
    g0 = local_grids(random_grid, c, np.array([0.0]), n=n, extent=(0.6, 0.6, 0.6))[0]
    g90 = local_grids(random_grid, c, np.array([np.pi / 2]), n=n, extent=(0.6, 0.6, 0.6))[0]
    # yaw 90: forward = +y, left = -x, so g90[i, j] samples (x, y) = (-v_j, u_i) = g0[n-1-j, i]
    np.testing.assert_array_equal(g90, np.transpose(g0[::-1], (1, 0, 2)))
    assert g0.any() and not g0.all()


def test_floor_anchor():
    grid = np.zeros((50, 50, 80), bool)
    grid[:, :, 25:35] = True  # a slab at z in [0.5, 0.7)
    occ = OccupancyGrid(grid, np.full(3, V / 2), V)
    g = local_grids(occ, np.array([[0.5, 0.5, 0.3]]), np.array([0.3]), n=10, extent=(0.4, 0.4, 1.0))[0]
    z = 0.3 + (np.arange(10) + 0.5) * 0.1  # sample heights
    expect = (z >= 0.5) & (z < 0.7)
    np.testing.assert_array_equal(g.all(axis=(0, 1)), expect)
    np.testing.assert_array_equal(g.any(axis=(0, 1)), expect)


def test_empty_batch_and_bad_inputs(random_grid):
    assert local_grids(random_grid, np.zeros((0, 3)), np.zeros(0), n=4).shape == (0, 4, 4, 4)
    with pytest.raises(ValueError, match="centers"):
        local_grids(random_grid, np.zeros((2, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="yaw"):
        local_grids(random_grid, np.zeros((2, 3)), np.zeros(3))
    with pytest.raises(ValueError, match="n must"):
        local_grids(random_grid, np.zeros((2, 3)), np.zeros(2), n=0)
    with pytest.raises(ValueError, match="extent"):
        local_grids(random_grid, np.zeros((2, 3)), np.zeros(2), extent=(1.0, -1.0, 1.0))


def test_scene_grids_without_cached_occupancy_share_a_memo():
    """Augmented scenes come without occupancy.npz: SceneGrids from the scene alone equals the one
    from its cached grid, and scene variations reuse the voxelised static part and object meshes."""
    import trimesh

    from trumans.scenes import furniture
    from trumans.scenes.occupancy import scene_occupancy
    from trumans.scenes.scene import Scene
    from trumans.scenes.scene_grids import SceneGrids

    rng = np.random.default_rng(0)
    floor = trimesh.creation.box((3.0, 3.0, 0.1))
    floor.apply_translation([1.5, 1.5, -0.05])
    chair = furniture.chair(rng, "chair_0")
    chair.pose[:3, 3] = [1.5, 1.5, 0.0]
    scene = Scene("s", static={"floor": floor}, objects={"chair_0": chair})
    ref = SceneGrids(scene_occupancy(scene, None, voxel=0.05), scene)
    memo: dict = {}
    a = SceneGrids(None, scene, voxel=0.05, memo=memo)
    n_memo = len(memo)
    moved = Scene("s2", static={"floor": floor}, objects={"chair_0": chair})
    b = SceneGrids(None, moved, voxel=0.05, memo=memo)
    assert len(memo) == n_memo == 2  # one static part, one chair mesh: reused by the variation
    centers, yaw = np.array([[1.5, 1.5, 0.0], [1.2, 1.0, 0.0]]), np.array([0.3, -1.0])
    np.testing.assert_array_equal(a.query(centers, yaw, n=16), ref.query(centers, yaw, n=16))
    np.testing.assert_array_equal(b.query(centers, yaw, n=16), ref.query(centers, yaw, n=16))
    assert a.query(centers, yaw, n=16).any()
    with pytest.raises(ValueError, match="needs an occupancy grid or a scene"):
        SceneGrids(None)
