"""When a carried object is let go, and where it comes to rest (issue 36.6): trumans.track.support,
trumans.track.release, and the tracker with them on a real pick-up clip."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from trumans.rotations import axis_angle_to_matrix
from trumans.scenes.scene import Scene, SceneObject
from trumans.track.release import carried_release, lift_off, touchdown
from trumans.track.support import SupportQuery, upright_pose

FPS = 30.0


def _at(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


@pytest.fixture(scope="module")
def room() -> Scene:
    """A floor (top at z = 0), a table whose top is 0.70-0.74 m over x in [1.4, 2.6], y in [0.7, 1.3],
    and a 10 cm cube (origin at its centre) on the floor at (0, 0)."""
    floor = trimesh.creation.box((8.0, 8.0, 0.02))
    floor.apply_translation((1.0, 1.0, -0.01))
    table = SceneObject("table_0", "table", trimesh.creation.box((1.2, 0.6, 0.04)), _at(2.0, 1.0, 0.72))
    cube = SceneObject("cube_0", "box", trimesh.creation.box((0.1, 0.1, 0.1)), _at(0.0, 0.0, 0.05), dof="free",
                       dynamic=True)
    return Scene("room", static={"floor": floor}, objects={"table_0": table, "cube_0": cube})


def test_support_gap_and_rest_pose_on_a_table_and_the_floor(room):
    q = SupportQuery(room)
    over_table, over_floor = _at(2.0, 1.0, 0.74 + 0.30 + 0.05), _at(0.5, 0.5, 0.30 + 0.05)
    gaps = q.gaps("cube_0", np.stack([over_table, over_floor]), {})
    np.testing.assert_allclose(gaps, [0.30, 0.30], atol=1e-9)
    # tilted by 0.5 rad about x and turned by 0.3 rad: it comes down upright, its yaw and footprint centre kept
    tilted = over_table.copy()
    tilted[:3, :3] = axis_angle_to_matrix(np.array([0.0, 0.0, 0.3])) @ axis_angle_to_matrix(np.array([0.5, 0.0, 0.0]))
    rest = q.rest_pose("cube_0", tilted, {})
    np.testing.assert_allclose(rest[:3, :3], axis_angle_to_matrix(np.array([0.0, 0.0, 0.3])), atol=1e-9)
    np.testing.assert_allclose(rest[:2, 3], [2.0, 1.0], atol=1e-9)
    assert abs(q.gap("cube_0", rest, {})) < 1e-9 and abs(rest[2, 3] - (0.74 + 0.05)) < 1e-9
    # a footprint partly over the table's edge (centre 3 cm past it) stays on the table
    edge = q.rest_pose("cube_0", _at(2.63, 1.0, 1.2), {})
    assert abs(edge[2, 3] - 0.79) < 1e-9
    assert abs(q.rest_pose("cube_0", _at(2.8, 1.0, 1.2), {})[2, 3] - 0.05) < 1e-9  # clear of it: the floor


def test_upright_pose_of_a_lying_object_uses_its_y_axis():
    v = trimesh.creation.box((0.1, 0.2, 0.3)).vertices
    lying = np.eye(4)
    lying[:3, :3] = axis_angle_to_matrix(np.array([0.0, -np.pi / 2, 0.0]))  # x points straight up
    up = upright_pose(v, lying, bottom_z=0.0)
    np.testing.assert_allclose(up[:3, :3], np.eye(3), atol=1e-9)  # its y axis had kept its heading
    assert abs((v @ up[:3, :3].T + up[:3, 3])[:, 2].min()) < 1e-12


def _ride(z: np.ndarray, x: np.ndarray | None = None, y: float = 0.0) -> np.ndarray:
    """Poses (n, 4, 4) of the cube (origin at its centre) with its bottom at heights z, x along the way."""
    out = np.tile(np.eye(4), (len(z), 1, 1))
    out[:, 0, 3] = 0.0 if x is None else x
    out[:, 1, 3] = y
    out[:, 2, 3] = z + 0.05
    return out


def test_a_contact_ending_at_the_pick_up_holds_until_the_put_down(room):
    """The contact ends at frame 12 (the reach); the hand lifts the cube 0.8 m over 1 s, carries it,
    and sets it on the floor again at frame 120 (touchdown), then rises empty."""
    z = np.r_[np.zeros(12), np.linspace(0, 0.8, 30), np.full(48, 0.8), np.linspace(0.8, 0.0, 31)[:-1], np.zeros(5),
              np.linspace(0.0, 0.6, 25)]
    q = SupportQuery(room)
    release = carried_release(q, "cube_0", _ride(z), attach=0, detach=10, contact_end=12, others={}, fps=FPS)
    assert release == 120 + 1  # the frame after it touches the floor
    # a put-down: the contact ends where the cube rests and the hand leaves it sideways
    rest = carried_release(q, "cube_0", _ride(np.zeros(60), np.linspace(0, 1, 60)), 0, 10, 12, {}, FPS)
    assert rest == 10
    # picked up and never set down: held to the end
    up = carried_release(q, "cube_0", _ride(np.r_[np.zeros(12), np.linspace(0, 0.8, 30), np.full(30, 0.8)]), 0, 10, 12,
                         {}, FPS)
    assert up == 72


def test_a_hand_leaving_a_table_does_not_take_the_object(room):
    """Let go on the table at frame 10; the hand rises 12 cm (< PICK_LIFT_M) while leaving: no carry.
    Passing a table edge at the same height (its gap jumps to 0.74 m) is no lift either."""
    q = SupportQuery(room)
    z = 0.74 + np.r_[np.zeros(12), np.linspace(0, 0.12, 20), np.full(20, 0.12)]
    assert carried_release(q, "cube_0", _ride(z, np.full(len(z), 2.0), 1.0), 0, 10, 12, {}, FPS) == 10
    x = np.r_[np.full(10, 2.5), np.linspace(2.5, 2.9, 20)]
    assert carried_release(q, "cube_0", _ride(np.full(30, 0.74), x, 1.0), 0, 10, 25, {}, FPS) == 10


def test_lift_off_and_touchdown():
    assert lift_off(np.array([0.0, -0.05, -0.12, -0.08, 0.02]), last=4) == 2  # pushed into the floor until frame 2
    assert lift_off(np.array([0.0, -0.01, 0.05]), last=2) == 0
    g = np.array([0.5, 0.3, 0.08, 0.06, 0.07, 0.2])  # comes down to 6 cm over a surface, then up again
    assert touchdown(g, 0) == 3
    assert touchdown(g, 0, speed=np.full(6, 1.0)) is None  # at walking pace it is carried past, not set down
    assert touchdown(np.array([0.5, 0.02, 0.0]), 0) == 1


def test_carried_release_refuses_frames_out_of_order(room):
    with pytest.raises(ValueError, match="attach < detach"):
        carried_release(SupportQuery(room), "cube_0", _ride(np.zeros(10)), 5, 5, 8, {}, FPS)


def test_tracker_holds_a_real_pick_up_to_the_end():
    """CMU 111_17 (held-out subject: bend, pick up a box, stand holding it to the clip's end): the box
    is held from the reach to the end (before issue 36.6: let go 0.1 s after the grasp, ending 92 cm
    from the hands), rides within 10 cm of the hands, and the output contact mask holds with it."""
    from trumans.mocap_corpus import load_corpus
    from trumans.track.eval_real import clip_figures, pool, real_case
    from trumans.track.interactions import track
    from trumans.track.model_io import load_contact_models

    clip = next(c for c in load_corpus(split="test") if c.name == "111_17")
    seq, scene = real_case(clip, 0)
    res = track(seq, scene, load_contact_models([], device="cpu"))
    fig = pool([clip_figures(seq, scene, res)])
    assert fig["held_share"] > 0.9 and fig["held_iou"] > 0.8
    assert fig["hand_obj_dist_cm"] < 10.0 and fig["obj_center_err_end_cm"] < 20.0
    assert fig["out_of_reach_s"] == 0.0 and fig["false_hold_s"] < 0.5
    held = [it for it in res.interactions if it.name.startswith("fit_box")]
    assert held and held[-1].end == seq.num_frames
    assert res.mask[held[-1].start:].any(axis=1).all()


def test_a_box_between_two_hands_turns_with_them_and_stays_level():
    """Hands 30 cm apart turn 90 deg about the vertical through their midpoint and rise 0.5 m, the left
    one 5 cm higher than the right: the box turns 90 deg about z, rises 0.5 m, and stays level about
    the hands' axis' horizontal normal (no wrist roll)."""
    from trumans.track.objects import two_hand_free_motion

    t = np.linspace(0, np.pi / 2, 20)
    mid = np.c_[np.full(20, 1.0), np.full(20, 2.0), np.linspace(0.3, 0.8, 20)]
    across = 0.15 * np.c_[-np.sin(t), np.cos(t), np.zeros(20)]
    left, right = mid + across, mid - across
    M = two_hand_free_motion(left, right)
    np.testing.assert_allclose(M[0], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(M[-1][:3, :3], axis_angle_to_matrix(np.array([0.0, 0.0, np.pi / 2])), atol=1e-9)
    np.testing.assert_allclose(M[-1][:3, :3] @ mid[0] + M[-1][:3, 3], mid[-1], atol=1e-9)  # the midpoint moves with them
    tilted = two_hand_free_motion(left + [0, 0, 0.05], right)[-1][:3, :3]
    x = tilted @ np.array([1.0, 0.0, 0.0])
    assert abs(x[2]) < 1e-9  # the box's front stays horizontal when one hand is higher
