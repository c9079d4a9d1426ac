"""The filter's rewritten inner loops (issue 36 point 7, speed) against plain reference versions
written out here: the same values (bit for bit where the arithmetic is the same, to float rounding
where the order of a sum changed)."""
import numpy as np
import pytest
import torch
from scipy.ndimage import median_filter

from trumans.refine.filter import FilterModel, configure_skip, filter_denoiser_config, FilterNetConfig, sample_x0, smooth_time
from trumans.refine.frame import FRAME_DIM, JOINTS, fill_missing, from_frame, orthonormalize_6d, to_frame
from trumans.refine.gate import GateConfig, input_noise
from trumans.refine.leg_swap import LEFT_LEG, RIGHT_LEG, SwapConfig, leg_swap_states
from trumans.refine.outliers import frozen_joint_mask
from trumans.refine.tracked import TrackedBody
from trumans.refine.wiener import fit_joint_wiener, neighbourhoods
from trumans.refine.windows import blend_windows, window_starts, window_weights
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import DiffusionConfig, GaussianDiffusion
from trumans.model.episodes import Normalizer
from trumans.model.nets.denoiser import Denoiser
from trumans.rotations import matrix_to_6d, sixd_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS


def _fill_reference(frames):
    """Every column of (..., L, D) interpolated in time, complete or not (the form before issue 36's speed-up)."""
    f = np.asarray(frames, dtype=np.float64)
    L = f.shape[-2]
    ok = np.isfinite(f)
    t = np.arange(L).reshape(L, 1)
    prev = np.maximum.accumulate(np.where(ok, t, -1), axis=-2)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(ok, t, L), -2), axis=-2), -2)
    has_p, has_n = prev >= 0, nxt < L
    vp = np.take_along_axis(f, np.clip(prev, 0, L - 1), -2)
    vn = np.take_along_axis(f, np.clip(nxt, 0, L - 1), -2)
    w = np.where(has_p & has_n, (t - prev) / np.maximum(nxt - prev, 1), 0.0)
    out = np.where(has_p & has_n, (1 - w) * vp + w * vn, np.where(has_p, vp, np.where(has_n, vn, 0.0)))
    return np.where(ok, f, out).astype(np.float32)


