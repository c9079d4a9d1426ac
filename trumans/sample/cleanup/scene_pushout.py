"""Post-episode push-out: the new frames' body moved out of the scene by a smooth root offset.

The penetration guidance (``trumans.sample.guidance.penetration``) is a soft term of the denoising: the
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
walk-past penetration) at their scene poses until the plan moves one. Solved by Gauss-Newton on the
spline coefficients: each depth linearised along the field's gradient, each step halved until the
objective does not rise (a few milliseconds an episode; 40 Adam steps with autograd took ~20 ms).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.interpolate import BSpline

from trumans.sample.cleanup.common import episode_joints, push_radii
from trumans.scenes.sdf import SceneSDF

__all__ = ["PushOutConfig", "seam_spline_basis", "push_out"]


@dataclass(frozen=True)
class PushOutConfig:
    """enabled: run the push-out (it needs the scene); knot: frames between spline knots; iters:
    Gauss-Newton iterations at most (the active set settles in 3-5); weight: the
    pull to no change against the squared depths; margin: m added to every radius (the field is
    sampled from voxels: half a voxel coarse); velocity / acceleration: weights of the offset's
    squared first / second differences (m per frame), so that it moves slowly and is nearly still
    at the episode's end (the next episode starts from it; without them the offset left episodes
    at up to 6 cm per frame and raised the seam jerk); halvings: times a Gauss-Newton step is
    halved at most until the objective does not rise; tolerance: m, the largest coefficient change
    of a step below which the iterations stop (converged or stalled)."""

    enabled: bool = True
    knot: int = 4
    iters: int = 8
    weight: float = 0.01
    margin: float = 0.01
    velocity: float = 3.0
    acceleration: float = 30.0
    halvings: int = 6
    tolerance: float = 1e-4

    def __post_init__(self) -> None:
        if self.knot < 1 or self.iters < 1 or self.halvings < 0:
            raise ValueError(f"knot and iters must be >= 1 and halvings >= 0, got {self.knot}, {self.iters}, "
                             f"{self.halvings}")
        for name in ("weight", "margin", "velocity", "acceleration", "tolerance"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")


def seam_spline_basis(n: int, knot: int) -> np.ndarray:
    """(n + 1, m) cubic B-spline basis at frames 0..n after a seam at frame 0 (knots every ``knot``
    frames); the first row (the seam) and its first two differences are zero; no column is zero."""
    t = knot * np.arange(-3, n // knot + 5, dtype=np.float64)
    D = BSpline.design_matrix(np.arange(n + 1, dtype=np.float64), t, 3).toarray()[:, 3:]
    return D[:, np.abs(D).sum(0) > 0]  # basis functions 0..2 are the ones not C2-zero at the seam knot 0;
    # those whose support starts after frame n are dropped


def push_out(joints: np.ndarray, sdf: SceneSDF, fixed: int, config: PushOutConfig = PushOutConfig()) -> np.ndarray:
    """joints (B, T, 24, 3) world m -> copy with frames >= ``fixed`` translated out of the scene
    (module doc); frames < ``fixed`` are kept (the offset is 0 at frame ``fixed - 1``)."""
    J = np.asarray(joints)
    episode_joints(J, fixed)
    B, T = J.shape[:2]
    seam = max(fixed - 1, 0)
    n = T - 1 - seam
    if n < 1:
        return J.copy()
    basis = seam_spline_basis(n, config.knot)[1:]  # (n, m)
    x = torch.as_tensor(J[:, seam + 1:], dtype=torch.float32)  # (B, n, 24, 3)
    r = torch.as_tensor(push_radii(config.margin), dtype=torch.float32)
    if not (torch.relu(r - sdf(x)) > 0).any():
        return J.copy()
    coef = _gauss_newton(x, sdf, r.numpy().astype(np.float64), basis, config, config.halvings)
    delta = np.einsum("nm,bmc->bnc", basis, coef)
    out = np.array(J, dtype=np.float64, copy=True)
    out[:, seam + 1:] += delta[:, :, None]
    return out.astype(J.dtype)


def _smoothness_hessian(basis: np.ndarray, config: PushOutConfig) -> np.ndarray:
    """(m, m) Hessian of the pull to no change plus the offset's squared first and second
    differences (the seam frame's offset is 0) in the spline coefficients of one coordinate."""
    n = basis.shape[0]
    B0 = np.vstack([np.zeros((1, basis.shape[1])), basis])  # the seam frame first
    D1, D2 = np.diff(np.eye(n + 1), 1, axis=0) @ B0, np.diff(np.eye(n + 1), 2, axis=0) @ B0
    return 2.0 * (config.weight * basis.T @ basis + config.velocity * D1.T @ D1 + config.acceleration * D2.T @ D2)


def _depths(x: torch.Tensor, sdf: SceneSDF, r: np.ndarray, basis: np.ndarray, coef: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For joints x (B, n, 24, 3) moved by the spline ``coef`` (B, m, 3): (offset (B, n, 3) m,
    depth r - sdf (B, n, 24) m, the field's gradient (B, n, 24, 3))."""
    delta = np.einsum("nm,bmc->bnc", basis, coef)
    d, g = sdf.value_and_gradient(x + torch.as_tensor(delta[:, :, None], dtype=torch.float32))
    return delta, r - d.numpy().astype(np.float64), g.numpy().astype(np.float64)


def _objective(depth: np.ndarray, coef: np.ndarray, H_reg: np.ndarray) -> np.ndarray:
    """(B,) the module doc's objective: squared positive depths (B, n, 24) plus the quadratic
    smoothness terms 0.5 c^T H_reg c of the coefficients (B, m, 3)."""
    c = coef.reshape(len(coef), -1)
    return (np.maximum(depth, 0.0) ** 2).sum((1, 2)) + 0.5 * np.einsum("bi,ij,bj->b", c, H_reg, c)


def _gauss_newton(x: torch.Tensor, sdf: SceneSDF, r: np.ndarray, basis: np.ndarray,
                  config: PushOutConfig, halvings: int = 6) -> np.ndarray:
    """Spline coefficients (B, m, 3) minimising the module doc's objective for joints x (B, n, 24, 3):
    Gauss-Newton on the depths (each linearised along the field's gradient, active where positive;
    the smoothness terms are quadratic), ``config.iters`` iterations at most, each step halved up to
    ``halvings`` times until the objective does not rise. Without that check the active set can
    ping-pong: a step that pushes every joint out leaves none active, the next step (smoothness
    only) pulls the body back in, and the iterations alternate between the two."""
    B, n = x.shape[:2]
    m = basis.shape[1]
    H_reg = np.kron(_smoothness_hessian(basis, config), np.eye(3))  # (3m, 3m), index (spline, axis)
    Bt = np.repeat(basis, 24, axis=0)  # (n * 24, m): the basis row of each point's frame
    coef = np.zeros((B, m, 3))
    delta, depth, g = _depths(x, sdf, r, basis, coef)
    cost = _objective(depth, coef, H_reg)
    for _ in range(config.iters):
        active = (depth > 0).reshape(B, -1).astype(np.float64)  # (B, N)
        if not active.any():
            break
        gf = g.reshape(B, -1, 3)  # (B, N, 3)
        # residual of point i: depth_i - g_i . (delta_t - delta0_t), linear in coef through Bt
        a = np.einsum("nm,bnc->bnmc", Bt, gf).reshape(B, -1, 3 * m)  # (B, N, 3m)
        target = depth.reshape(B, -1) + np.einsum("bnc,bnc->bn", gf, np.repeat(delta, 24, axis=1))
        H = 2.0 * np.einsum("bn,bni,bnj->bij", active, a, a) + H_reg
        rhs = 2.0 * np.einsum("bn,bni,bn->bi", active, a, target)
        step = np.linalg.solve(H, rhs[..., None])[..., 0].reshape(B, m, 3) - coef
        scale = np.ones(B)
        for _ in range(halvings + 1):  # backtracking: the largest step 2^-i that does not raise the objective
            trial = coef + scale[:, None, None] * step
            t_delta, t_depth, t_g = _depths(x, sdf, r, basis, trial)
            t_cost = _objective(t_depth, trial, H_reg)
            ok = t_cost <= cost + 1e-12
            if ok.all():
                break
            scale = np.where(ok, scale, 0.5 * scale)
        ok = t_cost <= cost + 1e-12  # rows still rising after the halvings keep their coefficients
        coef = np.where(ok[:, None, None], trial, coef)
        delta = np.where(ok[:, None, None], t_delta, delta)
        depth = np.where(ok[:, None, None], t_depth, depth)
        g = np.where(ok[:, None, None, None], t_g, g)
        cost = np.where(ok, t_cost, cost)
        if (np.abs(step) * (scale * ok)[:, None, None]).max() < config.tolerance:  # m: converged (or stalled)
            break
    return coef
