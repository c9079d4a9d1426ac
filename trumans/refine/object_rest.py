"""Objects at rest: one pose per rest, pooled over the whole rest (a post-step of the HOI filter).

An object moves only while a hand drives it and otherwise stays where it is (iReplica §4.3). A
window of the filter (~2 s) cannot tell a tracker's slow drift (knots every second or so) from a
slow move, but over a whole rest the drift averages out. So, on the filtered sequence at the
filter's rate:

- detection (``rest_mask``): the filtered object's speed, smoothed over ``smooth_s``, with
  hysteresis: a frame moves when it lies in a run above ``lo_m_s`` that reaches ``hi_m_s``; moving
  runs are padded by ``pad_s``; rests shorter than ``min_rest_s`` count as moving;
- pooling (``pool_rest``): each rest's translation becomes the mean of the tracked translations
  observed in it, and its rotation the chordal mean of the tracked rotations observed in it that lie
  within ``max_rot_deg`` of the filtered rotations' mean (flips left out; that mean itself where
  fewer than 3 remain). Tracked rather than filtered rotations: the filter leans on the object IMU,
  whose constant bias (~3°) no pooling removes;
- hands (``hand_link``, iReplica §4.3: a moved object is driven by a hand): a move during which one
  wrist keeps its place in the object's frame (the std of R(t)ᵀ(wrist(t) − p(t)) over the move, on the
  filtered sequence, under ``rigid_tol_m``) is a grasp with an unknown offset o in the object's frame,
  p(t) = wrist(t) − R(t) o. The rests' positions and the grasps' offsets are then one least-squares
  problem: every observed tracked translation of a rest measures its position, every one of a move
  measures wrist(t) − R(t) o, the wrist at the move's first and last frame ties the offset to the
  rests on either side (``link_weight``, in frames), and the filtered path is a weak prior for the
  offset (``prior_weight`` per frame). So the tracker's drift is averaged over every rest the hand
  links, not over one; the move itself follows the wrist (body drift removed first:
  ``trumans.refine.body_drift``), plus what the rests leave at its ends, faded out over ``fade_s``
  (no jump). The other moving frames keep their filtered motion, shifted by the translation change
  interpolated linearly between the neighbouring rests (held at the ends), so the path stays
  continuous. Where a move meets a pooled rest, the rest's rotation correction (R_rest R_filteredᵀ at
  the seam) is faded out over ``fade_s`` into the move, so the rotation does not step there either
  (the rest of the move keeps the filtered rotation: carrying the correction across the whole move
  raised the test error, 1.0 -> 1.1-1.5°).

Not in I'm-HOI (whose filter sees one window); measured in the README's filter section.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation, label, uniform_filter1d
from scipy.spatial.transform import Rotation

from trumans.intervals import runs
from trumans.rotations import matrix_to_6d, sixd_to_matrix

from trumans.skeleton import NUM_JOINTS, WRISTS

from trumans.refine.frame import FRAME_DIM, JOINTS, OBJ_R, OBJ_T

__all__ = ["RestConfig", "rest_mask", "held_mask", "pool_rest"]

_WRISTS = list(WRISTS)


@dataclass(frozen=True)
class RestConfig:
    """Speeds in m/s, durations in s, lengths in m, weights in frames (module doc). The detection
    defaults are the best of a grid on the dataset's val split (lo 0.1-0.2, hi 0.25-0.4, smooth
    0.15-0.5 s, pad 0-0.2 s); the hand link's too (rigid_tol 0.03-0.1 m, link weight 3-100, prior
    weight 0.05-1, fade 0.03-1 s; README). fade_s: what the rests leave at a driven move's ends is
    faded out over this long inside the move. held_*: the held-move test (``held_mask``): half its
    window, and how far the wrist must move within the window (best of a grid on val: window
    0.33-1.33 s, move 0.03-0.12 m). enabled: whether the post-step runs (``trumans.refine.post_steps``)."""

    enabled: bool = True
    lo_m_s: float = 0.2
    hi_m_s: float = 0.25
    smooth_s: float = 0.3
    pad_s: float = 0.0
    min_rest_s: float = 0.33
    max_rot_deg: float = 45.0
    hand_link: bool = True
    rigid_tol_m: float = 0.05
    link_weight: float = 30.0
    prior_weight: float = 0.05
    fade_s: float = 0.2
    held_window_s: float = 0.67
    held_min_move_m: float = 0.05

    def __post_init__(self) -> None:
        if not 0 < self.lo_m_s <= self.hi_m_s:
            raise ValueError(f"need 0 < lo_m_s <= hi_m_s, got {self.lo_m_s}, {self.hi_m_s}")
        if not 0 < self.max_rot_deg <= 180:
            raise ValueError(f"max_rot_deg must be in (0, 180], got {self.max_rot_deg}")
        if min(self.smooth_s, self.pad_s, self.min_rest_s) < 0:
            raise ValueError(f"smooth_s, pad_s and min_rest_s must be >= 0, got {self.smooth_s}, {self.pad_s}, "
                             f"{self.min_rest_s}")
        if min(self.held_window_s, self.held_min_move_m) < 0:
            raise ValueError(f"held_window_s and held_min_move_m must be >= 0, got {self.held_window_s}, "
                             f"{self.held_min_move_m}")
        if min(self.rigid_tol_m, self.link_weight, self.fade_s) < 0 or not self.prior_weight > 0:
            raise ValueError(f"need rigid_tol_m, link_weight, fade_s >= 0 and prior_weight > 0, got {self.rigid_tol_m}, "
                             f"{self.link_weight}, {self.fade_s}, {self.prior_weight}")


def rest_mask(obj_t: np.ndarray, fps: float, config: RestConfig = RestConfig()) -> np.ndarray:
    """obj_t: (T, 3) filtered object translations (m, finite) at ``fps`` -> (T,) bool, True where
    the object is at rest (module doc)."""
    p = np.asarray(obj_t, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
        raise ValueError(f"object translations must be (T, 3) with T >= 2, got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("object translations must be finite (fill or drop missing frames first)")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    v = np.gradient(p, axis=0) * fps
    k = max(1, int(round(config.smooth_s * fps)))
    speed = np.linalg.norm(uniform_filter1d(v, k, axis=0, mode="nearest"), axis=-1)
    lab, _ = label(speed > config.lo_m_s)
    fast = np.unique(lab[speed > config.hi_m_s])
    moving = np.isin(lab, fast[fast > 0])
    pad = int(round(config.pad_s * fps))
    if pad and moving.any():
        moving = binary_dilation(moving, iterations=pad)
    return _long_runs(~moving, config.min_rest_s * fps)


def _long_runs(mask: np.ndarray, min_frames: float) -> np.ndarray:
    """(T,) bool: the runs of True in ``mask`` at least ``min_frames`` long."""
    out = np.zeros(len(mask), dtype=bool)
    for a, b in runs(mask, min_len=max(1, int(np.ceil(min_frames)))):
        out[a:b] = True
    return out


def _window_variance(x: np.ndarray, ok: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """x: (T, 3), ok: (T,) bool -> (variance summed over the axes, count) of the ok rows in each
    frame's window [t - half, t + half] (clipped at the ends): (T,), (T,)."""
    size = 2 * half + 1
    box = lambda a: uniform_filter1d(a, size, axis=0, mode="constant") * size  # noqa: E731  (window sums)
    w = ok.astype(np.float64)
    xs = np.where(ok[:, None], x, 0.0)
    n = box(w)
    mean = box(xs) / np.maximum(n, 1)[:, None]
    return box((xs ** 2).sum(-1)) / np.maximum(n, 1) - (mean ** 2).sum(-1), n


