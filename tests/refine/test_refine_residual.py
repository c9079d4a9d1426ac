"""trumans.refine.residual: the filter's high frequencies, the tracked input's low ones."""
import numpy as np
import pytest

from trumans.refine.residual import ResidualConfig, keep_low_frequencies
from trumans.skeleton import FOOT_JOINTS, JOINT_INDEX

FPS = 30.0


def _smooth_motion(T: int = 240, seed: int = 0) -> np.ndarray:
    """(T, 24, 3) m: every joint on its own slow sinusoids (0.3-1.2 Hz, a few cm) around a body."""
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None] / FPS
    base = rng.normal(0.0, 0.3, (1, 24, 3)) + np.array([0.0, 0.0, 1.0])
    f, ph, a = rng.uniform(0.3, 1.2, (1, 24, 3)), rng.uniform(0, 2 * np.pi, (1, 24, 3)), rng.uniform(0.01, 0.05, (1, 24, 3))
    return base + a * np.sin(2 * np.pi * f * t + ph)


def _err_mm(X, G):
    return 1000 * np.linalg.norm(X - G, axis=-1).mean()


def test_white_jitter_and_a_slow_filter_error_both_go():
    """tracked = truth + white jitter (12 mm); filtered = truth + a slow error (a 3-cm offset and a
    0.2-Hz sway): the output keeps neither - closer to the truth than either input by a wide margin."""
    G = _smooth_motion()
    rng = np.random.default_rng(1)
    tracked = G + rng.normal(0.0, 0.012, G.shape)
    t = np.arange(len(G))[:, None, None] / FPS
    filtered = G + 0.03 + 0.02 * np.sin(2 * np.pi * 0.2 * t)
    out = keep_low_frequencies(filtered, tracked, FPS, ResidualConfig(hold_feet=False))
    e_in, e_filt, e_out = _err_mm(tracked, G), _err_mm(filtered, G), _err_mm(out, G)
    assert e_out < 0.45 * e_in and e_out < 0.25 * e_filt, (e_in, e_filt, e_out)


def test_a_gap_is_filled_with_the_filters_shape_meeting_the_tracked_frames():
    """filtered = truth + a constant: the residual is that constant everywhere (a gap's fill
    included), so the output is the truth exactly, in the gap too."""
    G = _smooth_motion(120)
    tracked = G.copy()
    tracked[40:70] = np.nan  # a 1-s gap of the whole body
    tracked[:, JOINT_INDEX["left_wrist"]] = np.nan  # a joint never tracked keeps the filter's
    filtered = G + np.array([0.05, -0.02, 0.01])
    out = keep_low_frequencies(filtered, tracked, FPS, ResidualConfig(hold_feet=False))
    keep = np.ones(24, bool)
    keep[JOINT_INDEX["left_wrist"]] = False
    np.testing.assert_allclose(out[:, keep], G[:, keep], atol=1e-9)
    np.testing.assert_allclose(out[:, ~keep], filtered[:, ~keep])


def test_a_planted_foot_does_not_take_the_inputs_low_passed_jitter_along():
    """The filter's feet stand still, the tracked ones jitter by 18 mm: without the hold the
    output's feet slide by centimetres a second over the stance; with it they do not move (one
    residual per stance), placed at the tracked feet's mean."""
    T = 150
    G = _smooth_motion(T)
    G[:, FOOT_JOINTS] = G[:1, FOOT_JOINTS]  # standing still the whole clip
    rng = np.random.default_rng(2)
    tracked = G + rng.normal(0.0, 0.018, G.shape)
    filtered = G + 0.02
    speed = lambda J: 100 * np.linalg.norm(np.diff(J[:, FOOT_JOINTS], axis=0), axis=-1).mean() * FPS  # cm/s
    loose = keep_low_frequencies(filtered, tracked, FPS, ResidualConfig(hold_feet=False))
    held = keep_low_frequencies(filtered, tracked, FPS)
    assert speed(loose) > 3.0 and speed(held) < 0.01, (speed(loose), speed(held))
    np.testing.assert_allclose(held[:, FOOT_JOINTS].mean(0), tracked[:, FOOT_JOINTS].mean(0), atol=0.004)
    other = [j for j in range(24) if j not in FOOT_JOINTS]
    np.testing.assert_array_equal(held[:, other], loose[:, other])


def test_bad_inputs_are_refused():
    G = _smooth_motion(30)
    with pytest.raises(ValueError, match=r"both be \(T, 24, 3\)"):
        keep_low_frequencies(G, G[:-1], FPS)
    with pytest.raises(ValueError, match="filtered joints must be finite"):
        keep_low_frequencies(np.where(np.arange(30)[:, None, None] == 3, np.nan, G), G, FPS)
    with pytest.raises(ValueError, match="fps must be a positive number"):
        keep_low_frequencies(G, G, 0.0)
    for bad, msg in [(dict(sigma_frames=0.0), "sigma_frames must be > 0"), (dict(fade_s=-1.0), "fade_s must be >= 0")]:
        with pytest.raises(ValueError, match=msg):
            ResidualConfig(**bad)


