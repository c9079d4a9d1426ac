"""trumans.sample.carry: objects moved after the body (TRUMANS §4.2) within their degrees of freedom."""
from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from trumans.track.objects import dof_limits, dof_value
from trumans.sample.carry import CarryConfig, initial_motion, object_tracks, optimise_motion, \
    plan_interactions
from trumans.sample.carry_metrics import carry_figures
from trumans.sample.carry_plan import GRASP_SPAN, OPEN_FRACTION, articulated_pose, surface_point
from trumans.sample.controller import Phase, compile_plan
from trumans.viz.export import export
from trumans.sample.plan import plan_from_dict, validate_plan
from trumans.scenes.procedural import make_room
from trumans.scenes.walkability import walkable_map
from trumans.scenes.occupancy import scene_occupancy
from trumans.track.objects import rotation_about_axis
from trumans.sequence import Sequence, load_sequence
from trumans.skeleton import JOINT_INDEX

VOCAB = ["walk", "stand", "reach", "pick_up", "put_down", "open_door", "close_door", "open_drawer", "close_drawer"]


@pytest.fixture(scope="module")
def room():
    return make_room(2)  # door_0 (hinge), cabinet_0 + drawers (slide), cups and books on table_0


def _smooth(n: int) -> np.ndarray:
    t = np.linspace(0, 1, n)
    return 3 * t ** 2 - 2 * t ** 3


def _rigid_hand(poses: np.ndarray, local: np.ndarray) -> np.ndarray:
    return np.einsum("nij,kj->nki", poses[:, :3, :3], local) + poses[:, None, :3, 3]


def test_free_object_path_is_recovered_from_a_noisy_hand(room):
    cup, n = room.objects["cup_0"], 30
    s = _smooth(n)
    true = np.tile(np.eye(4), (n, 1, 1))
    true[:, :3, :3] = Rotation.from_euler("z", 0.5 * s[:, None]).as_matrix() @ cup.pose[:3, :3]
    true[:, :3, 3] = cup.pose[:3, 3] + np.stack([0.8 * s, -0.3 * s, 0.3 * np.sin(np.pi * s)], 1)
    rng = np.random.default_rng(0)
    hand = _rigid_hand(true, np.array([[0.05, 0.0, 0.05], [0.12, 0.0, 0.06]])) + rng.normal(0, 0.004, (n, 2, 3))
    init = true.copy()
    init[1:-1, :3, 3] += rng.normal(0, 0.04, (n - 2, 3))
    out = optimise_motion(cup, init, hand, fix_end=True)
    np.testing.assert_allclose(out[[0, -1]], true[[0, -1]], atol=1e-9)  # grasp and put-down poses kept
    assert np.abs(out[:, :3, 3] - true[:, :3, 3]).max() < 0.02 < np.abs(init[:, :3, 3] - true[:, :3, 3]).max()
    ang = Rotation.from_matrix(np.einsum("nji,njk->nik", true[:, :3, :3], out[:, :3, :3])).magnitude()
    assert ang.max() < 0.1
    np.testing.assert_allclose(np.einsum("nij,njk->nik", out[:, :3, :3], out[:, :3, :3].transpose(0, 2, 1)),
                               np.tile(np.eye(3), (n, 1, 1)), atol=1e-9)  # rigid


def test_hinge_angle_is_recovered_and_the_door_only_turns_about_its_axis(room):
    door, n = room.objects["door_0"], 30
    axis, point = door.pose[:3, :3] @ door.axis, door.pose[:3, :3] @ door.hinge_point + door.pose[:3, 3]
    angle = 1.0 * _smooth(n)
    true = rotation_about_axis(angle, axis, point) @ door.pose
    handle = np.asarray(door.meta["handle"])
    hand = _rigid_hand(true, np.stack([handle, handle + [0.05, 0, 0]])) + np.random.default_rng(1).normal(0, 0.01, (n, 2, 3))
    init = initial_motion(door, door.pose, hand, np.tile(np.eye(3), (n, 1, 1)))
    out = optimise_motion(door, init, hand, fix_end=False)
    got = np.array([dof_value(door, p) for p in out])
    assert np.abs(got - angle).max() < 0.03
    # every pose is the scene pose turned about the hinge: the hinge point does not move, z stays up
    hp = np.einsum("nij,j->ni", out[:, :3, :3], door.hinge_point) + out[:, :3, 3]
    np.testing.assert_allclose(hp, np.broadcast_to(point, hp.shape), atol=1e-9)
    np.testing.assert_allclose(out[:, :3, 2], np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), atol=1e-9)


