"""CCD IK: reachable targets within 1 mm, unreachable ones reported, rigid bones, root DoF, planted feet."""
import numpy as np
import pytest

from trumans.ik.ccd import IKConfig, solve_ik
from trumans.skeleton import JOINT_INDEX as J, bone_lengths, forward_kinematics, rest_offsets
from trumans.synth.poses import pose

OFF = rest_offsets()


def _sitting(T: int):
    rot = np.repeat(pose("sit")[None], T, 0)
    P, _ = forward_kinematics(rot[:1], np.zeros((1, 3)), OFF)
    root = np.tile([0.0, 0.0, 0.04 - P[0, [J["left_foot"], J["right_foot"]], 2].min()], (T, 1))
    return forward_kinematics(rot, root, OFF)


def test_reachable_hand_targets_within_1mm_and_bones_rigid():
    T = 64
    rng = np.random.default_rng(0)
    P, G = _sitting(T)
    tgt = P.copy()
    act = np.zeros((T, 24), bool)
    tgt[:, J["right_wrist"]] += rng.normal(0, 0.04, (T, 3))
    tgt[:, J["left_index1"]] += rng.normal(0, 0.04, (T, 3))
    act[:, [J["right_wrist"], J["left_index1"]]] = True
    r = solve_ik(P, G, tgt, act)
    assert r.error[act].max() < 1e-3
    assert not r.unreachable.any()
    assert np.abs(bone_lengths(r.joints) - bone_lengths(P)).max() < 1e-9
    # the returned local rotations reproduce the joints by FK
    Pf, _ = forward_kinematics(r.local_rot, r.joints[:, 0], OFF)
    assert np.abs(Pf - r.joints).max() < 1e-9
    # untouched: legs and pelvis
    assert np.abs(r.joints[:, [0, 1, 2, 4, 5, 7, 8, 10, 11]] - P[:, [0, 1, 2, 4, 5, 7, 8, 10, 11]]).max() < 1e-12


def test_unreachable_targets_are_reported_not_hidden():
    T = 6
    P, G = _sitting(T)
    tgt = P.copy()
    act = np.zeros((T, 24), bool)
    tgt[:3, J["right_wrist"]] += [2.0, 0.0, 0.0]  # 2 m away: beyond the arm and spine
    tgt[3:, J["right_wrist"]] += [0.0, -0.03, 0.03]
    act[:, J["right_wrist"]] = True
    r = solve_ik(P, G, tgt, act)
    assert r.unreachable[:3, J["right_wrist"]].all()
    assert not r.unreachable[3:].any() and r.error[3:].max() < 1e-3


def test_seat_raise_moves_root_and_keeps_feet_planted():
    """A seat raised by 15 cm: the pelvis target moves up 15 cm; the root translation reaches it and
    the legs re-bend so the planted feet do not move."""
    T = 4
    P, G = _sitting(T)
    tgt = P.copy()
    act = np.zeros((T, 24), bool)
    tgt[:, 0] += [0.0, 0.0, 0.15]
    feet = [J["left_ankle"], J["right_ankle"], J["left_foot"], J["right_foot"]]
    act[:, [0] + feet] = True
    r = solve_ik(P, G, tgt, act)
    assert np.abs(r.joints[:, 0] - P[:, 0] - [0, 0, 0.15]).max() < 1e-3
    assert np.abs(r.joints[:, feet] - P[:, feet]).max() < 1e-3
    assert np.abs(bone_lengths(r.joints) - bone_lengths(P)).max() < 1e-9


def test_lying_straight_legs_move_with_the_body():
    """Lying with straight legs on a bed moved 5 cm sideways: pelvis, hips and ankles all get the
    same offset. The straight legs are already beyond the planted-leg reach limit, yet they move
    with the body, so the root translation must not be blocked."""
    T = 3
    rot = np.repeat(np.eye(3)[None, None], 24, 1).repeat(T, 0)  # rest pose: straight legs
    rot[:, 0] = [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]  # lying face up, feet towards +x
    P, G = forward_kinematics(rot, np.tile([0.0, 0.0, 0.6], (T, 1)), OFF)
    d = np.array([-0.05, 0.02, 0.0])  # partly along the legs, towards the head
    group = [0, J["left_hip"], J["right_hip"], J["spine1"], J["left_ankle"], J["right_ankle"]]
    tgt = P.copy()
    tgt[:, group] += d
    act = np.zeros((T, 24), bool)
    act[:, group] = True
    r = solve_ik(P, G, tgt, act)
    assert not r.unreachable.any() and r.error[act].max() < 1e-3
    np.testing.assert_allclose(r.joints[:, 0] - P[:, 0], np.tile(d, (T, 1)), atol=1e-3)


def test_low_priority_target_yields_to_contact():
    T = 3
    P, G = _sitting(T)
    tgt = P.copy()
    w = np.zeros((T, 24))
    tgt[:, 0] += [0, 0, 0.10]
    tgt[:, J["left_hip"]] += [0, 0, 0.05]  # conflicts with the pelvis (rigidly attached)
    w[:, 0], w[:, J["left_hip"]] = 1.0, 0.2
    r = solve_ik(P, G, tgt, w)
    assert r.error[:, 0].max() < 2e-3 < r.error[:, J["left_hip"]].min()


def test_fading_effector_is_done_within_tol_over_its_weight():
    """A frame's effector of weight w (``active`` = sqrt(w)) is done within tol / w: a half-faded
    wrist stops short of its target, a full-weight one reaches tol, and a frame whose weighted
    error is already within tol is left untouched."""
    T = 3
    P, G = _sitting(T)
    tgt = P.copy()
    tgt[:, J["right_wrist"]] += [0.0, -0.05, 0.03]
    a = np.zeros((T, 24))
    a[:, J["right_wrist"]] = [1.0, 0.3, 0.3]  # weights 1, 0.09, 0.09
    tgt[2, J["right_wrist"]] = P[2, J["right_wrist"]] + [0.0, 0.0, 0.0015]  # 1.5 mm x 0.09 < tol
    cfg = IKConfig()
    r = solve_ik(P, G, tgt, a, config=cfg)
    e = r.error[:, J["right_wrist"]]
    assert e[0] <= cfg.tol
    assert cfg.tol < e[1] and e[1] * 0.09 <= cfg.tol * 1.0001
    assert np.array_equal(r.joints[2], P[2])


def test_bad_inputs():
    P, G = _sitting(2)
    with pytest.raises(ValueError, match="joints must be"):
        solve_ik(P[:, :10], G, P, np.ones((2, 24), bool))
    with pytest.raises(ValueError, match="targets must be"):
        solve_ik(P, G, P[:1], np.ones((2, 24), bool))
    bad = P.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        solve_ik(P, G, bad, np.ones((2, 24), bool))
    with pytest.raises(ValueError, match="iterations"):
        IKConfig(iterations=0)
