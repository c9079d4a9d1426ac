"""Rotation conversions, numpy and torch.

Conventions (owned here, used everywhere):
- Rotation matrices act on column vectors: ``x_world = R @ x_local``.
- 6D representation (Zhou et al. 2019) = the first two *columns* of the matrix, concatenated:
  ``r6 = [R[:, 0], R[:, 1]]`` -> shape ``(..., 6)``. (pytorch3d keeps rows; we never do.)
- Quaternions are scalar-last ``(x, y, z, w)``, as scipy's ``Rotation``.
- Axis-angle is a rotation vector ``(..., 3)``: unit axis times angle in radians.
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

__all__ = [
    "matrix_to_6d",
    "sixd_to_matrix",
    "matrix_to_quat",
    "quat_to_matrix",
    "matrix_to_axis_angle",
    "axis_angle_to_matrix",
    "euler_to_matrix",
    "yaw_matrix",
]


def matrix_to_6d(R: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """(..., 3, 3) rotation matrices -> (..., 6): first two columns, column-major."""
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must be (..., 3, 3), got {tuple(R.shape)}")
    cols = R[..., :, :2]  # (..., 3, 2)
    if isinstance(R, torch.Tensor):
        return cols.transpose(-1, -2).reshape(*R.shape[:-2], 6)
    return np.swapaxes(cols, -1, -2).reshape(*R.shape[:-2], 6)


def sixd_to_matrix(r6: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt on the two columns (differentiable in torch)."""
    if r6.shape[-1] != 6:
        raise ValueError(f"6D rotations must be (..., 6), got {tuple(r6.shape)}")
    if isinstance(r6, torch.Tensor):
        a1, a2 = r6[..., :3], r6[..., 3:]
        b1 = torch.nn.functional.normalize(a1, dim=-1, eps=1e-8)
        b2 = torch.nn.functional.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1, eps=1e-8)
        b3 = torch.cross(b1, b2, dim=-1)
        return torch.stack([b1, b2, b3], dim=-1)
    a1, a2 = r6[..., :3], r6[..., 3:]
    b1 = a1 / np.maximum(np.linalg.norm(a1, axis=-1, keepdims=True), 1e-8)
    a2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    b2 = a2 / np.maximum(np.linalg.norm(a2, axis=-1, keepdims=True), 1e-8)
    b3 = np.cross(b1, b2)
    return np.stack([b1, b2, b3], axis=-1)


def _flat(R: np.ndarray) -> tuple[np.ndarray, tuple[int, ...]]:
    return R.reshape(-1, 3, 3), R.shape[:-2]


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4) quaternions, scalar-last (x, y, z, w), w >= 0."""
    flat, lead = _flat(np.asarray(R, dtype=np.float64))
    q = Rotation.from_matrix(flat).as_quat()
    q = np.where(q[:, 3:4] < 0, -q, q)
    return q.reshape(*lead, 4)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) scalar-last quaternions (normalised here) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4:
        raise ValueError(f"quaternions must be (..., 4) scalar-last, got {q.shape}")
    return Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(*q.shape[:-1], 3, 3)


def matrix_to_axis_angle(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 3) rotation vectors (radians)."""
    flat, lead = _flat(np.asarray(R, dtype=np.float64))
    return Rotation.from_matrix(flat).as_rotvec().reshape(*lead, 3)


def axis_angle_to_matrix(v: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """(..., 3) rotation vectors -> (..., 3, 3). The torch path is differentiable (Rodrigues)."""
    if v.shape[-1] != 3:
        raise ValueError(f"axis-angle must be (..., 3), got {tuple(v.shape)}")
    if isinstance(v, torch.Tensor):
        angle = v.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        k = v / angle
        K = torch.zeros(*v.shape[:-1], 3, 3, dtype=v.dtype, device=v.device)
        K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
        K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
        K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
        s, c = torch.sin(angle)[..., None], torch.cos(angle)[..., None]
        eye = torch.eye(3, dtype=v.dtype, device=v.device).expand_as(K)
        return eye + s * K + (1 - c) * (K @ K)
    v = np.asarray(v, dtype=np.float64)
    return Rotation.from_rotvec(v.reshape(-1, 3)).as_matrix().reshape(*v.shape[:-1], 3, 3)


def euler_to_matrix(angles: np.ndarray, order: str = "xyz") -> np.ndarray:
    """(..., 3) intrinsic Euler angles (radians, scipy upper-case order) -> (..., 3, 3)."""
    angles = np.asarray(angles, dtype=np.float64)
    return Rotation.from_euler(order.upper(), angles.reshape(-1, 3)).as_matrix().reshape(*angles.shape[:-1], 3, 3)


def yaw_matrix(yaw: np.ndarray | float) -> np.ndarray:
    """Rotation about +z by ``yaw`` radians: (...,) -> (..., 3, 3)."""
    yaw = np.asarray(yaw, dtype=np.float64)
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros(yaw.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1] = c, -s
    R[..., 1, 0], R[..., 1, 1] = s, c
    R[..., 2, 2] = 1.0
    return R