@pytest.mark.parametrize("shape", [(50, 7), (3, 40, 9), (2, 2, 11, 5), (1, 4)])
def test_fill_missing_fills_only_the_columns_with_gaps_and_gives_the_same_values(shape):
    rng = np.random.default_rng(len(shape))
    f = rng.normal(size=shape)
    f[rng.random(shape) < 0.2] = np.nan
    f[..., 0] = np.nan  # never observed: 0
    f[..., 1] = 2.5  # complete: as it is
    f[..., : shape[-2] // 2, 2] = np.nan  # a leading gap: the first observed value held
    f[..., -2:, 3 % shape[-1]] = np.nan  # a trailing gap
    out = fill_missing(f)
    assert out.dtype == np.float32 and out.shape == f.shape and np.isfinite(out).all()
    np.testing.assert_array_equal(out, _fill_reference(f))
    assert (out[..., 0] == 0).all() and (out[..., 1] == 2.5).all()


def test_orthonormalize_6d_treats_every_block_as_before():
    rng = np.random.default_rng(0)
    f = rng.normal(size=(2, 30, FRAME_DIM)).astype(np.float32)
    f[0, :, -1] = 1.0  # IMU present
    f[1, :, -1] = 0.0  # no IMU: its rotation stays 0
    ref = f.astype(np.float64).copy()
    for sl in [slice(72 + 6 * j, 78 + 6 * j) for j in range(NUM_JOINTS)] + [slice(219, 225), slice(225, 231)]:
        ref[..., sl] = matrix_to_6d(sixd_to_matrix(ref[..., sl]))
    ref[..., 225:231] *= ref[..., -1:] > 0.5
    np.testing.assert_array_equal(orthonormalize_6d(f), ref.astype(np.float32))
    assert (orthonormalize_6d(f)[1, :, 225:231] == 0).all()


def test_canonical_frame_moves_every_vector_as_the_einsum_form():
    rng = np.random.default_rng(1)
    f = rng.normal(size=(5, 16, FRAME_DIM)).astype(np.float32)
    f[rng.random(f.shape) < 0.05] = np.nan
    origin, yaw = rng.normal(size=(5, 3)), rng.uniform(-3, 3, 5)
    R = yaw_matrix(yaw).swapaxes(-1, -2)
    shift = -(R @ origin[..., None])[..., 0]
    ref = f.astype(np.float64)
    Rl = R[:, None]
    J = ref[..., JOINTS].reshape(5, 16, NUM_JOINTS, 3)
    ref[..., JOINTS] = (np.einsum("...ij,...kj->...ki", Rl, J) + shift[:, None, None]).reshape(5, 16, -1)
    ref[..., 216:219] = np.einsum("...ij,...j->...i", Rl, ref[..., 216:219]) + shift[:, None]
    for s in (72, 75, 219, 222, 225, 228, 231):  # the root's, object's and IMU's 6D columns, the acceleration
        ref[..., s:s + 3] = np.einsum("...ij,...j->...i", Rl, ref[..., s:s + 3])
    out = to_frame(f, origin, yaw)
    np.testing.assert_allclose(out, ref.astype(np.float32), atol=1e-6)  # NaN where a 3-vector had one, like the reference
    back = from_frame(out, origin, yaw)
    seen = np.isfinite(back)
    np.testing.assert_allclose(back[seen], f[seen], atol=1e-5)  # and back


def test_blend_windows_sums_each_frame_in_window_order():
    rng = np.random.default_rng(2)
    for T in (64, 65, 200, 30):
        starts = window_starts(T, 64, 16)
        pieces = rng.normal(size=(len(starts), 64, 4))
        w = window_weights(starts, 64)
        idx = starts[:, None] + np.arange(64)[None]
        keep = idx < T
        acc, tot = np.zeros((T, 4)), np.zeros(T)
        np.add.at(acc, idx[keep], (pieces * w[..., None])[keep])
        np.add.at(tot, idx[keep], w[keep])
        np.testing.assert_array_equal(blend_windows(pieces, starts, T), acc / tot[:, None])


def test_frozen_joint_mask_marks_every_frame_of_a_long_enough_run():
    rng = np.random.default_rng(3)
    for _ in range(50):
        T = int(rng.integers(1, 30))
        f = rng.integers(0, 2, size=(T, FRAME_DIM)).astype(np.float32)  # 0 / 1 values: many exact repeats
        f[rng.random(f.shape) < 0.05] = np.nan
        J = f[:, JOINTS].reshape(T, -1, 3)
        same = np.r_[np.zeros((1, NUM_JOINTS), bool), np.isfinite(J[1:]).all(-1) & (J[1:] == J[:-1]).all(-1)]
        for m in (1, 2, 3):
            want = np.zeros_like(same)
            for j in range(NUM_JOINTS):  # runs of `same`, walked one by one
                t = 0
                while t < T:
                    if same[t, j]:
                        e = t
                        while e < T and same[e, j]:
                            e += 1
                        want[t:e, j] = e - t >= m
                        t = e
                    else:
                        t += 1
            np.testing.assert_array_equal(frozen_joint_mask(f, m), want)


def _viterbi_reference(J, cfg):
    """The two-state reading of leg_swap_states with numpy 2 x 2 arrays per frame."""
    legs = list(LEFT_LEG + RIGHT_LEG)
    mirror = list(RIGHT_LEG + LEFT_LEG)
    X, Xs = J[:, legs], J[:, mirror]
    ok = np.isfinite(X).all(-1) & np.isfinite(Xs).all(-1)
    T = len(J)
    both = ok[1:] & ok[:-1]
    A = (np.nan_to_num(X), np.nan_to_num(Xs))
    step = np.empty((T - 1, 2, 2))
    for a in range(2):
        for b in range(2):
            step[:, a, b] = (((A[b][1:] - A[a][:-1]) ** 2).sum(-1) * both).sum(-1)
    linked = both.any(-1)
    sw, pr = cfg.switch_m ** 2, cfg.prior_m ** 2
    # the side cue: the left hip of each reading against the shoulders' left-right axis
    ls, rs = JOINT_INDEX["left_shoulder"], JOINT_INDEX["right_shoulder"]
    unary = np.zeros((T, 2))
    for t in range(T):
        axis = J[t, ls] - J[t, rs]
        proj = float(np.dot(J[t, LEFT_LEG[0]] - J[t, RIGHT_LEG[0]], axis / max(np.linalg.norm(axis), 1e-9)))
        proj = 0.0 if not np.isfinite(proj) else proj
        unary[t] = [cfg.side_weight * min(proj, 0.0) ** 2, pr + cfg.side_weight * max(proj, 0.0) ** 2]
    cost = unary[0].copy()
    back = np.zeros((T, 2), np.int8)
    for t in range(1, T):
        trans = np.array([[0.0, sw], [sw, 0.0]]) if linked[t - 1] else np.zeros((2, 2))
        tot = cost[:, None] + step[t - 1] + trans
        back[t] = tot.argmin(0)
        cost = tot.min(0) + unary[t]
    path = np.empty(T, np.int8)
    path[-1] = int(cost.argmin())
    for t in range(T - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path.astype(bool) & ok.any(-1)


def test_leg_swap_viterbi_on_python_floats_reads_the_same_states():
    rng = np.random.default_rng(4)
    t = np.arange(120)[:, None, None] / 30.0
    walk = rng.normal(0, 0.3, (1, NUM_JOINTS, 3)) + 0.05 * np.sin(2 * np.pi * t + rng.uniform(0, 6, (1, NUM_JOINTS, 3)))
    walk[:, list(LEFT_LEG)] += [0.0, 0.15, 0.0]  # the legs apart
    ls, rs = JOINT_INDEX["left_shoulder"], JOINT_INDEX["right_shoulder"]
    walk[:, ls] = walk[:, rs] + [0.0, 0.3, 0.0]  # shoulders and hips side by side, left on the left
    walk[:, LEFT_LEG[0]] = walk[:, RIGHT_LEG[0]] + [0.0, 0.2, 0.0]
    swapped = walk.copy()
    legs, mirror = list(LEFT_LEG + RIGHT_LEG), list(RIGHT_LEG + LEFT_LEG)
    swapped[40:52, legs] = walk[40:52, mirror]
    swapped[70:75] = np.nan  # a gap cuts the chain
    for J in (walk, swapped, swapped + rng.normal(0, 0.01, swapped.shape)):
        for cfg in (SwapConfig(), SwapConfig(switch_m=0.0, prior_m=0.0), SwapConfig(side_weight=0.0), SwapConfig(side_weight=5.0)):
            got = leg_swap_states(J, cfg)
            np.testing.assert_array_equal(got, _viterbi_reference(J, cfg))
    assert leg_swap_states(swapped)[40:52].all() and leg_swap_states(swapped).sum() == 12
    assert not leg_swap_states(swapped[:1]).any() and leg_swap_states(swapped[:2]).shape == (2,)


def test_gate_running_median_joint_by_joint_is_the_2d_median():
    rng = np.random.default_rng(5)
    for T in (3, 31, 200):
        J = rng.normal(0, 0.004, (T, NUM_JOINTS, 3)) + np.linspace(0, 1, T)[:, None, None]
        J[rng.random((T, NUM_JOINTS)) < 0.1] = np.nan
        cfg = GateConfig()
        got = input_noise(J, 30.0, cfg)
        # the same running median as one 2-D median filter over (frames, joints) with a (win, 1) footprint
        body = TrackedBody.read(J)
        r, seen = body.residual, body.seen
        med = np.nanmedian(np.where(seen, r, np.nan), axis=0)
        rm = np.where(seen, r, np.nan_to_num(med)[None])
        win = max(3, int(round(cfg.noise_window_s * 30.0)) | 1)
        want = median_filter(rm, size=(win, 1), mode="mirror") / (1.5382 * np.sqrt(1 - 7 / 21))
        np.testing.assert_array_equal(got, want)


def test_wiener_summed_offset_by_offset_is_the_neighbourhood_product():
    rng = np.random.default_rng(6)
    X = rng.normal(0, 0.3, (30, 20, 72)) + rng.normal(0, 1, (30, 1, 72))
    w = fit_joint_wiener(X + rng.normal(0, 0.01, X.shape), X, radius=3)
    J = torch.from_numpy(X[:4].astype(np.float32))
    u, P = neighbourhoods(J, 3)
    torch.testing.assert_close(w(J), P + w.bias + u @ w.weight, atol=2e-5, rtol=1e-5)
    with pytest.raises(ValueError, match="joints must be"):
        w(J[0])


def test_smooth_time_is_the_replicate_padded_convolution():
    x = torch.randn(3, 40, 5, generator=torch.Generator().manual_seed(7), dtype=torch.float64)
    for sigma in (0.7, 2.0, 9.0):  # 9: the kernel is wider than the window
        r = int(np.ceil(3 * sigma))
        k = torch.exp(-0.5 * (torch.arange(-r, r + 1, dtype=x.dtype) / sigma) ** 2)
        k = k / k.sum()
        idx = (torch.arange(40)[:, None] + torch.arange(-r, r + 1)[None]).clamp(0, 39)  # replicated edges
        want = (x[:, idx] * k[None, None, :, None]).sum(2)
        torch.testing.assert_close(smooth_time(x, sigma), want, atol=1e-12, rtol=1e-12)


def test_sampling_computes_the_skip_once_with_the_same_result():
    """sample_x0 hands the model its skip once for all steps: the same x̂0 as a model that recomputes it."""
    net = FilterNetConfig(d_model=16, layers=1, heads=2, ff=16, window=12, overlap=2, wiener_radius=1)
    mc = filter_denoiser_config(net, 1)
    torch.manual_seed(0)
    den = Denoiser(mc)
    rng = np.random.default_rng(8)
    walks = rng.normal(0, 0.3, (8, 12, 72))
    w = fit_joint_wiener(walks + rng.normal(0, 0.01, walks.shape), walks, radius=1)
    norm = Normalizer(rng.normal(0, 0.1, FRAME_DIM), rng.uniform(0.5, 2, FRAME_DIM))
    ck = Checkpoint(kind="filter", model_config=mc, model_state=den.state_dict(), diffusion_config=DiffusionConfig(),
                    normalizer=norm, extra={"categories": ["box"], "skip_sigma": 2.0, "wiener": w.to_extra()})
    model = configure_skip(FilterModel(den), ck).eval()
    cond = torch.from_numpy(rng.normal(0, 1, (3, 12, 261)).astype(np.float32))
    cat = torch.zeros(3, dtype=torch.long)
    x = torch.randn(3, 12, FRAME_DIM, generator=torch.Generator().manual_seed(1))
    t = torch.full((3,), 500)
    with torch.inference_mode():
        torch.testing.assert_close(model(x, t, frame_cond=cond, category=cat, skip=model.skip(cond)),
                                   model(x, t, frame_cond=cond, category=cat), atol=0, rtol=0)

    class Recomputing(torch.nn.Module):  # the model as a plain module: no skip handed in
        def __init__(self, m):
            super().__init__()
            self.m = m

        def forward(self, x, t, *, frame_cond, category):
            return self.m(x, t, frame_cond=frame_cond, category=category)

    diff = GaussianDiffusion(DiffusionConfig())
    noise = torch.randn(3, 12, FRAME_DIM, generator=torch.Generator().manual_seed(2))
    a = sample_x0(model, diff, cond, cat, num_steps=3, noise=noise)
    b = sample_x0(Recomputing(model), diff, cond, cat, num_steps=3, noise=noise)
    torch.testing.assert_close(a, b, atol=0, rtol=0)


def test_the_post_steps_read_the_tracked_body_once_with_the_pipelines_fill():
    """The fill the pipeline made for the network's condition is the fill the guards would make, and a
    clip hands its tracked body on from step to step."""
    from dataclasses import replace

    from trumans.refine.frame import fill_missing_joints
    from trumans.refine.post_steps import RefinedClip

    rng = np.random.default_rng(9)
    T = 50
    tracked = rng.normal(size=(T, FRAME_DIM)).astype(np.float32)
    tracked[rng.random((T, FRAME_DIM)) < 0.1] = np.nan
    tracked[:3] = np.nan  # a leading dropout
    padded = np.concatenate([tracked, np.full((14, FRAME_DIM), np.nan, np.float32)])  # a short clip's padding
    handed = fill_missing(padded)[:T, JOINTS].reshape(T, -1, 3)
    J = tracked[:, JOINTS].reshape(T, -1, 3)
    np.testing.assert_array_equal(handed, fill_missing_joints(J))
    clip = RefinedClip(np.zeros((T, FRAME_DIM), np.float32), tracked, 30.0, "box")
    np.testing.assert_array_equal(clip.tracked_body.filled, fill_missing_joints(J))
    assert replace(clip, frames=clip.frames + 1).tracked_body is clip.tracked_body
    with pytest.raises(ValueError, match="tracked_body has"):
        RefinedClip(clip.frames[:10], tracked[:10], 30.0, "box", tracked_body=clip.tracked_body)
    with pytest.raises(ValueError, match="filled joints must be"):
        TrackedBody.read(J, filled=handed[:5])
