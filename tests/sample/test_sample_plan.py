"""trumans.sample.plan (parsing, validation) and trumans.sample.controller (phases, closed-loop episode controls)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from trumans.sample.controller import TURN_FREE_MARGIN_M, Controller, Phase, compile_plan, free_margin, sit_down_subgoal
from trumans.sample.plan import Step, load_plan, plan_from_dict, validate_plan
from trumans.scenes import furniture
from trumans.scenes.occupancy import scene_occupancy
from trumans.scenes.scene import Scene
from trumans.scenes.walkability import walkable_map

VOCAB = ["stand", "walk", "sit_down", "sit", "stand_up", "drink", "reach", "lie_down", "lie", "get_up"]


@pytest.fixture(scope="module")
def room():
    import trimesh

    rng = np.random.default_rng(0)
    chair = furniture.chair(rng, "chair_0")
    chair.pose[:3, 3] = [3.0, 2.0, 0.0]
    floor = trimesh.creation.box((6.0, 4.0, 0.1))
    floor.apply_translation([3.0, 2.0, -0.05])
    scene = Scene("test_room", static={"floor": floor}, objects={"chair_0": chair})
    occ = scene_occupancy(scene, None, voxel=0.05)
    return scene, walkable_map(occ)


def test_plan_from_dict_and_files(tmp_path):
    d = {"start": [1, 1], "heading": 0.5, "steps": [{"do": "goto", "to": [2, 1]}, {"do": "sit_on", "object": "c",
                                                                                   "seconds": 3}]}
    p = plan_from_dict(d)
    assert p.start == (1.0, 1.0) and p.heading == 0.5
    assert p.steps == (Step("goto", to=(2.0, 1.0)), Step("sit_on", object="c", seconds=3.0))
    (tmp_path / "p.json").write_text(json.dumps(d))
    (tmp_path / "p.toml").write_text('start = [1, 1]\nheading = 0.5\n[[steps]]\ndo = "goto"\nto = [2, 1]\n'
                                     '[[steps]]\ndo = "sit_on"\nobject = "c"\nseconds = 3\n')
    assert load_plan(tmp_path / "p.json").steps == p.steps == load_plan(tmp_path / "p.toml").steps


@pytest.mark.parametrize("bad, msg", [
    ({"steps": []}, "non-empty"),
    ({"steps": [{"do": "fly"}]}, "unknown step 'fly'"),
    ({"steps": [{"do": "goto"}]}, "missing"),
    ({"steps": [{"do": "goto", "to": [1, "x"]}]}, "2 numbers"),
    ({"steps": [{"do": "goto", "to": [1, float("nan")]}]}, "finite"),
    ({"steps": [{"do": "act", "action": "drink", "seconds": -1}]}, "seconds"),
    ({"steps": [{"do": "goto", "to": [1, 2], "speed": 3}]}, "unknown keys"),
    ({"steps": [{"do": "reach", "target": "cup", "hand": "middle"}]}, "hand"),
    ({"stepz": []}, "unknown keys"),
])
def test_bad_plans_name_the_problem(bad, msg):
    with pytest.raises(ValueError, match=msg):
        plan_from_dict(bad)


def test_plan_files_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_plan(tmp_path / "none.json")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_plan(tmp_path / "x.json")
    (tmp_path / "x.yaml").write_text("a: 1")
    with pytest.raises(ValueError, match=".json or .toml"):
        load_plan(tmp_path / "x.yaml")


def test_validate_against_scene_and_vocabulary(room):
    scene, _ = room
    validate_plan(plan_from_dict({"steps": [{"do": "sit_on", "object": "chair_0"}]}), scene, VOCAB)
    with pytest.raises(ValueError, match="no object 'sofa_9'.*chair_0"):
        validate_plan(plan_from_dict({"steps": [{"do": "sit_on", "object": "sofa_9"}]}), scene, VOCAB)
    with pytest.raises(ValueError, match="unknown action 'dance'"):
        validate_plan(plan_from_dict({"steps": [{"do": "act", "action": "dance"}]}), scene, VOCAB)
    with pytest.raises(ValueError, match="is a chair; lie_on needs"):
        validate_plan(plan_from_dict({"steps": [{"do": "lie_on", "object": "chair_0"}]}), scene, VOCAB)


def test_compile_walk_sit_stand_act(room):
    scene, wm = room
    plan = plan_from_dict({"steps": [{"do": "sit_on", "object": "chair_0", "seconds": 2},
                                     {"do": "act", "action": "drink", "seconds": 1}, {"do": "goto", "to": [1.0, 1.0]}]})
    phases = compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {"sit_down": 1.5}, fps=10)
    kinds = [p.kind for p in phases]
    assert kinds == ["walk", "sit_down", "sit", "act", "stand_up", "walk"]
    assert phases[1].frames == 15 and phases[2].frames == 20  # checkpoint duration, plan seconds
    assert phases[3].actions == ("drink", "sit")  # a hand action while seated keeps the posture label
    seat = scene.objects["chair_0"].pose[:2, 3]
    assert np.linalg.norm(phases[1].goal - seat) < 0.3
    assert np.allclose(phases[-1].path[-1], [1.0, 1.0])


def test_sitting_down_starts_with_a_turn_when_the_model_knows_turn(room):
    scene, wm = room
    plan = plan_from_dict({"steps": [{"do": "sit_on", "object": "chair_0", "seconds": 2}]})
    phases = compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {"turn": 0.8}, fps=10,
                          vocabulary=("walk", "turn", "sit_down", "sit"))
    assert [p.kind for p in phases] == ["walk", "turn", "sit_down", "sit"]
    turn, sit_down = phases[1], phases[2]
    assert turn.frames == 8 and turn.actions == ("turn",)
    assert np.allclose(turn.goal, phases[0].path[-1])  # on the spot where the walk ends
    assert turn.heading is not None and turn.heading == sit_down.heading  # to the seat's sitting direction
    # a model without 'turn' sits down straight from the walk
    plain = compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {}, fps=10, vocabulary=("walk", "sit_down", "sit"))
    assert [p.kind for p in plain] == ["walk", "sit_down", "sit"]


def test_a_walk_off_the_body_s_heading_starts_with_a_turn_on_the_spot(room):
    """As in the procedural takes: a walk whose path leaves more than 35 degrees off where the body
    faces starts with a turn to the path's direction; the heading is followed through the plan."""
    scene, wm = room
    vocab = ("walk", "turn", "sit_down", "sit", "stand_up", "drink")
    there_and_back = plan_from_dict({"steps": [{"do": "goto", "to": [1.0, 1.0]}, {"do": "act", "action": "drink", "seconds": 2},
                                               {"do": "goto", "to": [1.0, 3.0]}]})
    # facing +y: the first walk goes straight on; the walk back turns (~180 degrees) after the drink
    phases = compile_plan(there_and_back, scene, wm, np.array([1.0, 3.0]), {"turn": 0.8}, fps=10,
                          vocabulary=vocab, heading=-np.pi / 2)
    assert [p.kind for p in phases] == ["walk", "act", "turn", "walk"]
    turn = phases[2]
    assert turn.frames == 8 and np.allclose(turn.goal, phases[0].path[-1])  # on the spot where the drink was
    assert abs(np.cos(turn.heading - np.pi / 2)) > 0.99  # to the path's direction, +y
    # facing +x at the start: the first walk (to -y) starts with a turn too
    phases = compile_plan(there_and_back, scene, wm, np.array([1.0, 3.0]), {}, fps=10, vocabulary=vocab, heading=0.0)
    assert [p.kind for p in phases] == ["turn", "walk", "act", "turn", "walk"]
    assert abs(np.cos(phases[0].heading + np.pi / 2)) > 0.99
    # unknown heading or a model without 'turn': no turn before the first walk
    assert compile_plan(there_and_back, scene, wm, np.array([1.0, 3.0]), {}, fps=10, vocabulary=vocab)[0].kind == "walk"
    plain = compile_plan(there_and_back, scene, wm, np.array([1.0, 3.0]), {}, fps=10, heading=0.0,
                         vocabulary=("walk", "drink"))
    assert [p.kind for p in plain] == ["walk", "act", "walk"]
    # standing up from a chair faces its sitting direction: walking on that way needs no turn; walking
    # back would, but the spot in front of the chair is too tight to turn in place (elbows, knees)
    sit = [{"do": "sit_on", "object": "chair_0", "seconds": 2}, {"do": "stand_up"}]
    phases = compile_plan(plan_from_dict({"steps": sit}), scene, wm, np.array([1.0, 2.0]), {}, fps=10,
                          vocabulary=vocab, heading=0.0)
    sit_down, stand_up = [p for p in phases if p.kind == "sit_down"][0], phases[-1]
    facing = np.array([np.cos(sit_down.heading), np.sin(sit_down.heading)])
    i = wm.index(stand_up.goal)
    assert free_margin(wm)[i[0], i[1]] < TURN_FREE_MARGIN_M
    for way in (1.0, -1.0):
        goal = stand_up.goal + way * 0.8 * facing
        plan = plan_from_dict({"steps": sit + [{"do": "goto", "to": goal.tolist()}]})
        got = [p.kind for p in compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {}, fps=10, vocabulary=vocab,
                                            heading=0.0)]
        assert got[-2:] == ["stand_up", "walk"]


