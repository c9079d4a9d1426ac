"""trumans eval safety: its room models are closed rooms, its command line refuses bad input."""
import numpy as np
import pytest

from trumans.cli import console_main
from trumans.sample.eval_safety import MESH_ROOMS, write_room_models
from trumans.scenes.io import import_mesh
from trumans.scenes.occupancy import scene_occupancy
from trumans.scenes.scene import Scene
from trumans.scenes.sdf import SceneSDF


def test_room_models_are_closed_rooms(tmp_path):
    paths = write_room_models(tmp_path)
    assert [p.stem for p in paths] == list(MESH_ROOMS) and all(p.is_file() for p in paths)
    corridor = import_mesh(paths[1])
    lo, hi = corridor.bounds
    np.testing.assert_allclose(hi[:2] - lo[:2], [1.8 + 0.34, 6.0 + 0.34], atol=1e-6)  # walls + floor overhang
    occ = scene_occupancy(Scene(name="corridor", static={"mesh": corridor}), None, voxel=0.04)
    enc = SceneSDF(occ).enclosed()
    assert enc.outside is not None and enc.outside.any()  # the walls close it: there is an outside
    with pytest.raises(ValueError, match="unknown room model"):
        write_room_models(tmp_path, ("cave",))


@pytest.mark.parametrize("argv, message", [
    (["--perturbations", "base,warp"], "--perturbations"),
    (["--plans", "0"], "--plans"),
    (["--mesh-rooms", "4"], "--mesh-rooms"),
])
def test_bad_command_lines_are_refused_before_sampling(argv, message, capsys):
    assert console_main(["eval", "safety", *argv]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("rooms", [1, 2, 3, 6, 9])
def test_every_room_gets_every_plan_kind(rooms):
    """Plans dealt to rooms in turn: with enough plans each room sees each kind (9 rooms once gave every plan
    of room 3 the 'lie' kind, and no room both sat and lay down)."""
    from trumans.sample.eval_safety import PLAN_KINDS, plan_kind

    plans = 3 * rooms
    kinds = {r: {plan_kind(i, rooms) for i in range(plans) if i % rooms == r} for r in range(rooms)}
    assert all(k == set(PLAN_KINDS) for k in kinds.values()), kinds
    assert [plan_kind(i, rooms) for i in range(min(rooms, 3))] == list(PLAN_KINDS)[:min(rooms, 3)]  # round 1 as before


def test_a_stool_facing_a_wall_is_sat_on_from_its_open_side():
    """room 9004's stool stands 0.7 m from the wall its meta side faces: standing up from it put the head 6 cm
    into the wall (the safety benchmark); the plan now sits facing the side with room (a stool has no back),
    while a seat with a back keeps its meta side."""
    from trumans.sample import controller as C
    from trumans.sample.scene_input import load_sample_scene

    sc = load_sample_scene("room:9004")
    margin = C.free_margin(sc.walkmap)

    def free_at(p):
        i = np.clip(sc.walkmap.index(p), 0, np.asarray(margin.shape) - 1)
        return float(margin[i[0], i[1]])

    stool = sc.scene.objects["stool_0"]
    seat, _ = C.seat_target(stool)
    meta_yaw = float(np.arctan2(stool.pose[1, 0], stool.pose[0, 0]) + stool.meta["sit_yaw"])
    stand, yaw = C._sitting_side(stool, sc.walkmap, seat, free_at)
    assert np.cos(meta_yaw) < -0.9  # the meta side faces -x, the wall at x = 0
    assert np.cos(yaw - meta_yaw) < 0.1  # turned away from it
    assert sc.walkmap.query(stand[None])[0]
    ahead = seat[:2] + 0.65 * np.array([np.cos(yaw), np.sin(yaw)])
    assert free_at(ahead) > 0.1
    chairs = [o for o in sc.scene.objects.values() if o.category == "chair"]
    for chair in chairs:
        s, _ = C.seat_target(chair)
        _, y = C._sitting_side(chair, sc.walkmap, s, free_at)
        assert np.isclose(y, np.arctan2(chair.pose[1, 0], chair.pose[0, 0]) + chair.meta.get("sit_yaw", 0.0))
