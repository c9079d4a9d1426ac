"""Foot cleanup of sampled episodes (sample.foot_cleanup): locks, floor, bone lengths, context."""
import numpy as np
import pytest

from sample.foot_cleanup import LEGS, FootCleanupConfig, clean_feet, foot_contacts, two_bone_positions
from sample.sampler import bone_lengths_of
from sample.synthesis_metrics import feet_skate_cm, floor_err_cm
from trumans.skeleton import rest_offsets, forward_kinematics

FPS = 30.0


def _standing(T: int) -> np.ndarray:
    """(1, T, 24, 3) rest pose with the feet on the floor (lowest foot joint at its rest height)."""
    rot = np.broadcast_to(np.eye(3), (T, 24, 3, 3)).copy()
    P, _ = forward_kinematics(rot, np.zeros((T, 3)), rest_offsets())
    L, R = LEGS["left"], LEGS["right"]
    low = min((P[0, [L[2], R[2]], 2] - 0.08).min(), (P[0, [L[3], R[3]], 2] - 0.04).min())
    P[..., 2] -= low
    return P[None]


def _sliding_planted_foot(T: int = 40) -> np.ndarray:
    """Standing body whose whole left leg slides 1 cm/frame forward and sinks 3 cm (a skating foot)."""
    J = _standing(T)
    left = list(LEGS["left"][1:])
    J[0, :, left, 0] += 0.01 * np.arange(T)[:, None]
    J[0, :, left, 2] -= 0.03
    return J  # the left shin and thigh are not rigid any more: the hip->knee bone changes length


def test_two_bone_positions_keeps_lengths_and_reaches():
    rng = np.random.default_rng(0)
    hip = rng.normal(size=(50, 3))
    knee = hip + rng.normal(size=(50, 3)) * 0.3
    target = hip + rng.normal(size=(50, 3)) * 0.4
    k, a = two_bone_positions(hip, knee, target, 0.42, 0.40)
    np.testing.assert_allclose(np.linalg.norm(k - hip, axis=-1), 0.42, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(a - k, axis=-1), 0.40, atol=1e-9)
    inside = np.linalg.norm(target - hip, axis=-1) < 0.81
    np.testing.assert_allclose(a[inside], target[inside], atol=1e-9)


def test_contacts_have_hysteresis():
    J = np.repeat(_standing(1), 30, axis=1)
    ankle, toe = LEGS["left"][2:]
    lift = np.r_[np.zeros(10), np.full(5, 0.08), np.full(5, 0.2), np.full(10, 0.08)]  # 0.08: between thresholds
    J[:, :, [ankle, toe], 2] += lift[:, None]
    c = foot_contacts(J, FPS)[0, :, 0]
    assert c[:15].all()  # 0.08 m up keeps an existing contact
    assert not c[15:].any()  # 0.2 m leaves it and 0.08 m does not re-enter
    assert foot_contacts(J, FPS)[0, :, 1].all()


def test_clean_feet_pins_planted_foot_and_keeps_bones():
    J = _standing(40)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEGS["left"][2:]
    moved = J.copy()  # the whole body slides forward 6 cm/s and sinks 3 cm: both feet skate under the floor
    moved[..., 0] += 0.002 * np.arange(40)[:, None]
    moved[..., 2] -= 0.03
    low = np.minimum(moved[0, :, ankle, 2] - 0.08, moved[0, :, toe, 2] - 0.04)
    assert feet_skate_cm(moved[0]) > 5 and low.min() < -0.005  # skating and under the floor
    out = clean_feet(moved, lengths, FPS, fixed=0)
    np.testing.assert_allclose(bone_lengths_of(out[0])[:, 1:], np.broadcast_to(lengths[1:], (40, 23)), atol=1e-6)
    assert np.ptp(out[0, :, ankle, :2], axis=0).max() < 1e-6  # pinned where it landed
    low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, toe, 2] - 0.04)
    np.testing.assert_allclose(low, 0.0, atol=1e-6)  # on the floor, not under it
    assert floor_err_cm(out[0])[1] < 1e-4
    assert feet_skate_cm(out[0]) < 0.1
    untouched = [j for j in range(24) if j not in LEGS["left"][1:] + LEGS["right"][1:]]
    np.testing.assert_array_equal(out[..., untouched, :], moved[..., untouched, :])


def test_context_frames_are_fixed_and_seed_the_lock():
    J = _standing(30)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEGS["right"][2:]
    moved = J.copy()
    moved[:, 10:, [ankle, toe], 1] += 0.005 * np.arange(1, 21)[:, None]  # the new frames drift the planted foot
    out = clean_feet(moved, lengths, FPS, fixed=10)
    np.testing.assert_array_equal(out[:, :10], moved[:, :10])
    np.testing.assert_allclose(out[0, 10:, ankle, :2], np.broadcast_to(moved[0, 9, ankle, :2], (20, 2)), atol=1e-4)


def test_swing_foot_is_left_free_and_bad_input_raises():
    J = np.repeat(_standing(1), 20, axis=1)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEGS["left"][2:]
    J[:, :, [ankle, toe], 0] += 0.05 * np.arange(20)[:, None]  # 1.5 m/s, a step in the air
    J[:, :, [ankle, toe], 2] += 0.15
    out = clean_feet(J, lengths, FPS)
    np.testing.assert_allclose(out, J, atol=1e-9)
    with pytest.raises(ValueError, match="joints must be"):
        clean_feet(J[0], lengths, FPS)
    with pytest.raises(ValueError, match="fixed"):
        clean_feet(J, lengths, FPS, fixed=99)
    with pytest.raises(ValueError, match="enter_height"):
        FootCleanupConfig(enter_height=0.2, exit_height=0.1)
