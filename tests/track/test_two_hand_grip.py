"""A box carried between two palms is held by both hands, whichever hands the contact network calls
(issue 36.6, CMU 111_36): trumans.track.interactions.two_hand_grip / two_hand_take, on hand-made
motion with a stubbed contact network, and the tracker on the real clip."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import trumans.track.interactions as interactions
from trumans.rotations import matrix_to_6d
from trumans.scenes.scene import Scene, SceneObject
from trumans.sequence import Sequence
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import REST_JOINTS
from trumans.track.interactions import track, two_hand_grip, with_both_hands
from trumans.track.objects import hand_points
from trumans.track.postprocess import ContactSegment
from trumans.track.predictor import CLASSES

FPS, T, CONTACT = 30.0, 180, 30  # the network calls the left hand only, from frame CONTACT on
WALK = 0.5  # m/s along +x (the body faces +x, its left is +y)
DRIFT = np.array([0.04, 0.09])  # m, the localisation error


def _box_scene() -> Scene:
    """A floor and a 25 x 30 x 30 cm box (origin at its centre) in the hands at frame 0: its +-y
    faces 1 cm inside the palms (hand points 32 cm apart at 1.05 m)."""
    floor = trimesh.creation.box((20.0, 20.0, 0.02))
    floor.apply_translation((0.0, 0.0, -0.01))
    pose = np.eye(4)
    pose[:3, 3] = (0.41, 0.0, 1.05)
    box = SceneObject("box_0", "box", trimesh.creation.box((0.25, 0.30, 0.30)), pose, dof="free", dynamic=True)
    return Scene("room", static={"floor": floor}, objects={"box_0": box})


def _motion(right_lets_go: bool) -> np.ndarray:
    """(T, 24, 3): the body walks along +x from frame 0; the left hand point holds the box's +y face
    at 1.05 m all along; the right one holds its -y face, or (``right_lets_go``) leaves it at frame
    10 to swing at the side (0.85 m up, +-15 cm fore and aft, once a second)."""
    t = np.arange(T, dtype=np.float64)
    x = WALK * t / FPS
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    j[..., 0] += x[:, None]
    sway = 0.01 * np.sin(t / 7)
    left = np.stack([0.35 + x, np.full(T, 0.16), 1.05 + sway], -1)
    right = np.stack([0.35 + x, np.full(T, -0.16), 1.05 + sway], -1)
    if right_lets_go:
        k = np.clip((t - 10) / 8, 0, 1)[:, None]
        hang = np.stack([x + 0.15 * np.sin(2 * np.pi * t / FPS), np.full(T, -0.22), np.full(T, 0.85)], -1)
        right = (1 - k) * right + k * hang
    for side, p in (("left", left), ("right", right)):
        j[:, J[f"{side}_wrist"]] = p + [-0.04, 0, 0]
        j[:, J[f"{side}_index1"]] = p + [0.04, 0, 0]
    return j


def _track(monkeypatch, right_lets_go: bool):
    """Track the drifted motion with a stub network: left hand in contact, class "free", from CONTACT on."""
    prob = np.zeros((T, 2), np.float32)
    prob[CONTACT:, 0] = 0.9
    cls = np.zeros((T, len(CLASSES)), np.float32)
    cls[:, CLASSES.index("free")] = 1.0
    monkeypatch.setattr(interactions, "contact_probabilities", lambda *a, **k: (prob, cls))
    joints = _motion(right_lets_go)
    noisy = joints.copy()
    noisy[:, :, :2] += DRIFT
    rot = matrix_to_6d(np.tile(np.eye(3), (T, 24, 1, 1))).astype(np.float32)
    res = track(Sequence(joints=noisy.astype(np.float32), fps=FPS, rotations=rot, scene="room"), _box_scene(), None)
    return joints, res


def test_a_box_carried_between_the_palms_is_held_by_both_hands(monkeypatch):
    """The network calls the left hand only, from frame 30, when the box has been carried 50 cm
    (before: taken there by the left hand where it stood at frame 0, the path bent back to it and
    the box carried off the hands). Both palms are on it from the first frame and move rigidly with
    one another: both hands hold it from there, it stays between them, and the correction undoes
    the localisation error instead of bending the path to the box's first pose."""
    joints, res = _track(monkeypatch, right_lets_go=False)
    (it,) = res.interactions
    assert it.name == "box_0" and it.start <= 2 and it.end == T
    assert all(seg.two_handed for seg in it.segments)
    out = res.sequence
    hands = hand_points(out.joints.astype(np.float64))
    centre = out.objects["box_0"].pose[:, :3, 3].astype(np.float64)
    mid = hands.mean(1)
    assert np.abs(centre[:, 1:] - mid[:, 1:]).max() < 0.02  # between the palms, at their height
    ahead = centre[:, 0] - mid[:, 0]
    assert ahead.std() < 0.005 and -0.01 < ahead.mean() < 0.07  # rigid with them, as far ahead as taken
    # across the palms the correction undoes the error (along the box's faces a side grip cannot
    # see it); the path is not bent back 50 cm to where the box stood at frame 0
    assert np.abs(res.correction[:, 1] + DRIFT[1]).max() < 0.02
    assert np.linalg.norm(res.correction, axis=1).max() < 0.12
    assert res.mask[it.start:].all()  # both hands in contact while they hold it


