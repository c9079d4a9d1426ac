"""The wider corruption family of ``trumans.refine.corrupt`` (issue 36, point 3): each kind does what
its docstring says, seeds reproduce, the defaults draw what they drew before, bad values are refused."""
from dataclasses import replace

import numpy as np
import pytest

from trumans.refine import CorruptionConfig, add_clean_imu, corrupt, frames_from_sequence
from trumans.refine.corrupt import WIDER_KINDS, vary_skeleton
from trumans.refine.frame import JOINTS, ROTATIONS
from trumans.rotations import sixd_to_matrix
from trumans.skeleton import JOINT_INDEX, PARENTS, forward_kinematics, rest_offsets

from helpers import carried_box_clip

B, L = 8, 64
# everything of the old model off: each test switches on the kind it looks at
QUIET = CorruptionConfig(jitter_m=0.0, p_spike=0.0, drift_m=0.0, joint_drift_m=0.0, rot_noise_rad=0.0,
                         p_joint_occlusion=0.0, p_no_rotations=0.0, p_dropout=0.0, p_freeze=0.0)
LEGS = [[JOINT_INDEX[f"{s}_{n}"] for n in ("hip", "knee", "ankle", "foot")] for s in ("left", "right")]


@pytest.fixture(scope="module")
def W():
    return add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(T=L, seed=k))[0] for k in range(B)]), 30.0)


def _J(f):
    return f[..., JOINTS].reshape(*f.shape[:-1], 24, 3).astype(np.float64)


def test_wider_kinds_are_off_by_default_and_seeded(W):
    assert not CorruptionConfig().wider and not CorruptionConfig().varies_skeleton
    assert set(WIDER_KINDS) <= set(CorruptionConfig().to_dict())
    rw = CorruptionConfig.real_world()
    assert rw.wider and rw.varies_skeleton and rw.p_burst == 0.0  # bursts: the held-out kind
    a, b = corrupt(W, 30.0, np.random.default_rng(7), rw), corrupt(W, 30.0, np.random.default_rng(7), rw)
    np.testing.assert_array_equal(a, b)
    assert a.shape == W.shape and a.dtype == np.float32 and not np.isinf(a).any()
    assert not np.array_equal(a, corrupt(W, 30.0, np.random.default_rng(8), rw), equal_nan=True)
    # a wider kind draws from a child generator: the old kinds' stream is unchanged only when all are off
    np.testing.assert_array_equal(corrupt(W, 30.0, np.random.default_rng(3)),
                                  corrupt(W, 30.0, np.random.default_rng(3), replace(CorruptionConfig(), p_burst=0.0)))


def test_random_walk_and_height_move_the_whole_body(W):
    walk = corrupt(W, 30.0, np.random.default_rng(0), replace(QUIET, walk_m_per_sqrt_s=0.05))
    d = _J(walk) - _J(W)
    np.testing.assert_allclose(d, np.broadcast_to(d[:, :, :1], d.shape), atol=1e-6)  # one offset per frame for every joint
    np.testing.assert_allclose(d[:, 0], 0.0, atol=1e-6)  # starts at 0
    end = np.linalg.norm(d[:, -1, 0, :2], axis=-1)
    assert 0.02 < end.mean() < 0.2  # ~0.05 m/sqrt(s) over 2.1 s: a random walk, not white noise
    step = np.linalg.norm(np.diff(d[:, :, 0], axis=1), axis=-1).mean()
    assert step < 0.02  # small steps
    assert np.abs(d[..., 2]).mean() < np.abs(d[..., :2]).mean()  # the vertical at 0.3 of that
    h = corrupt(W, 30.0, np.random.default_rng(0), replace(QUIET, height_m=(0.03, 0.05)))
    dz = _J(h)[..., 2] - _J(W)[..., 2]
    np.testing.assert_allclose(dz, np.broadcast_to(dz[:, :1, :1], dz.shape), atol=1e-6)  # constant per window
    assert ((np.abs(dz[:, 0, 0]) >= 0.03 - 1e-6) & (np.abs(dz[:, 0, 0]) <= 0.05 + 1e-6)).all()
    np.testing.assert_allclose(_J(h)[..., :2], _J(W)[..., :2], atol=1e-6)


