"""trumans.refine.foot_lock: planted foot joints pinned, the legs following by IK, rotations kept consistent."""
import numpy as np
import pytest

from trumans.refine.body_drift import DriftConfig, stance_mask
from trumans.refine.foot_lock import LockConfig, lock_feet, stance_corrections
from trumans.refine.frame import FRAME_DIM, JOINTS, OBJ_T, ROTATIONS
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import JOINT_INDEX, LEG_CHAINS, forward_kinematics, rest_offsets

FPS = 30.0
LA, LF, RA = JOINT_INDEX["left_ankle"], JOINT_INDEX["left_foot"], JOINT_INDEX["right_ankle"]
LEG = [JOINT_INDEX[n] for n in ("left_hip", "left_knee", "left_ankle", "left_foot")]


def _standing(T: int = 120, wobble_deg: float = 1.5, swing_right: bool = False):
    """An FK-exact body standing still whose left hip wobbles (the planted left foot wanders by ~1-2
    cm, slower than 0.2 m/s); with ``swing_right`` the right leg swings fast (not a stance)."""
    t = np.arange(T) / FPS
    aa = np.zeros((T, 24, 3))
    aa[:, JOINT_INDEX["left_hip"], 0] = np.radians(wobble_deg) * np.sin(2 * np.pi * 0.7 * t)
    aa[:, JOINT_INDEX["left_knee"], 1] = np.radians(5.0)  # a slight bend (the knee's side is defined)
    if swing_right:
        aa[:, JOINT_INDEX["right_hip"], 1] = np.radians(35.0) * np.sin(2 * np.pi * 1.0 * t)
    R = axis_angle_to_matrix(aa)
    root = np.tile([0.3, -0.2, 0.93], (T, 1))
    off = rest_offsets()
    J, _ = forward_kinematics(R, root, off)
    f = np.zeros((T, FRAME_DIM))
    f[:, JOINTS] = J.reshape(T, -1)
    f[:, ROTATIONS] = matrix_to_6d(R).reshape(T, -1)
    f[:, OBJ_T] = np.random.default_rng(0).normal(size=(T, 3))
    return f, R, root, off


def _joints(f):
    return f[:, JOINTS].reshape(len(f), 24, 3)


def test_a_wandering_planted_foot_is_pinned_and_the_leg_follows_consistently():
    f, R, root, off = _standing()
    J0 = _joints(f)
    assert np.ptp(J0[:, LA], axis=0).max() > 0.01  # the foot wanders by over 1 cm
    out = lock_feet(f, FPS, LockConfig(hold_s=0.0))  # each stance on its mean
    J = _joints(out)
    assert np.ptp(J[:, LA], axis=0).max() < 1e-6 and np.ptp(J[:, LF], axis=0).max() < 1e-6  # one stance: pinned
    for a, b in zip(LEG[:-1], LEG[1:]):  # bone lengths kept in every frame
        np.testing.assert_allclose(np.linalg.norm(J[:, b] - J[:, a], axis=-1), np.linalg.norm(J0[:, b] - J0[:, a], axis=-1), atol=1e-9)
    np.testing.assert_array_equal(J[:, LEG[0]], J0[:, LEG[0]])  # the hip stays
    others = [j for j in range(24) if j not in LEG]
    np.testing.assert_allclose(J[:, others], J0[:, others], atol=1e-12)  # (the still right foot: a zero correction)
    np.testing.assert_array_equal(out[:, OBJ_T], f[:, OBJ_T])
    # the rotations drive the same skeleton onto the new joints
    P, _ = forward_kinematics(sixd_to_matrix(out[:, ROTATIONS].reshape(-1, 24, 6)), root, off)
    np.testing.assert_allclose(P, J, atol=1e-6)
    legs = [j for chain in LEG_CHAINS for j in chain[:3]]  # hips, knees, ankles turn; every other rotation as it came
    rest = [j for j in range(24) if j not in legs]
    np.testing.assert_array_equal(out[:, ROTATIONS].reshape(-1, 24, 6)[:, rest], f[:, ROTATIONS].reshape(-1, 24, 6)[:, rest])


def test_a_swinging_foot_is_left_alone_and_corrections_fade_in():
    f, *_ = _standing(T=150, swing_right=True)
    out = lock_feet(f, FPS, LockConfig(fade_s=0.2))
    np.testing.assert_array_equal(_joints(out)[:, RA], _joints(f)[:, RA])  # 35 deg swings: never planted
    # a stance that ends: the correction w(t) (target - joint) fades out linearly over fade_s after it
    g, *_ = _standing(T=150, wobble_deg=1.5)
    J = _joints(g).copy()
    J[100:, [LA, LF]] += np.linspace(0, 1.5, 50)[:, None, None] * np.array([1.0, 0, 0])  # the foot leaves fast
    g[:, JOINTS] = J.reshape(150, -1)
    planted = stance_mask(J, FPS)[:, 0]  # FOOT_JOINTS[0]: the left ankle
    end = np.flatnonzero(planted)[np.flatnonzero(planted) < 110].max()
    target = J[:end + 1][planted[:end + 1], LA].mean(0)
    out = _joints(lock_feet(g, FPS, LockConfig(fade_s=0.2, toe_first=False, hold_s=0.0)))  # the ankle's own fade
    for k in range(1, 6):  # 0.2 s = 6 frames
        np.testing.assert_allclose(out[end + k, LA] - J[end + k, LA], (1 - k / 6) * (target - J[end + k, LA]), atol=1e-9)
    np.testing.assert_array_equal(out[end + 6:, LA], J[end + 6:, LA])


