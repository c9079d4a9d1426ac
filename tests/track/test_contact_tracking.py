"""Interaction tracking pieces (iReplica): post-processing, object motion from hands, bending energy."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.track.objects import (free_motion, hand_points, hinge_motion, one_hand_motion, rotation_about_axis,
                                      signed_angle, two_hand_motion)
from trumans.intervals import runs
from trumans.track.postprocess import PostprocessConfig, contact_mask, contact_segments, fill_gaps
from trumans.track.scores import average_precision, binary_scores
from trumans.track.trajectory import TrajectoryConfig, correct_trajectory, turning_angles


def _mask(s: str) -> np.ndarray:
    return np.array([c == "1" for c in s])


# ---------------------------------------------------------------- post-processing

def test_runs_half_open_and_gap_merging():
    m = _mask("0110010001")
    assert runs(m) == [(1, 3), (5, 6), (9, 10)]
    assert runs(m, max_gap=2) == [(1, 6), (9, 10)]  # gap of 2 filled, gap of 3 kept
    assert runs(m, max_gap=3) == [(1, 10)]


def test_fill_gaps_keeps_edges():
    m = _mask("0011000110000")
    out = fill_gaps(m, 3)
    assert out.astype(int).tolist() == [int(c) for c in "0011111110000"]
    assert not out[:2].any() and not out[-4:].any()  # gaps at the ends are not between two contacts


def test_contact_mask_fills_gaps_up_to_half_a_second():
    fps = 30.0
    p = np.zeros((200, 2))
    p[10:40, 0] = 0.9
    p[55:80, 0] = 0.9  # gap 40..55 = 15 frames = 0.5 s: filled
    p[100:120, 1] = 0.7
    p[136:150, 1] = 0.8  # gap 120..136 = 16 frames > 0.5 s: kept
    p[30, 0] = 0.49  # below threshold inside a run: a one-frame gap, filled
    m = contact_mask(p, fps)
    assert runs(m[:, 0]) == [(10, 80)]
    assert runs(m[:, 1]) == [(100, 120), (136, 150)]
    # a higher threshold removes the 0.7 run; min_len drops short stretches
    m2 = contact_mask(p, fps, PostprocessConfig(threshold=0.75, min_len_s=0.5))
    assert runs(m2[:, 1]) == [] and runs(m2[:, 0]) == [(10, 80)]


def test_segments_split_when_the_hands_change():
    m = np.zeros((40, 2), bool)
    m[2:10, 0] = True  # left alone
    m[6:14, 1] = True  # both 6..10, then right alone
    m[20:25, 1] = True  # right, then the hands swap without a break
    m[25:30, 0] = True
    segs = contact_segments(m)
    got = [(s.start, s.end, s.hands, s.interval) for s in segs]
    assert got == [(2, 6, (True, False), 0), (6, 10, (True, True), 0), (10, 14, (False, True), 0),
                   (20, 25, (False, True), 1), (25, 30, (True, False), 1)]
    assert segs[1].two_handed and not segs[0].two_handed
    assert contact_segments(np.zeros((5, 2), bool)) == []


def test_postprocess_bad_inputs():
    with pytest.raises(ValueError, match="boolean"):
        fill_gaps(np.array([0, 1, 1]), 2)
    with pytest.raises(ValueError, match="probabilities"):
        contact_mask(np.full((4, 2), 1.5), 30.0)
    with pytest.raises(ValueError, match="threshold"):
        PostprocessConfig(threshold=1.0)
    with pytest.raises(ValueError, match="fps"):
        contact_mask(np.zeros((4, 2)), 0.0)
    with pytest.raises(ValueError, match=r"\(T, 2\)"):
        contact_segments(np.zeros((4, 3), bool))


def test_average_precision_analytic():
    y = np.array([True, False, True, False])
    assert average_precision(np.array([0.9, 0.8, 0.7, 0.1]), y) == pytest.approx((1.0 + 2 / 3) / 2)
    assert average_precision(np.array([0.9, 0.1, 0.8, 0.2]), y) == pytest.approx(1.0)
    s = binary_scores(np.array([0.9, 0.8, 0.7, 0.1]), y)
    assert s["precision"] == pytest.approx(2 / 3) and s["recall"] == 1.0 and s["accuracy"] == 0.75
    with pytest.raises(ValueError, match="boolean"):
        average_precision(np.zeros(3), np.zeros(3))


# ---------------------------------------------------------------- objects from hands

def _circle(angles: np.ndarray, radius: float, center=(0.0, 0.0), z: float = 0.9) -> np.ndarray:
    return np.stack([center[0] + radius * np.cos(angles), center[1] + radius * np.sin(angles), np.full_like(angles, z)], 1)


@pytest.mark.parametrize("deg", [30.0, -45.0, 120.0, -150.0, 179.0])
def test_two_hand_angle_signed_beyond_90(deg):
    """The right hand stays put; the left hand swings about it: the object turns by exactly that
    signed angle (sin would fold 120 deg onto 60 deg and lose the sign of acos)."""
    a = np.radians(np.linspace(0.0, deg, 50))
    right = np.tile([1.0, 2.0, 0.9], (50, 1))
    left = right + _circle(a + 0.3, 0.5, z=0.0)  # hand vector starts at 0.3 rad
    M = two_hand_motion(left, right)
    yaw = np.arctan2(M[:, 1, 0], M[:, 0, 0])
    assert np.degrees(yaw[-1]) == pytest.approx(deg, abs=1e-6)
    assert np.allclose(M[:, :3, 3] + np.einsum("nij,j->ni", M[:, :3, :3], right[0]), right)  # pivot on the right hand
    assert signed_angle(np.array([1.0, 0.0]), np.array([-1.0, 0.1])) == pytest.approx(np.pi - np.arctan(0.1))


def test_two_hand_rotation_unwraps_past_180_and_translates():
    a = np.radians(np.linspace(0.0, 300.0, 120))
    right = np.stack([np.linspace(0, 1, 120), np.zeros(120), np.full(120, 0.8)], 1)
    left = right + _circle(a, 0.6, z=0.0)
    M = two_hand_motion(left, right)
    yaw = np.unwrap(np.arctan2(M[:, 1, 0], M[:, 0, 0]))
    assert np.degrees(yaw[-1]) == pytest.approx(300.0, abs=1e-6)
    # a point on the object at the right hand follows the right hand (eq. 3), heights untouched
    assert np.allclose(np.einsum("nij,j->ni", M[:, :3, :3], right[0]) + M[:, :3, 3], right)


def test_hinge_angle_unwraps_past_180():
    hinge, axis = np.array([2.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    a = np.radians(np.linspace(0.0, 270.0, 91))
    hand = _circle(a, 0.8, center=hinge[:2], z=1.0)
    M = hinge_motion(hand, hinge, axis)
    handle = hand[0]
    moved = np.einsum("nij,j->ni", M[:, :3, :3], handle) + M[:, :3, 3]
    assert np.allclose(moved, hand, atol=1e-9)  # the handle follows the hand all the way round
    yaw = np.unwrap(np.arctan2(M[:, 1, 0], M[:, 0, 0]))
    assert np.degrees(yaw[-1]) == pytest.approx(270.0)
    assert np.all(np.diff(yaw) > 0)  # continuous, no jump at +-180
    # hinge points stay put; the axis sign decides the direction
    assert np.allclose(np.einsum("nij,j->ni", M[:, :3, :3], hinge) + M[:, :3, 3], hinge)
    M_neg = hinge_motion(hand, hinge, -axis)
    assert np.allclose(M_neg, M)  # same physical rotation described about the flipped axis


def test_one_hand_slide_and_free_follow_the_hand():
    hand = np.stack([np.linspace(0, 0.3, 10), np.linspace(0, 0.2, 10), np.linspace(0.9, 1.0, 10)], 1)
    M = one_hand_motion(hand)
    assert np.allclose(M[:, :3, :3], np.eye(3)) and np.allclose(M[:, 2, 3], 0.0)
    assert np.allclose(M[-1, :2, 3], [0.3, 0.2])
    M_axis = one_hand_motion(hand, np.array([1.0, 0.0, 0.0]))
    assert np.allclose(M_axis[-1, :3, 3], [0.3, 0.0, 0.0])
    R = rotation_about_axis(np.linspace(0, 2.0, 10), np.array([0.3, -0.5, 0.8]), np.zeros(3))[:, :3, :3]
    F = free_motion(R, hand)
    H = np.tile(np.eye(4), (10, 1, 1))
    H[:, :3, :3], H[:, :3, 3] = R, hand
    assert np.allclose(F @ H[0], H)


def test_hand_points_and_bad_inputs():
    j = np.zeros((3, 24, 3))
    j[:, 20], j[:, 22] = [0, 1, 1], [0, 1.2, 1]
    assert np.allclose(hand_points(j)[:, 0], [0, 1.1, 1])
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        one_hand_motion(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="NaN"):
        hinge_motion(np.full((3, 3), np.nan), np.zeros(3), np.array([0, 0, 1.0]))
    with pytest.raises(ValueError, match="hand_rot"):
        free_motion(np.zeros((2, 3, 3)), np.zeros((3, 3)))


# ---------------------------------------------------------------- bending energy (eqs. 1-2)

def _curvy_path(T: int = 300) -> np.ndarray:
    t = np.arange(T) / 30.0
    return np.stack([0.8 * t, 0.6 * np.sin(t / 2.0)], 1)


def test_bending_pulls_path_to_control_point_keeping_turning_angles():
    path = _curvy_path()
    target = path[250] + np.array([0.0, 0.15])  # 15 cm sideways
    cfg = TrajectoryConfig(rigidity=1.0, free_start=False)
    out = correct_trajectory(path, np.array([250]), target[None], 30.0, cfg)
    assert np.allclose(out[0], path[0])  # start fixed
    assert np.linalg.norm(out[250] - target) < 0.02  # pulled (from 15 cm) to within 2 cm
    assert np.allclose(np.linalg.norm(np.diff(out, axis=0), axis=1), np.linalg.norm(np.diff(path, axis=0), axis=1))
    dev = turning_angles(out) - turning_angles(path)
    assert np.abs(dev).max() < 0.01  # turning angles kept (rad per frame)
    # a stiffer path keeps its angles better and reaches less far
    stiff = correct_trajectory(path, np.array([250]), target[None], 30.0, TrajectoryConfig(rigidity=100.0, free_start=False))
    assert np.abs(turning_angles(stiff) - turning_angles(path)).max() < np.abs(dev).max()
    assert np.linalg.norm(stiff[250] - target) > np.linalg.norm(out[250] - target)


def test_free_start_single_point_translates_rigidly():
    path = _curvy_path(100)
    out = correct_trajectory(path, np.array([60]), (path[60] + [0.1, -0.05])[None], 30.0)
    assert np.allclose(out - path, [0.1, -0.05])
    assert np.allclose(turning_angles(out), turning_angles(path))
    assert np.allclose(correct_trajectory(path, np.zeros(0, int), np.zeros((0, 2)), 30.0), path)


def test_two_control_points_are_both_met():
    path = _curvy_path()
    t = np.array([100, 280])
    pts = path[t] + np.array([[0.05, 0.05], [0.05, -0.08]])
    out = correct_trajectory(path, t, pts, 30.0, TrajectoryConfig(rigidity=0.1))
    assert np.linalg.norm(out[t] - pts, axis=1).max() < 0.03


def test_trajectory_bad_inputs():
    path = _curvy_path(10)
    with pytest.raises(ValueError, match="frame indices"):
        correct_trajectory(path, np.array([10]), np.zeros((1, 2)), 30.0)
    with pytest.raises(ValueError, match="matching"):
        correct_trajectory(path, np.array([1, 2]), np.zeros((1, 2)), 30.0)
    with pytest.raises(ValueError, match=r"\(T, 2\)"):
        correct_trajectory(np.zeros((5, 3)), np.array([1]), np.zeros((1, 2)), 30.0)
    with pytest.raises(ValueError, match="rigidity"):
        TrajectoryConfig(rigidity=-1.0)