def test_a_hand_that_leaves_the_box_is_no_two_hand_grip(monkeypatch):
    """The control: the right hand leaves the box at frame 10 and swings at the side; the left one
    carries it. The hold stays one-handed, as the network calls it."""
    _, res = _track(monkeypatch, right_lets_go=True)
    (it,) = res.interactions
    assert it.name == "box_0"
    assert all(seg.hands == (True, False) for seg in it.segments)


def test_two_hand_grip_needs_both_palms_on_it_moving_together():
    """two_hand_grip on hand points (n, 2, 3): a 30-cm box between palms 32 cm apart, carried 1 m."""
    n = 60
    x = np.linspace(0.0, 1.0, n)
    hands = np.stack([np.stack([x, np.full(n, 0.16), np.full(n, 1.0)], -1),
                      np.stack([x, np.full(n, -0.16), np.full(n, 1.0)], -1)], 1)
    centre, dist = np.array([0.0, 0.0, 1.0]), np.array([0.01, 0.01])
    assert two_hand_grip(hands, dist, centre, 0.30, FPS, 0.12) == n
    assert two_hand_grip(hands, np.array([0.01, 0.20]), centre, 0.30, FPS, 0.12) == 0  # one hand not on it
    assert two_hand_grip(hands, dist, np.array([0.0, 0.4, 1.0]), 0.30, FPS, 0.12) == 0  # not between them
    assert two_hand_grip(hands, dist, centre, 0.10, FPS, 0.12) == 0  # far wider apart than the object
    still = hands.copy()
    still[..., 0] = 0.0
    assert two_hand_grip(still, dist, centre, 0.30, FPS, 0.12) == 0  # resting on it, not carrying
    opened = hands.copy()
    opened[40:, 0, 1] += 0.2  # the left hand lets go at frame 40
    assert 38 <= two_hand_grip(opened, dist, centre, 0.30, FPS, 0.12) <= 42
    opened[15:, 0, 1] += 0.2  # ... at frame 15: too short a grip
    assert two_hand_grip(opened, dist, centre, 0.30, FPS, 0.12) == 0


def test_with_both_hands_recuts_the_segments():
    segs = (ContactSegment(10, 20, (True, False), 3), ContactSegment(20, 25, (True, True), 3),
            ContactSegment(25, 40, (False, True), 3))
    got = with_both_hands(segs, 12, 30)
    assert [(s.start, s.end, s.hands, s.interval) for s in got] == [
        (10, 12, (True, False), 3), (12, 30, (True, True), 3), (30, 40, (False, True), 3)]
    assert with_both_hands(segs, 5, 5) == segs


def test_tracker_holds_a_real_two_hand_carry_between_the_palms():
    """CMU 111_36 (held-out subject, "walk and carry": a box between the palms from the first frame;
    the network calls the left hand only, from frame 30). Before: the box rode on the left wrist
    17 cm from the hands (centre 32 cm off); now both hands hold it from the start, within 3 cm."""
    from trumans.mocap_corpus import load_corpus
    from trumans.track.eval_real import clip_figures, pool, real_case
    from trumans.track.model_io import load_contact_models

    clip = next(c for c in load_corpus(split="test") if c.name == "111_36")
    seq, scene = real_case(clip, 0)
    res = track(seq, scene, load_contact_models([], device="cpu"))
    fig = pool([clip_figures(seq, scene, res)])
    assert fig["held_share"] > 0.95 and fig["held_iou"] > 0.95
    assert fig["hand_obj_dist_cm"] < 3.0 and fig["obj_center_err_cm"] < 10.0
    assert fig["out_of_reach_s"] == 0.0 and fig["false_hold_s"] < 0.5
    held = [seg for it in res.interactions if it.name.startswith("fit_box") for seg in it.segments]
    assert held and sum(s.end - s.start for s in held if s.two_handed) > 0.95 * seq.num_frames
