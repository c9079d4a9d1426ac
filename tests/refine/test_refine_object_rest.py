"""Object rests pooled over the whole rest (trumans.refine.object_rest)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from trumans.refine.frame import FRAME_DIM, JOINTS, OBJ_R, OBJ_T
from trumans.refine.object_rest import RestConfig, held_mask, pool_rest, rest_mask
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import JOINT_INDEX

FPS = 30.0


def _frames(obj_t: np.ndarray, obj_r: np.ndarray | None = None) -> np.ndarray:
    f = np.zeros((len(obj_t), FRAME_DIM), np.float32)
    f[:, OBJ_T] = obj_t
    f[:, OBJ_R] = matrix_to_6d(np.broadcast_to(np.eye(3), (len(obj_t), 3, 3))) if obj_r is None else obj_r
    return f


def _move_between_rests(T: int = 240, a: int = 90, b: int = 150, dist: float = 0.6) -> np.ndarray:
    """(T, 3): at rest at the origin, a 2 s move of ``dist`` m along x (smooth-step), at rest again."""
    s = np.clip((np.arange(T) - a) / (b - a), 0, 1)
    p = np.zeros((T, 3))
    p[:, 0] = dist * (3 * s ** 2 - 2 * s ** 3)
    return p


def test_rest_mask_finds_the_move():
    p = _move_between_rests()
    rest = rest_mask(p, FPS)
    assert rest[:80].all() and rest[-80:].all()
    assert not rest[105:135].any()  # peak speed 0.45 m/s


def test_rest_mask_static_object_with_slow_drift_is_all_rest():
    t = np.arange(300) / FPS
    p = 0.03 * np.stack([np.sin(2 * np.pi * 0.3 * t), np.cos(2 * np.pi * 0.2 * t), 0 * t], -1)  # <= 6 cm/s
    assert rest_mask(p, FPS).all()


def test_rest_mask_drops_short_rests():
    p = _move_between_rests(T=200, a=0, b=199, dist=2.0)  # slow (< 0.2 m/s) only in its first and last 0.85 s
    assert not rest_mask(p, FPS, RestConfig(min_rest_s=1.0)).any()


def test_pool_rest_averages_drift_out_of_a_static_object():
    rng = np.random.default_rng(0)
    T = 300
    t = np.arange(T) / FPS
    truth = np.array([1.0, 2.0, 0.8])
    drift = 0.03 * np.stack([np.sin(2 * np.pi * t / 2.5), np.cos(2 * np.pi * t / 5.0), np.sin(2 * np.pi * t / 10.0)], -1)
    tracked = _frames(truth + drift + rng.normal(0, 0.02, (T, 3)))
    filtered = _frames(truth + drift)  # a filter that removed the jitter but, window by window, kept the drift
    # rotations: the filter's carry a constant 3 deg bias (an IMU's), the tracked ones noise and a flip
    true_R = axis_angle_to_matrix(np.array([0.0, 0.0, 0.7]))
    bias = axis_angle_to_matrix(np.array([np.radians(3.0), 0.0, 0.0]))
    filtered[:, OBJ_R] = matrix_to_6d(bias @ axis_angle_to_matrix(rng.normal(0, 0.01, (T, 3))) @ true_R)
    noisy = axis_angle_to_matrix(rng.normal(0, 0.08, (T, 3))) @ true_R
    noisy[100:110] = noisy[100:110] @ axis_angle_to_matrix(np.array([np.pi, 0.0, 0.0]))  # a flip
    tracked[:, OBJ_R] = matrix_to_6d(noisy)
    tracked[200:220, OBJ_R] = np.nan
    out = pool_rest(filtered, tracked, FPS)
    err_in = np.linalg.norm(filtered[:, OBJ_T] - truth, axis=-1).mean()
    err_out = np.linalg.norm(out[:, OBJ_T] - truth, axis=-1).mean()
    assert np.ptp(out[:, OBJ_T], axis=0).max() < 1e-5  # one pose for the whole rest
    assert err_out < 0.3 * err_in
    R = sixd_to_matrix(out[:, OBJ_R].astype(np.float64))
    assert np.allclose(R, R[0], atol=1e-5)
    ang = lambda A: np.degrees(np.arccos(np.clip((np.trace(A @ true_R.T) - 1) / 2, -1, 1)))  # noqa: E731
    assert ang(R[0]) < 1.0  # the tracked mean: no bias, the flip left out
    # without usable tracked rotations the filtered ones' mean is kept (bias and all)
    tracked[:, OBJ_R] = np.nan
    R2 = sixd_to_matrix(pool_rest(filtered, tracked, FPS)[:, OBJ_R].astype(np.float64))
    assert 2.5 < ang(R2[0]) < 3.5
    assert out.dtype == filtered.dtype and np.array_equal(out[:, :OBJ_T.start], filtered[:, :OBJ_T.start])


def test_pool_rest_keeps_the_move_continuous():
    p = _move_between_rests()
    offset = np.array([0.05, -0.03, 0.0])  # the filter's output sits 5 cm off; tracked is centred
    filtered = _frames(p + offset)
    tracked = _frames(p)
    out = pool_rest(filtered, tracked, FPS)
    # the rests land on the tracked mean (the slowest ends of the move count as rest: < 2 mm), the
    # move keeps its shape, nothing jumps, and the 5 cm offset is gone everywhere
    assert np.ptp(out[:60, OBJ_T], axis=0).max() < 1e-6 and np.ptp(out[-60:, OBJ_T], axis=0).max() < 1e-6
    assert np.abs(out[:60, OBJ_T]).max() < 2e-3 and np.abs(out[-60:, OBJ_T] - p[-1]).max() < 2e-3
    assert np.abs(np.diff(out[:, OBJ_T], axis=0)).max() <= np.abs(np.diff(p, axis=0)).max() + 1e-3
    err = np.abs(out[:, OBJ_T] - p).max(-1)
    assert err.mean() < 5e-3 and err.max() < 0.03  # the move starts late by its slowest (rest-counted) part


def test_pool_rest_without_an_observed_object_is_identity():
    p = _move_between_rests()
    filtered = _frames(p)
    tracked = _frames(p)
    tracked[:, OBJ_T] = np.nan
    assert np.array_equal(pool_rest(filtered, tracked, FPS), filtered)


def test_pool_rest_ignores_missing_tracked_frames():
    T = 201
    truth = np.array([0.5, 0.5, 0.5])
    tracked = _frames(np.tile(truth, (T, 1)))
    tracked[::3, OBJ_T] = np.nan
    tracked[1::3, OBJ_T] += 0.02
    tracked[2::3, OBJ_T] -= 0.02
    out = pool_rest(_frames(np.tile(truth + 0.04, (T, 1))), tracked, FPS)
    assert np.allclose(out[:, OBJ_T], truth, atol=1e-5)


def test_bad_inputs_raise():
    p = _move_between_rests()
    with pytest.raises(ValueError, match="must both be"):
        pool_rest(_frames(p), _frames(p)[:, :10], FPS)
    with pytest.raises(ValueError, match="finite"):
        rest_mask(np.full((10, 3), np.nan), FPS)
    with pytest.raises(ValueError, match=r"\(T, 3\)"):
        rest_mask(np.zeros((10, 2)), FPS)
    with pytest.raises(ValueError, match="fps"):
        rest_mask(p, 0.0)
    with pytest.raises(ValueError, match="lo_m_s"):
        RestConfig(lo_m_s=0.5, hi_m_s=0.2)
    with pytest.raises(ValueError, match="max_rot_deg"):
        RestConfig(max_rot_deg=0.0)


def _carried(T: int = 240, a: int = 90, b: int = 150, turn_deg: float = 60.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cup carried by the right wrist between two rests: (obj_t (T, 3), obj_R (T, 3, 3), joints
    (T, 24, 3)); the grasp sits at o in the cup's frame, the cup turns ``turn_deg`` about z on the way,
    the left wrist hangs still 0.8 m away, the wrists rest on the cup before and after the move."""
    s = np.clip((np.arange(T) - a) / (b - a), 0, 1)  # at a steady 0.3 m/s: the rests are found to the frame
    p = np.stack([0.6 * s, 0 * s, 0 * s], -1)
    R = axis_angle_to_matrix(np.stack([0 * s, 0 * s, np.radians(turn_deg) * s], -1))
    o = np.array([0.05, 0.0, 0.03])
    J = np.zeros((T, 24, 3))
    J[:, JOINT_INDEX["right_wrist"]] = p + R @ o
    J[:, JOINT_INDEX["left_wrist"]] = np.array([0.0, 0.8, 1.0])
    return p, R, J


