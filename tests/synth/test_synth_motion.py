"""Procedural motion primitives: limb IK, poses, walking, sitting, lying, continuity."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.rotations import euler_to_matrix
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import bone_lengths, forward_kinematics, heading, rest_offsets
from trumans.ik.limb import LIMBS, limb_reach, set_global_rotation, solve_limb
from trumans.synth.legs import foot_places, standing_state
from trumans.synth.locomotion import stand, turn, walk
from trumans.synth.motion import Motion, concat_motions
from trumans.synth.poses import POSES, blend_into, ease, keyframe_track, pose, slerp_rot
from trumans.synth.lying import get_up, lie, lie_down, lying_state
from trumans.synth.posture import seat_clearance, seated_state, sit, sit_down, stand_up
from trumans.synth.vocab import SYNTH_ACTIONS

ANKLES, FEET = [J["left_ankle"], J["right_ankle"]], [J["left_foot"], J["right_foot"]]


def _random_body(rng: np.random.Generator, T: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    off = rest_offsets(rng.uniform(0.9, 1.1, 24))
    rot = np.tile(np.eye(3), (T, 24, 1, 1))
    rot[:, 0] = euler_to_matrix(rng.normal(0, 0.4, (T, 3)))
    rot[:, [3, 6, 9, 13, 14]] = euler_to_matrix(rng.normal(0, 0.2, (T, 5, 3)))
    rot[:, [7, 8, 20, 21]] = euler_to_matrix(rng.normal(0, 0.5, (T, 4, 3)))
    return rot, rng.normal(0, 1, (T, 3)), off


def _check_motion(m: Motion) -> np.ndarray:
    joints = m.joints()
    assert np.isfinite(joints).all()
    np.testing.assert_allclose(bone_lengths(joints), np.broadcast_to(np.linalg.norm(m.offsets[1:], axis=1),
                                                                     (m.num_frames, 23)), atol=1e-7)
    assert all(a.name in SYNTH_ACTIONS for a in m.actions)
    return joints


def _contact_slides(m: Motion, joints: np.ndarray) -> list[float]:
    """Max horizontal drift of each ankle and foot joint within each contact run (m)."""
    out = []
    for f in range(2):
        d = np.diff(np.concatenate([[0], m.foot_contact[:, f].astype(int), [0]]))
        for s, e in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            for j in (ANKLES[f], FEET[f]):
                out.append(float(np.linalg.norm(joints[s:e, j, :2] - joints[s, j, :2], axis=1).max()))
    return out


# ---------------------------------------------------------------- limb IK
@pytest.mark.parametrize("limb", list(LIMBS))
def test_limb_ik_reaches_and_keeps_end_orientation(limb):
    rng = np.random.default_rng(0)
    rot, root, off = _random_body(rng, 300)
    a, b, c, _, _ = LIMBS[limb]
    P, G = forward_kinematics(rot, root, off)
    lo, hi = limb_reach(off, limb)
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = P[:, a] + d * rng.uniform(lo + 0.01, hi - 1e-3, (300, 1))
    new, ok = solve_limb(rot, root, off, limb, target)
    P2, G2 = forward_kinematics(new, root, off)
    assert ok.all()
    assert np.linalg.norm(P2[:, c] - target, axis=1).max() < 1e-3
    np.testing.assert_allclose(G2[:, c], G[:, c], atol=1e-9)  # end joint's global orientation kept
    changed = np.abs(new - rot).max(axis=(0, 2, 3)) > 1e-12
    assert set(np.flatnonzero(changed)) <= {a, b, c}
    # Bone lengths are exact (rotations only).
    np.testing.assert_allclose(bone_lengths(P2), bone_lengths(P), atol=1e-9)
    # The middle joint is a hinge: its local rotation axis is the limb's flexion axis.
    from trumans.rotations import matrix_to_axis_angle
    aa = matrix_to_axis_angle(new[:, b])
    ang = np.linalg.norm(aa, axis=1)
    axis = aa[ang > 1e-3] / ang[ang > 1e-3, None]
    assert np.abs(np.abs(axis @ LIMBS[limb][4]) - 1).max() < 1e-6


@pytest.mark.parametrize("limb", ["left_arm", "right_leg"])
def test_limb_ik_unreachable_clamps_and_reports(limb):
    rng = np.random.default_rng(1)
    rot, root, off = _random_body(rng, 50)
    a, _, c, _, _ = LIMBS[limb]
    P, _ = forward_kinematics(rot, root, off)
    hi = limb_reach(off, limb)[1]
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    far = P[:, a] + d * (hi + rng.uniform(0.05, 1.0, (50, 1)))
    new, ok = solve_limb(rot, root, off, limb, far)
    P2, _ = forward_kinematics(new, root, off)
    assert not ok.any()
    np.testing.assert_allclose(np.linalg.norm(P2[:, c] - P2[:, a], axis=1), hi, atol=1e-9)  # full extension
    dirs = (P2[:, c] - P2[:, a]) / hi
    assert ((dirs * d).sum(1) > 1 - 1e-9).all()  # pointing at the target


def test_limb_ik_pole_tip_mask_and_bad_input():
    off = rest_offsets()
    T = 4
    rot = np.repeat(pose("stand", off)[None], T, axis=0)
    root = np.tile(off[0], (T, 1))
    P, G = forward_kinematics(rot, root, off)
    # Hand in front of the chest, elbow pointing down: the elbow ends up below the shoulder-wrist line.
    tgt = P[:, J["right_shoulder"]] + np.array([0.35, 0.1, -0.15])
    pole = P[:, J["right_shoulder"]] + np.array([0.0, 0.0, -1.0])
    new, ok = solve_limb(rot, root, off, "right_arm", tgt, pole=pole, effector="tip")
    P2, G2 = forward_kinematics(new, root, off)
    assert ok.all() and np.abs(P2[:, J["right_index1"]] - tgt).max() < 1e-9
    mid = 0.5 * (P2[:, J["right_shoulder"]] + P2[:, J["right_wrist"]])
    assert (P2[:, J["right_elbow"], 2] < mid[:, 2] - 0.02).all()
    # Default knee pole: knees bend forward (+x for a body facing +x).
    low = P[:, J["left_hip"]] + np.array([0.1, 0.0, -0.6])
    new, ok = solve_limb(rot, root, off, "left_leg", low)
    P3, _ = forward_kinematics(new, root, off)
    line = 0.5 * (P3[:, J["left_hip"]] + P3[:, J["left_ankle"]])
    assert ok.all() and (P3[:, J["left_knee"], 0] > line[:, 0] + 0.05).all()
    # Masked frames are untouched.
    mask = np.array([True, False, True, False])
    new, ok = solve_limb(rot, root, off, "left_leg", low, mask=mask)
    np.testing.assert_array_equal(new[~mask], rot[~mask])
    assert ok.all()
    with pytest.raises(ValueError, match="limb"):
        solve_limb(rot, root, off, "tail", low)
    with pytest.raises(ValueError, match="tip"):
        solve_limb(rot, root, off, "left_leg", low, effector="tip")
    with pytest.raises(ValueError, match="root"):
        solve_limb(rot, root[:2], off, "left_leg", low)


def test_set_global_rotation_round_trip():
    rng = np.random.default_rng(2)
    rot, root, off = _random_body(rng, 20)
    R = euler_to_matrix(rng.normal(0, 1, (20, 3)))
    for j in (0, J["left_wrist"], "head"):
        new = set_global_rotation(rot, root, off, j, R)
        _, G = forward_kinematics(new, root, off)
        jj = J[j] if isinstance(j, str) else j
        np.testing.assert_allclose(G[:, jj], R, atol=1e-12)


# ---------------------------------------------------------------- poses
def test_poses_and_slerp():
    off = rest_offsets()
    for name in POSES:
        R = pose(name, off)
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), (24, 3, 3)), atol=1e-9)
    # Standing: arms hang down by the thighs (wrists below the shoulders, near the hips).
    P, _ = forward_kinematics(pose("stand", off)[None], off[0][None], off)
    for side in ("left", "right"):
        w, s = P[0, J[f"{side}_wrist"]], P[0, J[f"{side}_shoulder"]]
        assert s[2] - w[2] > 0.4 and abs(w[1]) < 0.3
    # Drink: index finger at the mouth (in front of / below the head joint).
    P, _ = forward_kinematics(pose("drink", off)[None], off[0][None], off)
    np.testing.assert_allclose(P[0, J["right_index1"]] - P[0, J["head"]], [0.12, -0.02, -0.07], atol=1e-6)
    # Slerp: end points, midpoint angle, keyframes hit.
    a, b = np.eye(3), euler_to_matrix(np.array([0.0, 0.0, 1.2]))
    out = slerp_rot(a, b, np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(out[0], a, atol=1e-12)
    np.testing.assert_allclose(out[2], b, atol=1e-12)
    np.testing.assert_allclose(out[1], euler_to_matrix(np.array([0.0, 0.0, 0.6])), atol=1e-12)
    tr = keyframe_track([(0, pose("stand")), (10, pose("sit")), (20, pose("stand"))], 25)
    np.testing.assert_allclose(tr[10], pose("sit"), atol=1e-12)
    np.testing.assert_allclose(tr[24], pose("stand"), atol=1e-12)
    assert ease(np.array([0.0, 0.5, 1.0])).tolist() == [0.0, 0.5, 1.0]
    with pytest.raises(ValueError, match="unknown pose"):
        pose("dance")


# ---------------------------------------------------------------- walking
@pytest.mark.parametrize("scale,seed", [(1.0, 0), (0.9, 1), (1.1, 2)])
def test_walk_plants_feet_and_follows_path(scale, seed):
    rng = np.random.default_rng(seed)
    off = rest_offsets(scale * rng.uniform(0.97, 1.03, 24))
    path = np.array([[0.0, 0.0], [3.0, 0.5], [4.0, 2.5]])
    m = walk(path, off, rng, speed=1.2, start_yaw=np.pi / 2, end_yaw=-np.pi)
    joints = _check_motion(m)
    slides = _contact_slides(m, joints)
    assert len(slides) >= 8 and max(slides) < 0.02
    assert np.linalg.norm(joints[-1, 0, :2] - path[-1]) < 0.1
    assert np.linalg.norm(joints[0, 0, :2] - path[0]) < 0.1
    assert joints[:, FEET, 2].min() > 0.04 - 0.005 and joints[:, ANKLES, 2].min() > 0.0
    v = np.linalg.norm(np.diff(m.root[:, :2], axis=0), axis=1) * m.fps
    assert 1.0 < v.max() < 1.6  # reaches about the commanded speed, never much faster
    names = [a.name for a in m.actions]
    assert names == ["turn", "walk", "turn"]
    hd = heading(joints)
    assert abs(np.angle(np.exp(1j * (hd[0] - np.pi / 2)))) < 0.05
    assert abs(np.angle(np.exp(1j * (hd[-1] + np.pi)))) < 0.05
    # Feet alternate: each foot is in flat contact 35-75 % of the time, at least one planted mostly.
    assert ((m.foot_contact.mean(0) > 0.35) & (m.foot_contact.mean(0) < 0.75)).all()
    # Pelvis stays near standing height (bob a few cm).
    assert joints[:, 0, 2].min() > off[0, 2] - 0.12


@pytest.mark.parametrize("scale,seed", [(0.9, 0), (1.1, 2)])
def test_feet_do_not_slide_while_touching_the_floor(scale, seed):
    """Toe-off rolls over the planted toe, heel strike over the planted heel, and the foot travels
    only once the toe is clear of the floor: the foot joint does not slide while it is within the
    contact band (the builder's floor contact), in walks and in turns in place."""
    from trumans.contacts.rule import CONTACT_THRESHOLD, JOINT_RADIUS
    from trumans.eval.metrics import foot_slides

    rng = np.random.default_rng(seed)
    off = rest_offsets(scale)
    for m in (walk(np.array([[0.0, 0.0], [3.0, 0.5], [4.0, 2.5]]), off, rng, speed=1.4, start_yaw=np.pi / 2,
                   end_yaw=-np.pi),
              turn(off, np.zeros(2), 0.0, 2.5, rng), turn(off, np.zeros(2), 0.3, -1.2, rng)):
        feet = _check_motion(m)[:, FEET]
        band = feet[..., 2] < JOINT_RADIUS[FEET[0]] + CONTACT_THRESHOLD
        step = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1)
        assert step[band[1:] & band[:-1]].max() < 0.01
        slides = foot_slides(feet, band)
        assert slides.mean() < 0.003 and slides.max() < 0.012
        assert feet[..., 2].min() > JOINT_RADIUS[FEET[0]] - 0.005  # the toe never digs into the floor


