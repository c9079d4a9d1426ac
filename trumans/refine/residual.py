"""Keep the tracked input's low frequencies: the filter's output plus the low-passed residual
(a post-step of the HOI filter; our addition, not I'm-HOI's).

The network's estimate is good where the tracked input is bad in the short term (jitter, spikes,
bursts, gaps: high frequencies) and poor where the input is good in the long term: its own error
is slow (a pose a little off for a second, a limb held a few cm away). A smoother of the input has
the opposite profile. So the output takes the high frequencies from the filter and the low ones
from the input: with r = tracked - filtered per joint and coordinate,

    out = filtered + G_sigma(r),

r's gaps (missing and frozen entries) filled linearly in time first, so a gap is filled with the
filter's shape bent to meet the tracked frames on either side; G a Gaussian of ``sigma_frames``.
The smoothing runs on the difference, not on the motion, so the detail the filter drew stays.

Where the tracked frames around a short gap are clean, they say more about it than the filter does:
a cubic spline through a joint's tracked frames fills a gap of up to ``spline_max_s`` far better
(14 corpus train clips under the tracker model's dropouts, 2-20 frames: 12.7 mm in the gaps against
the filter's 23.8 and a straight line's 28.5; PCHIP 19.2, Akima 17.7). Through jittery frames a
spline swings with the noise, so (``spline_gap_weights``) the output on such a gap is the spline
where the local jitter (``gate.input_noise``) is under ``spline_below_m``, filtered + G(r) as above
where it is over ``linear_above_m``, and a smoothstep blend between (the spline replaces the
output in the gap rather than r before the Gaussian, which would blur it: dropouts 0.63 -> 0.59 of
a tuned Gaussian's error on the same clips).

Under jitter the Gaussian also passes the input's own white noise (a third of it at 3 frames).
With the filter checkpoint's residual basis (``residual_basis.py``: the few joint-space patterns the
filter's slow error takes, in the heading frame) the smoothed residual is projected on that subspace,
and what lies outside it comes back through a wider Gaussian (``tail_sigma_frames``). With the noise
cut that way the Gaussian inside the subspace can be narrower (the basis' own sigma, 2 frames for the
shipped one): tracker jitter on held-out clips 8.85 -> 8.40 mm (a tuned smoother: 10.66).

A planted foot must not take the input's low-passed jitter along (it would slide by centimetres a
second and hide the stance from the foot lock after it): with ``hold_feet``, on the stances of the
filter's own feet (``body_drift.stance_mask``) each foot joint's added residual is its mean over the
stance, faded in and out over ``fade_s`` (``foot_lock.stance_corrections``).

First of the post-steps: the steps after it read the body it returns. Chosen on corpus train clips
(docs/refine.md): sigma 2-4 frames give the same errors within 0.3 mm; a running median before the
Gaussian (against spikes) did not help. Units: metres; joints (T, 24, 3) z-up world; frames at the
filter's rate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d, label

from trumans.easing import smoothstep
from trumans.refine.body_drift import DriftConfig, stance_mask
from trumans.refine.foot_lock import stance_corrections
from trumans.refine.frame import fill_missing_joints
from trumans.refine.gate import GateConfig, input_noise
from trumans.refine.residual_basis import ResidualBasis, heading_yaw
from trumans.refine.tracked import TrackedBody, as_tracked_body
from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS

__all__ = ["ResidualConfig", "keep_low_frequencies", "spline_gap_weights"]


@dataclass(frozen=True)
class ResidualConfig:
    """enabled: whether the post-step runs; sigma_frames: the Gaussian's std (frames at the filter's
    rate); hold_feet: planted foot joints keep one residual per stance, faded over ``fade_s``
    seconds; stance: how stances are found (the body-drift fit's detection; only the detection is read);
    spline_gaps: gaps of up to ``spline_max_s`` seconds in clean tracked frames are filled by a cubic
    spline (module doc) - fully where the local jitter (std per axis, m) is under ``spline_below_m``,
    not at all over ``linear_above_m`` (the gate's thresholds by default); basis: project the smoothed
    residual on the filter's residual basis when the checkpoint has one (module doc; the Gaussian is
    then the basis' own ``sigma_frames``, the one it was fitted with), the rest of the residual through
    a Gaussian of ``tail_sigma_frames`` (0: the rest dropped)."""

    enabled: bool = True
    sigma_frames: float = 3.0
    hold_feet: bool = True
    fade_s: float = 0.2
    stance: DriftConfig = DriftConfig()
    spline_gaps: bool = True
    spline_max_s: float = 0.5
    spline_below_m: float = 0.002
    linear_above_m: float = 0.005
    basis: bool = True
    tail_sigma_frames: float = 8.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma_frames) and self.sigma_frames > 0):
            raise ValueError(f"residual sigma_frames must be > 0, got {self.sigma_frames}")
        if not (np.isfinite(self.fade_s) and self.fade_s >= 0):
            raise ValueError(f"residual fade_s must be >= 0, got {self.fade_s}")
        if not self.stance.enabled:
            raise ValueError("residual stance is the stance detection only: its enabled must stay true")
        if not (np.isfinite(self.spline_max_s) and self.spline_max_s >= 0):
            raise ValueError(f"residual spline_max_s must be >= 0 s, got {self.spline_max_s}")
        if not (np.isfinite(self.tail_sigma_frames) and self.tail_sigma_frames >= 0):
            raise ValueError(f"residual tail_sigma_frames must be >= 0, got {self.tail_sigma_frames}")
        if not 0 <= self.spline_below_m < self.linear_above_m:
            raise ValueError(f"residual needs 0 <= spline_below_m < linear_above_m, got {self.spline_below_m}, "
                             f"{self.linear_above_m}")


def spline_gap_weights(body: TrackedBody, fps: float, config: ResidualConfig = ResidualConfig()) -> np.ndarray:
    """(T, 24) in [0, 1]: how much of each missing entry of the tracked body is the cubic spline's
    (module doc): 0 on observed entries, on gaps longer than ``spline_max_s`` and on gaps at either
    end of a joint's track; inside a short gap, 1 - smoothstep of the local jitter between
    ``spline_below_m`` and ``linear_above_m``."""
    seen = body.seen
    T = len(seen)
    w = np.zeros(seen.shape)
    if not config.spline_gaps or seen.all() or T < 4:
        return w
    gaps, n = label(~seen.T, structure=[[0, 0, 0], [1, 1, 1], [0, 0, 0]])  # (24, T) each joint's gaps, 0 = seen
    if n:
        length = np.bincount(gaps.ravel(), minlength=n + 1)
        at_end = np.zeros(n + 1, bool)
        at_end[gaps[:, [0, -1]].ravel()] = True  # a gap at either end of a track has one side only
        ok = (length <= config.spline_max_s * fps) & ~at_end
        ok[0] = False
        w = (ok[gaps] & (seen.sum(0) >= 4)[:, None]).T.astype(np.float64)  # a spline needs 4 tracked frames
    if w.any():
        noise = input_noise(body, fps, GateConfig(keep_below_m=config.spline_below_m, filter_above_m=config.linear_above_m))
        w *= 1.0 - smoothstep((noise - config.spline_below_m) / (config.linear_above_m - config.spline_below_m))
    return w


def _spline_fill(body: TrackedBody, weights: np.ndarray) -> np.ndarray:
    """(T, 24, 3): the tracked joints with each entry of positive ``weights`` the cubic spline
    (``scipy.interpolate.CubicSpline``, not-a-knot) through that joint's tracked frames; NaN elsewhere
    in the gaps."""
    J = body.joints.copy()
    t = np.arange(len(J), dtype=np.float64)
    todo = np.flatnonzero((weights > 0).any(0))
    if not len(todo):
        return J
    # joints tracked on the same frames (a whole-body dropout) share one spline fit
    _, group = np.unique(body.seen[:, todo].T, axis=0, return_inverse=True)
    for g in np.unique(group):
        js = todo[group.ravel() == g]
        seen = body.seen[:, js[0]]
        fill = (weights[:, js] > 0).any(1)
        J[np.ix_(fill, js)] = CubicSpline(t[seen], body.joints[seen][:, js], axis=0)(t[fill])
    return J


def keep_low_frequencies(filtered: np.ndarray, tracked: np.ndarray | TrackedBody, fps: float,
                         config: ResidualConfig = ResidualConfig(), basis: ResidualBasis | None = None) -> np.ndarray:
    """filtered (T, 24, 3) m (finite), tracked (T, 24, 3) m (NaN = missing; or its ``TrackedBody``) at
    ``fps`` -> filtered + G(tracked - filtered), projected on ``basis`` when given (and
    ``config.basis``), short clean gaps splined, planted feet held (module docstring): (T, 24, 3)
    float64. A joint never tracked keeps the filter's."""
    body = tracked if isinstance(tracked, TrackedBody) else None
    F, X = np.asarray(filtered, np.float64), np.asarray(tracked.joints if body is not None else tracked, np.float64)
    if F.ndim != 3 or F.shape[1:] != (NUM_JOINTS, 3) or X.shape != F.shape:
        raise ValueError(f"filtered and tracked joints must both be (T, {NUM_JOINTS}, 3), got {F.shape} and {X.shape}")
    if not np.isfinite(F).all():
        raise ValueError("the filtered joints must be finite")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    r = fill_missing_joints(X - F)
    r = np.where(np.isfinite(r), r, 0.0)  # a joint never tracked: nothing to keep
    if basis is not None and config.basis:
        yaw = heading_yaw(F)
        low = basis.project(gaussian_filter1d(r, basis.sigma_frames, axis=0, mode="nearest"), yaw)
        if config.tail_sigma_frames > 0:
            low += gaussian_filter1d(r - basis.project(r, yaw), config.tail_sigma_frames, axis=0, mode="nearest")
    else:
        low = gaussian_filter1d(r, config.sigma_frames, axis=0, mode="nearest")
    if config.spline_gaps and not np.isfinite(X).all():
        body = body if body is not None else as_tracked_body(X)
        w = spline_gap_weights(body, fps, config)
        if w.any():
            spline = _spline_fill(body, w)
            take = w > 0
            low[take] += w[take, None] * ((spline - F)[take] - low[take])
    if config.hold_feet and len(F) >= 2:
        planted = stance_mask(F, fps, config.stance)
        if planted.any():
            low[:, FOOT_JOINTS] += stance_corrections(low, planted, config.fade_s * fps)
    return F + low
