"""Issue 36's guards around the HOI filter: the input's own bones (``bones``), the do-no-harm gate
(``gate``), height from the floor (``floor``), leg swaps (``leg_swap``), held joints
(``outliers.frozen_joint_mask``), the independent tracker model (``tracker_noise``) and the body
benchmark's figures (``benchmark``)."""
import numpy as np
import pytest

from trumans.mocap_corpus import load_corpus
from trumans.refine.benchmark import (foreign_skeleton, limb_errors, motion_types, real_body_clips, tune_smoother,
                                      translation_aligned_errors, BodyClip, clip_errors)
from trumans.refine.bones import BonesConfig, input_bone_lengths, project_bone_lengths
from trumans.refine.floor import FloorConfig, floor_offset, keep_above_floor
from trumans.refine.frame import JOINTS, pack_frames
from trumans.refine.gate import GateConfig, gate_joints, gate_weights, input_noise, noise_level
from trumans.refine.leg_swap import LEFT_LEG, RIGHT_LEG, SwapConfig, leg_swap_states, unswap_leg_frames, unswap_legs
from trumans.refine.outliers import drop_frozen_joints, frozen_joint_mask
from trumans.refine.tracker_noise import TRACKER_KINDS, TrackerConfig, tracker_corrupt
from trumans.skeleton import FOOT_JOINTS, PARENTS

FPS = 30.0


@pytest.fixture(scope="module")
def walk() -> np.ndarray:
    """A real held-out walk (CMU 132_45, 382 frames at 30 fps): (T, 24, 3) float64 m."""
    clip = next(c for c in load_corpus(split="test") if c.name == "132_45")
    return clip.joints.astype(np.float64)


def _lengths(J: np.ndarray) -> np.ndarray:
    return np.linalg.norm(J[:, 1:] - J[:, PARENTS[1:]], axis=-1)


def test_bone_lengths_are_read_through_jitter_and_projected_exactly(walk):
    rng = np.random.default_rng(0)
    true = np.median(_lengths(walk), axis=0)
    noisy = walk + rng.normal(0, 0.01, walk.shape)
    noisy[40:50] = np.nan  # a dropout
    noisy[100, 5] += 0.3  # a spike
    est = input_bone_lengths(noisy, noise_level(noisy))
    long = true > 0.05
    rel = np.abs(est[1:][long] / true[long] - 1)
    assert est[0] == 0.0 and rel.max() < 0.03 and rel.mean() < 0.01
    raw = input_bone_lengths(noisy, None, BonesConfig(smooth_frames=0.0))  # no low-pass, no bias correction
    assert np.abs(raw[1:][long] / true[long] - 1).mean() > np.abs(est[1:][long] / true[long] - 1).mean()
    # the projection lands on the lengths and moves a body already on them by nothing
    L = np.r_[0.0, true * 1.1]
    out = project_bone_lengths(walk + rng.normal(0, 0.005, walk.shape), L)
    np.testing.assert_allclose(_lengths(out), np.broadcast_to(L[1:], (len(walk), 23)), atol=1e-9)
    own = np.r_[0.0, _lengths(walk)[0]]
    np.testing.assert_allclose(project_bone_lengths(walk[:1], own), walk[:1], atol=1e-9)
    keep = np.full(24, np.nan)  # NaN keeps every bone: the identity
    np.testing.assert_allclose(project_bone_lengths(walk, keep), walk, atol=1e-12)
    with pytest.raises(ValueError, match=r"must be \(T, 24, 3\)"):
        input_bone_lengths(walk[:, :20])
    with pytest.raises(ValueError, match=r"lengths must be \(24,\)"):
        project_bone_lengths(walk, true)


def test_the_gate_keeps_clean_input_and_hands_noise_and_failures_to_the_filter(walk):
    rng = np.random.default_rng(1)
    assert np.median(input_noise(walk, FPS)) < 0.0005 and input_noise(walk, FPS).max() < 0.003  # real motion: locally a cubic
    noisy = walk + rng.normal(0, 0.005, walk.shape)
    assert abs(np.median(input_noise(noisy, FPS)) / 0.005 - 1) < 0.15  # the jitter's std, read back
    assert abs(np.median(noise_level(noisy)) / 0.005 - 1) < 0.15
    filtered = walk + 0.03  # any other body
    kept = gate_joints(filtered, walk, FPS)  # clean: untouched but for a few fast frames of the extremities
    assert (kept == walk).all(-1).mean() > 0.97 and np.linalg.norm(kept - walk, axis=-1).mean() < 0.001
    noisier = walk + rng.normal(0, 0.01, walk.shape)
    np.testing.assert_allclose(gate_joints(filtered, noisier, FPS), filtered, atol=1e-12)  # noisy: the filter's
    failed = walk.copy()
    failed[100:103, 7] = np.nan  # a joint missing for 3 frames
    failed[200, 20] += 0.2  # a spike
    w = gate_weights(failed, FPS)
    assert (w[100:103, 7] == 1).all() and w[200, 20] == 1
    reach = GateConfig().fail_pad + GateConfig().feather  # ramped around, zero beyond
    assert w[100 - reach:103 + reach, 7].min() > 0 and w[100 - reach - 1, 7] == 0 and w[103 + reach, 7] == 0
    assert w[150, 7] == 0 and w[250, 20] == 0
    assert np.abs(np.diff(w[:, 7])).max() <= 1 / (GateConfig().feather + 1) + 1e-9  # no jump
    wide = gate_weights(failed, FPS, GateConfig(fail_pad=1, feather=4))
    assert (wide[98:106, 7] > 0).all() and (wide[[96, 97, 98, 104, 105, 106], 7] < 1).all()
    assert np.abs(np.diff(wide[:, 7])).max() <= 1 / 5 + 1e-9
    with pytest.raises(ValueError, match="keep_below_m < filter_above_m"):
        GateConfig(keep_below_m=0.01, filter_above_m=0.005)


