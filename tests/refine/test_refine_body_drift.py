"""The whole-body drift seen by the planted feet (trumans.refine.body_drift)."""
import numpy as np
import pytest

from trumans.skeleton import FOOT_JOINTS
from trumans.refine.body_drift import DriftConfig, estimate_body_drift, remove_body_drift, stance_mask
from trumans.refine.frame import FRAME_DIM, JOINTS
from trumans.skeleton import JOINT_INDEX, REST_JOINTS

FPS = 30.0


def _walk(T: int = 300, step_m: float = 0.6) -> np.ndarray:
    """(T, 24, 3) a body walking along x: each foot swings for 12 frames every 30 (smooth step of
    ``step_m``), the feet half a cycle apart, planted otherwise; the rest of the body glides."""
    t = np.arange(T)
    J = np.repeat(np.asarray(REST_JOINTS, np.float64)[None], T, axis=0)
    J[:, :, 0] += step_m / 30 * t[:, None]  # the body at the feet's mean speed
    for side, phase in (("left", 0), ("right", 15)):
        c = (t - phase) % 30  # swing in cycle frames 0..11
        k = (t - phase) // 30
        s = np.clip(c / 12, 0, 1)
        x = step_m * (k + 3 * s ** 2 - 2 * s ** 3)
        for j in (f"{side}_ankle", f"{side}_foot"):
            J[:, JOINT_INDEX[j], 0] = REST_JOINTS[JOINT_INDEX[j]][0] + x
    return J


def _drift(T: int) -> np.ndarray:
    """(T, 3) zero-mean smooth drift, ~1.5 cm, under 0.1 m/s."""
    s = np.arange(T) / FPS
    d = 0.015 * np.stack([np.sin(2 * np.pi * 0.15 * s), np.cos(2 * np.pi * 0.1 * s + 1), np.sin(2 * np.pi * 0.2 * s)], -1)
    return d - d.mean(0)


def test_stance_mask_finds_planted_feet_of_a_walk():
    planted = stance_mask(_walk(), FPS)
    assert planted.shape == (300, 4)
    left = FOOT_JOINTS.index(JOINT_INDEX["left_ankle"])
    c = np.arange(300) % 30
    assert planted[(c >= 15) & (c < 28), left].all()  # mid-stance
    assert not planted[(c >= 4) & (c < 9), left].any()  # mid-swing (peak speed 1.5 m/s)


def test_stance_mask_drops_stances_shorter_than_the_minimum():
    J = np.zeros((60, 24, 3))
    J[:, :, 0] = np.arange(60)[:, None] * 0.05  # 1.5 m/s everywhere ...
    J[20:24, FOOT_JOINTS, 0] = J[20, FOOT_JOINTS, 0]  # ... but the feet stop for 4 frames
    assert not stance_mask(J, FPS).any()
    assert stance_mask(J, FPS, DriftConfig(min_stance_s=0.0, smooth_s=1 / FPS))[21:23].all()  # central differences


def test_drift_of_a_noise_free_walk_is_recovered_from_the_stances():
    J = _walk()
    d = _drift(len(J))
    exact = DriftConfig(ridge=1e-3, robust_iters=0, min_rms_m=0.0)  # no noise: a weak prior, any drift trusted
    fixed = remove_body_drift(_pack(J + d[:, None]), FPS, exact)[:, JOINTS].reshape(-1, 24, 3)
    before, after = np.linalg.norm(d, axis=-1).mean(), np.linalg.norm(fixed - J, axis=-1).mean()
    assert after < 0.1 * before
    # the default prior is tuned for the filter's noisy output: it shrinks the estimate, never overshoots
    est = estimate_body_drift(J + d[:, None], FPS)
    assert np.linalg.norm(est - d, axis=-1).mean() < 0.8 * before
    assert np.linalg.norm(est, axis=-1).mean() < np.linalg.norm(d, axis=-1).mean()


def test_a_standing_body_keeps_only_a_constant_offset():
    J = np.repeat(np.asarray(REST_JOINTS, np.float64)[None], 240, axis=0)
    d = _drift(240) + np.array([0.02, 0.0, 0.0])  # the constant part is not observable
    fixed = J + d[:, None] - estimate_body_drift(J + d[:, None], FPS)[:, None]
    off = (fixed - J).reshape(-1, 3)
    assert off.std(0).max() < 0.001
    np.testing.assert_allclose(off.mean(0), [0.02, 0.0, 0.0], atol=0.002)