def test_lying_down_sits_on_the_edge_first_and_gets_up_through_sitting():
    import trimesh

    rng = np.random.default_rng(1)
    sofa = furniture.sofa(rng, "sofa_0")
    sofa.pose[:3, 3] = [3.0, 3.0, 0.0]
    floor = trimesh.creation.box((6.0, 6.0, 0.1))
    floor.apply_translation([3.0, 3.0, -0.05])
    scene = Scene("lie_room", static={"floor": floor}, objects={"sofa_0": sofa})
    wm = walkable_map(scene_occupancy(scene, None, voxel=0.05))
    plan = plan_from_dict({"steps": [{"do": "lie_on", "object": "sofa_0", "seconds": 3}, {"do": "get_up"}]})
    vocab = ("walk", "turn", "sit_down", "sit", "stand_up", "lie_down", "lie", "get_up")
    phases = compile_plan(plan, scene, wm, np.array([1.0, 1.0]), {}, fps=10, vocabulary=vocab)
    assert [p.kind for p in phases] == ["walk", "turn", "sit_down", "lie_down", "lie", "get_up", "stand_up"]
    sit_down, lie_down, get_up, stand_up = phases[2], phases[3], phases[5], phases[6]
    # the seat place nearest the lying pelvis, the body stands up where it came from
    places = [sofa.pose[:3, :3] @ np.asarray(c) + sofa.pose[:3, 3] for c in sofa.meta["seat_centers"]]
    nearest = min(places, key=lambda c: np.linalg.norm(c[:2] - lie_down.goal))
    assert np.allclose(sit_down.goal, nearest[:2]) and sit_down.info["seat_height"] == pytest.approx(nearest[2])
    assert np.allclose(get_up.goal, sit_down.goal) and np.allclose(stand_up.goal, phases[0].path[-1])
    # a model without sit_down lies down straight from the walk, as before
    plain = compile_plan(plan, scene, wm, np.array([1.0, 1.0]), {}, fps=10, vocabulary=("walk", "lie_down", "lie", "get_up"))
    assert [p.kind for p in plain] == ["walk", "lie_down", "lie", "get_up"]