def _with_joints(obj_t: np.ndarray, R: np.ndarray, J: np.ndarray) -> np.ndarray:
    f = _frames(obj_t, matrix_to_6d(R))
    f[:, JOINTS] = J.reshape(len(J), -1)
    return f


def test_hand_link_ties_the_rests_through_the_carrying_wrist():
    p, R, J = _carried()
    T = len(p)
    # the tracker's drift: +4 cm in x before the move, -4 cm after, changing during it (the filter
    # kept it); jitter
    drift = np.zeros((T, 3))
    drift[:, 0] = 0.04 - 0.08 * np.clip((np.arange(T) - 90) / 60, 0, 1)
    rng = np.random.default_rng(0)
    tracked = _with_joints(p + drift + rng.normal(0, 0.01, (T, 3)), R, J)
    filtered = _with_joints(p + drift, R, J)
    linked = pool_rest(filtered, tracked, FPS)
    alone = pool_rest(filtered, tracked, FPS, RestConfig(hand_link=False))
    err = lambda f: np.linalg.norm(f[:, OBJ_T] - p, axis=-1)  # noqa: E731
    mv = slice(100, 140)
    assert err(alone)[:60].mean() > 0.035 and err(alone)[-60:].mean() > 0.035  # each rest keeps its own drift
    assert err(linked)[mv].max() < 0.02  # the move follows the wrist ...
    R_out = sixd_to_matrix(linked[mv, OBJ_R].astype(np.float64))
    o_hat = np.einsum("tji,tj->ti", R_out, J[mv, JOINT_INDEX["right_wrist"]] - linked[mv, OBJ_T])
    assert np.ptp(o_hat, axis=0).max() < 1e-5  # ... minus one grasp offset in the cup's (output) frame
    assert np.array_equal(linked[:, :OBJ_T.start], filtered[:, :OBJ_T.start])
    # a wrist trusted at the grasp and the release ties the two rests together: where the cup does
    # not turn, they lie apart by the wrist's displacement between the move's first and last frame
    # (a turn lets the unknown grasp offset absorb part of their difference), and share one drift
    p, R, J = _carried(turn_deg=0.0)
    tracked = _with_joints(p + drift + rng.normal(0, 0.01, (T, 3)), R, J)
    filtered = _with_joints(p + drift, R, J)
    tied = pool_rest(filtered, tracked, FPS, RestConfig(link_weight=1e4))
    alone = pool_rest(filtered, tracked, FPS, RestConfig(hand_link=False))
    moving = np.flatnonzero(~rest_mask(filtered[:, OBJ_T], FPS))
    s, e = moving[0], moving[-1] + 1
    wrist = J[:, JOINT_INDEX["right_wrist"]]
    assert np.abs(tied[e, OBJ_T] - tied[s - 1, OBJ_T] - (wrist[e] - wrist[s - 1])).max() < 1e-3
    assert np.abs(alone[e, OBJ_T] - alone[s - 1, OBJ_T] - (wrist[e] - wrist[s - 1])).max() > 0.03
    assert err(tied).mean() < 0.6 * err(alone).mean()