def test_a_flat_floor_ties_the_height_of_stances_far_apart():
    """Stand, walk off at 1 m/s (no stance), stand again, while the tracker's height drifts 2 cm in
    between: each stance alone cannot see the change, one floor height for all stances can."""
    T = 180
    J = np.repeat(np.asarray(REST_JOINTS, np.float64)[None], T, axis=0)
    J[:, :, 0] += np.clip(np.arange(T) - 60, 0, 60)[:, None] / FPS
    s = np.clip((np.arange(T) - 60) / 60, 0, 1)
    d = np.zeros((T, 3))
    d[:, 2] = 0.02 * (3 * s ** 2 - 2 * s ** 3)
    planted = stance_mask(J + d[:, None], FPS)
    assert planted[:50].all() and planted[130:].all() and not planted[70:110].any()

    def gap(cfg: DriftConfig) -> float:  # the height change left between the two stances (m)
        fixed = J + d[:, None] - estimate_body_drift(J + d[:, None], FPS, cfg)[:, None]
        return (fixed[130:, 0, 2] - J[130:, 0, 2]).mean() - (fixed[:50, 0, 2] - J[:50, 0, 2]).mean()

    assert abs(gap(DriftConfig())) < 0.003
    assert abs(gap(DriftConfig(flat_floor=False))) > 0.015  # the stances' own heights absorb it
    # the second stance on a 40 cm step is not on the floor: its height is its own again
    J[120:, :, 2] += 0.4
    fixed = J + d[:, None] - estimate_body_drift(J + d[:, None], FPS)[:, None]
    assert abs((fixed[130:, 0, 2] - J[130:, 0, 2]).mean() - (fixed[:50, 0, 2] - J[:50, 0, 2]).mean()) > 0.015


def test_no_stance_means_no_correction():
    J = np.repeat(np.asarray(REST_JOINTS, np.float64)[None], 90, axis=0)
    J[:, :, 0] += np.arange(90)[:, None] / FPS  # the whole body at 1 m/s: no foot is planted
    assert not stance_mask(J, FPS).any()
    assert np.array_equal(estimate_body_drift(J, FPS), np.zeros((90, 3)))
    f = _pack(J)
    assert np.array_equal(remove_body_drift(f, FPS), f)


def test_remove_body_drift_moves_only_the_joints():
    f = _pack(_walk() + _drift(300)[:, None])
    f[:, JOINTS.stop:] = np.random.default_rng(0).normal(size=(300, FRAME_DIM - JOINTS.stop))
    out = remove_body_drift(f, FPS, DriftConfig(min_rms_m=0.0))
    assert out.dtype == np.float32 and out.shape == f.shape
    assert np.array_equal(out[:, JOINTS.stop:], f[:, JOINTS.stop:])
    moved = (out[:, JOINTS] - f[:, JOINTS]).reshape(300, 24, 3)
    np.testing.assert_allclose(moved, moved[:, :1].repeat(24, 1), atol=1e-6)  # one translation per frame


def test_a_drift_smaller_than_real_feet_read_is_left_alone():
    """min_rms_m: a fitted drift whose rms (its mean removed) is under it is not trusted - real planted
    feet that roll and pivot read 4-14 mm - and the body comes back as it went in; over it, every
    joint moves by minus the fitted drift."""
    J = _walk()
    f = _pack(J + _drift(len(J))[:, None])  # ~1.5 cm per axis
    assert np.array_equal(remove_body_drift(f, FPS), f)  # the default threshold: 5 cm
    est = estimate_body_drift(f[:, JOINTS].reshape(-1, 24, 3).astype(np.float64), FPS)
    rms = float(np.sqrt(((est - est.mean(0)) ** 2).sum(-1).mean()))
    assert rms > 0.003
    assert np.array_equal(remove_body_drift(f, FPS, DriftConfig(min_rms_m=1.1 * rms)), f)
    moved = (remove_body_drift(f, FPS, DriftConfig(min_rms_m=0.9 * rms)) - f)[:, JOINTS].reshape(-1, 24, 3)
    np.testing.assert_allclose(moved, np.broadcast_to(-est[:, None], moved.shape), atol=1e-5)
    with pytest.raises(ValueError, match="min_rms_m"):
        DriftConfig(min_rms_m=-0.01)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="joints must be"):
        estimate_body_drift(np.zeros((10, 23, 3)), FPS)
    J = _walk(60)
    J[5, 3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        estimate_body_drift(J, FPS)
    with pytest.raises(ValueError, match="fps"):
        stance_mask(_walk(60), 0.0)
    with pytest.raises(ValueError, match="frame vectors"):
        remove_body_drift(np.zeros((10, 10)), FPS)
    with pytest.raises(ValueError, match="speed_m_s"):
        DriftConfig(speed_m_s=0.0)
    with pytest.raises(ValueError, match="floor_band_m"):
        DriftConfig(floor_band_m=-0.01)
    with pytest.raises(ValueError, match="robust_iters"):
        DriftConfig(robust_iters=-1)


def _pack(J: np.ndarray) -> np.ndarray:
    f = np.zeros((len(J), FRAME_DIM), np.float32)
    f[:, JOINTS] = J.reshape(len(J), -1)
    return f