@pytest.mark.parametrize("name, beyond", [("door_0", 2.2), ("cabinet_0_drawer_1", 0.8)])
def test_dof_limits_hold_when_the_hand_pulls_too_far(room, name, beyond):
    obj, n = room.objects[name], 25
    lo, hi = dof_limits(obj)
    assert lo == 0.0 and hi == pytest.approx(obj.meta.get("max_angle", obj.meta.get("max_travel")))
    if obj.dof == "hinge":
        axis, point = obj.pose[:3, :3] @ obj.axis, obj.pose[:3, :3] @ obj.hinge_point + obj.pose[:3, 3]
        moved = rotation_about_axis(beyond * _smooth(n), axis, point) @ obj.pose
    else:
        moved = np.tile(obj.pose, (n, 1, 1))
        moved[:, :3, 3] += (beyond * _smooth(n))[:, None] * (obj.pose[:3, :3] @ obj.axis)
    hand = _rigid_hand(moved, np.stack([np.asarray(obj.meta["handle"])] * 2))
    init = initial_motion(obj, obj.pose, hand, np.tile(np.eye(3), (n, 1, 1)))
    out = optimise_motion(obj, init, hand, fix_end=False)
    v = np.array([dof_value(obj, p) for p in out])
    assert v.min() >= lo - 1e-9 and v.max() <= hi + 1e-9 and v.max() > hi - 0.05  # pulled to, not past, the end


def _joints_with_hand(wrist: np.ndarray) -> np.ndarray:
    """(T, 24, 3) body whose right wrist follows ``wrist`` (T, 3); the rest is a plausible stand."""
    T = len(wrist)
    j = np.zeros((T, 24, 3))
    j[:, :, 2] = 1.0
    j[:, JOINT_INDEX["right_wrist"]] = wrist
    j[:, JOINT_INDEX["right_index1"]] = wrist + [0.0, 0.0, -0.08]
    j[:, JOINT_INDEX["right_elbow"]] = wrist + [-0.25, 0.0, 0.05]
    return j


def _pick_place_phases(room, grasp: np.ndarray, place: np.ndarray) -> tuple[list[Phase], np.ndarray]:
    phases = [Phase("reach", ("pick_up",), 10, hand_goal=grasp, info={"object": "cup_0", "do": "pick_up"}),
              Phase("walk", ("walk",), path=np.zeros((2, 2))),
              Phase("reach", ("put_down",), 10, hand_goal=place, info={"object": "cup_0", "do": "put_down"})]
    phase = np.repeat([0, 1, 2], 10)
    return phases, phase


