"""Do no harm: the filter's output is blended with the tracked input by how noisy the input is
there (a post-step of the HOI filter).

The filter is trained on one corruption mix, so on a clean or lightly corrupted input it smooths
as if the input were that noisy (a clean real clip came back moved by ~20 mm). The input says
itself how much to trust it, per frame and per joint:

- **jitter** (``input_noise``): real motion at 30 fps is locally a cubic to well under a millimetre
  (clean corpus clips: 0.1-0.6 mm), tracker jitter is not. The residual of a local cubic fit
  (Savitzky-Golay, 7 frames, order 3: residual std = sqrt(1 - 7/21) = 0.816 of white noise's) has,
  for white noise of std s per axis, a 3D norm whose median is 1.538 * 0.816 s; the running median
  of that norm over ``noise_window_s`` gives the local jitter s(t, j) (the fill and the residual are
  read once per clip, ``tracked.TrackedBody``);
- **failures**: missing or frozen entries (NaN in the tracked input after
  ``trumans.refine.outliers``) and spikes (a residual above ``spike_sigmas`` s + ``spike_m``) are
  the filter's alone, widened by ``fail_pad`` frames.

The weight of the filter is w = max(smoothstep((s - keep_below_m) / (filter_above_m -
keep_below_m)), failures feathered over ``feather`` frames); the output is tracked + w (filtered -
tracked), joint by joint. Below ``keep_below_m`` the input is returned as it came. The weights are
smooth in time, so nothing jumps where the gate opens.

Not in I'm-HOI (its filter rewrites every frame). Units: metres; joints (T, 24, 3) z-up world.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation

from trumans.easing import smoothstep
from trumans.skeleton import NUM_JOINTS

from trumans.refine.tracked import TrackedBody, as_tracked_body

__all__ = ["GateConfig", "input_noise", "noise_level", "failure_mask", "gate_weights", "gate_joints"]

_RES_STD = np.sqrt(1.0 - 7.0 / 21.0)  # residual std of SG(7, 3) on white noise, per unit noise std
_NORM_MEDIAN = 1.5382  # median of the norm of a 3D standard normal: sqrt(chi2_3 median 2.366)


@dataclass(frozen=True)
class GateConfig:
    """enabled: whether the post-step runs (``trumans.refine.post_steps``); keep_below_m /
    filter_above_m: local input jitter (std per axis, m) under which the input is kept as it is /
    over which the filter's output replaces it (smoothstep between); noise_window_s: the running
    median's length (s); spike_sigmas, spike_m: a residual over spike_sigmas * jitter + spike_m is a
    spike; fail_pad: frames around a failure (missing, frozen, spike) that are the filter's alone;
    feather: frames over which that weight ramps down. Measured on 14 corpus train clips (tracker
    model, dropouts alone, filter / tuned Gaussian, translation-aligned / limb): pad 1 + feather 4
    0.87 / 0.86, pad 0 + feather 1 0.80 / 0.76, pad 0 + feather 0 0.79 / 0.74 but a larger
    acceleration error; the input residual (the first post-step) already bends the filter's fill of a
    gap to meet the tracked frames on either side, so a wide ramp only blurs good frames."""

    enabled: bool = True
    keep_below_m: float = 0.002
    filter_above_m: float = 0.005
    noise_window_s: float = 1.0
    spike_sigmas: float = 6.0
    spike_m: float = 0.008
    fail_pad: int = 0
    feather: int = 1

    def __post_init__(self) -> None:
        if not 0 <= self.keep_below_m < self.filter_above_m:
            raise ValueError(f"gate needs 0 <= keep_below_m < filter_above_m, got {self.keep_below_m}, "
                             f"{self.filter_above_m}")
        if not self.noise_window_s > 0 or self.spike_sigmas < 0 or self.spike_m < 0:
            raise ValueError(f"gate noise_window_s must be > 0, spike_sigmas and spike_m >= 0, got "
                             f"{self.noise_window_s}, {self.spike_sigmas}, {self.spike_m}")
        if self.fail_pad < 0 or self.feather < 0:
            raise ValueError(f"gate fail_pad and feather must be >= 0 frames, got {self.fail_pad}, {self.feather}")


def _check(joints: np.ndarray) -> np.ndarray:
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, {NUM_JOINTS}, 3), got {J.shape}")
    return J


def _noise_residual(body: TrackedBody, fps: float, config: GateConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(local jitter (T, 24) m, cubic-fit residual (T, 24) m, observed (T, 24) bool) of a tracked body."""
    win = max(3, int(round(config.noise_window_s * fps)) | 1)
    # the running median over observed frames: missing ones count as the joint's own median residual
    return body.running_median(win) / (_NORM_MEDIAN * _RES_STD), body.residual, body.seen


