"""The filter's regularisers (I'm-HOI §3.2, eqs. 7-13) on predicted and true frame vectors.

All take metric frame vectors (B, L, 235) (``trumans.refine.frame`` layout; positions in metres, in the
window's canonical frame) and return a scalar (mean over the batch). Norms are L1 as in the paper;
a sum over joints is a sum, a mean over time is a mean, exactly as each equation writes it.
"""
from __future__ import annotations

import torch

from trumans.rotations import sixd_to_matrix
from trumans.skeleton import NUM_JOINTS, forward_kinematics

from trumans.refine.frame import IMU_A, IMU_FLAG, IMU_R, JOINTS, OBJ_R, OBJ_T, ROTATIONS

__all__ = ["loss_off", "loss_vel", "loss_consist", "loss_imu", "loss_pose", "loss_residual", "ACC_FACTOR"]

# Eq. 13 writes the acceleration increment as a_t τ²/2. With a_t defined as a second difference over
# τ² (eq. 16), the exact trajectory satisfies (j_{t+1} - j_t) - (j_t - j_{t-1}) = a_t τ², so the
# paper's 1/2 would penalise the ground truth itself; we use the factor that makes it vanish there.
ACC_FACTOR = 1.0


def _joints(x: torch.Tensor) -> torch.Tensor:
    return x[..., JOINTS].reshape(*x.shape[:-1], NUM_JOINTS, 3)


def loss_off(x_hat: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Eq. 8: (1/T) Σ_t Σ_i ‖(ĵ_o,t − ĵ_h,t^i) − (j_o,t − j_h,t^i)‖₁: the object centre relative to
    every joint."""
    rel_hat = x_hat[..., None, OBJ_T] - _joints(x_hat)  # (B, L, 24, 3)
    rel = x[..., None, OBJ_T] - _joints(x)
    return (rel_hat - rel).abs().sum((-1, -2)).mean()


def loss_pose(x_hat: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """(1/T) Σ_t Σ_i ‖(ĵ_h,t^i − ĵ_h,t^0) − (j_h,t^i − j_h,t^0)‖₁: every joint relative to the pelvis
    (joint 0). Not in I'm-HOI: the simple loss on absolute joints is dominated by the tracker's
    whole-body drift, which no filter can see, so it hardly constrains the body's pose itself."""
    J_hat, J = _joints(x_hat), _joints(x)
    return ((J_hat - J_hat[..., :1, :]) - (J - J[..., :1, :])).abs().sum((-1, -2)).mean()


def loss_residual(x_hat: torch.Tensor, x: torch.Tensor, filled: torch.Tensor, sigma: float) -> torch.Tensor:
    """(1/T) Σ_t Σ_i ‖(ĵ + G_σ(f − ĵ))_t^i − j_t^i‖₁: the joints as the input-residual post-step
    (``trumans.refine.residual``) will return them, the filter's estimate ĵ plus the Gaussian
    low-pass (σ frames) of the filled tracked joints f minus it, against the truth. Not in I'm-HOI:
    it aims the network at what that step leaves to it (the high frequencies) instead of the slow
    error the step takes from the input anyway. filled: (B, L, 235) the condition's tracked frame
    vectors with gaps filled, metres, in the window's frame."""
    from trumans.refine.filter import smooth_time  # the network's own Gaussian (the filter module imports this one's users)

    J_hat, J, F = _joints(x_hat), _joints(x), _joints(filled)
    B, L = J_hat.shape[:2]
    low = smooth_time((F - J_hat).reshape(B, L, -1), sigma).reshape(B, L, NUM_JOINTS, 3)
    return ((J_hat + low) - J).abs().sum((-1, -2)).mean()


def loss_vel(x_hat: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Eq. 10: (1/(T−1)) Σ_{t≥1} ‖(ĵ_t − ĵ_{t−1}) − (j_t − j_{t−1})‖₁ with j = [j_h, j_o]."""
    def pts(v: torch.Tensor) -> torch.Tensor:
        return torch.cat([_joints(v), v[..., None, OBJ_T]], dim=-2)  # (B, L, 25, 3)

    d_hat, d = pts(x_hat).diff(dim=1), pts(x).diff(dim=1)
    return (d_hat - d).abs().sum((-1, -2)).mean()


def loss_consist(x_hat: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """Eq. 9: (1/T) Σ_t ‖ĵ_h,t − J(M(β, θ̂_h,t))‖₁: predicted joints against forward kinematics of
    the predicted rotations on our skeleton (``skeleton.forward_kinematics``), rooted at the
    predicted pelvis. offsets: (B, 24, 3) the subject's rest offsets (m) — our stand-in for β."""
    B, L = x_hat.shape[:2]
    rot = sixd_to_matrix(x_hat[..., ROTATIONS].reshape(B, L, NUM_JOINTS, 6))
    J_hat = _joints(x_hat)
    fk, _ = forward_kinematics(rot, J_hat[..., 0, :], offsets[:, None].expand(B, L, NUM_JOINTS, 3))
    return (J_hat - fk).abs().sum((-1, -2)).mean()


def loss_imu(x_hat: torch.Tensor, x: torch.Tensor, tracked: torch.Tensor, fps: float) -> torch.Tensor:
    """Eqs. 11-13: L_rot + (1/(T−1)) Σ_t L_acc,t on windows whose tracked input has an IMU.

    L_rot (eq. 12) = (1/T) Σ_t ‖θ̂_o,t − q_t‖₁ (measured IMU rotation q, 6D);
    L_acc,t (eq. 13) = ‖(ĵ_o,t − ĵ_o,t−1 + a_t τ² · ACC_FACTOR) − (j_o,t+1 − j_o,t)‖₁ (measured
    free acceleration a, τ = 1/fps, true next displacement). tracked: (B, L, 235) the condition's
    frame vectors (NaN-free where the IMU flag is 1)."""
    has = tracked[..., IMU_FLAG] > 0.5  # (B, L)
    w = has.to(x_hat.dtype)
    q = torch.nan_to_num(tracked[..., IMU_R])
    a = torch.nan_to_num(tracked[..., IMU_A])
    l_rot = ((x_hat[..., OBJ_R] - q).abs().sum(-1) * w).sum() / w.sum().clamp_min(1.0)
    tau = 1.0 / fps
    o_hat, o = x_hat[..., OBJ_T], x[..., OBJ_T]
    pred = o_hat[:, 1:-1] - o_hat[:, :-2] + a[:, 1:-1] * tau ** 2 * ACC_FACTOR  # t = 1 .. T-2
    target = o[:, 2:] - o[:, 1:-1]
    wa = w[:, 1:-1]
    l_acc = ((pred - target).abs().sum(-1) * wa).sum() / wa.sum().clamp_min(1.0)
    return l_rot + l_acc