def test_the_training_loss_sees_the_filter_as_the_residual_step_returns_it():
    """``loss_residual`` (training with the residual step in the loop): a slow error of the estimate
    (a constant offset) costs nothing and gets no gradient - the step takes the low frequencies from
    the input -, a fast one (white noise) costs about what it is; and the loss is the post-step's
    output error (same Gaussian, no gaps, feet not held)."""
    import torch

    from trumans.refine.frame import FRAME_DIM, JOINTS
    from trumans.refine.losses import loss_residual

    G = _smooth_motion(64)
    rng = np.random.default_rng(2)
    tracked = G + rng.normal(0.0, 0.01, G.shape)

    def frames(J):
        f = torch.zeros(1, len(J), FRAME_DIM, dtype=torch.float64)
        f[0, :, JOINTS] = torch.as_tensor(J.reshape(len(J), -1))
        return f

    x, filled = frames(G), frames(tracked)
    offset = frames(G + 0.05).requires_grad_(True)
    slow = loss_residual(offset, x, filled, 3.0)
    slow.backward()
    exact = loss_residual(frames(G), x, filled, 3.0)
    assert abs(slow.item() - exact.item()) < 1e-9  # the offset is the input's business:
    assert offset.grad[0, :, JOINTS].sum(0).abs().max() < 1e-9  # no gradient along it
    noise = rng.normal(0.0, 0.01, G.shape)
    fast = loss_residual(frames(G + noise), x, x, 3.0).item()  # a clean input: the fast error is all there is
    assert 0.8 * np.abs(noise).sum((1, 2)).mean() < fast < np.abs(noise).sum((1, 2)).mean()
    filt = G + 0.02 * np.sin(np.arange(64) / 5.0)[:, None, None] + noise  # vs the post-step itself
    from scipy.ndimage import gaussian_filter1d
    step = filt + gaussian_filter1d(tracked - filt, 3.0, axis=0, mode="nearest", truncate=3.0)
    assert abs(loss_residual(frames(filt), x, filled, 3.0).item() - np.abs(step - G).sum((1, 2)).mean()) < 1e-9


def test_a_short_gap_in_clean_frames_is_splined_and_a_noisy_or_long_one_is_not():
    """A 12-frame gap of the whole body in clean tracked motion: the cubic spline through the tracked
    frames fills it (the output there much nearer the truth than the linear fill's, whatever the
    filter drew); the frames outside the gap are the same either way. The same gap in 12-mm jitter,
    and a 1-s gap, keep the linear fill exactly."""
    from trumans.refine.frame import fill_missing_joints
    from trumans.refine.residual import spline_gap_weights
    from trumans.refine.tracked import TrackedBody

    G = _smooth_motion(150)
    rng = np.random.default_rng(3)
    gap = slice(60, 72)
    tracked = G.copy()
    tracked[gap] = np.nan
    filtered = fill_missing_joints(tracked)  # a filter that draws a straight line through the gap
    spline = keep_low_frequencies(filtered, tracked, FPS, ResidualConfig(hold_feet=False))
    linear = keep_low_frequencies(filtered, tracked, FPS, ResidualConfig(hold_feet=False, spline_gaps=False))
    e_spline, e_linear = _err_mm(spline[gap], G[gap]), _err_mm(linear[gap], G[gap])
    assert e_spline < 0.25 * e_linear and e_spline < 5.0, (e_spline, e_linear)
    outside = np.ones(150, bool)
    outside[gap] = False
    np.testing.assert_allclose(spline[outside], linear[outside])
    w = spline_gap_weights(TrackedBody.read(tracked), FPS)
    assert (w[gap] == 1).all() and (w[:60] == 0).all() and (w[72:] == 0).all()
    np.testing.assert_allclose(keep_low_frequencies(filtered, TrackedBody.read(tracked), FPS, ResidualConfig(hold_feet=False)),
                               spline)  # the post-steps hand over the body they read once
    noisy = G + rng.normal(0.0, 0.012, G.shape)
    noisy[gap] = np.nan
    assert not spline_gap_weights(TrackedBody.read(noisy), FPS).any()
    np.testing.assert_allclose(keep_low_frequencies(filtered, noisy, FPS, ResidualConfig(hold_feet=False)),
                               keep_low_frequencies(filtered, noisy, FPS, ResidualConfig(hold_feet=False, spline_gaps=False)))
    long = G.copy()
    long[40:80] = np.nan  # 1.3 s: longer than spline_max_s
    assert not spline_gap_weights(TrackedBody.read(long), FPS).any()
    with pytest.raises(ValueError, match="spline_below_m < linear_above_m"):
        ResidualConfig(spline_below_m=0.01, linear_above_m=0.005)
