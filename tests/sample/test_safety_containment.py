"""The containment step (trumans.sample.cleanup.containment) against an adversarial stand-in network
that always overshoots its goal by 40 cm toward a wall: the body stays inside the room."""
import numpy as np
import pytest
import trimesh
from helpers import standing_body, tiny_checkpoint

from trumans.eval.safety import core_depths, crossings, room_exits
from trumans.sample.cleanup.containment import ContainmentConfig, contain
from trumans.sample.plan import far_point, plan_from_dict
from trumans.sample.rollout import sample_plan
from trumans.sample.sampler import EpisodeSampler, SamplerConfig
from trumans.scenes.occupancy import scene_occupancy
from trumans.scenes.scene import Scene
from trumans.scenes.scene_grids import SceneGrids
from trumans.scenes.sdf import SceneSDF
from trumans.scenes.walkability import walkable_map
from trumans.skeleton import JOINT_INDEX

PELVIS = JOINT_INDEX["pelvis"]
WALL_Y = 3.0  # the wall the plan walks at: y in [3.0, 3.1]


def closed_room() -> Scene:
    """Interior [0, 3] x [0, 3] m, four 10 cm walls 2.5 m high, a floor slab; no door."""
    box = lambda lo, hi: trimesh.creation.box(bounds=[lo, hi])  # noqa: E731
    t = 0.1
    static = {"floor": box((-t, -t, -0.05), (3 + t, 3 + t, 0.0)),
              "wall_0": box((-t, -t, 0), (3 + t, 0, 2.5)), "wall_1": box((-t, 3, 0), (3 + t, 3 + t, 2.5)),
              "wall_2": box((-t, 0, 0), (0, 3, 2.5)), "wall_3": box((3, 0, 0), (3 + t, 3, 2.5))}
    return Scene(name="closed", static=static)


class Overshoot(EpisodeSampler):
    """A stand-in network: the last context pose slid in a straight line to 40 cm past its pelvis
    goal (past where it stands when the goal is where it stands: toward the +y wall)."""

    def episode(self, context, labels, goals, object_poses=None, generator=None, **overlap):
        L, k = self.L, self.k
        out = np.repeat(context[:, -1:], L, 1).astype(np.float64)
        out[:, :k] = context
        for b, g in enumerate(goals):
            c = context[b, -1, PELVIS, :2].astype(np.float64)
            goal = np.asarray(g.point[:2], np.float64) if g.joint == "pelvis" else c
            d = goal - c
            u = d / np.linalg.norm(d) if np.linalg.norm(d) > 0.05 else np.array([0.0, 1.0])
            s = np.linspace(0.0, 1.0, L - k + 1)[1:, None]
            out[b, k:, :, :2] += (s * (goal + 0.4 * u - c))[:, None]
        return out.astype(np.float32)


@pytest.fixture(scope="module")
def room():
    scene = closed_room()
    occ = scene_occupancy(scene, None, voxel=0.04)
    return scene, occ, walkable_map(occ)


def _run(room, config: SamplerConfig):
    from dataclasses import replace

    config = replace(config, overlap=0)  # the stand-in does not follow an overlap's frames, as a network does
    scene, occ, wm = room
    ckpt = tiny_checkpoint()
    sampler = Overshoot(ckpt, SceneGrids(occ, scene), config)
    plan = plan_from_dict({"start": [1.5, 1.2], "heading": float(np.pi / 2), "steps": [
        {"do": "goto", "to": [1.5, 2.7]}, {"do": "act", "action": "drink", "seconds": 3.0}]})
    return sample_plan(ckpt, sampler, scene, wm, plan, max_seconds=40.0).joints[0], SceneSDF(occ)


def test_a_network_that_overshoots_toward_the_wall_stays_inside(room):
    J, sdf = _run(room, SamplerConfig(goal_guidance=0.0))
    pelvis = J[:, PELVIS]
    assert pelvis[:, 1].max() <= WALL_Y - 0.22 + 0.02  # the torso's clearance from the wall
    assert not room_exits(pelvis[:, :2], sdf).any()
    assert not crossings(J, sdf).any()
    assert core_depths(J, sdf).max() < 0.05