def held_mask(tracked_t: np.ndarray, rotations: np.ndarray, wrists: np.ndarray, fps: float,
              config: RestConfig = RestConfig()) -> np.ndarray:
    """Frames where the tracked object moves with a wrist (module doc), whatever its speed.

    tracked_t: (T, 3) tracked object translations (m, NaN = missing); rotations: (T, 3, 3) the
    filtered object rotations; wrists: (T, W, 3) the filtered wrists -> (T,) bool. In each frame's
    window (± ``held_window_s``) the two hypotheses have three parameters each: the object stays at
    one point (residual = the variance of its tracked translations), or it follows a wrist at one
    offset o in its own frame, p = wrist − R o (residual = the variance of Rᵀ(wrist − p)). A frame
    is held where some wrist's residual is below the still one's and that wrist moves at least
    ``held_min_move_m`` (bounding-box diagonal) within the window; at least 6 observed frames."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    y = np.asarray(tracked_t, dtype=np.float64)
    T = len(y)
    rotations, wrists = np.asarray(rotations, dtype=np.float64), np.asarray(wrists, dtype=np.float64)
    if y.ndim != 2 or y.shape[1] != 3 or rotations.shape != (T, 3, 3) or wrists.ndim != 3 or wrists.shape[0] != T \
            or wrists.shape[2] != 3:
        raise ValueError(f"need tracked_t (T, 3), rotations (T, 3, 3) and wrists (T, W, 3), got {y.shape}, "
                         f"{rotations.shape}, {wrists.shape}")
    if not (np.isfinite(rotations).all() and np.isfinite(wrists).all()):
        raise ValueError("rotations and wrists must be finite (the filter's output); only tracked_t may have NaN")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    half = max(1, int(round(config.held_window_s * fps)))
    ok = np.isfinite(y).all(-1)
    still, n = _window_variance(y, ok, half)
    best = np.full(T, -np.inf)
    moved = np.zeros(T)
    for h in range(wrists.shape[1]):  # two wrists; frames and windows are vectorised
        q = np.einsum("tji,tj->ti", rotations, wrists[:, h] - np.where(ok[:, None], y, 0.0))
        held, _ = _window_variance(q, ok, half)
        size = 2 * half + 1
        box = maximum_filter1d(wrists[:, h], size, axis=0, mode="nearest") - minimum_filter1d(wrists[:, h], size, axis=0, mode="nearest")
        score = still - held
        better = score > best
        best = np.where(better, score, best)
        moved = np.where(better, np.linalg.norm(box, axis=-1), moved)
    return (n >= 6) & (best > 0) & (moved >= config.held_min_move_m)


def _rest_rotation(filtered6: np.ndarray, tracked6: np.ndarray, max_deg: float) -> np.ndarray:
    """One rest's rotation (6,) from its filtered (N, 6) and tracked (N, 6, NaN = missing)
    rotations: the chordal mean (scipy's ``Rotation.mean``) of the tracked ones within ``max_deg``
    of the filtered ones' mean, else that mean."""
    ref = Rotation.from_matrix(sixd_to_matrix(filtered6)).mean()
    seen = tracked6[np.isfinite(tracked6).all(-1)]
    if len(seen) >= 3:
        rots = Rotation.from_matrix(sixd_to_matrix(seen))
        near = (rots * ref.inv()).magnitude() <= np.radians(max_deg)
        if near.sum() >= 3:
            ref = rots[near].mean()
    return matrix_to_6d(ref.as_matrix())


def _join_rotations(out: np.ndarray, filtered6: np.ndarray, pooled: np.ndarray, fade: float) -> None:
    """In place on ``out`` (T, 235): where a run of frames outside ``pooled`` (T,) bool meets a pooled
    frame, the correction R_pooled R_filteredᵀ there is faded out over ``fade`` frames into the run
    (its rotation vector scaled down linearly), so the rotation does not step at the seam.
    filtered6: (T, 6) the filter's rotations."""
    if not pooled.any():
        return
    T = len(out)
    for s, e in runs(~pooled):
        k = np.arange(s, e)
        turn = Rotation.identity(e - s)
        for t, w in ((s - 1, 1 - (k - s + 1) / fade), (e, 1 - (e - k) / fade)):
            if 0 <= t < T:
                fix = Rotation.from_matrix(sixd_to_matrix(out[t, OBJ_R])) * Rotation.from_matrix(sixd_to_matrix(filtered6[t])).inv()
                turn = Rotation.from_rotvec(np.clip(w, 0, 1)[:, None] * fix.as_rotvec()[None]) * turn
        out[s:e, OBJ_R] = matrix_to_6d((turn * Rotation.from_matrix(sixd_to_matrix(filtered6[s:e]))).as_matrix())


def _grasping_wrist(P: np.ndarray, R: np.ndarray, joints: np.ndarray, a: int, b: int, tol: float) -> int | None:
    """The wrist (joint index) that keeps its place in the object's frame over frames [a, b) within
    ``tol`` m (std of R(t)ᵀ(wrist(t) − p(t)), summed over axes in quadrature), the steadier of the
    two; None if neither does. P: (T, 3), R: (T, 3, 3), joints: (T, 24, 3)."""
    rel = np.einsum("tji,thj->hti", R[a:b], joints[a:b][:, _WRISTS] - P[a:b, None])  # (2, n, 3) in the object's frame
    spread = np.linalg.norm(rel.std(axis=1), axis=-1)
    h = int(np.argmin(spread))
    return _WRISTS[h] if spread[h] <= tol else None


def _solve_positions(P: np.ndarray, R: np.ndarray, joints: np.ndarray, tr: np.ndarray, seen: np.ndarray,
                     rests: list[tuple[int, int]], moves: list[tuple[int, int, int]], config: RestConfig) -> np.ndarray:
    """Least squares (module doc) for the rests' positions and the grasps' offsets: (len(rests) +
    len(moves), 3). moves: (first, end, wrist) of each rigid move; rests: [a, b) with >= 3 observed
    frames. Normal equations, assembled block by block (every R(t) is orthonormal, so RᵀR = I)."""
    K = len(rests)
    n = K + len(moves)
    if n == 0:
        return np.zeros((0, 3))
    A = np.zeros((n, 3, n, 3))
    y = np.zeros((n, 3))
    eye = np.eye(3)
    for k, (a, b) in enumerate(rests):
        ok = seen[a:b]
        A[k, :, k, :] += ok.sum() * eye
        y[k] += tr[a:b][ok].sum(0)
    rest_at = {t: k for k, (a, b) in enumerate(rests) for t in (a, b - 1)}
    for m, (s, e, w) in enumerate(moves):
        i = K + m
        ok = seen[s:e]
        Rm = R[s:e]
        A[i, :, i, :] += (ok.sum() + config.prior_weight * (e - s)) * eye
        y[i] += np.einsum("tji,tj->i", Rm[ok], joints[s:e, w][ok] - tr[s:e][ok])
        y[i] += config.prior_weight * np.einsum("tji,tj->i", Rm, joints[s:e, w] - P[s:e])
        for t in (s - 1, e):  # the rests on either side: p_k + R(t) o = wrist(t)
            k = rest_at.get(t)
            if k is None:
                continue
            c = config.link_weight
            A[k, :, k, :] += c * eye
            A[i, :, i, :] += c * eye
            A[k, :, i, :] += c * R[t]
            A[i, :, k, :] += c * R[t].T
            y[k] += c * joints[t, w]
            y[i] += c * R[t].T @ joints[t, w]
    return np.linalg.solve(A.reshape(3 * n, 3 * n), y.reshape(-1)).reshape(n, 3)


def pool_rest(filtered: np.ndarray, tracked: np.ndarray, fps: float,
              config: RestConfig = RestConfig()) -> np.ndarray:
    """filtered: (T, 235) the filter's output (body drift already removed), tracked: (T, 235) its
    input on the same frames (NaN = missing) -> (T, 235) a copy with one object pose per rest and,
    with ``config.hand_link``, moves driven by a grasping wrist (module doc). Rests with fewer than 3
    observed tracked translations are left as filtered; so is a sequence without an observed object."""
    out = np.array(filtered, dtype=np.float64, copy=True)
    tr = np.asarray(tracked, dtype=np.float64)
    if out.ndim != 2 or out.shape[1] != FRAME_DIM or tr.shape != out.shape:
        raise ValueError(f"filtered and tracked must both be (T, {FRAME_DIM}), got {out.shape} and {tr.shape}")
    if len(out) < 2 or not np.isfinite(out[:, OBJ_T]).all() or not np.isfinite(tr[:, OBJ_T]).any():
        return out.astype(filtered.dtype)
    T = len(out)
    P = out[:, OBJ_T].copy()
    trp = tr[:, OBJ_T]
    seen = np.isfinite(trp).all(-1)
    rest = rest_mask(P, fps, config)
    pooled = np.zeros(T, dtype=bool)
    for a, b in runs(rest):  # rotations: one per rest as the speed sees it (slow moves hardly turn)
        if seen[a:b].sum() >= 3:
            out[a:b, OBJ_R] = _rest_rotation(out[a:b, OBJ_R], tr[a:b, OBJ_R], config.max_rot_deg)[None]
            pooled[a:b] = True
    _join_rotations(out, np.asarray(filtered, dtype=np.float64)[:, OBJ_R], pooled, max(1.0, config.fade_s * fps))
    R = sixd_to_matrix(out[:, OBJ_R])
    joints = out[:, JOINTS].reshape(T, NUM_JOINTS, 3)
    link = config.hand_link and np.isfinite(joints[:, _WRISTS]).all()
    if link:  # slow moves the speed misses, seen as the tracked object following a wrist
        held = held_mask(trp, sixd_to_matrix(np.asarray(filtered, np.float64)[:, OBJ_R]), joints[:, _WRISTS], fps, config)
        rest = _long_runs(rest & ~held, config.min_rest_s * fps)
    rests = [(a, b) for a, b in runs(rest) if seen[a:b].sum() >= 3]
    moves = []
    if link:
        for s, e in runs(~rest):
            w = _grasping_wrist(P, R, joints, max(s - 1, 0), min(e + 1, T), config.rigid_tol_m)
            if w is not None:
                moves.append((s, e, w))
    x = _solve_positions(P, R, joints, np.nan_to_num(trp), seen, rests, moves, config)
    offset = np.full((T, 3), np.nan)
    for k, (a, b) in enumerate(rests):
        out[a:b, OBJ_T] = x[k]
        offset[a:b] = x[k] - P[a:b]
    have = np.isfinite(offset[:, 0])
    driven = np.zeros(T, dtype=bool)
    for m, (s, e, w) in enumerate(moves):
        a, b = max(s - 1, 0), min(e + 1, T)
        path = joints[a:b, w] - R[a:b] @ x[len(rests) + m]  # frames s-1 .. e: the wrist's path
        # what the rests on either side leave at the move's ends, spread linearly over it (no jump)
        gap = [out[t, OBJ_T] - path[t - a] if 0 <= t < T and have[t] else np.zeros(3) for t in (s - 1, e)]
        k = np.arange(s, e)[:, None]
        fade = max(1.0, config.fade_s * fps)
        out[s:e, OBJ_T] = (path[s - a:e - a] + np.clip(1 - (k - s + 1) / fade, 0, 1) * gap[0]
                           + np.clip(1 - (e - k) / fade, 0, 1) * gap[1])
        driven[s:e] = True
    free = ~have & ~driven
    if have.any() and free.any():
        t = np.arange(T)
        out[free, OBJ_T] = P[free] + np.stack([np.interp(t[free], t[have], offset[have, i]) for i in range(3)], -1)
    return out.astype(filtered.dtype)