def test_a_held_toe_stays_put_when_the_filters_toe_bone_changes_length():
    """The filter's toe bone is a few mm longer or shorter from frame to frame: placed at that
    frame's length from the held ankle (``toe_first`` off) the toe base moves by the length's
    changes; with the toe first (the ankle on the sphere of the clip's toe length around the held
    toe) it stays on its target and the ankle stands still too."""
    f, *_ = _standing()
    J = _joints(f).copy()
    rng = np.random.default_rng(4)
    u = (J[:, LF] - J[:, LA]) / np.linalg.norm(J[:, LF] - J[:, LA], axis=-1, keepdims=True)
    J[:, LF] += rng.uniform(-0.003, 0.003, (len(J), 1)) * u  # the toe bone's length varies by +-3 mm
    f[:, JOINTS] = J.reshape(len(J), -1)
    assert stance_mask(J, FPS)[:, [0, 2]].all()  # left ankle and toe base planted throughout
    loose = _joints(lock_feet(f, FPS, LockConfig(toe_first=False, hold_s=0.0)))
    held = _joints(lock_feet(f, FPS, LockConfig(hold_s=0.0)))
    assert np.ptp(loose[:, LF], axis=0).max() > 0.003  # it moves with the length
    assert np.ptp(held[:, LF], axis=0).max() < 1e-9 and np.ptp(held[:, LA], axis=0).max() < 1e-9
    np.testing.assert_allclose(held[0, LF], J[:, LF].mean(0), atol=1e-9)  # on the toe's stance mean
    np.testing.assert_allclose(np.linalg.norm(held[:, LF] - held[:, LA], axis=-1),
                               np.median(np.linalg.norm(J[:, LF] - J[:, LA], axis=-1)), atol=1e-9)


def _planted_left_ankle(T: int, frames: slice) -> np.ndarray:
    planted = np.zeros((T, 4), bool)
    planted[frames, 0] = True  # FOOT_JOINTS[0]: the left ankle
    return planted


def test_a_long_stance_follows_the_feet_slow_shift_and_drops_the_jitter():
    """hold_s > 0: within a 4-s stance the target is the ankle's Gaussian-weighted mean over the
    stance's own frames, so a slow 1 cm/s shift (a foot rolling or sliding on a bed) is followed
    where the mean would leave it up to 2 cm off, and the 3-mm jitter is gone."""
    T = 120
    rng = np.random.default_rng(0)
    clean = np.zeros((T, 24, 3))
    clean[:, LA, 0] = np.linspace(0.0, 0.04, T)  # 4 cm over 4 s
    J = clean + rng.normal(0.0, 0.003, clean.shape)
    planted = _planted_left_ankle(T, slice(None))
    follow = J[:, LA] + stance_corrections(J, planted, 6.0, smooth=30.0)[:, 0]
    pinned = J[:, LA] + stance_corrections(J, planted, 6.0)[:, 0]
    np.testing.assert_allclose(pinned, np.broadcast_to(J[:, LA].mean(0), pinned.shape), atol=1e-12)
    err_follow = np.linalg.norm(follow - clean[:, LA], axis=-1)
    err_pinned = np.linalg.norm(pinned - clean[:, LA], axis=-1)
    assert err_pinned.max() > 0.018 and err_follow.max() < 0.5 * err_pinned.max()
    assert err_follow[40:80].max() < 0.003  # well inside the stance (over a sigma from its ends): on the shift
    step_in = np.linalg.norm(np.diff(J[:, LA], axis=0), axis=-1).mean()
    step_out = np.linalg.norm(np.diff(follow, axis=0), axis=-1).mean()
    assert step_out < 0.1 * step_in  # the frame-to-frame slide: the shift's 0.3 mm, not the jitter's ~5 mm


def test_a_short_stance_is_all_but_pinned_whatever_hold_s():
    """A 0.5-s walking stance under a 1-s hold: the Gaussian weights over its 15 frames are nearly
    equal, so the target is within a fraction of a millimetre of the stance mean."""
    T = 60
    rng = np.random.default_rng(1)
    J = rng.normal(0.0, 0.004, (T, 24, 3))
    planted = _planted_left_ankle(T, slice(20, 35))
    held = J[:, LA] + stance_corrections(J, planted, 6.0, smooth=30.0)[:, 0]
    assert np.ptp(held[20:35], axis=0).max() < 0.1 * np.ptp(J[20:35, LA], axis=0).max()
    np.testing.assert_allclose(held[20:35].mean(0), J[20:35, LA].mean(0), atol=3e-4)
    np.testing.assert_array_equal(held[:14], J[:14, LA])  # farther than the 6-frame fade: untouched


def test_bad_inputs_and_nothing_to_lock():
    f, *_ = _standing()
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        lock_feet(f[:, :10], FPS)
    with pytest.raises(ValueError, match="fps"):
        lock_feet(f, 0.0)
    with pytest.raises(ValueError, match="fade_s"):
        LockConfig(fade_s=-1.0)
    with pytest.raises(ValueError, match="hold_s"):
        LockConfig(hold_s=float("nan"))
    g = f.copy()
    g[5, 0] = np.nan
    np.testing.assert_array_equal(lock_feet(g, FPS), g)  # missing joints: left as they are
    strict = LockConfig(stance=DriftConfig(speed_m_s=1e-4))  # only the exactly still right foot is planted
    np.testing.assert_allclose(lock_feet(f, FPS, strict), f, atol=1e-12)
