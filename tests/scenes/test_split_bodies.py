"""split_bodies' parts cache (trumans.scenes.raycast.split_parts): a moved, scaled or copied mesh
reuses the parts of its topology and gets exactly what a fresh trimesh split gives it."""
import numpy as np
import pytest
import trimesh

from trumans.scenes import raycast
from trumans.scenes.raycast import bodies_inside, split_bodies, split_parts


def _chair() -> trimesh.Trimesh:
    """Six overlapping boxes (seat, back, four legs): six closed bodies, as the procedural chairs."""
    parts = [((0.5, 0.5, 0.05), (0, 0, 0.45)), ((0.5, 0.05, 0.5), (0, 0.225, 0.7))]
    parts += [((0.05, 0.05, 0.45), (x, y, 0.225)) for x in (-0.2, 0.2) for y in (-0.2, 0.2)]
    boxes = []
    for ext, c in parts:
        b = trimesh.creation.box(ext)
        b.apply_translation(c)
        boxes.append(b)
    return trimesh.util.concatenate(boxes)


def _open_box_and_box() -> trimesh.Trimesh:
    """A box without its top and one side (an open body: trimesh's split fills a lone triangle or
    quad hole, not this six-edge one) beside a closed box."""
    a = trimesh.creation.box((0.4, 0.4, 0.4))
    a.update_faces((a.face_normals[:, 2] < 0.9) & (a.face_normals[:, 0] < 0.9))
    a.remove_unreferenced_vertices()
    b = trimesh.creation.box((0.2, 0.2, 0.2))
    b.apply_translation((1.0, 0.0, 0.0))
    return trimesh.util.concatenate([a, b])


def _fresh_parts(mesh: trimesh.Trimesh) -> list:
    raycast.SPLIT_PARTS_CACHE.clear()
    merged = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=True)
    return split_parts(merged, "auto")


def _variants(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    moved = mesh.copy()
    moved.apply_transform(trimesh.transformations.rotation_matrix(0.3, (0, 0, 1), (0.1, 0.2, 0)))
    moved.apply_translation((0.13, -0.07, 0.0))
    scaled = mesh.copy()
    scaled.vertices = np.asarray(scaled.vertices) * (1.07, 0.93, 1.31)
    return [moved, scaled]


@pytest.mark.parametrize("make", [_chair, _open_box_and_box])
def test_cached_parts_equal_a_fresh_split(make):
    mesh = make()
    for other in _variants(mesh):
        fresh = _fresh_parts(other)  # a miss: trimesh's split of this very mesh
        _fresh_parts(mesh)  # the cache now holds the parts of the original only
        merged = trimesh.Trimesh(np.asarray(other.vertices), np.asarray(other.faces), process=True)
        cached = split_parts(merged, "auto")
        assert len(raycast.SPLIT_PARTS_CACHE) == 1  # a hit: no second entry
        assert len(cached) == len(fresh)
        for (v1, f1, c1), (v2, f2, c2) in zip(cached, fresh):
            assert c1 == c2
            np.testing.assert_array_equal(f1, f2)
            np.testing.assert_array_equal(v1, v2)


def test_chair_bodies_inside_matches_the_union_of_its_boxes():
    mesh = _chair()
    raycast.SPLIT_PARTS_CACHE.clear()
    split_bodies(mesh)  # fills the cache
    scaled = mesh.copy()
    s = np.array([1.1, 0.9, 1.2])
    scaled.vertices = np.asarray(scaled.vertices) * s
    bodies = split_bodies(scaled)  # from the cache
    assert len(bodies) == 6 and all(b.closed for b in bodies)
    rng = np.random.default_rng(0)
    p = rng.uniform((-0.35, -0.35, -0.05), (0.35, 0.35, 1.2), (4000, 3)) * s
    q = p / s  # the same points in the unscaled chair, where the boxes are known
    inside = np.zeros(len(q), bool)
    margin = np.full(len(q), np.inf)  # distance to the nearest box face, to skip points on a surface
    for ext, c in [((0.5, 0.5, 0.05), (0, 0, 0.45)), ((0.5, 0.05, 0.5), (0, 0.225, 0.7))] + \
            [((0.05, 0.05, 0.45), (x, y, 0.225)) for x in (-0.2, 0.2) for y in (-0.2, 0.2)]:
        d = np.abs(q - c) - np.asarray(ext) / 2
        inside |= (d < 0).all(1)
        margin = np.minimum(margin, np.abs(d).min(1))
    ok = margin > 1e-4
    assert inside[ok].sum() > 100
    np.testing.assert_array_equal(bodies_inside(bodies, p)[ok], inside[ok])


def test_open_body_stays_open_and_cache_is_bounded(monkeypatch):
    monkeypatch.setattr(raycast, "SPLIT_PARTS_CACHE_SIZE", 2)
    raycast.SPLIT_PARTS_CACHE.clear()
    bodies = split_bodies(_open_box_and_box())
    assert sorted(b.closed for b in bodies) == [False, True]
    for n in (1, 2, 3):  # three topologies: the least recently used is dropped
        split_bodies(trimesh.creation.icosphere(subdivisions=n))
    assert len(raycast.SPLIT_PARTS_CACHE) == 2