def test_hand_link_meets_the_rests_without_a_jump():
    # the body sits 6 cm off (a drift the feet did not see): the wrist's path and the rests disagree
    # by a few cm where they meet; that gap is faded out over fade_s instead of jumping
    p, R, J = _carried(turn_deg=90.0)
    J[:, JOINT_INDEX["right_wrist"]] += [0.06, 0.0, 0.0]
    rng = np.random.default_rng(0)
    tracked = _with_joints(p + rng.normal(0, 0.01, (len(p), 3)), R, J)
    step = lambda f: np.abs(np.diff(f[:, OBJ_T], axis=0)).max()  # noqa: E731
    truth_step = np.abs(np.diff(p, axis=0)).max()  # 1 cm per frame
    assert step(pool_rest(_with_joints(p, R, J), tracked, FPS, RestConfig(fade_s=0.0))) > truth_step + 0.01
    assert step(pool_rest(_with_joints(p, R, J), tracked, FPS)) < truth_step + 0.004


def test_hand_link_ignores_a_wrist_that_does_not_hold_the_object():
    p, R, J = _carried()
    J[:, JOINT_INDEX["right_wrist"]] = np.array([0.3, -0.8, 1.0])  # nobody holds the cup: it moves alone
    T = len(p)
    rng = np.random.default_rng(1)
    tracked = _with_joints(p + rng.normal(0, 0.02, (T, 3)), R, J)
    filtered = _with_joints(p + 0.03, R, J)
    assert np.array_equal(pool_rest(filtered, tracked, FPS), pool_rest(filtered, tracked, FPS, RestConfig(hand_link=False)))


def test_rest_config_rejects_bad_hand_link_settings():
    with pytest.raises(ValueError, match="prior_weight"):
        RestConfig(prior_weight=0.0)
    with pytest.raises(ValueError, match="rigid_tol_m"):
        RestConfig(rigid_tol_m=-0.1)
    with pytest.raises(ValueError, match="fade_s"):
        RestConfig(fade_s=-1.0)