def test_extremity_jitter_and_bursts(W):
    base = replace(QUIET, jitter_m=0.01)
    ext = corrupt(W, 30.0, np.random.default_rng(0), replace(base, extremity_jitter=2.0))
    e = np.linalg.norm(_J(ext) - _J(W), axis=-1).mean(axis=(0, 1))
    wrists = [JOINT_INDEX["left_wrist"], JOINT_INDEX["right_ankle"]]
    assert e[wrists].mean() > 1.6 * e[[JOINT_INDEX["spine2"], JOINT_INDEX["left_knee"]]].mean()
    # the extremities' extra share follows the window's severity (one factor per window for both)
    var = corrupt(W, 30.0, np.random.default_rng(0), replace(base, extremity_jitter=2.0, position_scale=(0.1, 2.0)))
    ev = np.linalg.norm(_J(var) - _J(W), axis=-1).mean(axis=1)  # (B, 24)
    core = [JOINT_INDEX[n] for n in ("spine1", "spine2", "spine3", "neck", "left_knee", "right_knee")]
    ratio = ev[:, wrists].mean(-1) / ev[:, core].mean(-1)
    assert ev[:, core].mean(-1).std() > 0.002 and np.all(np.abs(ratio - 2.0) < 0.5)
    burst = corrupt(W, 30.0, np.random.default_rng(0), replace(QUIET, p_burst=0.05, burst_m=0.04))
    eb = np.linalg.norm(_J(burst) - _J(W), axis=-1).mean(-1)  # (B, L)
    hit = eb > 1e-6
    assert 0.05 < hit.mean() < 0.9 and 0.03 < eb[hit].mean() < 0.1  # runs of 4 cm noise, clean elsewhere


def test_leg_swaps_exchange_the_legs(W):
    sw = corrupt(W, 30.0, np.random.default_rng(1), replace(QUIET, p_swap=0.03))
    J, G = _J(sw), _J(W)
    swapped = np.abs(J - G).max(axis=(-1, -2)) > 1e-6  # (B, L)
    assert swapped.any() and not swapped.all()
    a, b = LEGS
    np.testing.assert_allclose(J[swapped][:, a], G[swapped][:, b], atol=1e-6)
    np.testing.assert_allclose(J[swapped][:, b], G[swapped][:, a], atol=1e-6)
    R, Rg = sw[..., ROTATIONS].reshape(B, L, 24, 6), W[..., ROTATIONS].reshape(B, L, 24, 6)
    np.testing.assert_allclose(R[swapped][:, a], Rg[swapped][:, b], atol=1e-6)
    others = [j for j in range(24) if j not in a + b]
    np.testing.assert_allclose(J[:, :, others], G[:, :, others], atol=1e-6)


def test_held_parts_repeat_silently(W):
    cfg = replace(QUIET, jitter_m=0.01, p_held=0.05, held_frames=(4, 8))
    h = corrupt(W, 30.0, np.random.default_rng(2), cfg)
    ref = corrupt(W, 30.0, np.random.default_rng(2), replace(cfg, p_held=0.0))  # a new draw, so compare by repeats
    assert np.isfinite(h[..., JOINTS]).all()  # no missing flag
    J = _J(h)
    repeats = (np.diff(J, axis=1) == 0).all(-1)  # (B, L-1, 24): bit-for-bit repeats
    assert repeats.any()
    assert not (np.diff(_J(ref), axis=1) == 0).all(-1).any()  # jitter alone never repeats
    lw = JOINT_INDEX["left_wrist"]
    frac = repeats.mean(axis=(0, 1))
    assert frac[lw] > frac[JOINT_INDEX["spine1"]]  # limbs are held on their own, more often than the body


