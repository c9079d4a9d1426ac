"""trumans.track.interactions: tracked doors and drawers stay within their range; a small object is
attached when the hand reaches its grasp point, furniture when the hand stops on it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from trumans.track.objects import dof_value
from trumans.track.interactions import AttachedContact, attach_contact, attach_detach, clip_to_limits, drive_contact
from trumans.track.object_choice import ObjectQueries
from trumans.scenes.procedural import make_room
from trumans.scenes.scene import Scene, SceneObject
from trumans.track.objects import rotation_about_axis
from trumans.track.postprocess import ContactSegment
from trumans.skeleton import JOINT_INDEX


@pytest.fixture(scope="module")
def room():
    return make_room(2)  # door_0 (hinge, max_angle 1.4), cabinet_0_drawer_* (slide, max_travel), chair_0, cups


def _hinge(door) -> tuple[np.ndarray, np.ndarray]:
    return door.pose[:3, :3] @ door.axis, door.pose[:3, :3] @ door.hinge_point + door.pose[:3, 3]


def _slid(drawer, travel: np.ndarray) -> np.ndarray:
    poses = np.tile(drawer.pose, (len(travel), 1, 1))
    poses[:, :3, 3] += travel[:, None] * (drawer.pose[:3, :3] @ drawer.axis)
    return poses


def test_a_drawer_stops_at_closed_and_at_full_travel(room):
    drawer = room.objects["cabinet_0_drawer_0"]
    top = drawer.meta["max_travel"]
    travel = np.array([-0.08, 0.0, 0.1, top, top + 0.05])
    out = clip_to_limits(drawer, _slid(drawer, travel))
    got = np.array([dof_value(drawer, p) for p in out])
    np.testing.assert_allclose(got, [0.0, 0.0, 0.1, top, top], atol=1e-12)
    np.testing.assert_allclose(out[1:4], _slid(drawer, travel)[1:4], atol=1e-12)  # within range: unchanged
    np.testing.assert_allclose(out[:, :3, :3], np.tile(drawer.pose[:3, :3], (5, 1, 1)))


def test_an_offset_across_the_slide_axis_is_kept(room):
    drawer = room.objects["cabinet_0_drawer_1"]
    poses = _slid(drawer, np.array([-0.05]))
    side = np.cross([0.0, 0.0, 1.0], drawer.pose[:3, :3] @ drawer.axis)
    poses[0, :3, 3] += 0.02 * side
    out = clip_to_limits(drawer, poses)
    np.testing.assert_allclose(out[0, :3, 3], drawer.pose[:3, 3] + 0.02 * side, atol=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_door_does_not_swing_through_its_frame_or_past_its_stop(room, sign):
    door = dataclasses.replace(room.objects["door_0"], meta={**room.objects["door_0"].meta, "open_sign": sign})
    axis, point = _hinge(door)
    opened = sign * np.array([-0.3, 0.0, 0.7, 1.4, 1.9, 2.6])  # 2.6 rad: past 180 deg from closed when unwrapped
    poses = rotation_about_axis(np.unwrap(opened), axis, point) @ door.pose
    out = clip_to_limits(door, poses)
    got = np.array([dof_value(door, p) for p in out])
    np.testing.assert_allclose(got, sign * np.array([0.0, 0.0, 0.7, 1.4, 1.4, 1.4]), atol=1e-9)
    np.testing.assert_allclose(out[1:4], poses[1:4], atol=1e-12)
    np.testing.assert_allclose(out[:, :3, 3] @ axis, np.full(6, door.pose[:3, 3] @ axis), atol=1e-12)  # about the hinge


def test_objects_without_a_range_are_unchanged(room):
    for name in ("chair_0", "cup_0"):
        obj = room.objects[name]
        poses = np.tile(obj.pose, (3, 1, 1))
        poses[:, 0, 3] += [-2.0, 0.0, 3.0]
        np.testing.assert_array_equal(clip_to_limits(obj, poses), poses)
    drawer = room.objects["cabinet_0_drawer_0"]
    no_meta = dataclasses.replace(drawer, meta={k: v for k, v in drawer.meta.items() if k != "max_travel"})
    poses = _slid(drawer, np.array([-0.3, 0.6]))
    np.testing.assert_array_equal(clip_to_limits(no_meta, poses), poses)


def test_a_hand_pushing_on_past_closed_leaves_the_drawer_closed(room):
    """The tracker's drive: a drawer pulled out 20 cm, then pushed 30 cm back (the sensed hand overshoots)."""
    drawer = room.objects["cabinet_0_drawer_0"]
    axis = drawer.pose[:3, :3] @ drawer.axis
    handle = drawer.pose[:3, :3] @ np.asarray(drawer.meta["handle"]) + drawer.pose[:3, 3]
    n, T = 20, 60
    joints = np.zeros((T, 24, 3))
    travel = np.r_[np.zeros(10), np.linspace(0.0, 0.2, n), np.full(5, 0.2), np.linspace(0.2, -0.1, n), np.full(5, -0.1)]
    for j in ("right_wrist", "right_index1"):
        joints[:, JOINT_INDEX[j]] = handle + travel[:, None] * axis
    wrist_rot = np.tile(np.eye(3), (T, 2, 1, 1))
    segs = (ContactSegment(10, 30, (False, True), 0), ContactSegment(35, 55, (False, True), 1))
    poses = {drawer.name: np.tile(drawer.pose, (T, 1, 1))}
    for seg in segs:
        drive_contact(AttachedContact(drawer.name, "slide", seg.start, seg.end, (seg,), handle), room, poses, joints,
                      wrist_rot)
    got = np.array([dof_value(drawer, p) for p in poses[drawer.name]])
    assert got[29] == pytest.approx(0.2, abs=1e-9)  # opened by the hand
    assert got.min() == pytest.approx(0.0, abs=1e-12)  # never inside the cabinet
    assert got[-1] == pytest.approx(0.0, abs=1e-12)  # left closed


