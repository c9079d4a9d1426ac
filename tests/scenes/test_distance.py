"""SceneDistance vs analytic box / sphere distances, overlaps, shapes and bad inputs."""
import numpy as np
import pytest
import trimesh

from trumans.scenes.distance import SceneDistance

H = np.array([0.5, 0.3, 0.2])  # box half extents, m


def box_sdf(p: np.ndarray, center: np.ndarray, h: np.ndarray) -> np.ndarray:
    q = np.abs(p - center) - h
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(axis=-1), 0)


@pytest.fixture(scope="module")
def scene():
    box = trimesh.creation.box(2 * H)
    box.apply_translation([1.0, 0.0, 0.5])
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.4)
    sphere.apply_translation([-1.0, 0.5, 0.6])
    return SceneDistance({"box": box, "sphere": sphere})


def test_box_signed_distance_matches_analytic(scene):
    rng = np.random.default_rng(0)
    p = np.array([1.0, 0.0, 0.5]) + rng.uniform(-0.8, 0.8, (400, 3))
    p = p[np.linalg.norm(p - [-1.0, 0.5, 0.6], axis=1) > 1.2]  # keep the box the closest mesh
    r = scene.query(p)
    ref = box_sdf(p, np.array([1.0, 0.0, 0.5]), H)
    assert np.all(r.mesh_index == 0) and r.names == ["box", "sphere"]
    np.testing.assert_allclose(r.signed, ref, atol=2e-5)
    np.testing.assert_allclose(r.dist, np.abs(ref), atol=2e-5)
    np.testing.assert_array_equal(r.inside, ref < 0)
    np.testing.assert_allclose(np.linalg.norm(r.closest - p, axis=1), r.dist, atol=1e-5)


def test_sphere_distance_and_normals(scene):
    rng = np.random.default_rng(1)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radius = rng.uniform(0.1, 0.8, (200, 1))
    c = np.array([-1.0, 0.5, 0.6])
    p = c + d * radius
    r = scene.query(p)
    assert np.all(r.mesh_index == 1)
    np.testing.assert_allclose(r.signed, radius[:, 0] - 0.4, atol=4e-3)  # facet sag of the icosphere
    np.testing.assert_array_equal(r.inside, radius[:, 0] < 0.4)
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-5)
    assert np.all(np.sum(r.normal * d, axis=1) > 0.95)  # outward


def test_box_face_normal_is_outward(scene):
    r = scene.query(np.array([[1.8, 0.0, 0.5], [1.0, 0.0, 0.55], [1.0, -0.9, 0.5]]))
    np.testing.assert_allclose(r.normal, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-6)


def test_batch_shape_and_query_mesh(scene):
    p = np.zeros((2, 5, 3)) + [0.0, 0.0, 0.5]
    r = scene.query(p)
    assert r.dist.shape == (2, 5) and r.closest.shape == (2, 5, 3) and r.inside.shape == (2, 5)
    only = scene.query_mesh(np.array([[1.0, 0.0, 0.5]]), "sphere")
    assert only.names == ["sphere"] and only.mesh_index[0] == 0
    assert only.dist[0] == pytest.approx(np.linalg.norm([2.0, -0.5, -0.1]) - 0.4, abs=4e-3)
    assert not only.inside[0]
    with pytest.raises(KeyError, match="no mesh named"):
        scene.query_mesh(p, "table")


def test_overlapping_meshes_stay_inside():
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.box((1, 1, 1))
    b.apply_translation([0.5, 0, 0])
    p = np.array([[0.25, 0.1, 0.05], [-0.3, 0, 0], [0.8, 0, 0], [1.5, 0, 0]])
    for sd in (SceneDistance({"a": a, "b": b}), SceneDistance({"ab": trimesh.util.concatenate([a, b])})):
        r = sd.query(p)
        np.testing.assert_array_equal(r.inside, [True, True, True, False])
        assert np.all(r.signed[:3] <= 0) and r.signed[3] == pytest.approx(0.5, abs=1e-5)
    per = SceneDistance({"a": a, "b": b}).inside_per_mesh(p)
    np.testing.assert_array_equal(per, [[True, True], [True, False], [False, True], [False, False]])


def test_bad_inputs(scene):
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        scene.query(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="NaN"):
        scene.query(np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="non-empty dict"):
        SceneDistance({})
    with pytest.raises(ValueError, match="empty"):
        SceneDistance({"e": trimesh.Trimesh()})


def test_degenerate_mesh_is_refused_not_silently_untouchable():
    import trimesh

    from trumans.scenes.distance import SceneDistance

    flat = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [2, 0, 0]], faces=[[0, 1, 2]], process=False)
    with pytest.raises(ValueError, match="degenerate"):
        SceneDistance({"sliver": flat})