def test_walk_determinism_and_variation():
    off = rest_offsets()
    path = np.array([[0.0, 0.0], [2.0, 0.0]])
    m1 = walk(path, off, np.random.default_rng(5))
    m2 = walk(path, off, np.random.default_rng(5))
    m3 = walk(path, off, np.random.default_rng(6))
    np.testing.assert_array_equal(m1.rot, m2.rot)
    np.testing.assert_array_equal(m1.root, m2.root)
    assert m1.num_frames != m3.num_frames or not np.allclose(m1.rot, m3.rot)
    with pytest.raises(ValueError, match="path"):
        walk(np.zeros((1, 2)), off, np.random.default_rng(0))
    with pytest.raises(ValueError, match="speed"):
        walk(path, off, np.random.default_rng(0), speed=9.0)


def test_stand_and_turn():
    off = rest_offsets(1.05)
    rng = np.random.default_rng(3)
    m = stand(off, np.array([1.0, 2.0]), 0.7, 90, rng)
    joints = _check_motion(m)
    assert m.foot_contact.all() and max(_contact_slides(m, joints)) < 1e-6
    r0, p0 = standing_state(off, np.array([1.0, 2.0]), 0.7)
    np.testing.assert_allclose(m.rot[[0, -1]], np.stack([r0, r0]), atol=1e-9)
    np.testing.assert_allclose(joints[:, ANKLES], np.broadcast_to(foot_places(off, [1.0, 2.0], 0.7), (90, 2, 3)),
                               atol=1e-9)
    assert np.ptp(joints[:, J["head"]], axis=0).max() > 1e-3  # it breathes/sways
    t = turn(off, np.array([0.0, 0.0]), 0.0, np.pi / 2, rng)
    tj = _check_motion(t)
    assert max(_contact_slides(t, tj)) < 0.02
    assert abs(heading(tj[-1]) - np.pi / 2) < 0.02 and np.linalg.norm(tj[-1, 0, :2]) < 1e-6