def test_carried_cup_rides_the_hand_and_rests_on_the_cabinet(room, tmp_path):
    cup, cab = room.objects["cup_0"], room.objects["cabinet_0"]
    grasp = cup.pose[:3, :3] @ np.asarray(cup.meta["grasp_point"]) + cup.pose[:3, 3]
    top = cab.pose[:3, :3] @ np.asarray(cab.meta["surface_center"]) + cab.pose[:3, 3]
    place = top + (grasp - cup.pose[:3, 3]) + [0.0, 0.0, 0.03]  # released 3 cm above the top
    wrist = np.concatenate([np.linspace(grasp + [0.4, 0, 0.1], grasp, 10),
                            grasp + np.linspace(0, 1, 20)[:, None] * (place - grasp)
                            + np.sin(np.pi * np.linspace(0, 1, 20))[:, None] * [0, 0, 0.2]])
    joints = _joints_with_hand(wrist)
    phases, phase = _pick_place_phases(room, grasp, place)
    its, missed = plan_interactions(phase, phases, joints)
    assert missed == [] and len(its) == 1 and (its[0].start, its[0].end) == (9, 29)
    tracks, its, info = object_tracks(joints, phase, phases, room)
    pose = tracks["cup_0"].pose.astype(np.float64)
    np.testing.assert_allclose(pose[:10], np.broadcast_to(cup.pose, (10, 4, 4)), atol=1e-6)  # at rest until the grasp
    final = pose[-1]
    assert final[2, 3] == pytest.approx(top[2], abs=2e-3)  # standing on the cabinet top, not in the air
    np.testing.assert_allclose(final[:3, 2], [0, 0, 1], atol=1e-6)  # upright
    assert np.linalg.norm(final[:2, 3] - (place - (grasp - cup.pose[:3, 3]))[:2]) < 0.03  # where the hand let go
    fig = carry_figures(joints, tracks, its, info, room, phases)
    assert fig["hoi_grasps_reached"] == 1 and fig["hoi_grasps_missed"] == 0
    assert fig["hoi_hand_obj_dist_std_cm"] < 1.5 < fig["hoi_hand_obj_dist_std_cm_static"]
    assert fig["hoi_place_err_cm"] < 4.0 and fig["hoi_float_cm"] < 0.5 and fig["hoi_obj_penetration_max_cm"] < 1.0
    # the moving cup goes through npz and GLB
    seq = Sequence(joints=joints.astype(np.float32), fps=10.0, objects=tracks)
    out = export(seq, tmp_path / "carry", {"npz", "glb"}, scene=room)
    back = load_sequence(out["npz"])
    np.testing.assert_allclose(back.objects["cup_0"].pose, tracks["cup_0"].pose)
    assert back.objects["cup_0"].category == "cup"
    data = out["glb"].read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + jlen])
    node = [n.get("name") for n in gltf["nodes"]].index("cup_0")
    ch = [c for c in gltf["animations"][0]["channels"] if c["target"] == {"node": node, "path": "translation"}]
    acc = gltf["accessors"][gltf["animations"][0]["samplers"][ch[0]["sampler"]]["output"]]
    view = gltf["bufferViews"][acc["bufferView"]]
    t = np.frombuffer(data[28 + jlen:], np.float32, acc["count"] * 3, view["byteOffset"]).reshape(-1, 3)
    np.testing.assert_allclose(t, pose[:, :3, 3], atol=1e-5)
    assert "cup_0" in trimesh.load(out["glb"]).geometry


def test_an_unreached_grasp_moves_nothing(room):
    cup = room.objects["cup_0"]
    grasp = cup.pose[:3, :3] @ np.asarray(cup.meta["grasp_point"]) + cup.pose[:3, 3]
    joints = _joints_with_hand(np.tile(grasp + [1.0, 0.0, 0.0], (30, 1)))  # the hand stays 1 m away
    phases, phase = _pick_place_phases(room, grasp, grasp)
    tracks, its, info = object_tracks(joints, phase, phases, room, CarryConfig(reach_m=0.25))
    assert tracks == {} and its == [] and info["missed"][0][0] == "cup_0"
    assert info["missed"][0][1] == pytest.approx(1.0, abs=1e-6)
    assert carry_figures(joints, tracks, its, info, room, phases) == {
        "hoi_grasps_reached": 0, "hoi_grasps_missed": 1, "hoi_missed_dist_cm": 100.0}


def test_compiled_object_steps_give_place_and_handle_goals(room):
    occ = scene_occupancy(room, None, voxel=0.05)
    wm = walkable_map(occ)
    plan = plan_from_dict({"start": [2.4, 2.4], "steps": [
        {"do": "pick_up", "object": "cup_0"}, {"do": "put_down", "object": "cup_0", "target": "cabinet_0"},
        {"do": "open", "object": "door_0"}]})
    validate_plan(plan, room, VOCAB)
    phases = compile_plan(plan, room, wm, np.array([2.4, 2.4]), {}, 10.0)
    reach = [p for p in phases if p.kind == "reach"]
    assert [p.info["do"] for p in reach] == ["pick_up", "put_down", "open", "open"]
    cup, cab, door = room.objects["cup_0"], room.objects["cabinet_0"], room.objects["door_0"]
    off = cup.pose[:3, :3] @ np.asarray(cup.meta["grasp_point"])
    np.testing.assert_allclose(reach[0].hand_goal, cup.pose[:3, 3] + off)
    top = surface_point(cab)
    assert top[2] == pytest.approx(cab.meta["surface_height"]) and np.linalg.norm(top[:2] - cab.pose[:2, 3]) > 0.1
    np.testing.assert_allclose(reach[1].hand_goal, top + off)
    for p in reach:  # the pelvis stands within reach of every hand goal
        stand = phases[phases.index(p) - 1].goal if phases[phases.index(p) - 1].kind == "walk" else None
        if stand is not None:
            assert np.linalg.norm(stand - p.hand_goal[:2]) < 0.9
    handle = np.asarray(door.meta["handle"])
    opened = articulated_pose(door, OPEN_FRACTION)
    np.testing.assert_allclose(reach[2].hand_goal, door.pose[:3, :3] @ handle + door.pose[:3, 3])
    np.testing.assert_allclose(reach[3].hand_goal, opened[:3, :3] @ handle + opened[:3, 3])
    assert reach[2].span == (0.0, GRASP_SPAN) and reach[3].span == (GRASP_SPAN, 1.0)
    assert dof_value(door, opened) == pytest.approx(OPEN_FRACTION * door.meta["max_angle"] * door.meta["open_sign"])


