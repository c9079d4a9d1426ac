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
at it), nor its contact depth (``trumans.eval.safety.contact_depths``: the contact radius where the
nearest surface faces the joint's outward direction - a heel, a hip, a lying back -, the core
radius elsewhere) past ``max_depth_seated`` on the others: sitting down, seated, lying down, lying,
getting up. There the body rests on furniture by design, so the cap is on the contact-rule depth the
benchmark measures (``trumans eval safety``'s penetration; the field sees it to within ~2 cm of the
meshes, so 2.5 cm keeps the mesh figure under 5 cm): an elbow, knee, hip or heel that the network
swings into the sofa while lying down or getting up stops at the cushion. (The cap was 6 cm of
core depth, and lie-down runs reached 5-7.6 cm.)

Each candidate (the frame, then each blend the bisection tries) is first slid: translated rigidly
(bone lengths exact) along the field's gradient by what its worst offending joint goes past the
test - its depth past the cap, or its segment's dip, the gradient taken at the segment's deepest
point - (horizontally on frames the feet carry), up to ``slide_iters`` times and ``slide_max`` m in
all; the bisection keeps the largest blend whose slid frame passes. Without it a joint resting at
its cap against a corner froze the whole body: an elbow at a pillar's face or at the end of a
partition, which every frame of the network's walk took a little deeper (and whose segment from the
frozen frame to the network's next ones then cut the corner), held the blend weight at 0 for the rest
of the plan (the safety benchmark's unfinished wall plans, plan 6 in the L-shaped room, plans 26 / 35
through the partition's gap). The slide moves the body off the barrier by that much instead, so it
walks on along it.

The test is the benchmark's with a stricter ``depth`` (half of ``trumans.eval.safety.CROSS_DEPTH``),
in the field the pipeline gives the steps (the scene's ``enclosed`` one).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from trumans.eval.safety import CROSS_DEPTH, contact_depths, core_depths, swept_dips
from trumans.scenes.sdf import SceneSDF

from trumans.sample.cleanup.common import episode_joints

__all__ = ["SweptGuardConfig", "guard_crossings"]


@dataclass(frozen=True)
class SweptGuardConfig:
    """enabled: run the guard (it needs the scene); depth: m a joint's segment may dip below its
    ends into a solid; max_depth: m of core depth a joint may reach on frames the feet carry;
    max_depth_seated: m of contact depth (``contact_depths``) on the others (deeper only where it
    already was; module doc); iters: bisection halvings of the blend weight; slide_iters / slide_max:
    pushes at most and m in all of the slide of each candidate frame (module doc; 0 = blend only)."""

    enabled: bool = True
    depth: float = 0.5 * CROSS_DEPTH
    max_depth: float = 0.02
    max_depth_seated: float = 0.025
    iters: int = 8
    slide_iters: int = 4
    slide_max: float = 0.03

    def __post_init__(self) -> None:
        depths = (self.depth, self.max_depth, self.max_depth_seated, self.slide_max)
        if not all(np.isfinite(d) and d >= 0 for d in depths) or self.iters < 1 or self.slide_iters < 0:
            raise ValueError(f"depth, max_depth, max_depth_seated and slide_max must be >= 0 m, iters >= 1 and "
                             f"slide_iters >= 0, got {depths}, {self.iters} and {self.slide_iters}")


def _bad(a: np.ndarray, b: np.ndarray, sdf: SceneSDF, config: SweptGuardConfig, upright: bool) -> bool:
    """Whether frame b (24, 3) after frame a crosses a solid, or takes a joint deeper than the cap
    (core depth over ``max_depth`` when ``upright``, else contact depth over ``max_depth_seated``)
    and deeper than it was."""
    pair = np.stack([a, b])
    if (swept_dips(pair, sdf)[1] > config.depth).any():
        return True
    d, cap = _depths(pair, sdf, config, upright)
    return bool((d[1] > np.maximum(d[0], cap[1]) + 1e-6).any())


def _depths(joints: np.ndarray, sdf: SceneSDF, config: SweptGuardConfig, upright: bool | np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """joints (T, 24, 3); upright: bool or (T,) -> (depths (T, 24) m: core depth on upright frames,
    contact depth on the others; caps (T, 1) m)."""
    up = np.broadcast_to(np.asarray(upright, bool), (len(joints),))
    d = core_depths(joints, sdf)
    if not up.all():
        d = np.where(up[:, None], d, contact_depths(joints, sdf))
    return d, np.where(up, config.max_depth, config.max_depth_seated)[:, None]


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
        deep, cap = _depths(J[b, s:], sdf, config, up[b, s:])
        if not ((swept_dips(J[b, s:], sdf) > config.depth).any() or (deep > cap).any()):
            continue
        for t in range(max(fixed, 1), T):
            prev = out[b, t - 1]
            if not _bad(prev, J[b, t], sdf, config, up[b, t]):
                continue
            frame = _slide(prev, J[b, t], sdf, config, up[b, t])
            if not _bad(prev, frame, sdf, config, up[b, t]):
                out[b, t] = frame
                continue
            lo, hi, best = 0.0, 1.0, prev
            for _ in range(config.iters):
                mid = 0.5 * (lo + hi)
                trial = _slide(prev, prev + mid * (J[b, t] - prev), sdf, config, up[b, t])
                if _bad(prev, trial, sdf, config, up[b, t]):
                    hi = mid
                else:
                    lo, best = mid, trial
            out[b, t] = best
    return out.astype(np.asarray(joints).dtype)


def _slide(prev: np.ndarray, frame: np.ndarray, sdf: SceneSDF, config: SweptGuardConfig, upright: bool) -> np.ndarray:
    """frame (24, 3) after ``prev`` (24, 3), translated rigidly out of the solid (module doc): each push moves it
    along the field's gradient by what its worst offending joint goes past the test - its depth past
    ``max(its depth before, cap)``, or its segment's dip past ``config.depth`` (the gradient taken at the
    segment's deepest point) -, horizontally when ``upright``; ``config.slide_iters`` pushes at most,
    ``config.slide_max`` m in all."""
    out = frame.copy()
    moved = 0.0
    field = sdf.enclosed()
    for _ in range(config.slide_iters):
        pair = np.stack([prev, out])
        d, cap = _depths(pair, sdf, config, upright)
        excess = d[1] - np.maximum(d[0], cap[1])
        dips = swept_dips(pair, sdf)[1] - config.depth
        j_d, j_c = int(np.argmax(excess)), int(np.argmax(dips))
        if max(excess[j_d], dips[j_c]) <= 1e-6:
            break
        if excess[j_d] >= dips[j_c]:
            at, amount = out[j_d], float(excess[j_d])
        else:  # the deepest point of the joint's segment
            u = np.linspace(0.0, 1.0, 17)[:, None]
            seg = prev[j_c] + u * (out[j_c] - prev[j_c])
            at = seg[int(np.argmin(field(torch.as_tensor(seg, dtype=torch.float32)).numpy()))]
            amount = float(dips[j_c])
        g = field.value_and_gradient(torch.as_tensor(at, dtype=torch.float32))[1].numpy().astype(np.float64)
        if upright:
            g[2] = 0.0
        n = float(np.linalg.norm(g))
        step = min(amount + 1e-4, config.slide_max - moved)
        if n < 1e-6 or step <= 0:
            break
        out = out + step * g / n
        moved += step
    return out
