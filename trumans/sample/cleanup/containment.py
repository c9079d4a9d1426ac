"""Containment: a hard constraint on where the body stands, whatever the network drew.

The penetration guidance and the push-out are soft: they trade depth against change, and a body
the network walks 40 cm past its goal into a wall comes out of them still in it (on another
machine, whose floating point made the demo's rollout diverge, the body crossed the wall and drank
outside the room). This step is a projection, not a penalty:

- on every new frame the feet carry (``support_weights``: 1 standing and walking, eased to 0 over
  sitting down and back over standing up, 0 seated or lying) the pelvis's floor point must have
  ``w * clearance`` m of free space around it between ankle and head height (the field's
  ``clearance_map``: its minimum over that band per floor column; ``clearance`` 0.22 m keeps the
  shoulders' core out of a wall the body walks along, about the walk map's 0.25 m body radius; half
  a voxel is added, since the voxel field measures from voxel centres);
- the field is the scene's ``enclosed`` one (a closed room's outside is solid), so the constraint
  also holds the body inside the room.

A frame that breaks it is moved (all 24 joints, horizontally) to where it holds: along the map's
gradient by the missing clearance, repeated (``iters``; a distance field's gradient has unit length,
so one step is exact away from corners), and where that does not converge (inside furniture the map
is flat), to the free column nearest where the previous frame's corrected pelvis would carry on
(so a body walking through a table leaves it on one side, not on whichever side is nearest at each
frame). A frame the feet only partly carry (0 < w < 1: sitting down, standing up) is moved by at most
the clearance it is asked for, ``w * clearance``, and never to a far column: its pelvis is over the
seat it sits on, whose column is solid; a far move there threw the body 20-30 cm in one frame
(issue 35), and the cap makes the correction fade with w. The per-frame moves are eased over ``spread`` frames either side
(smoothstep falloff of the largest nearby move) and the eased path is projected once more, so the
constraint holds on every frame while a correction does not appear in one frame - except where
the correction would change faster than ``max_speed``: a body the network walks *through* a table
must come out on one side of it and then, where the table ends, on the other, and a per-frame
projection switches sides in one frame (35 cm in the default demo, issue 35). The change of the
correction is limited to ``max_speed`` (forward and backward passes), so the clearance is short on
the few frames of such a switch and the body never jumps. The
context frames stay. Bone lengths are unchanged (a rigid shift); the feet re-lock after it (the
foot cleanup runs later).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from trumans.scenes.sdf import SceneSDF
from trumans.skeleton import JOINT_INDEX

from trumans.easing import smoothstep
from trumans.sample.cleanup.common import episode_joints

__all__ = ["ContainmentConfig", "contain"]

_PELVIS = JOINT_INDEX["pelvis"]


@dataclass(frozen=True)
class ContainmentConfig:
    """enabled: run the projection (it needs the scene); clearance: m of free space an upright
    pelvis keeps around it between ankle and head height; spread: frames over which a correction
    is eased in and out; iters: gradient steps of the projection before the nearest-column fallback;
    max_speed: m/s, the fastest the correction may change between frames (module doc)."""

    enabled: bool = True
    clearance: float = 0.22
    spread: int = 3
    iters: int = 8
    max_speed: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.max_speed) and self.max_speed > 0):
            raise ValueError(f"max_speed must be a finite number > 0 m/s, got {self.max_speed}")
        if not (np.isfinite(self.clearance) and 0.0 <= self.clearance <= 1.0):
            raise ValueError(f"clearance must be in [0, 1] m, got {self.clearance}")
        if self.spread < 0 or self.iters < 1:
            raise ValueError(f"spread must be >= 0 and iters >= 1, got {self.spread} and {self.iters}")


class _Map:
    """Bilinear samples of a clearance map (Nx, Ny) m and its gradient at world xy points."""

    def __init__(self, m: np.ndarray, origin: np.ndarray, cell: float) -> None:
        self.m, self.origin, self.cell = m, origin, cell
        self.gx, self.gy = np.gradient(m, cell)

    def _ij(self, p: np.ndarray) -> np.ndarray:
        return ((p - self.origin) / self.cell).T  # (2, n) fractional cell indices

    def value(self, p: np.ndarray) -> np.ndarray:
        return ndimage.map_coordinates(self.m, self._ij(p), order=1, mode="nearest")

    def gradient(self, p: np.ndarray) -> np.ndarray:
        ij = self._ij(p)
        return np.stack([ndimage.map_coordinates(g, ij, order=1, mode="nearest") for g in (self.gx, self.gy)], -1)

    def nearest_with(self, p: np.ndarray, need: float) -> np.ndarray:
        """The centre (2,) of the column with value >= ``need`` nearest p (2,); p itself if none has."""
        ok = np.argwhere(self.m >= need)
        if not len(ok):
            return p
        c = self.origin + self.cell * ok
        return c[int(np.argmin(np.linalg.norm(c - p, axis=1)))]


def _project(mp: _Map, p: np.ndarray, need: np.ndarray, iters: int, cap: np.ndarray) -> np.ndarray:
    """Points p (n, 2) world m, consecutive frames, moved where the map is >= need (n,) m, each by at
    most cap (n,) m (inf: no limit; a capped point never takes the far fallback; module doc)."""
    q = np.array(p, dtype=np.float64, copy=True)
    slack = 1e-3  # m past the bound, so the bilinear value at the result is not just under it
    for _ in range(iters):
        miss = need - mp.value(q)
        act = (miss > 0) & (need > 0)
        if not act.any():
            break
        g = mp.gradient(q[act])
        norm = np.linalg.norm(g, axis=-1, keepdims=True)
        q[act] += (miss[act, None] + slack) * g / np.maximum(norm, 1e-9)
    miss = need - mp.value(q)
    for i in np.flatnonzero((miss > 0) & (need > 0) & ~np.isfinite(cap)):
        carry_on = q[i] if i == 0 else q[i - 1] + (p[i] - p[i - 1])
        q[i] = mp.nearest_with(carry_on, need[i] + slack)
    move = q - p
    length = np.linalg.norm(move, axis=-1)
    over = length > cap
    move[over] *= (cap[over] / length[over])[:, None]
    return p + move


def contain(joints: np.ndarray, sdf: SceneSDF, weight: np.ndarray, fixed: int,
            config: ContainmentConfig = ContainmentConfig(), fps: float = 10.0) -> np.ndarray:
    """joints (B, T, 24, 3) world m at ``fps``; weight (B, T) in [0, 1], how much the feet carry the
    body (``support_weights``) -> copy with frames >= ``fixed`` moved horizontally so that each upright
    pelvis has ``weight * clearance`` m of free space in ``sdf.enclosed()`` (module doc)."""
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be > 0, got {fps}")
    J = episode_joints(joints, fixed)
    w = np.asarray(weight, dtype=np.float64)
    if w.shape != J.shape[:2] or not (np.isfinite(w).all() and (w >= 0).all() and (w <= 1).all()):
        raise ValueError(f"weight must be (B, T) = {J.shape[:2]} in [0, 1], got shape {w.shape}")
    field = sdf.enclosed()
    mp = _Map(*field.clearance_map(), field.voxel)
    out = J.copy()
    B, T = J.shape[:2]
    for b in range(B):
        p = J[b, fixed:, _PELVIS, :2]
        need = (config.clearance + 0.5 * field.voxel) * w[b, fixed:]  # the field is half a voxel coarse
        if not len(p) or not (need > mp.value(p)).any():
            continue
        cap = np.where(w[b, fixed:] < 1.0, need, np.inf)  # a partly carried body: at most what it is asked
        d = _project(mp, p, need, config.iters, cap) - p  # (n, 2) hard per-frame moves
        eased = _ease(d, config.spread)
        d = _project(mp, p + eased, need, config.iters, np.maximum(cap - np.linalg.norm(eased, axis=-1), 0.0)) - p
        out[b, fixed:, :, :2] += _limit_change(d, config.max_speed / fps)[:, None]
    return out.astype(np.asarray(joints).dtype)


def _ease(d: np.ndarray, spread: int) -> np.ndarray:
    """(n, 2) moves -> (n, 2): at each frame the largest nearby move scaled by a smoothstep falloff
    over ``spread`` frames (a move is kept in full at its own frame)."""
    if spread == 0:
        return d
    n = len(d)
    mag = np.linalg.norm(d, axis=-1)
    out = d.copy()
    for t in range(n):
        s = np.arange(max(0, t - spread), min(n, t + spread + 1))
        fall = smoothstep(1.0 - np.abs(s - t) / (spread + 1.0))
        i = int(np.argmax(mag[s] * fall))
        if mag[s[i]] * fall[i] > mag[t]:
            out[t] = d[s[i]] * fall[i]
    return out


def _limit_change(d: np.ndarray, step: float, passes: int = 4) -> np.ndarray:
    """(n, 2) moves after fixed frames (move 0) -> (n, 2) whose consecutive moves differ by at most
    ``step`` m: forward and backward passes, each pulling a move to within ``step`` of its neighbour."""
    d = np.array(d, dtype=np.float64, copy=True)

    def pull(t: int, ref: np.ndarray) -> None:
        gap = d[t] - ref
        n = np.linalg.norm(gap)
        if n > step:
            d[t] = ref + gap * (step / n)

    for _ in range(passes):
        for t in range(len(d)):
            pull(t, d[t - 1] if t else np.zeros(2))
        for t in range(len(d) - 2, -1, -1):
            pull(t, d[t + 1])
    return d
