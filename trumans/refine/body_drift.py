"""The tracker's whole-body drift, estimated from planted feet (a post-step of the HOI filter).

A tracker's slow drift moves every joint alike, so a window of the filter (~2 s) cannot tell it
from the body's own motion. But a foot planted on the ground does not move: while it stands, what
the filtered foot does is the drift's change (plus noise). Chaining the stances of both feet gives
the drift's changes over the whole sequence, in the spirit of iReplica's contact-based trajectory
correction (§4.1, "Contact-based human trajectory correction": contacts with the static scene are
control points for a drifting trajectory); here the contacts are the feet's and the scene is not
needed. The drift's constant part (one offset for the whole sequence) stays unobservable.

On the filtered joints at the filter's rate:

- stances (``stance_mask``): frames where a foot joint (ankles, feet) moves slower than
  ``speed_m_s`` (speed smoothed over ``smooth_s``), in runs of at least ``min_stance_s``;
- drift (``estimate_body_drift``): a piecewise-linear curve d(t) (knots every ``knot_s``) fitted by
  least squares to the stance frames, each stance's own unknown position eliminated (the foot minus
  its stance mean = d minus its stance mean). With ``flat_floor`` (conventions: the floor is z = 0
  everywhere) a foot joint stands at one height in all its floor stances (those within
  ``floor_band_m`` of its lowest; a higher one is on a step or a bed and keeps its own), so for
  the vertical part only that one height is eliminated and stances far apart in time are tied
  together. A ridge prior (``ridge`` = (σ_noise / σ_drift)² per knot: no observation -> no correction) and a second-difference smoothness term
  (``smoothness``); iteratively reweighted (Huber-like, scale ``robust_m``, ``robust_iters`` passes)
  so that a foot that slides or rolls in a "stance" counts less;
- correction (``remove_body_drift``): every joint minus d(t). Rotations and the object are untouched.

Not in I'm-HOI (whose filter sees one window); measured in the README's filter section.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.ndimage import label, uniform_filter1d
from scipy.sparse import csr_matrix

from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS
from trumans.stance import planted

from trumans.refine.frame import FRAME_DIM, JOINTS

__all__ = ["DriftConfig", "stance_mask", "estimate_body_drift", "remove_body_drift"]



@dataclass(frozen=True)
class DriftConfig:
    """Speeds in m/s, durations in s, lengths in m (module doc). The defaults are the best of a grid
    on the dataset's val split (speed 0.15-0.25, knots 0.33-1 s, ridge 0.3-3, robust 1-2 cm; then
    floor_band 1-20 cm, flat from 5 to 12; README). flat_floor: the stances within ``floor_band_m``
    of a foot joint's lowest share one height (module doc). enabled: whether the post-step runs
    (``trumans.refine.post_steps``); as ``LockConfig.stance`` only the stance detection is read.
    min_rms_m: ``remove_body_drift`` leaves the body as it is when the fitted drift (its mean
    removed) is smaller than this rms (m): on clean real motion, whose planted feet roll and pivot,
    the fit reads 4-14 mm of drift that is not there (12 corpus train clips: 7.1 mm rms, max 19); a
    tracker's drift worth removing is larger (an inertial tracker's: decimetres). 0 = always."""

    enabled: bool = True
    speed_m_s: float = 0.2
    smooth_s: float = 0.17
    min_stance_s: float = 0.17
    knot_s: float = 0.5
    ridge: float = 1.0
    smoothness: float = 1.0
    robust_m: float = 0.01
    robust_iters: int = 3
    flat_floor: bool = True
    floor_band_m: float = 0.05
    min_rms_m: float = 0.05

    def __post_init__(self) -> None:
        for name in ("speed_m_s", "smooth_s", "knot_s", "ridge", "robust_m", "floor_band_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"drift {name} must be a positive number, got {v}")
        if not (np.isfinite(self.min_stance_s) and self.min_stance_s >= 0) or not self.smoothness >= 0:
            raise ValueError(f"drift min_stance_s and smoothness must be >= 0, got {self.min_stance_s}, {self.smoothness}")
        if not (np.isfinite(self.min_rms_m) and self.min_rms_m >= 0):
            raise ValueError(f"drift min_rms_m must be >= 0, got {self.min_rms_m}")
        if self.robust_iters < 0:
            raise ValueError(f"drift robust_iters must be >= 0, got {self.robust_iters}")


def _check(joints: np.ndarray, fps: float) -> np.ndarray:
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, {NUM_JOINTS}, 3), got {J.shape}")
    if not np.isfinite(J).all():
        raise ValueError("joints must be finite (fill missing frames first: the filter's output has none)")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    return J


def stance_mask(joints: np.ndarray, fps: float, cfg: DriftConfig = DriftConfig()) -> np.ndarray:
    """(T, 24, 3) joints (m) at ``fps`` -> (T, 4) bool: each foot joint of ``FOOT_JOINTS`` planted
    (``trumans.stance.planted`` on its smoothed 3-D speed alone, stances of ``min_stance_s`` or more)."""
    J = _check(joints, fps)
    if len(J) < 2:
        return np.zeros((len(J), len(FOOT_JOINTS)), bool)
    speed = np.linalg.norm(np.gradient(J[:, FOOT_JOINTS], axis=0), axis=-1) * fps
    speed = uniform_filter1d(speed, max(1, round(cfg.smooth_s * fps)), axis=0)
    return planted(speed, enter_speed=cfg.speed_m_s, min_frames=cfg.min_stance_s * fps)


def _design(T: int, fps: float, knot_s: float) -> csr_matrix:
    """(T, K) sparse piecewise-linear (degree-1 B-spline) basis with knots every ``knot_s`` from
    frame 0 (two non-zeros per row)."""
    step = max(knot_s * fps, 1.0)
    n = int(np.ceil((T - 1) / step - 1e-9)) + 1
    knots = np.linspace(0.0, (n - 1) * step, n) if n > 1 else np.array([0.0, 1.0])
    t = np.concatenate([[knots[0]], knots, [knots[-1]]])
    return BSpline.design_matrix(np.arange(T, dtype=np.float64), t, 1).tocsr()


def estimate_body_drift(joints: np.ndarray, fps: float, cfg: DriftConfig = DriftConfig()) -> np.ndarray:
    """(T, 24, 3) filtered joints (m) at ``fps`` -> (T, 3) the whole-body drift's change (m), zero
    where no stance observes it (the ridge prior) and zero-mean only where the stances say so."""
    J = _check(joints, fps)
    T = len(J)
    planted = stance_mask(J, fps, cfg)
    if not planted.any():
        return np.zeros((T, 3))
    B = _design(T, fps, cfg.knot_s)
    K = B.shape[1]
    runs, _ = label(planted.T, structure=[[0, 0, 0], [1, 1, 1], [0, 0, 0]])  # (4, T) stance ids, 0 = none
    j, t = np.nonzero(runs)
    foot = J[t, np.asarray(FOOT_JOINTS)[j]]  # (N, 3)
    stance = runs[j, t]
    # the unknown each observation is relative to: its stance's position, or on a flat floor, for
    # the height, its joint's one height over the whole sequence; a stance higher than the joint's
    # lowest by more than floor_band_m stands on something else (a step, a bed) and keeps its own
    height_group = stance
    if cfg.flat_floor:  # conventions: the floor is z = 0 everywhere
        level = np.zeros(stance.max() + 1)
        np.add.at(level, stance, foot[:, 2])
        level /= np.maximum(np.bincount(stance), 1)
        lowest = np.full(len(FOOT_JOINTS), np.inf)
        np.minimum.at(lowest, j, level[stance])
        on_floor = level[stance] <= lowest[j] + cfg.floor_band_m
        height_group = np.where(on_floor, stance.max() + 1 + j, stance)
    parts = ((slice(0, 2), stance), (slice(2, 3), height_group))
    Bt = B[t]  # (N, K) sparse: the basis at each observation
    N = len(t)

    # Each system is min |W^1/2 (A c - r)|^2 + prior, A = Bt - E M (Bt minus its group means, E the
    # (N, G) group indicator, M the (G, K) group means of Bt) and r the centred observations; A is
    # never formed: A^T W A = Bt^T W Bt - C M - M^T C^T + M^T diag(E^T w) M with C = Bt^T W E.
    def system(group: np.ndarray, y: np.ndarray) -> tuple[csr_matrix, np.ndarray, np.ndarray]:
        E = csr_matrix((np.ones(N), (np.arange(N), group)), shape=(N, group.max() + 1))
        count = np.maximum(np.asarray(E.sum(0)).ravel(), 1)
        M = (E.T @ Bt).toarray() / count[:, None]
        r = y - (np.asarray(E.T @ y) / count[:, None])[group]
        return E, M, r

    systems = [(group, *system(group, foot[:, ax])) for ax, group in parts]
    D2 = np.diff(np.eye(K), 2, axis=0)
    prior = cfg.ridge * np.eye(K) + cfg.smoothness * D2.T @ D2
    w = np.ones(N)
    for _ in range(cfg.robust_iters + 1):
        coef, res2 = [], 0.0
        BtW = Bt.T.multiply(w[None]).tocsr()  # (K, N)
        BWB = (BtW @ Bt).toarray()
        for group, E, M, r in systems:
            C = (BtW @ E).toarray()  # (K, G)
            ew = np.asarray(E.T @ w).ravel()
            AtWA = BWB - C @ M - M.T @ C.T + M.T @ (ew[:, None] * M)
            AtWr = BtW @ r - M.T @ np.asarray(E.T @ (w[:, None] * r))
            c = np.linalg.solve(AtWA + prior, AtWr)  # (K, D)
            coef.append(c)
            res2 = res2 + ((r - (Bt @ c - (M @ c)[group])) ** 2).sum(-1)
        w = np.minimum(1.0, cfg.robust_m / np.maximum(np.sqrt(res2), 1e-12))
    return B @ np.concatenate(coef, axis=1)


def remove_body_drift(frames: np.ndarray, fps: float, cfg: DriftConfig = DriftConfig()) -> np.ndarray:
    """Filtered frame vectors (T, 235) at ``fps`` -> the same with every joint position minus the
    drift of ``estimate_body_drift``, or unchanged when that drift's rms is under ``cfg.min_rms_m``."""
    f = np.asarray(frames, dtype=np.float32)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    J = f[:, JOINTS].reshape(len(f), NUM_JOINTS, 3)
    drift = estimate_body_drift(J, fps, cfg)
    if cfg.min_rms_m > 0 and np.sqrt(((drift - drift.mean(0)) ** 2).sum(-1).mean()) < cfg.min_rms_m:
        return f.copy()  # smaller than what real feet that roll and pivot read as drift: not trusted
    out = f.copy()
    out[:, JOINTS] = (J - drift[:, None].astype(np.float32)).reshape(len(f), -1)
    return out