# ---------------------------------------------------------------- sitting and lying
SEAT = np.array([2.0, 0.0, 0.45])
SIT_YAW = np.pi
STAND_POS = np.array([1.55, 0.0])
LIE = np.array([2.25, 0.9, 0.45])
LIE_YAW = np.pi / 2


def test_sit_down_stand_up():
    off = rest_offsets(0.95)
    rng = np.random.default_rng(4)
    m = sit_down(off, SEAT, SIT_YAW, STAND_POS, rng)
    joints = _check_motion(m)
    assert [a.name for a in m.actions] == ["sit_down"]
    assert abs(joints[-1, 0, 2] - seat_clearance(off) - SEAT[2]) < 0.03
    assert 0.08 * 0.9 < seat_clearance(off) < 0.10
    assert np.linalg.norm(joints[-1, 0, :2] - SEAT[:2]) < 0.03
    feet = joints[:, ANKLES + FEET]
    assert np.abs(feet - feet[0]).max() < 1e-6  # feet planted throughout
    assert joints[:, 0, 2].min() > SEAT[2] + seat_clearance(off) - 0.02  # never below the seat
    r1, p1 = seated_state(off, SEAT, SIT_YAW, STAND_POS)
    np.testing.assert_allclose(m.rot[-1], r1, atol=1e-9)
    u = stand_up(off, SEAT, SIT_YAW, STAND_POS, rng)
    _check_motion(u)
    r0, p0 = standing_state(off, STAND_POS, SIT_YAW)
    np.testing.assert_allclose(u.rot[-1], r0, atol=1e-9)
    np.testing.assert_allclose(u.root[-1], p0, atol=1e-9)
    with pytest.raises(ValueError, match="reach"):
        seated_state(off, np.array([2.0, 0.0, 1.2]), SIT_YAW, STAND_POS)  # bar far too high


