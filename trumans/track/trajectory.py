"""Root-trajectory correction by bending energy (iReplica §4.1 eqs. 1-2, supp. §11).

The trajectory is a 2D curve on the floor (the gravity axis is fixed by the ground). The new
curve keeps every step's length (body-worn sensors measure distance well; curvature drifts) and
rotates step k by an angle ``delta_k``, so its heading is ``alpha_hat_k = alpha_k + delta_k`` and
its turning angle between steps k and k+1 deviates from the original by ``delta_{k+1} - delta_k``.
Eq. 1's energy of the heading-rate deviation is discretised (and squared, so that it has a
minimum) as ``E_tr = fps * sum_k (delta_{k+1} - delta_k)^2`` (rad^2/s), and eq. 2 becomes

    min_{delta, t0}  sum_i |l_hat(tau_i) - p_i|^2  +  rigidity * E_tr  +  heading_weight * mean_k delta_k^2,

with ``l_hat_k = l_0 + t0 + sum_{j<k} R(delta_j) (l_{j+1} - l_j)``. ``t0`` (a translation of the
start) is free when ``free_start`` (the start is only as well localised as the rest; with one
control point the whole path then translates rigidly), else 0. The last term (not in the paper)
is a tiny preference for small rotations that makes the minimum unique (a global rotation has no
bending energy). Solved with L-BFGS on all steps at once (torch, float64).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

__all__ = ["TrajectoryConfig", "turning_angles", "bending_energy", "rebuild_path", "correct_trajectory"]


@dataclass(frozen=True)
class TrajectoryConfig:
    """rigidity: lambda of eq. 2 (m^2 s / rad^2; larger keeps the local curvature, smaller lets the
    path bend to the control points); free_start: the start may translate; heading_weight (m^2):
    regulariser on the step rotations; iterations: L-BFGS iterations."""

    rigidity: float = 1.0
    free_start: bool = True
    heading_weight: float = 1e-3
    iterations: int = 100

    def __post_init__(self) -> None:
        if not self.rigidity >= 0 or not self.heading_weight >= 0:
            raise ValueError(f"rigidity and heading_weight must be >= 0, got {self.rigidity}, {self.heading_weight}")
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")


def turning_angles(path: np.ndarray) -> np.ndarray:
    """Signed turning angle (rad, atan2 of cross and dot) between consecutive steps of a 2D path
    (T, 2) -> (T - 2,); 0 where a step has zero length."""
    p = np.asarray(path, dtype=np.float64)
    d = np.diff(p, axis=0)
    a, b = d[:-1], d[1:]
    return np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(-1))


def bending_energy(delta: torch.Tensor, fps: float) -> torch.Tensor:
    """Discretised eq. 1 (squared): fps * sum_k (delta_{k+1} - delta_k)^2 for step rotations
    delta (T - 1,) rad."""
    return fps * (delta[1:] - delta[:-1]).pow(2).sum()


def rebuild_path(path0: torch.Tensor, steps: torch.Tensor, delta: torch.Tensor, t0: torch.Tensor) -> torch.Tensor:
    """l_hat (T, 2) from the start point (2,), the original steps (T-1, 2), the step rotations
    delta (T-1,) and the start translation t0 (2,)."""
    c, s = torch.cos(delta), torch.sin(delta)
    rot = torch.stack([c * steps[:, 0] - s * steps[:, 1], s * steps[:, 0] + c * steps[:, 1]], dim=-1)
    start = (path0 + t0)[None]
    return torch.cat([start, start + torch.cumsum(rot, dim=0)], dim=0)


def correct_trajectory(
    path: np.ndarray,
    times: np.ndarray,
    points: np.ndarray,
    fps: float,
    config: TrajectoryConfig = TrajectoryConfig(),
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Bend a 2D root path towards control points (module doc, eq. 2).

    path: (T, 2) m, floor plane; times: (K,) frame indices of the control points; points: (K, 2)
    m, where the path should be at those frames; weights: optional (K,) >= 0 per control point.
    Returns the corrected path (T, 2) float64 (the input when K = 0)."""
    p = np.asarray(path, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 1:
        raise ValueError(f"path must be (T, 2) with T >= 1, got {p.shape}")
    times = np.asarray(times)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2) if np.size(points) else np.zeros((0, 2))
    if times.ndim != 1 or len(times) != len(pts):
        raise ValueError(f"times must be (K,) matching points (K, 2), got {times.shape} and {np.shape(points)}")
    if len(times) and (not np.issubdtype(times.dtype, np.integer) or times.min() < 0 or times.max() >= len(p)):
        raise ValueError(f"times must be integer frame indices in [0, {len(p) - 1}], got {times}")
    if not (np.isfinite(p).all() and np.isfinite(pts).all()):
        raise ValueError("path and points must be finite")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    w = np.ones(len(pts)) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (len(pts),) or (w < 0).any():
        raise ValueError(f"weights must be (K,) >= 0, got {np.shape(weights)}")
    if len(pts) == 0:
        return p.copy()
    if len(p) == 1 or (config.free_start and len(pts) == 1):
        # one control point with a free start (or a single frame): the optimum is a pure translation
        return p + (pts[0] - p[times[0]])

    path_t = torch.from_numpy(p)
    steps = path_t[1:] - path_t[:-1]
    idx = torch.from_numpy(times.astype(np.int64))
    target, wt = torch.from_numpy(pts), torch.from_numpy(w)
    delta = torch.zeros(len(p) - 1, dtype=torch.float64, requires_grad=True)
    t0 = torch.zeros(2, dtype=torch.float64, requires_grad=config.free_start)
    params = [delta, t0] if config.free_start else [delta]
    opt = torch.optim.LBFGS(params, lr=1.0, max_iter=config.iterations, line_search_fn="strong_wolfe",
                            tolerance_grad=1e-12, tolerance_change=1e-15, history_size=20)

    def closure() -> torch.Tensor:
        opt.zero_grad()
        new = rebuild_path(path_t[0], steps, delta, t0)
        loss = (wt * (new[idx] - target).pow(2).sum(-1)).sum()
        loss = loss + config.rigidity * bending_energy(delta, fps) + config.heading_weight * delta.pow(2).mean()
        loss.backward()
        return loss

    opt.step(closure)
    with torch.no_grad():
        return rebuild_path(path_t[0], steps, delta, t0).numpy()