def test_unreachable_goal_fails_before_sampling(room):
    scene, wm = room
    plan = plan_from_dict({"steps": [{"do": "goto", "to": [3.0, 2.0]}]})  # inside the chair
    with pytest.raises(ValueError, match="step 1.*not on walkable floor"):
        compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {}, fps=10)
    with pytest.raises(ValueError, match="not seated or lying"):
        compile_plan(plan_from_dict({"steps": [{"do": "stand_up"}]}), scene, wm, np.array([1.0, 2.0]), {}, fps=10)


def test_controller_walk_progress_and_goals():
    path = np.array([[0.0, 0.0], [3.0, 0.0]])
    ctrl = Controller([Phase("walk", ("walk",), path=path, goal=path[-1])], VOCAB, L=16, k=2, fps=10, speed=1.0)
    prev = np.zeros((2, len(VOCAB)), np.float32)
    c = ctrl.next(np.array([0.0, 0.0]), prev)
    assert c.labels.shape == (16, len(VOCAB))
    w = c.labels[2:, VOCAB.index("walk")]
    assert np.all(np.diff(w) > 0) and 1.0 < w[0] < w[-1] < 2.0  # progress rises from 1 towards 2
    assert np.allclose(c.goal, [1.4, 0.0])  # 14 new frames at 1 m/s, 10 fps
    # a body that lagged behind: the next goal is anchored on where it is, not where it should be
    c2 = ctrl.next(np.array([0.5, 0.1]), c.labels[-2:])
    assert np.allclose(c2.goal, [1.9, 0.0])
    c2 = ctrl.next(np.array([0.3, 0.1]), c2.labels[-2:])  # never backwards along the path
    assert np.allclose(c2.goal, [1.9, 0.0])
    c3 = ctrl.next(np.array([2.6, 0.0]), c2.labels[-2:])
    assert np.allclose(c3.goal, [3.0, 0.0]) and ctrl.done
    assert c3.labels[-1, VOCAB.index("stand")] == 1.5  # after the plan: stand
    assert np.isclose(c3.labels[c3.phases >= 0, VOCAB.index("walk")].max(), 2.0)