def test_sitting_down_with_the_arms_held_back():
    """arm_swing=0 (e.g. at a desk) keeps the hands from swinging forward while the trunk leans."""
    off = rest_offsets()
    fwd = np.array([np.cos(SIT_YAW), np.sin(SIT_YAW)])
    reach = {}
    for a in (1.0, 0.0):
        m = stand_up(off, SEAT, SIT_YAW, STAND_POS, np.random.default_rng(3), arm_swing=a)
        j = _check_motion(m)
        reach[a] = float(((j[:, [J["left_index1"], J["right_index1"]], :2] - STAND_POS) @ fwd).max())
        np.testing.assert_allclose(m.rot[-1], standing_state(off, STAND_POS, SIT_YAW)[0], atol=1e-9)
    assert reach[0.0] < reach[1.0] - 0.1


def test_lie_down_ends_horizontal_on_the_surface():
    off = rest_offsets()
    rng = np.random.default_rng(7)
    m = lie_down(off, LIE, LIE_YAW, SEAT, rng, sit_yaw=SIT_YAW, stand_pos=STAND_POS)
    joints = _check_motion(m)
    end = joints[-1]
    d = end[J["head"]] - end[J["pelvis"]]
    d_spine = end[J["neck"]] - end[J["pelvis"]]
    assert abs(d_spine[2]) / np.linalg.norm(d_spine) < 0.1  # horizontal trunk
    assert np.dot(d[:2] / np.linalg.norm(d[:2]), [np.cos(LIE_YAW), np.sin(LIE_YAW)]) > 0.99
    spine = [J[n] for n in ("pelvis", "spine1", "spine2", "spine3", "neck")]
    clear = seat_clearance(off)
    assert joints[:, spine, 2].min() > LIE[2] + clear - 0.03  # body surface never sinks > ~2 cm
    assert end[:, 2].min() > LIE[2] + 0.02  # the whole body rests on top of the bed
    np.testing.assert_allclose(m.rot[-1], lying_state(off, LIE, LIE_YAW)[0], atol=1e-9)
    g = get_up(off, LIE, LIE_YAW, SEAT, rng, sit_yaw=SIT_YAW, stand_pos=STAND_POS)
    np.testing.assert_allclose(g.rot[-1], seated_state(off, SEAT, SIT_YAW, STAND_POS)[0], atol=1e-9)
    assert [a.name for a in g.actions] == ["get_up"]


