"""trumans.refine.residual_basis: the filter's slow error in a few joint-space patterns, in the heading frame."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from trumans.model.checkpoint import load_checkpoint, save_checkpoint
from trumans.paths import MODELS_DIR
from trumans.refine.pipeline import HOIFilter
from trumans.refine.residual import ResidualConfig, keep_low_frequencies
from trumans.refine.residual_basis import (BASIS_KEY, ResidualBasis, fit_residual_basis, heading_yaw,
                                           to_heading_frame)
from trumans.skeleton import JOINT_INDEX

FPS = 30.0
_HIPS = [3 * JOINT_INDEX[h] + a for h in ("left_hip", "right_hip") for a in range(3)]


def _patterns() -> np.ndarray:
    """(3, 72) orthonormal patterns in the heading frame that leave the hips (the heading) alone."""
    P = np.random.default_rng(0).normal(size=(72, 3))
    P[_HIPS] = 0.0
    return np.linalg.qr(P)[0].T


PATTERNS = _patterns()


def _turning_body(T: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(joints (T, 24, 3) m, yaw (T,) rad): a body whose hips span x in its own frame, turning a full
    circle while its joints sway a few cm."""
    rng = np.random.default_rng(seed)
    local = rng.normal(0.0, 0.25, (24, 3)) + np.array([0.0, 0.0, 1.0])
    local[JOINT_INDEX["left_hip"]] = [0.1, 0.0, 0.9]
    local[JOINT_INDEX["right_hip"]] = [-0.1, 0.0, 0.9]
    t = np.arange(T)[:, None, None] / FPS
    sway = 0.03 * np.sin(2 * np.pi * rng.uniform(0.3, 1.0, (1, 24, 3)) * t + rng.uniform(0, 6, (1, 24, 3)))
    sway[:, [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]] = 0.0
    yaw = np.linspace(0.0, 2 * np.pi, T)
    return to_heading_frame(local[None] + sway, yaw, inverse=True) + np.array([0.5, -0.2, 0.0]), yaw


def _slow_error(yaw: np.ndarray, seed: int = 1) -> np.ndarray:
    """(T, 24, 3) world: the three patterns with slow coefficients (15 cm over the unit patterns: a few cm
    per joint), turned with the body."""
    rng = np.random.default_rng(seed)
    t = np.arange(len(yaw))[:, None] / FPS
    coef = 0.15 * np.sin(2 * np.pi * rng.uniform(0.1, 0.4, (1, 3)) * t + rng.uniform(0, 6, (1, 3)))
    return to_heading_frame((coef @ PATTERNS).reshape(-1, 24, 3), yaw, inverse=True)


def test_the_heading_is_the_hips_axis_and_the_frame_turns_back_exactly():
    J, yaw = _turning_body()
    np.testing.assert_allclose(np.unwrap(heading_yaw(J)), yaw, atol=1e-9)
    v = np.random.default_rng(3).normal(size=J.shape)
    np.testing.assert_allclose(to_heading_frame(to_heading_frame(v, yaw), yaw, inverse=True), v, atol=1e-12)
    np.testing.assert_allclose(to_heading_frame(v, yaw)[..., 2], v[..., 2])  # heights untouched


def test_a_basis_fitted_on_a_turning_bodys_errors_spans_their_patterns():
    """The errors take three patterns of the body's own frame while it turns a full circle: a rank-3
    fit in the heading frame finds exactly their span; the same errors read in the world would need
    more directions (they turn), so the fit is heading-frame or it fails."""
    G, yaw = _turning_body()
    F = G - _slow_error(yaw)
    basis = fit_residual_basis([F], [G], rank=3, sigma_frames=2.0)
    assert basis.rank == 3 and basis.sigma_frames == 2.0
    np.testing.assert_allclose(basis.vectors @ basis.vectors.T, np.eye(3), atol=1e-9)
    # principal angles between the spans: the singular values of V P^T are all 1 (to the few tenths of a
    # degree the world-frame low-pass of turning errors leaks)
    np.testing.assert_allclose(np.linalg.svd(basis.vectors @ PATTERNS.T, compute_uv=False), 1.0, atol=2e-3)
    world = (G - F).reshape(len(G), -1)
    s = np.linalg.svd(world, compute_uv=False)
    assert (s[3] / s[0]) > 0.05  # in the world the turning errors spread beyond three directions