def test_height_is_read_from_the_feet_and_no_foot_ends_under_the_floor(walk):
    assert floor_offset(walk) == 0.0  # the corpus stands on z = 0
    up = walk + [0, 0, 0.04]
    assert abs(floor_offset(up) - 0.04) < 0.002
    assert floor_offset(walk + [0, 0, 0.01]) == 0.0  # inside the dead band
    assert floor_offset(walk + [0, 0, 0.8]) == 0.0  # too far: the motion's own (a bed, stairs)
    down = walk - [0, 0, 0.05]
    fixed = keep_above_floor(down, FPS, floor_offset(down))
    np.testing.assert_allclose(fixed, walk, atol=0.002)
    dipped = walk.copy()
    dipped[150:160, FOOT_JOINTS[0], 2] -= 0.1  # a foot through the floor for 10 frames
    lifted = keep_above_floor(dipped, FPS)
    assert (lifted[:, list(FOOT_JOINTS), 2] >= -1e-12).all()
    assert np.abs(np.diff(lifted[:, 0, 2] - dipped[:, 0, 2])).max() < 0.03  # the lift is smooth
    np.testing.assert_allclose(lifted[:100], dipped[:100])  # and local
    with pytest.raises(ValueError, match="dead_band_m <= max_offset_m"):
        FloorConfig(dead_band_m=1.0, max_offset_m=0.5)


def test_leg_swaps_are_read_from_the_sequence_and_undone(walk):
    swapped = walk.copy()
    legs = list(LEFT_LEG) + list(RIGHT_LEG)
    swapped[120:128, legs] = walk[120:128, list(RIGHT_LEG) + list(LEFT_LEG)]
    truth = np.zeros(len(walk), bool)
    truth[120:128] = True
    np.testing.assert_array_equal(leg_swap_states(swapped), truth)
    np.testing.assert_allclose(unswap_legs(swapped), walk)
    frames = pack_frames(swapped, None, np.broadcast_to(np.eye(4), (len(walk), 4, 4)))
    back = unswap_leg_frames(frames)
    np.testing.assert_allclose(back[:, JOINTS].reshape(-1, 24, 3), walk, atol=1e-6)
    np.testing.assert_array_equal(back[:, 72:], frames[:, 72:])  # rotations (missing here), object, IMU
    assert not leg_swap_states(walk).any()
    rng = np.random.default_rng(2)
    noisy = swapped + rng.normal(0, 0.01, walk.shape)
    noisy[60:70] = np.nan  # a dropout cuts the chain
    assert (leg_swap_states(noisy) == truth).mean() > 0.99
    # a swap that would have to save more than the switch cost stays
    assert not leg_swap_states(swapped, SwapConfig(switch_m=10.0)).any()


def test_a_swap_right_after_a_gap_is_read_from_the_hips_against_the_shoulders(walk):
    """A gap cuts the chain, and a piece that starts inside a swap gives the frame-to-frame travel
    nothing to tell the two labellings apart: without the side cue (``side_weight`` 0) the reading
    is wrong there; with it (the left hip on the left of the right hip along the shoulders' axis)
    the swap is found exactly."""
    swapped = walk.copy()
    legs = list(LEFT_LEG) + list(RIGHT_LEG)
    swapped[110:150, legs] = walk[110:150, list(RIGHT_LEG) + list(LEFT_LEG)]
    swapped[100:110] = np.nan  # the tracker lost the body, came back with the legs swapped for 40 frames,
    swapped[150:160] = np.nan  # and lost it again
    truth = np.zeros(len(walk), bool)
    truth[110:150] = True
    np.testing.assert_array_equal(leg_swap_states(swapped), truth)
    assert (leg_swap_states(swapped, SwapConfig(side_weight=0.0)) != truth).sum() == 40  # fewer swapped frames won
    assert not leg_swap_states(walk).any() and not leg_swap_states(walk[:, :, [1, 0, 2]] * [1, -1, 1]).any()
    with pytest.raises(ValueError, match="side_weight"):
        SwapConfig(side_weight=-1.0)


