"""Swept guard: no joint passes through a solid between two frames, whatever the steps before did.

The push-outs and the containment look at frames one by one; a hand, a foot or the whole body can
still move through a thin wall, a table top or a pillar's corner between two frames and come out
on the other side, where each frame alone is free (``trumans.eval.safety``: a *crossing*, the
joint's segment between the frames dipping below its ends into a solid). This step runs last and
walks the new frames in order: when a joint of frame t crosses on its way from frame t-1 (as
already guarded), frame t becomes the blend ``(1 - a) * frame[t-1] + a * frame[t]`` with the largest
``a`` in [0, 1] (bisection, ``iters`` halvings) at which no joint crosses. ``a = 0`` is the previous
frame, which crosses nothing, so the guarantee holds on every frame. The body stops at the barrier
for as long as the network keeps driving it through, and goes on once its motion leaves it. The
blend of two nearby frames keeps bone lengths to within a few mm (it is not re-projected, which
could move a joint back into the solid). The context frames stay.

The same blend also caps how deep a joint may go: no joint's core depth
(``trumans.eval.safety.core_depths``) may grow past ``max_depth`` on frames the feet carry
(``weight`` 1: standing, walking; a knee that strides into a low table or a pillar's corner stops
at it), nor past ``max_depth_seated`` on the others (seated and lying legs rest against furniture
by design and are the push-out's; the cap only keeps a body from creeping through a wall over
several frames, each of which enters it a little further).

The test is the benchmark's with a stricter ``depth`` (half of ``trumans.eval.safety.CROSS_DEPTH``),
in the field the pipeline gives the steps (the scene's ``enclosed`` one).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.eval.safety import CROSS_DEPTH, core_depths, swept_dips
from trumans.scenes.sdf import SceneSDF

from trumans.sample.cleanup.common import episode_joints

__all__ = ["SweptGuardConfig", "guard_crossings"]


@dataclass(frozen=True)
class SweptGuardConfig:
    """enabled: run the guard (it needs the scene); depth: m a joint's segment may dip below its
    ends into a solid; max_depth / max_depth_seated: m of core depth a joint may reach on frames
    the feet carry / on the others (deeper only where it already was); iters: bisection halvings
    of the blend weight."""

    enabled: bool = True
    depth: float = 0.5 * CROSS_DEPTH
    max_depth: float = 0.02
    max_depth_seated: float = 0.06
    iters: int = 8

    def __post_init__(self) -> None:
        depths = (self.depth, self.max_depth, self.max_depth_seated)
        if not all(np.isfinite(d) and d >= 0 for d in depths) or self.iters < 1:
            raise ValueError(f"depth, max_depth and max_depth_seated must be >= 0 m and iters >= 1, got {depths} "
                             f"and {self.iters}")


def _bad(a: np.ndarray, b: np.ndarray, sdf: SceneSDF, config: SweptGuardConfig, upright: bool) -> bool:
    """Whether frame b (24, 3) after frame a crosses a solid, or takes a joint deeper than the cap
    (``max_depth`` when ``upright``, else ``max_depth_seated``) and deeper than it was."""
    pair = np.stack([a, b])
    if (swept_dips(pair, sdf)[1] > config.depth).any():
        return True
    d = core_depths(pair, sdf)
    cap = config.max_depth if upright else config.max_depth_seated
    return bool((d[1] > np.maximum(d[0], cap) + 1e-6).any())


def guard_crossings(joints: np.ndarray, sdf: SceneSDF, fixed: int, config: SweptGuardConfig = SweptGuardConfig(),
                    weight: np.ndarray | None = None) -> np.ndarray:
    """joints (B, T, 24, 3) world m -> copy whose frames >= ``fixed`` cross no solid of ``sdf``
    from the frame before and go no deeper than the caps: ``config.max_depth`` where ``weight``
    (B, T) (how much the feet carry the body, ``support_weights``; None = nowhere) is 1,
    ``config.max_depth_seated`` elsewhere (module doc); frames < ``fixed`` are kept."""
    J = episode_joints(joints, fixed)
    out = J.copy()
    B, T = J.shape[:2]
    up = np.zeros((B, T), bool) if weight is None else np.asarray(weight) >= 1.0
    if up.shape != (B, T):
        raise ValueError(f"weight must be (B, T) = {(B, T)}, got shape {up.shape}")
    s = max(fixed - 1, 0)
    for b in range(B):  # a cheap screen of the whole episode first
        deep = core_depths(J[b, s:], sdf)
        if not ((swept_dips(J[b, s:], sdf) > config.depth).any()
                or (deep > np.where(up[b, s:, None], config.max_depth, config.max_depth_seated)).any()):
            continue
        for t in range(max(fixed, 1), T):
            prev = out[b, t - 1]
            if not _bad(prev, J[b, t], sdf, config, up[b, t]):
                continue
            lo, hi = 0.0, 1.0
            for _ in range(config.iters):
                mid = 0.5 * (lo + hi)
                if _bad(prev, prev + mid * (J[b, t] - prev), sdf, config, up[b, t]):
                    hi = mid
                else:
                    lo = mid
            out[b, t] = prev + lo * (J[b, t] - prev)
    return out.astype(np.asarray(joints).dtype)
