"""Trust a smoother of the input where the filter is less sure than it is (a post-step of the HOI
filter; our addition, not I'm-HOI's).

After the gate, every joint has two estimates: the filter's ``F`` and a Gaussian low-pass of the
tracked input, ``S = G_sigma(X)`` (``X``'s failures - missing or frozen entries and spikes,
``gate.failure_mask`` - replaced by ``F`` first, so that ``S`` carries none of them). The network is
good on the poses it has seen often (walking) and poorer on rarer ones (lying, getting up from the
floor, picking up), where a smoother of a merely jittery input can be nearer the truth. With
independent errors of variances ``e_F^2`` and ``e_S^2`` the least-variance combination is the
inverse-variance one,

    out = F + w (S - F),    w = e_F^2 / (e_F^2 + e_S^2),

per frame and joint. ``e_S^2`` is predicted from the input: the white noise the Gaussian passes,
``3 s^2 / (2 sigma sqrt(pi))`` for a local jitter ``s`` per axis (``gate.input_noise``), plus the detail
it would blur away, read on ``F``: ``|F - G_sigma(F)|^2``. ``e_F^2`` cannot be read directly, but the
two estimates' disagreement has the expectation ``E|F - S|^2 = e_F^2 + e_S^2``, so over a running
window of ``window_s`` (box means) ``e_F^2 ~ max(0, mean |F - S|^2 - mean e_S^2)``: where the filter
agrees with the smoothed input to within what the input's noise explains, the filter's output
stays; where it disagrees by more, the smoother takes the share its smaller error earns. Failures
get ``w = 0`` (the smoother has nothing there), widened by ``fail_pad`` frames; so do the foot
joints unless ``feet`` (the foot lock holds them; the smoother's feet slide with the input's jitter).

After the gate (whose output on a clean input is that input, so ``F`` and ``S`` differ by the
smoother's blur and ``w`` stays ~0) and before the bones (a blend of two bodies does not keep
lengths). Right after the residual step it gained nothing (held-out real clips under jitter 0.80 ->
0.79 of the tuned smoother's error; after the gate 0.76 -> 0.74, docs/refine.md). Units: metres;
joints (T, 24, 3) z-up world; frames at the filter's rate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation, gaussian_filter1d, uniform_filter1d

from trumans.refine.gate import GateConfig, failure_mask, input_noise
from trumans.refine.tracked import TrackedBody, as_tracked_body
from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS

__all__ = ["BlendConfig", "smoother_weights", "blend_with_smoother"]


@dataclass(frozen=True)
class BlendConfig:
    """enabled: whether the post-step runs (``trumans.refine.post_steps``); sigma_frames: the
    smoother's Gaussian std (frames at the filter's rate); window_s: the running window (s) over
    which the disagreement and the smoother's predicted error are averaged; fail_pad: frames around a
    failure of the input where the smoother is not used; feet: blend the foot joints too (ankles, toe
    bases). Chosen on the corpus's held-out clips (docs/refine.md): window 0.5 s against 1 s, the
    smoother's sigma the one tuned per family there (1.5 frames under every noisy family)."""

    enabled: bool = True
    sigma_frames: float = 1.5
    window_s: float = 0.5
    fail_pad: int = 2
    feet: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma_frames) and self.sigma_frames > 0):
            raise ValueError(f"smoother sigma_frames must be > 0, got {self.sigma_frames}")
        if not (np.isfinite(self.window_s) and self.window_s > 0):
            raise ValueError(f"smoother window_s must be > 0 s, got {self.window_s}")
        if self.fail_pad < 0:
            raise ValueError(f"smoother fail_pad must be >= 0 frames, got {self.fail_pad}")


def smoother_weights(filtered: np.ndarray, tracked: np.ndarray | TrackedBody, fps: float,
                     config: BlendConfig = BlendConfig()) -> tuple[np.ndarray, np.ndarray]:
    """filtered (T, 24, 3) m (finite), tracked (T, 24, 3) m (NaN = missing; or its ``TrackedBody``) at
    ``fps`` -> (the smoother's weight w (T, 24) in [0, 1], the smoother S (T, 24, 3) m) (module doc)."""
    F = np.asarray(filtered, np.float64)
    body = as_tracked_body(tracked)
    if F.ndim != 3 or F.shape[1:] != (NUM_JOINTS, 3) or F.shape != body.joints.shape:
        raise ValueError(f"filtered and tracked joints must both be (T, {NUM_JOINTS}, 3), got {F.shape} and "
                         f"{body.joints.shape}")
    if not np.isfinite(F).all():
        raise ValueError("the filtered joints must be finite")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    gate = GateConfig()
    fail = failure_mask(body, fps, gate)
    sigma = config.sigma_frames
    X = np.where(fail[..., None] | ~np.isfinite(body.joints), F, body.joints)
    S = gaussian_filter1d(X, sigma, axis=0, mode="nearest")
    noise = input_noise(body, fps, gate)  # (T, 24) jitter per axis, m
    e_s2 = 3.0 * noise ** 2 / (2.0 * sigma * np.sqrt(np.pi)) \
        + ((F - gaussian_filter1d(F, sigma, axis=0, mode="nearest")) ** 2).sum(-1)
    win = max(1, int(round(config.window_s * fps)))
    e_s2 = uniform_filter1d(e_s2, win, axis=0, mode="nearest")
    e_f2 = np.maximum(0.0, uniform_filter1d(((F - S) ** 2).sum(-1), win, axis=0, mode="nearest") - e_s2)
    w = np.divide(e_f2, e_f2 + e_s2, out=np.zeros_like(e_f2), where=e_f2 + e_s2 > 0)
    if fail.any():
        if config.fail_pad > 0:
            fail = binary_dilation(fail, np.ones((2 * config.fail_pad + 1, 1), bool))
        w[fail] = 0.0
    if not config.feet:
        w[:, list(FOOT_JOINTS)] = 0.0
    return w, S


def blend_with_smoother(filtered: np.ndarray, tracked: np.ndarray | TrackedBody, fps: float,
                        config: BlendConfig = BlendConfig()) -> np.ndarray:
    """filtered + w (S - filtered) (module doc; ``smoother_weights``): (T, 24, 3) float64 m."""
    w, S = smoother_weights(filtered, tracked, fps, config)
    F = np.asarray(filtered, np.float64)
    return F + w[..., None] * (S - F)