def test_held_joints_are_missing_single_repeats_are_not(walk):
    f = pack_frames(walk, None, np.broadcast_to(np.eye(4), (len(walk), 4, 4)))
    J = f[:, JOINTS].reshape(len(f), 24, 3)
    J[50:56, 20] = J[49, 20]  # the left wrist held for 6 frames after frame 49
    J[80, 7] = J[79, 7]  # one exact repeat: left alone
    f[:, JOINTS] = J.reshape(len(f), -1)
    m = frozen_joint_mask(f)
    assert m[50:56, 20].all() and not m[49, 20] and m.sum() == 6
    out = drop_frozen_joints(f)[:, JOINTS].reshape(len(f), 24, 3)
    assert np.isnan(out[50:56, 20]).all() and np.isfinite(out[49, 20]).all() and np.isfinite(out[80, 7]).all()


def test_the_tracker_model_does_each_kind_it_names(walk):
    X = walk[None]
    rng = lambda: np.random.default_rng(3)
    for kind in TRACKER_KINDS:
        a = tracker_corrupt(X, FPS, rng(), TrackerConfig().only(kind))
        np.testing.assert_array_equal(a, tracker_corrupt(X, FPS, rng(), TrackerConfig().only(kind)))  # seeded
    h = tracker_corrupt(X, FPS, rng(), TrackerConfig().only("height"))[0] - walk
    assert 0.02 <= abs(h[0, 0, 2]) <= 0.06 and np.allclose(h[..., 2], h[0, 0, 2], atol=1e-6) and np.allclose(h[..., :2], 0, atol=1e-6)
    d = tracker_corrupt(X, FPS, rng(), TrackerConfig(p_dropout=0.05).only("dropout"))[0]
    gone = np.isnan(d).all((-1, -2))
    assert gone.any() and np.isfinite(d[~gone]).all()
    fz = tracker_corrupt(X, FPS, rng(), TrackerConfig(p_freeze=0.05).only("freeze"))[0].astype(np.float64)
    same = (np.diff(fz, axis=0) == 0).all(-1)
    assert same.any() and np.isfinite(fz).all()  # held outputs, no missing flag
    sw = tracker_corrupt(X, FPS, rng(), TrackerConfig(p_swap=0.02).only("swap"))[0]
    ex = np.abs(sw[:, list(LEFT_LEG)] - walk[:, list(RIGHT_LEG)]).max((-1, -2)) < 1e-5
    assert ex.any() and np.allclose(sw[~ex], walk[~ex], atol=1e-5)
    with pytest.raises(ValueError, match="subset of"):
        TrackerConfig(kinds=("fog",))
    with pytest.raises(ValueError, match=r"must be \(B, T, 24, 3\)"):
        tracker_corrupt(walk, FPS, rng())


def test_benchmark_figures_on_analytic_cases(walk):
    rng = np.random.default_rng(4)
    moved = walk + [0.3, -0.2, 0.1]  # a constant offset: nothing for the translation-aligned error
    np.testing.assert_allclose(translation_aligned_errors(moved, walk), 0, atol=1e-12)
    bent = walk.copy()
    bent[:, 20] += [0.0, 0.03, 0.04]  # the left wrist 5 cm off
    e = limb_errors(bent, walk)
    assert np.isclose(e.max(), 0.05) and np.isclose(e.sum(), 0.05 * len(walk))  # the wrist from its shoulder only
    sway = walk + np.cumsum(rng.normal(0, 0.01, (len(walk), 1, 3)), axis=0)  # a whole-body drift
    np.testing.assert_allclose(limb_errors(sway, walk), 0, atol=1e-12)
    fig = clip_errors(walk - [0, 0, 0.1], walk, FPS)
    assert fig["under"].mean() > 0.5 and np.isclose(fig["tmpjpe"], 0).all() and np.isclose(fig["mpjpe"], 0.1).all()
    assert fig["bone_dev"][0] < 1e-9 and np.nanmax(fig["skate"]) < 0.05  # the truth's planted feet: under 5 cm/s
    # a noisier input is smoothed more
    clips = [BodyClip("w", walk, FPS, motion_types(walk, FPS))]
    pairs = lambda s: [(walk + rng.normal(0, s, walk.shape), walk)]
    assert tune_smoother("gauss", pairs(0.002)) < tune_smoother("gauss", pairs(0.03))
    # the foreign skeleton has 0.85x legs and a 1.15x spine, the rest as it was
    (f,) = foreign_skeleton(clips)
    r = np.median(_lengths(f.joints), 0) / np.median(_lengths(walk), 0)
    idx = {n: i - 1 for i, n in enumerate(("pelvis", "left_hip", "right_hip", "spine1", "left_knee"))}
    assert np.isclose(r[idx["left_knee"]], 0.85, atol=0.01) and np.isclose(r[idx["spine1"]], 1.15, atol=0.01)
    assert np.isclose(r[idx["left_hip"]], 1.0, atol=0.01)
    assert abs(np.percentile(f.joints[:, list(FOOT_JOINTS), 2].min(1), 5)) < 0.05  # still on the floor


def test_real_clips_have_motion_types():
    clips = real_body_clips("test", max_clips=4, seed=0)
    assert len(clips) == 4 and all(c.types.shape == (len(c.joints), 5) for c in clips)
    assert sum(c.types.any(0).sum() for c in clips) > 0