def test_controller_timed_phase_spans_episodes():
    ph = [Phase("sit_down", ("sit_down",), frames=20, goal=np.array([1.0, 1.0]))]
    ctrl = Controller(ph, VOCAB, L=16, k=2, fps=10)
    a = ctrl.next(np.zeros(2), np.zeros((2, len(VOCAB)), np.float32))
    b = ctrl.next(np.zeros(2), a.labels[-2:])
    col = VOCAB.index("sit_down")
    seq = np.concatenate([a.labels[2:, col], b.labels[2:, col]])[:20]
    np.testing.assert_allclose(seq, 1.0 + np.arange(1, 21) / 20, atol=1e-6)
    assert ctrl.done and np.allclose(b.goal, [1.0, 1.0])
    assert b.labels[-1, VOCAB.index("sit")] == 1.5  # held posture after sitting down


def test_an_episode_ending_inside_a_sit_down_gets_the_data_s_profile_not_the_seat():
    """The seat is the subgoal only of the episode in which the sit-down ends; before that the
    pelvis subgoal follows the data's smooth step from where the sit-down starts."""
    start, seat = np.array([0.0, 0.0]), np.array([0.4, 0.0])
    ph = [Phase("sit_down", ("sit_down",), frames=20, goal=seat, start=start)]
    ctrl = Controller(ph, VOCAB, L=16, k=2, fps=10)
    a = ctrl.next(start, np.zeros((2, len(VOCAB)), np.float32))  # 14 of 20 frames: progress 0.7
    np.testing.assert_allclose(a.goal, start + (3 * 0.7 ** 2 - 2 * 0.7 ** 3) * (seat - start))
    assert 0.0 < a.goal[0] < 0.4
    b = ctrl.next(a.goal, a.labels[-2:])
    assert ctrl.done and np.allclose(b.goal, seat)
    np.testing.assert_allclose([sit_down_subgoal(start, seat, p)[0] for p in (-1.0, 0.0, 0.5, 1.0, 2.0)],
                               [0.0, 0.0, 0.2, 0.4, 0.4])


def test_compiled_sit_down_starts_where_the_walk_ends(room):
    scene, wm = room
    plan = plan_from_dict({"steps": [{"do": "sit_on", "object": "chair_0", "seconds": 2}]})
    phases = compile_plan(plan, scene, wm, np.array([1.0, 2.0]), {}, fps=10, vocabulary=("walk", "turn", "sit_down", "sit"))
    assert np.allclose(phases[2].start, phases[0].path[-1]) and phases[3].start is None