def test_a_hand_reaching_over_a_small_object_attaches_at_its_grasp_point():
    """A mouse (11 x 6 x 3.6 cm, top at 0.776 m) reached for from +x: the hand comes in 2 cm above
    its top (frames 0-11, from 10 cm off its centre) and settles 1.5 cm over the grasp point (top
    centre). Within 1 cm of its closest approach to the surface from frame 4 on, it reaches the
    grasp point at frame 10: the mouse is held from there, not dragged in from frame 4."""
    pose = np.eye(4)
    pose[:3, 3] = (2.0, 1.0, 0.758)
    top = 0.776
    hands = np.zeros((40, 1, 3))
    hands[:, 0, 0] = np.r_[np.linspace(2.10, 2.0, 12), np.full(28, 2.0)]
    hands[:, 0, 1] = 1.0
    hands[:, 0, 2] = np.r_[np.full(12, top + 0.02), np.full(28, top + 0.015)]
    segs = (ContactSegment(100, 140, (False, True), 0),)
    frames = {}
    for key, meta in (("grasp", {"grasp_point": [0.0, 0.0, 0.018]}), ("surface", {})):
        mouse = SceneObject("mouse_0", "mouse", trimesh.creation.box((0.11, 0.06, 0.036)), pose, dof="free",
                            dynamic=True, meta=meta)
        held, frames[key], near, target = attach_contact(ObjectQueries(Scene("desk", objects={"mouse_0": mouse})),
                                                         "mouse_0", pose, hands, segs, 100, 30.0, 0.015)
        assert held[0].start == frames[key] and held[-1].end <= 140
        np.testing.assert_allclose(near[0, 2], top, atol=1e-6)  # the contact point is on its top
    assert frames == {"grasp": 110, "surface": 104}


def test_furniture_is_taken_where_the_hand_stops_whatever_the_offset():
    """A hand comes 20 cm in to a chair's back (surface at x = 0; frames 0-10), rests on it
    (10-12) and pulls it 30 cm (12-40). Sensed 10 cm too far in (the localisation error), the
    hand is nearest the chair at rest mid-reach; the stop rule attaches at the rest either way."""
    ease = lambda n: 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, n))
    x = np.r_[0.2 * (1 - ease(11)), np.zeros(2), 0.3 * ease(27)]
    near = {}
    for offset in (0.0, -0.1):
        hands = np.zeros((40, 1, 3))
        hands[:, 0, 0] = x + offset
        dist = np.abs(hands[:, 0, 0])  # to the chair's back at rest
        stop, detach = attach_detach(hands, dist, 100, 140, 30.0, attach="stop")
        assert 110 <= stop <= 112 and detach > stop
        near[offset] = attach_detach(hands, dist, 100, 140, 30.0)[0]
    assert near[0.0] >= 109 and near[-0.1] <= 106  # the approach rule: drifted, attached mid-reach
    with pytest.raises(ValueError, match="attach must be"):
        attach_detach(hands, dist, 100, 140, 30.0, attach="grasp")