def _slow_slide(T: int = 240, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A drawer pulled out 15 cm at 0.075 m/s (frames 80-140, slower than the speed detection sees)
    by the right wrist, which reaches it from 0.5 m away (frames 30-60), holds it until frame 160 and
    leaves (160-190): (truth (T, 3), tracked (T, 235), filtered (T, 235), joints (T, 24, 3)).
    Tracked = truth + 1 cm jitter + a 2 cm drift; filtered = truth + the same drift."""
    t = np.arange(T)
    p = np.stack([0.15 * np.clip((t - 80) / 60, 0, 1), 0 * t, 0 * t + 0.5], -1)
    o = np.array([0.0, 0.0, 0.05])  # the handle, above the drawer's origin
    grasp = p + o
    away = grasp[0] + [-0.5, 0.0, 0.0]
    reach = np.clip((t - 30) / 30, 0, 1)[:, None]
    leave = np.clip((t - 160) / 30, 0, 1)[:, None]
    wrist = np.where(t[:, None] < 60, away + reach * (grasp[0] - away), grasp)
    wrist = np.where(t[:, None] >= 160, grasp[-1] + leave * (away - grasp[0]), wrist)
    J = np.zeros((T, 24, 3))
    J[:, JOINT_INDEX["right_wrist"]] = wrist
    J[:, JOINT_INDEX["left_wrist"]] = [0.0, 0.8, 1.0]
    rng = np.random.default_rng(seed)
    drift = 0.02 * np.stack([np.sin(2 * np.pi * t / 150), np.cos(2 * np.pi * t / 200), 0 * t], -1)
    R = np.broadcast_to(np.eye(3), (T, 3, 3))
    return p, _with_joints(p + drift + rng.normal(0, 0.01, (T, 3)), R, J), _with_joints(p + drift, R, J), J


def test_held_mask_finds_a_slow_pull_and_not_a_reach():
    p, tracked, filtered, J = _slow_slide()
    R = np.broadcast_to(np.eye(3), (len(p), 3, 3))
    wrists = J[:, [JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"]]]
    held = held_mask(tracked[:, OBJ_T], R, wrists, FPS)
    assert held[95:125].all()  # the pull
    assert not held[:40].any() and not held[200:].any()  # the reach starts, the wrist has left
    assert rest_mask(filtered[:, OBJ_T], FPS).all()  # the speed alone sees no move at all
    # without a moving wrist nothing is held, whatever the object does
    still = np.broadcast_to(J[:1, [JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"]]], wrists.shape)
    assert not held_mask(tracked[:, OBJ_T], R, still, FPS).any()
    with pytest.raises(ValueError, match="held_window_s"):
        RestConfig(held_window_s=-1.0)
    with pytest.raises(ValueError, match=r"wrists \(T, W, 3\)"):
        held_mask(tracked[:, OBJ_T], R, wrists[:-1], FPS)
    with pytest.raises(ValueError, match="finite"):
        held_mask(tracked[:, OBJ_T], R, np.full_like(wrists, np.nan), FPS)


def test_pool_rest_follows_a_slow_pull_through_the_wrist():
    p, tracked, filtered, _ = _slow_slide()
    err = lambda f: np.linalg.norm(f[:, OBJ_T] - p, axis=-1)  # noqa: E731
    alone = err(pool_rest(filtered, tracked, FPS, RestConfig(hand_link=False)))
    linked = err(pool_rest(filtered, tracked, FPS))
    assert alone[:60].mean() > 0.05 and alone[-40:].mean() > 0.05  # one rest over the whole clip
    assert linked.mean() < 0.4 * alone.mean() and linked.max() < 0.04


def test_rest_rotation_corrections_fade_into_the_move_without_a_step():
    p, R, J = _carried(turn_deg=60.0)
    T = len(p)
    bias = Rotation.from_rotvec([0.0, np.radians(8.0), 0.0])  # the filter's rotation is off by 8 deg throughout
    filtered = _with_joints(p, (bias * Rotation.from_matrix(R)).as_matrix(), J)
    noise = Rotation.from_rotvec(np.random.default_rng(2).normal(0, 0.02, (T, 3)))
    tracked = _with_joints(p, (noise * Rotation.from_matrix(R)).as_matrix(), J)
    out = pool_rest(filtered, tracked, FPS, RestConfig(hand_link=False))
    Ro = Rotation.from_matrix(sixd_to_matrix(out[:, OBJ_R].astype(np.float64)))
    err = np.degrees((Ro * Rotation.from_matrix(R).inv()).magnitude())
    assert err[:80].max() < 1.0 and err[-80:].max() < 1.0  # the rests: pooled from the tracked rotations
    assert abs(err[120] - 8.0) < 0.5  # mid-move: the filter's rotation
    step = np.degrees((Ro[1:] * Ro[:-1].inv()).magnitude())
    fade = RestConfig().fade_s * FPS
    assert step.max() < np.degrees(np.radians(60.0) / 60) + 8.0 / fade + 0.3  # faded in, not one 8 deg step
    assert step.max() < 4.0