@pytest.mark.parametrize("scale", [0.9, 1.1])
def test_lie_down_lifts_the_legs_over_the_edge(scale):
    """The feet leave the floor and rise above the surface before swinging onto it: no leg joint
    passes below the bed top (x > 1.8 m here: the seat is 0.2 m in from the edge) on its way; with
    the knees up (leg_reach) the feet end flat on the surface."""
    from trumans.contacts.rule import JOINT_RADIUS

    off = rest_offsets(scale)
    legs = [J[f"{s}_{n}"] for s in ("left", "right") for n in ("knee", "ankle", "foot")]
    for reach in (None, 0.5 * scale):
        m = lie_down(off, LIE, LIE_YAW, SEAT, np.random.default_rng(1), sit_yaw=SIT_YAW, stand_pos=STAND_POS,
                     leg_reach=reach)
        P = _check_motion(m)[:, legs]
        over = (P[..., 0] > 1.8) & (P[..., 1] > -0.3) & (P[..., 1] < 1.9)
        assert over[-1].all() and not over[0].any()
        assert (P[..., 2] - JOINT_RADIUS[legs] - LIE[2])[over].min() > -0.005
        assert m.foot_contact[0].all() and not m.foot_contact[-1].any()
        np.testing.assert_allclose(m.rot[-1], lying_state(off, LIE, LIE_YAW, reach)[0], atol=1e-9)
        np.testing.assert_allclose(m.rot[0], seated_state(off, SEAT, SIT_YAW, STAND_POS)[0], atol=1e-9)
        assert np.linalg.norm(np.diff(_check_motion(m), axis=0), axis=2).max() < 0.05  # smooth


