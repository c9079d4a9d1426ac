"""Walk maps (ankle-to-head columns, radius inflation) and path planning around walls."""
import numpy as np
import pytest
import trimesh

from trumans.scenes.occupancy import OccupancyGrid, compute_occupancy
from trumans.scenes.walkability import NoPathError, WalkMap, nearest_walkable, plan_path, walkable_map

V = 0.02


def box(ext, center):
    m = trimesh.creation.box(ext)
    m.apply_translation(center)
    return m


@pytest.fixture(scope="module")
def wall_with_gap():
    """4 x 4 m area, a wall at x = 2 with a 0.8 m gap at y in [1.6, 2.4]."""
    walls = [box((0.2, 1.6, 2.0), (2.0, 0.8, 1.0)), box((0.2, 1.6, 2.0), (2.0, 3.2, 1.0))]
    occ = compute_occupancy(walls, np.array([[0, 0, 0], [4, 4, 2.2]]), V)
    return walkable_map(occ)


def dense(path: np.ndarray, k: int = 40) -> np.ndarray:
    t = np.linspace(0, 1, k)[None, :, None]
    return (path[:-1, None] + (path[1:] - path[:-1])[:, None] * t).reshape(-1, 2)


def test_path_goes_through_gap(wall_with_gap):
    wm = wall_with_gap
    start, goal = np.array([0.5, 0.5]), np.array([3.5, 0.6])
    path = plan_path(wm, start, goal, spacing=0.6)
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    pts = dense(path)
    assert wm.query(pts).all()  # never through blocked (or inflated) cells
    near_wall = pts[np.abs(pts[:, 0] - 2.0) < 0.05]
    assert len(near_wall) and np.all((near_wall[:, 1] > 1.6) & (near_wall[:, 1] < 2.4))
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() <= 0.9 + 1e-9
    assert 0.45 <= np.median(steps) <= 0.75
    straight = np.linalg.norm(goal - start)
    length = steps.sum()
    assert straight < length < straight + 2 * 1.5  # a detour through the gap, not a wander


def test_straight_line_when_free(wall_with_gap):
    path = plan_path(wall_with_gap, np.array([0.5, 0.5]), np.array([0.5, 3.5]), spacing=0.6)
    np.testing.assert_allclose(path[:, 0], 0.5, atol=1e-9)  # smoothed to one segment
    assert len(path) == 6  # 3 m / 0.6 m = 5 steps


def test_blocked_and_disconnected():
    walls = [box((2.0, 0.1, 2.0), (2.0, 1.0, 1.0)), box((2.0, 0.1, 2.0), (2.0, 3.0, 1.0)),
             box((0.1, 2.0, 2.0), (1.0, 2.0, 1.0)), box((0.1, 2.0, 2.0), (3.0, 2.0, 1.0))]
    occ = compute_occupancy(walls, np.array([[0, 0, 0], [4, 4, 2.2]]), V)
    wm = walkable_map(occ)
    with pytest.raises(NoPathError, match="not reachable"):
        plan_path(wm, np.array([0.4, 0.4]), np.array([2.0, 2.0]))
    with pytest.raises(NoPathError, match="start"):
        plan_path(wm, np.array([2.0, 1.0]), np.array([0.4, 0.4]))
    with pytest.raises(NoPathError, match="goal"):
        plan_path(wm, np.array([0.4, 0.4]), np.array([9.0, 9.0]))
    assert issubclass(NoPathError, ValueError)


def test_walkable_heights_and_inflation():
    meshes = [box((0.4, 0.4, 0.05), (1.0, 1.0, 0.025)),  # below the ankle: walkable
              box((0.4, 0.4, 0.3), (2.0, 1.0, 0.9)),  # table top at 0.75-1.05 m: blocked
              box((0.4, 0.4, 0.2), (3.0, 1.0, 2.1))]  # above the head: walkable
    occ = compute_occupancy(meshes, np.array([[0, 0, 0], [4, 2, 2.4]]), V)
    wm = walkable_map(occ, z_min=0.1, z_max=1.8, body_radius=0.25)
    assert wm.walkable.shape == occ.shape[:2]
    assert wm.query(np.array([[1.0, 1.0], [3.0, 1.0]])).all()
    assert not wm.query(np.array([2.0, 1.0]))
    # table edge at x = 2.2: inflated by 0.25 m -> blocked until ~2.45, free beyond
    assert not wm.query(np.array([2.4, 1.0])) and wm.query(np.array([2.5, 1.0]))
    # outside the map and within the radius of its border: not walkable
    assert not wm.query(np.array([-1.0, 1.0])) and not wm.query(np.array([0.1, 1.0]))
    no_radius = walkable_map(occ, body_radius=0.0)
    assert no_radius.query(np.array([2.25, 1.0])) and not no_radius.query(np.array([2.15, 1.0]))


def test_nearest_walkable(wall_with_gap):
    p = nearest_walkable(wall_with_gap, np.array([2.0, 0.5]))
    assert wall_with_gap.query(p) and abs(p[0] - 2.0) == pytest.approx(0.35, abs=0.03)
    many = nearest_walkable(wall_with_gap, np.array([[2.0, 0.5], [1.0, 1.0]]))
    assert many.shape == (2, 2) and wall_with_gap.query(many).all()
    np.testing.assert_allclose(many[1], [1.0, 1.0], atol=V)
    with pytest.raises(NoPathError, match="no walkable"):
        nearest_walkable(WalkMap(np.zeros((3, 3), bool), np.zeros(2), 0.1), np.zeros(2))


def test_bad_inputs(wall_with_gap):
    occ = OccupancyGrid(np.zeros((4, 4, 4), bool), np.zeros(3), V)
    with pytest.raises(ValueError, match="z_max"):
        walkable_map(occ, z_min=1.0, z_max=0.5)
    with pytest.raises(ValueError, match="spacing"):
        plan_path(wall_with_gap, np.array([0.5, 0.5]), np.array([1.0, 1.0]), spacing=0)
    with pytest.raises(ValueError, match="start"):
        plan_path(wall_with_gap, np.array([0.5, 0.5, 0.0]), np.array([1.0, 1.0]))
    # a grid lower than head height cannot be walked on (outside = occupied)
    assert not walkable_map(occ).walkable.any()
