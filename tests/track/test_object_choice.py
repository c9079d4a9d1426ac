"""Which object a contact takes: grasp points, release support, the choice among close candidates."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from trumans.track.object_choice import ObjectQueries, choose_free_object, object_candidates, release_support_gap
from trumans.scenes.scene import Scene, SceneObject


def _at(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


@pytest.fixture(scope="module")
def desk_scene() -> Scene:
    """A 1.2 x 0.6 m table top (0.70-0.74 m) centred at (2, 1); on it a pen (14 x 1 x 1 cm) at
    (2.0, 1.0) and a laptop (33 x 32 x 2 cm) whose near edge is 9 cm from the pen, and a floor."""
    table = SceneObject("table_0", "table", trimesh.creation.box((1.2, 0.6, 0.04)), _at(2.0, 1.0, 0.72))
    pen = SceneObject("pen_0", "pen", trimesh.creation.box((0.14, 0.01, 0.01)), _at(2.0, 1.0, 0.745),
                      dof="free", dynamic=True, meta={"grasp_point": [0.0, 0.0, 0.005]})
    laptop = SceneObject("laptop_0", "laptop", trimesh.creation.box((0.33, 0.32, 0.02)), _at(2.0, 1.255, 0.75),
                         dof="free", dynamic=True, meta={"grasp_point": [0.165, 0.0, 0.0]})
    floor = trimesh.creation.box((6.0, 6.0, 0.02))
    floor.apply_translation((2.0, 1.0, -0.01))
    return Scene("desk", static={"floor": floor}, objects={o.name: o for o in (table, pen, laptop)})


def _poses(scene: Scene) -> dict[str, np.ndarray]:
    return {n: o.pose[None] for n, o in scene.objects.items() if o.dof != "static"}


def test_a_declared_grasp_point_ranks_a_small_object_before_a_large_surface(desk_scene):
    """A hand drifted 8 cm toward the laptop is 1 cm above the laptop's near edge but 8 cm from the
    pen: the surface rule (no grasp points) takes the laptop, the grasp points the pen (the
    laptop is held at its +x edge, 23 cm from the hand)."""
    q = ObjectQueries(desk_scene)
    hands = np.array([[[2.0, 1.08, 0.765]]])  # (n=1, k=1, 3)
    ranked = object_candidates(q, _poses(desk_scene), 0, hands, "free", 0.5)
    assert [n for n, _ in ranked] == ["pen_0", "laptop_0"]
    assert ranked[0][1] == pytest.approx(np.hypot(0.08, 0.015), abs=1e-6)
    bare = Scene("bare", static=desk_scene.static,
                 objects={n: SceneObject(o.name, o.category, o.mesh, o.pose, o.dof, dynamic=o.dynamic)
                          for n, o in desk_scene.objects.items()})
    ranked = object_candidates(ObjectQueries(bare), _poses(bare), 0, hands, "free", 0.5)
    assert ranked[0][0] == "laptop_0" and ranked[0][1] < 0.02
    # the radius is on the surface distance; other dofs are not candidates
    assert object_candidates(q, _poses(desk_scene), 0, hands + [0, 0, 1.0], "free", 0.5) == []
    assert object_candidates(q, _poses(desk_scene), 0, hands, "hinge", 0.5) == []


def test_release_support_gap_on_a_table_and_past_its_edge(desk_scene):
    q = ObjectQueries(desk_scene)
    others = {"table_0": desk_scene.objects["table_0"].pose}
    on_top = _at(2.3, 0.9, 0.745)  # resting on the table top (0.74)
    assert release_support_gap(q, "pen_0", on_top, others) == pytest.approx(0.005, abs=1e-4)
    past = _at(2.75, 0.9, 0.745)  # centre 15 cm past the table's +x edge (2.6)
    assert release_support_gap(q, "pen_0", past, others) == pytest.approx(0.15, abs=2e-3)
    # on the floor (a static mesh) it rests again; another object can be the support too
    assert release_support_gap(q, "pen_0", _at(4.0, 1.0, 0.005), others) == pytest.approx(0.005, abs=1e-4)
    on_laptop = _at(2.0, 1.255, 0.765)
    others_l = others | {"laptop_0": desk_scene.objects["laptop_0"].pose}
    assert release_support_gap(q, "pen_0", on_laptop, others_l) == pytest.approx(0.005, abs=1e-4)
    assert release_support_gap(q, "pen_0", on_laptop, others) > 0.01  # the laptop is the object itself: ignored


def test_choose_free_object_prefers_the_one_that_rests_among_close_candidates():
    cands = [("a", 0.02), ("b", 0.10), ("c", 0.40)]
    assert choose_free_object(cands, {"a": 0.30, "b": 0.005}, ambiguity=0.15) == "b"  # a would fall
    assert choose_free_object(cands, {"a": 0.015, "b": 0.005}, ambiguity=0.15) == "a"  # both rest: nearest
    assert choose_free_object(cands, {"a": 0.30, "b": 0.005}, ambiguity=0.05) == "a"  # b is too far to doubt
    assert choose_free_object(cands, {"a": 0.30, "c": 0.005}, ambiguity=0.15) == "a"  # c is outside the window
    assert choose_free_object(cands, {}, ambiguity=0.15) == "a"  # still held at the end: nothing let go
    assert choose_free_object(cands[:1], {"a": 0.5}, ambiguity=0.15) == "a"
    with pytest.raises(ValueError, match="no candidate"):
        choose_free_object([], {}, ambiguity=0.15)