@pytest.mark.parametrize("steps, match", [
    ([{"do": "pick_up", "object": "table_0"}], "cannot be picked up"),
    ([{"do": "pick_up", "object": "door_0"}], "cannot be picked up"),
    ([{"do": "put_down", "object": "cup_0"}], "is not held"),
    ([{"do": "pick_up", "object": "cup_0"}, {"do": "pick_up", "object": "cup_1"}], "already holds 'cup_0'"),
    ([{"do": "pick_up", "object": "cup_0"}, {"do": "put_down", "object": "cup_0", "target": "bed_0"}], "without a surface"),
    ([{"do": "pick_up", "object": "cup_0"}, {"do": "put_down", "object": "cup_0", "target": "nowhere"}], "no object 'nowhere'"),
    ([{"do": "open", "object": "cup_0"}], "door"),
])
def test_bad_object_plans_fail_before_sampling(room, steps, match):
    with pytest.raises(ValueError, match=match):
        validate_plan(plan_from_dict({"steps": steps}), room, VOCAB)


def test_later_episodes_see_objects_where_the_plan_left_them(room):
    from trumans.sample.carry_plan import planned_object_poses
    from trumans.sample.controller import Controller
    from trumans.scenes.scene_grids import SceneGrids

    occ = scene_occupancy(room, None, voxel=0.05)
    plan = plan_from_dict({"start": [2.4, 2.4], "steps": [
        {"do": "pick_up", "object": "cup_0"}, {"do": "put_down", "object": "cup_0", "target": "cabinet_0"},
        {"do": "open", "object": "door_0"}]})
    phases = compile_plan(plan, room, walkable_map(occ), np.array([2.4, 2.4]), {}, 10.0)
    grids = SceneGrids(None, room, voxel=0.1)
    ctrl = Controller(phases, VOCAB, 16, 2, 10.0)
    assert planned_object_poses([ctrl], grids) is None  # nothing moved yet
    done = {p.info["do"]: i + 1 for i, p in enumerate(phases) if "after" in p.info}
    ctrl.index = done["pick_up"]
    held = planned_object_poses([ctrl], grids)["cup_0"][0]
    assert held[2, 3] < -10  # carried: out of the scene grids
    ctrl.index = len(phases)
    moved = planned_object_poses([ctrl, Controller(phases, VOCAB, 16, 2, 10.0)], grids)
    placed = moved["cup_0"]
    assert placed[0, 2, 3] == pytest.approx(room.objects["cabinet_0"].meta["surface_height"])
    np.testing.assert_allclose(placed[1], room.objects["cup_0"].pose)  # the second sample has not started
    np.testing.assert_allclose(moved["door_0"][0], articulated_pose(room.objects["door_0"], OPEN_FRACTION))
    # the open door is in the local grid in front of the doorway, the closed one is not
    door = room.objects["door_0"]
    c = articulated_pose(door, OPEN_FRACTION) @ np.array([0.0, 0.0, 0.0, 1.0])
    mid = 0.5 * (c[:3] + (door.pose[:3, :3] @ door.hinge_point + door.pose[:3, 3]))
    centre = np.array([[mid[0], mid[1], 0.0]])
    with_open = grids.query(centre, np.zeros(1), {"door_0": moved["door_0"][:1]})
    closed = grids.query(centre, np.zeros(1))
    assert with_open.sum() > closed.sum()
