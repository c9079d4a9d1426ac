"""A linear minimum-mean-square-error (Wiener) estimate of clean joint positions from tracked ones:
the filter's skip for the joints (``trumans.refine.filter.FilterModel``; our addition, not I'm-HOI's).

For frame t the input is the tracked joints (gaps filled) of frames t-R .. t+R relative to the
tracked pelvis at t, K = (2R+1)·72 values u_t, and the estimate is ĵ_t = P_t + b + W u_t (P_t the
tracked pelvis repeated for every joint). W (K, 72) and b (72,) are fitted in closed form (ridge
regression) on corrupted training windows, so the estimate uses how the joints of one skeleton move
together, which a smoother working on each coordinate alone (Savitzky–Golay, a Gaussian) cannot:
on the default corruption it halves the root-aligned error a tuned Savitzky–Golay leaves.
Windows are padded by repeating their edge frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from trumans.skeleton import NUM_JOINTS

__all__ = ["JointWiener", "fit_joint_wiener", "neighbourhoods", "WIENER_RADIUS"]

WIENER_RADIUS = 8  # frames each side (at the filter's 30 fps: ±0.27 s)
_D = 3 * NUM_JOINTS


def neighbourhoods(joints: torch.Tensor, radius: int) -> tuple[torch.Tensor, torch.Tensor]:
    """joints (B, L, 72) m -> (u (B, L, (2R+1)·72): frames t-R .. t+R relative to the pelvis at t,
    edges repeated; P (B, L, 72): the pelvis at t repeated for every joint)."""
    if joints.dim() != 3 or joints.shape[-1] != _D:
        raise ValueError(f"joints must be (B, L, {_D}), got {tuple(joints.shape)}")
    B, L, _ = joints.shape
    padded = torch.nn.functional.pad(joints.transpose(1, 2), (radius, radius), mode="replicate").transpose(1, 2)
    u = padded.unfold(1, 2 * radius + 1, 1).permute(0, 1, 3, 2)  # (B, L, 2R+1, 72)
    P = joints[..., :3].repeat(1, 1, NUM_JOINTS)
    return (u - P[:, :, None]).reshape(B, L, -1), P


@dataclass
class JointWiener:
    """ĵ_t = P_t + b + W u_t (module docstring). radius R in frames; weight (K, 72), bias (72,) float32."""

    radius: int
    weight: torch.Tensor
    bias: torch.Tensor

    def __post_init__(self) -> None:
        K = (2 * self.radius + 1) * _D
        if self.radius < 0 or tuple(self.weight.shape) != (K, _D) or tuple(self.bias.shape) != (_D,):
            raise ValueError(f"a Wiener skip of radius {self.radius} needs weight ({K}, {_D}) and bias ({_D},), got "
                             f"{tuple(self.weight.shape)} / {tuple(self.bias.shape)}; the checkpoint is inconsistent")
        if not (torch.isfinite(self.weight).all() and torch.isfinite(self.bias).all()):
            raise ValueError("the Wiener skip's weights are not finite; the checkpoint is corrupt - retrain it")
        self.weight = self.weight.float()
        self.bias = self.bias.float()

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        """joints (B, L, 72) m, gaps filled -> estimated clean joints (B, L, 72) m.

        W u_t is summed offset by offset, (joints at t + k - P_t) W_k for k = -R .. R, into one
        (B·L, 72) accumulator: the same estimate as ``neighbourhoods(joints) @ W`` (to float32
        rounding, ~1e-6 m) without building the (B, L, (2R+1)·72) neighbourhoods (4x faster)."""
        if joints.dim() != 3 or joints.shape[-1] != _D:
            raise ValueError(f"joints must be (B, L, {_D}), got {tuple(joints.shape)}")
        B, L, _ = joints.shape
        R = self.radius
        padded = torch.cat([joints[:, :1].expand(B, R, _D), joints, joints[:, -1:].expand(B, R, _D)], dim=1)
        P = joints[..., :3].repeat(1, 1, NUM_JOINTS)
        W = self.weight.to(joints).view(2 * R + 1, _D, _D)  # row block k: the frame at offset k - R
        acc = (P + self.bias.to(joints)).reshape(B * L, _D)
        for k in range(2 * R + 1):
            acc.addmm_((padded[:, k:k + L] - P).reshape(B * L, _D), W[k])
        return acc.view(B, L, _D)

    def to_extra(self) -> dict:
        """Plain data for a checkpoint's ``extra`` (tensors and ints only)."""
        return {"radius": int(self.radius), "weight": self.weight.clone(), "bias": self.bias.clone()}

    @classmethod
    def from_extra(cls, d: dict) -> "JointWiener":
        if not isinstance(d, dict) or set(d) != {"radius", "weight", "bias"}:
            raise ValueError(f"extra['wiener'] must hold radius, weight and bias, got {d!r:.80}")
        return cls(int(d["radius"]), torch.as_tensor(d["weight"]), torch.as_tensor(d["bias"]))


def fit_joint_wiener(tracked: np.ndarray, clean: np.ndarray, radius: int = WIENER_RADIUS,
                     ridge: float = 1e-4) -> JointWiener:
    """Least squares with a ridge of ``ridge`` x samples on every frame with a full neighbourhood.
    tracked: (N, L, 72) m, gaps filled (finite); clean: (N, L, 72) m, same frame."""
    X = torch.as_tensor(np.asarray(tracked), dtype=torch.float64)
    Y = torch.as_tensor(np.asarray(clean), dtype=torch.float64)
    if X.shape != Y.shape or X.dim() != 3 or X.shape[-1] != _D:
        raise ValueError(f"tracked and clean must both be (N, L, {_D}), got {tuple(X.shape)} / {tuple(Y.shape)}")
    if X.shape[1] <= 2 * radius:
        raise ValueError(f"windows of {X.shape[1]} frames have no frame with a full ±{radius} neighbourhood")
    if not (torch.isfinite(X).all() and torch.isfinite(Y).all()):
        raise ValueError("fit_joint_wiener needs finite joints: fill the tracked gaps first (fill_missing)")
    u, P = neighbourhoods(X, radius)
    inner = slice(radius, X.shape[1] - radius)
    U = u[:, inner].reshape(-1, u.shape[-1])
    T = (Y - P)[:, inner].reshape(-1, _D)
    mu, mt = U.mean(0), T.mean(0)
    A = U - mu
    W = torch.linalg.solve(A.T @ A + ridge * len(A) * torch.eye(A.shape[1], dtype=A.dtype), A.T @ (T - mt))
    return JointWiener(radius, W.float(), (mt - mu @ W).float())