def input_noise(tracked: np.ndarray | TrackedBody, fps: float, config: GateConfig = GateConfig()) -> np.ndarray:
    """Local jitter of tracked joints (T, 24, 3) m (NaN = missing; or their ``TrackedBody``) at ``fps``:
    (T, 24) m, the std per axis of white noise that would give the running median of the cubic-fit residual."""
    return _noise_residual(as_tracked_body(tracked), fps, config)[0]


def noise_level(tracked: np.ndarray | TrackedBody) -> np.ndarray:
    """Each joint's jitter over the whole clip: tracked joints (T, 24, 3) m (NaN = missing; or their
    ``TrackedBody``) -> (24,) m, the std per axis of white noise that would give the median cubic-fit
    residual over the observed frames (0 for a joint never observed)."""
    body = as_tracked_body(tracked)
    med = body.residual_median if body.seen.any() else np.zeros(NUM_JOINTS)
    return np.nan_to_num(med) / (_NORM_MEDIAN * _RES_STD)


def failure_mask(tracked: np.ndarray | TrackedBody, fps: float, config: GateConfig = GateConfig()) -> np.ndarray:
    """(T, 24) bool: the entries of tracked joints (T, 24, 3) m (NaN = missing; or their
    ``TrackedBody``) at ``fps`` that are failures: missing (frozen entries were made missing before)
    or spikes (a cubic-fit residual over ``spike_sigmas`` x the local jitter + ``spike_m``)."""
    noise, r, seen = _noise_residual(as_tracked_body(tracked), fps, config)
    return ~seen | (r > config.spike_sigmas * _RES_STD * noise + config.spike_m)


def gate_weights(tracked: np.ndarray | TrackedBody, fps: float, config: GateConfig = GateConfig()) -> np.ndarray:
    """The filter's weight per frame and joint (T, 24) in [0, 1] for tracked joints (T, 24, 3) m
    (NaN = missing; or their ``TrackedBody``) at ``fps``: 1 on failures (``failure_mask``; widened by
    ``fail_pad``, ramped down over ``feather`` frames), else by the local jitter (``input_noise``)."""
    body = as_tracked_body(tracked)
    noise = _noise_residual(body, fps, config)[0]
    w = smoothstep((noise - config.keep_below_m) / (config.filter_above_m - config.keep_below_m))
    fail = failure_mask(body, fps, config)
    if config.fail_pad > 0:
        fail = binary_dilation(fail, np.ones((2 * config.fail_pad + 1, 1), bool))
    f = fail.astype(np.float64)
    if config.feather > 0:  # a linear ramp down over `feather` frames on either side
        k = config.feather
        ramp = f.copy()
        for s in range(1, k + 1):
            v = 1.0 - s / (k + 1)
            ramp = np.maximum(ramp, v * np.roll(f, s, axis=0) * (np.arange(len(f)) >= s)[:, None])
            ramp = np.maximum(ramp, v * np.roll(f, -s, axis=0) * (np.arange(len(f)) < len(f) - s)[:, None])
        f = ramp
    return np.maximum(w, f)


def gate_joints(filtered: np.ndarray, tracked: np.ndarray | TrackedBody, fps: float,
                config: GateConfig = GateConfig()) -> np.ndarray:
    """filtered + tracked joints (T, 24, 3) m (tracked NaN = missing; or its ``TrackedBody``) -> tracked
    (gaps filled) + w (filtered - tracked), w = ``gate_weights``: (T, 24, 3) m."""
    body = as_tracked_body(tracked)
    F, J = _check(filtered), body.joints
    if F.shape != J.shape:
        raise ValueError(f"filtered and tracked joints must have one shape, got {F.shape} and {J.shape}")
    w = gate_weights(body, fps, config)[..., None]
    X = np.where(np.isfinite(J), J, F)  # missing entries: the filter's (their weight is 1 anyway)
    return X + w * (F - X)