@pytest.mark.parametrize("kind, actions", [("act", ("drink",)), ("turn", ("turn",))])
def test_a_phase_done_in_place_waits_for_the_walk_before_it_to_end(kind, actions):
    """A drink or a turn after a walk starts with an episode (the rest of the walk's last episode
    stays walking); a body still far from the walk's end walks one more episode onto it."""
    vocab = VOCAB + ["turn"]
    path = np.array([[0.0, 0.0], [2.0, 0.0]])
    ph = [Phase("walk", ("walk",), path=path, goal=path[-1]), Phase(kind, actions, frames=20, goal=None)]
    ctrl = Controller(ph, vocab, L=16, k=2, fps=10, speed=1.0)
    prev = np.zeros((2, len(vocab)), np.float32)
    a = ctrl.next(np.zeros(2), prev)  # walks 1.4 m
    b = ctrl.next(np.array([1.4, 0.0]), a.labels[-2:])  # 0.6 m left: 6 frames, then still walking
    col, walk = vocab.index(actions[0]), vocab.index("walk")
    assert not b.labels[2:, col].any() and np.all(b.labels[8:, walk] == 2.0) and np.allclose(b.goal, [2.0, 0.0])
    c = ctrl.next(np.array([1.5, 0.0]), b.labels[-2:])  # lagging 0.5 m > arrive_m: one more walking episode
    assert not c.labels[2:, col].any() and np.all(c.labels[2:, walk] == 2.0) and np.allclose(c.goal, [2.0, 0.0])
    d = ctrl.next(np.array([1.95, 0.0]), c.labels[-2:])  # arrived: the phase starts at the episode's first new frame
    assert np.all(d.labels[2:, col] > 1.0) and not d.labels[2:, walk].any()


def _corner_map() -> tuple:
    """A 4 x 4 m walk map (5 cm cells) with a blocked 2 x 2 m block in its corner x, y > 1 m
    (a table the path turns around), and an L-shaped path along its two sides, 0.2 m off it."""
    from trumans.scenes.walkability import WalkMap

    xy = np.stack(np.meshgrid(np.arange(-1.0, 3.0, 0.05), np.arange(-1.0, 3.0, 0.05), indexing="ij"), -1)
    walkable = ~((xy[..., 0] > 1.0) & (xy[..., 1] > 1.0))
    path = np.array([[0.8, 2.9], [0.8, 0.8], [2.9, 0.8]])  # down the left side, then right along the bottom
    return WalkMap(walkable, np.array([-1.0, -1.0]), 0.05), path


def test_line_of_sight_arc_pulls_a_subgoal_past_a_corner_back_into_view():
    from trumans.sample.controller import line_of_sight_arc, off_walkable

    wm, path = _corner_map()
    off, cum = off_walkable(wm), np.array([0.0, 2.1, 4.2])
    # far from the corner: the straight line to the subgoal stays on the floor, the subgoal stays
    assert line_of_sight_arc(wm, off, path, cum, 0.0, 1.4, path[0]) == 1.4
    # from (0.8, 1.6) a subgoal 1.4 m on, at (1.4, 0.8), is seen only across the block's corner
    # (1.0, 1.0); pulled back, the line to it (sampled densely) keeps off the block
    body = np.array([0.8, 1.6])
    s = line_of_sight_arc(wm, off, path, cum, 1.3, 2.7, body, slack=0.0)
    assert 1.3 < s < 2.7
    end = np.array([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])])
    assert wm.query(body + np.linspace(0, 1, 200)[:, None] * (end - body)).all()
    # the slack lets the line cut into the blocked cells by that much, no more
    s10 = line_of_sight_arc(wm, off, path, cum, 1.3, 2.7, body, slack=0.1)
    assert s <= s10 < 2.7