def test_without_the_constraints_the_same_network_leaves_the_room(room):
    """The control: the soft push-out alone does not hold the stand-in back (so the test above can
    fail); the swept guard alone (no containment) stops it at the wall."""
    cleanup = SamplerConfig().cleanup
    J, sdf = _run(room, SamplerConfig(goal_guidance=0.0, cleanup=cleanup.switched(containment=False,
                                                                                  swept_guard=False)))
    assert J[:, PELVIS, 1].max() > WALL_Y - 0.1
    assert room_exits(J[:, PELVIS, :2], sdf).any() or core_depths(J, sdf).max() > 0.1
    J, sdf = _run(room, SamplerConfig(goal_guidance=0.0, cleanup=cleanup.switched(containment=False)))
    assert not room_exits(J[:, PELVIS, :2], sdf).any() and not crossings(J, sdf).any()
    assert core_depths(J, sdf).max() < 0.05


def test_contain_moves_only_upright_frames_and_keeps_the_context(room):
    scene, occ, wm = room
    sdf = SceneSDF(occ)
    T, k = 12, 2
    J = standing_body(T)
    J[..., :2] += (np.array([1.5, 2.95]) - J[0, 0, PELVIS, :2])  # pelvis 5 cm from the wall's face
    w = np.ones((1, T))
    w[0, 8:] = 0.0  # seated frames: the constraint is off
    out = contain(J, sdf, w, k, ContainmentConfig(spread=0, max_speed=1e3))
    np.testing.assert_array_equal(out[0, :k], J[0, :k])
    assert np.all(out[0, k:8, PELVIS, 1] <= WALL_Y - 0.22 + 0.02)  # within half a 4 cm voxel
    np.testing.assert_allclose(out[0, 8:], J[0, 8:])
    np.testing.assert_allclose(out[..., 2], J[..., 2])  # horizontal moves only
    d = out - J
    assert np.abs(d - d[:, :, :1]).max() < 1e-9  # a rigid shift of each frame
    # by default the correction changes by at most max_speed / fps a frame: it leaves the (fixed, too
    # close) context and goes back to 0 on the seated frames over two frames each
    d = contain(J, sdf, w, k, ContainmentConfig(spread=0))[0, :, PELVIS, 1] - J[0, :, PELVIS, 1]
    step = ContainmentConfig().max_speed / 10.0
    assert np.abs(np.diff(d)).max() <= step + 1e-6 and d[k] == pytest.approx(-step)
    assert np.all(out[0, k + 1:8, PELVIS, 1] <= WALL_Y - 0.22 + 0.02) and d[9] == 0.0
    with pytest.raises(ValueError, match="weight"):
        contain(J, sdf, np.ones((1, T + 1)), k)
    with pytest.raises(ValueError, match="clearance"):
        ContainmentConfig(clearance=-0.1)


def test_far_point_keeps_off_the_walkable_edge(room):
    scene, occ, wm = room
    p = far_point(wm, np.array([1.5, 1.5]), within=3.0, margin=0.3)
    # the walkable floor ends 0.25 m from the walls; the point is 0.3 m inside that
    assert np.all(p >= 0.25 + 0.3 - 0.05) and np.all(p <= 3.0 - 0.25 - 0.3 + 0.05)
    assert np.linalg.norm(p - 1.5) > 0.8  # still far: a corner of the inner square
    with pytest.raises(ValueError, match="walkable"):
        far_point(wm, np.array([-1.0, -1.0]))


def test_the_swept_guard_stops_a_body_at_a_thin_wall_it_would_jump_through():
    from trumans.sample.cleanup.swept import SweptGuardConfig, guard_crossings
    from trumans.scenes.occupancy import OccupancyGrid

    origin = np.array([0.01, 0.01, -0.09])
    x, y, z = np.meshgrid(*(origin[i] + 0.02 * np.arange(n) for i, n in enumerate((150, 150, 120))), indexing="ij")
    sdf = SceneSDF(OccupancyGrid((z < 0) | ((x > 1.5) & (x < 1.62)), origin, 0.02))  # a 12 cm wall across
    T, k = 10, 2
    J = standing_body(T)
    J[..., 0] += (np.r_[1.0, 1.1, 1.2, 1.3, 1.95, 2.05, 2.15, 2.25, 2.35, 2.45] - J[0, :, PELVIS, 0])[:, None]
    J[..., 1] += 1.5 - J[0, 0, PELVIS, 1]
    assert crossings(J[0], sdf).any()
    out = guard_crossings(J, sdf, k)
    assert not crossings(out[0], sdf).any()
    np.testing.assert_array_equal(out[0, :k], J[0, :k])
    assert out[0, :, PELVIS, 0].max() < 1.5  # the body stays on its side of the wall
    assert core_depths(out[0], sdf).max() <= SweptGuardConfig().max_depth_seated + 1e-3  # the cap off the feet
    # upright frames also do not walk deeper than max_depth into the wall
    up = guard_crossings(J, sdf, k, SweptGuardConfig(max_depth=0.01), weight=np.ones((1, T)))
    assert core_depths(up[0], sdf).max() <= 0.01 + 1e-3
    with pytest.raises(ValueError, match="max_depth"):
        SweptGuardConfig(max_depth=-1.0)


