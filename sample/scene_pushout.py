"""Post-episode push-out: the new frames' body moved out of the scene by a smooth root offset.

The penetration guidance (``sample.penetration_guidance``) is a soft term of the denoising: the
sampled body still brushes furniture (a walk past a chair, knees into a stool while sitting down).
After each episode every new frame t gets an offset delta_t (m, world, added to all 24 joints: a
rigid translation, bone lengths unchanged) minimising

    sum_t sum_j relu(r_j + margin - sdf(x_tj + delta_t))^2 + weight * sum_t |delta_t|^2
        + velocity * sum_t |delta_t - delta_t-1|^2 + acceleration * sum_t |second difference|^2,

the scene term of the guidance (sum of squared depths, Huang et al. 2023 Eq. 10) plus a pull to
no change and to a slow, smooth offset. delta is a uniform cubic B-spline over the frames (knots every ``knot`` frames) whose
basis functions that do not vanish at the last context frame are dropped, so delta, its velocity
and its acceleration are 0 there: the context stays and the seam gets no jump. r_j: the body's
contact radius (``trumans.contacts.rule.JOINT_RADIUS``) for the seat joints (pelvis, hips: the
training data rests their skin on seats) and its core radius elsewhere; sdf: a scene field as the
guidance's, floor excluded (feet are the foot cleanup's, which runs after this and keeps planted
feet where they landed); the rollout gives it the dynamic objects (chairs, stools: most of the
walk-past penetration) at their scene poses until the plan moves one. Solved with a few Adam steps on the spline coefficients.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.interpolate import BSpline

from trumans.contacts.rule import JOINT_CORE_RADIUS, JOINT_RADIUS
from trumans.skeleton import SEAT

from .penetration_guidance import SceneSDF

__all__ = ["PushOutConfig", "push_radii", "seam_spline_basis", "push_out"]


@dataclass(frozen=True)
class PushOutConfig:
    """knot: frames between spline knots; iters / lr: Adam steps and step size (m); weight: the
    pull to no change against the squared depths; margin: m added to every radius (the field is
    sampled from voxels: half a voxel coarse); velocity / acceleration: weights of the offset's
    squared first / second differences (m per frame), so that it moves slowly and is nearly still
    at the episode's end (the next episode starts from it; without them the offset left episodes
    at up to 6 cm per frame and raised the seam jerk)."""

    knot: int = 4
    iters: int = 40
    lr: float = 0.01
    weight: float = 0.01
    margin: float = 0.01
    velocity: float = 3.0
    acceleration: float = 30.0

    def __post_init__(self) -> None:
        if self.knot < 1 or self.iters < 1:
            raise ValueError(f"knot and iters must be >= 1, got {self.knot}, {self.iters}")
        for name in ("lr", "weight", "margin", "velocity", "acceleration"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")


def push_radii(margin: float = 0.0) -> np.ndarray:
    """(24,) m: the contact radius for the seat joints, the core radius elsewhere, plus ``margin``."""
    r = JOINT_CORE_RADIUS.copy()
    r[list(SEAT)] = JOINT_RADIUS[list(SEAT)]
    return r + margin


def seam_spline_basis(n: int, knot: int) -> np.ndarray:
    """(n + 1, m) cubic B-spline basis at frames 0..n after a seam at frame 0 (knots every ``knot``
    frames); the first row (the seam) and its first two differences are zero."""
    t = knot * np.arange(-3, n // knot + 5, dtype=np.float64)
    D = BSpline.design_matrix(np.arange(n + 1, dtype=np.float64), t, 3).toarray()
    return D[:, 3:]  # basis functions 0..2 are the ones not C2-zero at the seam knot 0


def push_out(joints: np.ndarray, sdf: SceneSDF, fixed: int, config: PushOutConfig = PushOutConfig()) -> np.ndarray:
    """joints (B, T, 24, 3) world m -> copy with frames >= ``fixed`` translated out of the scene
    (module doc); frames < ``fixed`` are kept (the offset is 0 at frame ``fixed - 1``)."""
    J = np.asarray(joints)
    if J.ndim != 4 or J.shape[2:] != (24, 3):
        raise ValueError(f"joints must be (B, T, 24, 3), got {J.shape}")
    B, T = J.shape[:2]
    if not 0 <= fixed <= T:
        raise ValueError(f"fixed must be in [0, {T}] frames, got {fixed}")
    seam = max(fixed - 1, 0)
    n = T - 1 - seam
    if n < 1:
        return J.copy()
    basis = torch.as_tensor(seam_spline_basis(n, config.knot)[1:], dtype=torch.float32)  # (n, m)
    x = torch.as_tensor(J[:, seam + 1:], dtype=torch.float32)  # (B, n, 24, 3)
    r = torch.as_tensor(push_radii(config.margin), dtype=torch.float32)
    with torch.no_grad():
        if not (torch.relu(r - sdf(x)) > 0).any():
            return J.copy()
    coef = torch.zeros((B, basis.shape[1], 3), requires_grad=True)
    opt = torch.optim.Adam([coef], lr=config.lr)
    with torch.enable_grad():
        for _ in range(config.iters):
            delta = basis @ coef  # (B, n, 3)
            depth = torch.relu(r - sdf(x + delta[:, :, None]))
            d0 = torch.cat([torch.zeros_like(delta[:, :1]), delta], 1)  # the seam frame: 0
            vel, acc = d0[:, 1:] - d0[:, :-1], d0[:, 2:] - 2 * d0[:, 1:-1] + d0[:, :-2]
            loss = (depth ** 2).sum() + config.weight * (delta ** 2).sum() + config.velocity * (vel ** 2).sum() \
                + config.acceleration * (acc ** 2).sum()
            opt.zero_grad()
            loss.backward()
            opt.step()
    delta = (basis @ coef).detach().numpy().astype(np.float64)
    out = np.array(J, dtype=np.float64, copy=True)
    out[:, seam + 1:] += delta[:, :, None]
    return out.astype(J.dtype)