def test_the_projected_residual_keeps_the_filters_slow_error_and_cuts_white_jitter():
    """tracked = truth + 12 mm white jitter, filtered = truth - a slow error inside the basis. A
    Gaussian of s frames passes white noise at 1 / sqrt(2 sqrt(pi) s): the plain step (3 frames) 0.31
    of it; with the basis the noise outside the subspace (69 of 72 dimensions) goes through the tail's
    8 frames (0.19), and without a tail nearly nothing passes - while the filter's error is still
    corrected."""
    G, yaw = _turning_body(seed=4)
    E = _slow_error(yaw, seed=5)
    F = G - E
    tracked = G + np.random.default_rng(6).normal(0.0, 0.012, G.shape)
    basis = ResidualBasis(PATTERNS, 2.0)
    cfg = ResidualConfig(hold_feet=False, spline_gaps=False)
    err = lambda X: 1000 * np.linalg.norm(X - G, axis=-1).mean()
    plain = keep_low_frequencies(F, tracked, FPS, cfg)
    with_basis = keep_low_frequencies(F, tracked, FPS, cfg, basis)
    assert err(with_basis) < 0.75 * err(plain), (err(with_basis), err(plain))
    no_tail = keep_low_frequencies(F, tracked, FPS, replace(cfg, tail_sigma_frames=0.0), basis)
    assert err(no_tail) < 0.3 * err(plain), (err(no_tail), err(plain))  # 3/72 of the noise at 2 frames: ~0.2
    assert err(with_basis) < 0.3 * err(F) and err(no_tail) < 0.1 * err(F), (err(with_basis), err(no_tail), err(F))
    # switched off by the config: the plain step, bit for bit
    np.testing.assert_array_equal(keep_low_frequencies(F, tracked, FPS, replace(cfg, basis=False), basis), plain)
    # no tail: what lies outside the subspace is dropped, so 10-mm noise outside it leaves nothing (to the
    # ~0.1 mm the Gaussian mixes of the headings of neighbouring frames: the body turns 1.2 deg a frame)
    noise = np.random.default_rng(7).normal(0.0, 0.01, G.shape)
    outside = noise - basis.project(noise, heading_yaw(F))
    got = keep_low_frequencies(F, F + outside, FPS, replace(cfg, tail_sigma_frames=0.0), basis)
    np.testing.assert_allclose(got, F, atol=5e-4)


def test_turning_the_world_turns_the_output():
    G, yaw = _turning_body(seed=8)
    F = G - _slow_error(yaw, seed=9)
    tracked = G + np.random.default_rng(10).normal(0.0, 0.01, G.shape)
    basis = ResidualBasis(PATTERNS, 2.0)
    cfg = ResidualConfig(hold_feet=False, spline_gaps=False)
    out = keep_low_frequencies(F, tracked, FPS, cfg, basis)
    turn = np.full(len(G), 0.7)
    rot = lambda X: to_heading_frame(X, turn, inverse=True)
    np.testing.assert_allclose(keep_low_frequencies(rot(F), rot(tracked), FPS, cfg, basis), rot(out), atol=1e-9)


def test_a_corrupt_basis_is_refused_and_a_good_one_round_trips():
    good = ResidualBasis(PATTERNS, 2.0)
    back = ResidualBasis.from_extra(good.to_extra())
    np.testing.assert_allclose(back.vectors, good.vectors, atol=1e-6)
    assert back.sigma_frames == 2.0
    with pytest.raises(ValueError, match="orthonormal"):
        ResidualBasis(2 * PATTERNS, 2.0)
    with pytest.raises(ValueError, match=r"\(k, 72\)"):
        ResidualBasis(PATTERNS[:, :70], 2.0)
    bad = PATTERNS.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        ResidualBasis(bad, 2.0)
    with pytest.raises(ValueError, match="not finite"):
        ResidualBasis(PATTERNS, 0.0)
    with pytest.raises(ValueError, match="vectors and sigma_frames"):
        ResidualBasis.from_extra({"vectors": PATTERNS})
    G, _ = _turning_body(T=40)
    with pytest.raises(ValueError, match="rank"):
        fit_residual_basis([G], [G], rank=0)
    with pytest.raises(ValueError, match="one clean clip"):
        fit_residual_basis([G], [], rank=3)
    with pytest.raises(ValueError, match="finite"):
        fit_residual_basis([G * np.nan], [G], rank=3)


def test_the_shipped_filter_carries_a_basis_and_a_corrupt_one_is_refused_at_load(tmp_path):
    shipped = MODELS_DIR / "refine.pt"
    assert HOIFilter.load().residual_basis is not None
    ck = load_checkpoint(shipped, kind="filter")
    assert ck.meta[BASIS_KEY]["rank"] == ResidualBasis.from_extra(ck.extra[BASIS_KEY]).rank
    broken = dict(ck.extra)
    broken[BASIS_KEY] = {"vectors": 3 * torch.as_tensor(ck.extra[BASIS_KEY]["vectors"]),
                         "sigma_frames": ck.extra[BASIS_KEY]["sigma_frames"]}
    path = tmp_path / "broken.pt"
    save_checkpoint(path, replace(ck, extra=broken))
    with pytest.raises(ValueError, match="orthonormal"):
        load_checkpoint(path, kind="filter")
