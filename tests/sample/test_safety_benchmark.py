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