def test_clean_share_hands_windows_over_clean(W):
    c = corrupt(W, 30.0, np.random.default_rng(4), replace(CorruptionConfig(), p_clean=0.5, p_no_rotations=0.0))
    exact = (c[..., JOINTS] == W[..., JOINTS]).all(axis=(1, 2))
    assert 0 < exact.sum() < B
    np.testing.assert_array_equal(c[exact][..., ROTATIONS], W[exact][..., ROTATIONS])
    assert (np.abs(c[~exact][..., JOINTS] - W[~exact][..., JOINTS]) > 1e-4).any()


def test_vary_skeleton_scales_bones_and_keeps_rotations_exact(W):
    off = np.broadcast_to(rest_offsets(), (B, 24, 3)).astype(np.float32).copy()
    cfg = replace(CorruptionConfig(), leg_scale=(0.85, 1.15), spine_scale=(0.9, 1.15))
    f, o = vary_skeleton(W, off, np.random.default_rng(0), cfg)
    f2, o2 = vary_skeleton(W, off, np.random.default_rng(0), cfg)
    np.testing.assert_array_equal(f, f2)
    assert f.shape == W.shape and o.shape == off.shape
    bone = lambda X: np.linalg.norm(X[..., 1:, :] - X[..., PARENTS[1:], :], axis=-1)
    ratio = bone(_J(f)) / bone(_J(W))  # (B, L, 23)
    knee, spine2, wrist = JOINT_INDEX["left_knee"] - 1, JOINT_INDEX["spine2"] - 1, JOINT_INDEX["left_wrist"] - 1
    assert ((ratio[..., knee] >= 0.85 - 1e-4) & (ratio[..., knee] <= 1.15 + 1e-4)).all()
    assert ((ratio[..., spine2] >= 0.9 - 1e-4) & (ratio[..., spine2] <= 1.15 + 1e-4)).all()
    np.testing.assert_allclose(ratio[..., wrist], 1.0, atol=1e-4)
    assert ratio[..., knee].std() > 0.01  # windows differ
    # FK of the unchanged rotations on the scaled offsets lands on the new joints
    R = sixd_to_matrix(f[..., ROTATIONS].reshape(B, L, 24, 6).astype(np.float64))
    fk, _ = forward_kinematics(R, _J(f)[..., 0, :], np.broadcast_to(o[:, None].astype(np.float64), (B, L, 24, 3)))
    np.testing.assert_allclose(fk, _J(f), atol=1e-4)
    feet = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("ankle", "foot")]
    np.testing.assert_allclose(_J(f)[:, :, feet, 2].min(axis=(1, 2)), _J(W)[:, :, feet, 2].min(axis=(1, 2)), atol=1e-5)
    np.testing.assert_array_equal(f[..., ROTATIONS.stop:], W[..., ROTATIONS.stop:])  # object and IMU untouched
    same = vary_skeleton(W, off, np.random.default_rng(0), CorruptionConfig())
    assert same[0] is W and same[1] is off  # off: nothing drawn, nothing copied
    with pytest.raises(ValueError, match="offsets"):
        vary_skeleton(W, off[:, :5], np.random.default_rng(0), cfg)


@pytest.mark.parametrize("bad, match", [
    ({"p_swap": 1.5}, "probability"),
    ({"p_held": -0.1}, "finite and >= 0"),
    ({"height_m": (0.05, 0.01)}, "height_m"),
    ({"leg_scale": (0.0, 1.1)}, "leg_scale"),
    ({"spine_scale": (1.2, 0.9)}, "spine_scale"),
    ({"held_frames": (0, 5)}, "held_frames"),
    ({"burst_m": float("nan")}, "burst_m"),
    ({"walk_m_per_sqrt_s": "0.01"}, "walk_m_per_sqrt_s"),
])
def test_bad_wider_values_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        CorruptionConfig(**bad)


def test_the_real_world_training_config_spells_the_preset():
    from trumans.train.tasks.filter import load_filter_config

    cfg = load_filter_config("real")
    assert cfg.corruption == CorruptionConfig.real_world()
    assert load_filter_config("cpu").corruption == CorruptionConfig()  # the shipped model's config is unchanged