def _table_room() -> SceneSDF:
    """A 3 x 3 m floor (2 cm voxels) with a 60 x 60 cm block from the floor to 75 cm at its middle."""
    from trumans.scenes.occupancy import OccupancyGrid

    origin = np.array([0.01, 0.01, -0.09])
    x, y, z = np.meshgrid(*(origin[i] + 0.02 * np.arange(n) for i, n in enumerate((150, 150, 120))), indexing="ij")
    table = (np.abs(x - 1.5) < 0.3) & (np.abs(y - 1.5) < 0.3) & (z < 0.75)
    return SceneSDF(OccupancyGrid((z < 0) | table, origin, 0.02))


def test_a_body_walked_through_a_table_comes_out_on_one_side_without_a_jump():
    """A network that walks straight through a table: the per-frame projection must put the pelvis
    on one side of it and, where the table ends, switch sides; the correction changes by at most
    max_speed / fps a frame, so the body never jumps (the control, without the limit, does)."""
    sdf = _table_room()
    T, k, fps = 24, 2, 10.0
    J = standing_body(T)[0]
    path = np.stack([np.linspace(0.6, 2.4, T), np.full(T, 1.52)], -1)  # 7.8 cm a frame, 2 cm off the middle
    J[..., :2] += (path - J[:, PELVIS, :2])[:, None]
    w = np.ones((1, T))
    jumps = {}
    for speed in (1.0, 1e3):
        out = contain(J[None], sdf, w, k, ContainmentConfig(max_speed=speed), fps=fps)
        d = out[0, :, PELVIS, :2] - J[:, PELVIS, :2]
        jumps[speed] = np.linalg.norm(np.diff(d, axis=0), axis=-1).max()
        assert np.linalg.norm(d, axis=-1)[T // 2] > 0.3  # out of the table's middle
    assert jumps[1.0] <= 1.0 / fps + 1e-6
    assert jumps[1e3] > 0.3  # the control: an unlimited projection switches sides in one frame


def test_a_partly_carried_body_over_a_seat_moves_at_most_the_clearance_it_is_asked():
    """Sitting down, the pelvis is over the seat, whose column is solid: a frame the feet carry with
    weight w moves by at most w * clearance (the far fallback threw it 20-30 cm), none at w = 0."""
    sdf = _table_room()
    T, k = 10, 2
    J = standing_body(T)[0]
    J[..., :2] += (np.array([1.45, 1.5]) - J[0, PELVIS, :2])  # over the block
    w = np.zeros((1, T))
    w[0, k:] = np.linspace(0.3, 0.0, T - k)
    config = ContainmentConfig()
    out = contain(J[None], sdf, w, k, config)
    move = np.linalg.norm(out[0, :, PELVIS, :2] - J[:, PELVIS, :2], axis=-1)
    need = w[0] * (config.clearance + 0.5 * sdf.enclosed().voxel)
    assert move[k] == pytest.approx(need[k]) and move.max() <= need.max() + 1e-6  # eased onto its neighbours
    upright = contain(J[None], sdf, np.ones((1, T)), k, config)  # the control: an upright body leaves the block
    assert np.linalg.norm(upright[0, -1, PELVIS, :2] - J[-1, PELVIS, :2]) > 0.3
    with pytest.raises(ValueError, match="max_speed"):
        ContainmentConfig(max_speed=0.0)
    with pytest.raises(ValueError, match="fps"):
        contain(J[None], sdf, w, k, config, fps=0.0)