def test_concatenated_day_is_continuous_and_deterministic():
    def day(seed: int) -> Motion:
        rng = np.random.default_rng(seed)
        off = rest_offsets(1.02)
        parts = [
            stand(off, [0.0, 0.0], 0.0, 15, rng),
            walk(np.array([[0.0, 0.0], [1.0, 0.6], [1.55, 0.0]]), off, rng, start_yaw=0.0, end_yaw=SIT_YAW),
            sit_down(off, SEAT, SIT_YAW, STAND_POS, rng),
            sit(off, SEAT, SIT_YAW, STAND_POS, 30, rng),
            lie_down(off, LIE, LIE_YAW, SEAT, rng, sit_yaw=SIT_YAW, stand_pos=STAND_POS),
            lie(off, LIE, LIE_YAW, 30, rng),
            get_up(off, LIE, LIE_YAW, SEAT, rng, sit_yaw=SIT_YAW, stand_pos=STAND_POS),
            stand_up(off, SEAT, SIT_YAW, STAND_POS, rng),
            walk(np.array([[1.55, 0.0], [0.0, -1.0]]), off, rng, start_yaw=SIT_YAW),
        ]
        return concat_motions(parts), [p.num_frames for p in parts]

    m, lens = day(11)
    joints = _check_motion(m)
    jump = np.linalg.norm(np.diff(joints, axis=0), axis=2)
    for b in np.cumsum(lens)[:-1]:
        assert jump[b - 1].max() < 0.05
    assert np.linalg.norm(np.diff(m.root, axis=0), axis=1).max() * m.fps < 2.0  # pelvis never teleports
    m2, _ = day(11)
    np.testing.assert_array_equal(m.rot, m2.rot)


def test_blend_into_removes_a_jump():
    off = rest_offsets()
    rng = np.random.default_rng(9)
    a = stand(off, [0.0, 0.0], 0.0, 10, rng)
    b = stand(off, [0.3, 0.1], 0.5, 40, rng)
    out = blend_into(a, b, 15)
    j = concat_motions([a, out]).joints()
    assert np.linalg.norm(np.diff(j, axis=0), axis=2).max() < 0.05
    np.testing.assert_array_equal(out.rot[15:], b.rot[15:])
    assert not out.foot_contact[:5].any()


def test_reversed_motion_and_heading():
    """Motion.reversed plays frames, object tracks and grasp flags backwards under one label;
    yaw_of inverts yaw_matrix (rotations and 4x4 poses)."""
    from trumans.rotations import yaw_matrix
    from trumans.synth.motion import yaw_of

    rng = np.random.default_rng(0)
    off = rest_offsets(1.0)
    m = walk(np.array([[0.0, 0.0], [1.0, 0.5]]), off, rng)
    T = m.num_frames
    m.objects["box"] = np.broadcast_to(np.eye(4), (T, 4, 4)).copy()
    m.objects["box"][:, 0, 3] = np.arange(T)
    m.grasp[20] = np.arange(T) < 5
    r = m.reversed("walk_back")
    np.testing.assert_array_equal(r.rot, m.rot[::-1])
    np.testing.assert_array_equal(r.root, m.root[::-1])
    np.testing.assert_array_equal(r.foot_contact, m.foot_contact[::-1])
    np.testing.assert_array_equal(r.objects["box"][:, 0, 3], np.arange(T)[::-1])
    assert r.grasp[20][-5:].all() and not r.grasp[20][:-5].any()
    assert [(a.name, a.start, a.end) for a in r.actions] == [("walk_back", 0, T)]
    yaws = np.array([-3.0, -1.2, 0.0, 0.4, 3.1])
    np.testing.assert_allclose(yaw_of(yaw_matrix(yaws)), yaws, atol=1e-12)
    H = np.broadcast_to(np.eye(4), (5, 4, 4)).copy()
    H[:, :3, :3] = yaw_matrix(yaws) @ euler_to_matrix(np.array([0.0, 0.3, 0.0]), "ZYX")  # pitched: heading kept
    np.testing.assert_allclose(yaw_of(H), yaws, atol=1e-12)