def test_line_of_sight_arc_from_a_body_pressed_to_a_wall_end_never_aims_through_the_wall():
    """A 5 cm partition (x 1.0-1.05, y < 1.6) with the walk map's 0.25 m margin around it; the path
    goes up the left side, round the wall's end and down the right side. A pelvis 15 cm from the
    end (off the margin) must not get a subgoal on the far side of the wall (it used to get the
    farthest candidate, 1 m ahead, straight through the partition)."""
    from trumans.sample.controller import line_of_sight_arc, off_walkable
    from trumans.scenes.walkability import WalkMap

    xy = np.stack(np.meshgrid(np.arange(-1.0, 3.0, 0.05), np.arange(-1.0, 3.0, 0.05), indexing="ij"), -1)
    dist = np.hypot(np.maximum(np.abs(xy[..., 0] - 1.025) - 0.025, 0.0), np.maximum(xy[..., 1] - 1.6, 0.0))
    wm = WalkMap(dist >= 0.25, np.array([-1.0, -1.0]), 0.05)  # m from the wall, walkable past the margin
    path = np.array([[0.7, 0.0], [0.7, 1.95], [1.35, 1.95], [1.35, 0.0]])
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    off = off_walkable(wm)
    body = np.array([0.9, 1.5])  # pressed to the wall's left face near its end: off the margin
    assert not wm.query(body[None])[0]
    s = line_of_sight_arc(wm, off, path, cum, 1.6, 2.6, body)
    end = np.array([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])])
    assert s < 2.6 and end[0] < 1.0 + 0.25  # still on the near side or on the round the end
    # the straight line from the body to the subgoal does not cross the partition
    line = body + np.linspace(0, 1, 400)[:, None] * (end - body)
    assert not ((line[:, 0] >= 1.0) & (line[:, 0] <= 1.05) & (line[:, 1] <= 1.6)).any()


def test_controller_with_walkmap_does_not_aim_across_a_corner():
    wm, path = _corner_map()
    ph = [Phase("walk", ("walk",), path=path, goal=path[-1])]
    prev = np.zeros((2, len(VOCAB)), np.float32)
    free = Controller(ph, VOCAB, L=16, k=2, fps=10, speed=1.0)
    seen = Controller(ph, VOCAB, L=16, k=2, fps=10, speed=1.0, walkmap=wm)
    body = np.array([0.8, 1.6])
    g_free, g_seen = free.next(body, prev).goal, seen.next(body, prev).goal
    assert np.allclose(g_free, [1.4, 0.8])  # 1.4 m on along the path: past the corner
    u = np.linspace(0, 1, 200)[:, None]
    assert not off_line_within(wm, body + u * (g_free - body), 0.05)
    assert off_line_within(wm, body + u * (g_seen - body), 0.05)  # within the default slack of the floor
    assert seen.walk_s < free.walk_s  # the walk's progress follows the nearer subgoal
    # a straight stretch is unchanged
    a, b = Controller(ph, VOCAB, 16, 2, 10, 1.0), Controller(ph, VOCAB, 16, 2, 10, 1.0, walkmap=wm)
    assert np.allclose(a.next(path[0], prev).goal, b.next(path[0], prev).goal)


def off_line_within(wm, line: np.ndarray, slack: float) -> bool:
    """Every point of ``line`` (N, 2) lies within ``slack`` m of walkable floor."""
    from trumans.sample.controller import off_walkable

    idx = np.clip(wm.index(line), 0, np.asarray(wm.walkable.shape) - 1)
    return bool((off_walkable(wm)[idx[:, 0], idx[:, 1]] <= slack + 1e-9).all())


def test_a_reach_target_out_of_a_persons_reach_is_refused():
    from trumans.sample.plan import MAX_REACH_HEIGHT, Plan, Step, validate_plan
    from trumans.scenes.procedural import make_room

    room = make_room(seed=0)
    vocab = ["walk", "reach", "sit_down", "sit", "stand_up"]
    validate_plan(Plan(steps=[Step("reach", target=(1.0, 1.0, 1.2))]), room, vocab)
    for z in (50.0, -0.5, MAX_REACH_HEIGHT + 0.1):
        with pytest.raises(ValueError, match="out of a standing person's reach"):
            validate_plan(Plan(steps=[Step("reach", target=(1.0, 1.0, z))]), room, vocab)
