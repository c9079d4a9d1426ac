"""Rotation conversions, numpy and torch.

Conventions (owned here, used everywhere):
- Rotation matrices act on column vectors: ``x_world = R @ x_local``.
- 6D representation (Zhou et al. 2019) = the first two *columns* of the matrix, concatenated:
  ``r6 = [R[:, 0], R[:, 1]]`` -> shape ``(..., 6)``. (pytorch3d keeps rows; we never do.)
- Quaternions are scalar-last ``(x, y, z, w)``, as scipy's ``Rotation``.
- Axis-angle is a rotation vector ``(..., 3)``: unit axis times angle in radians.
- Yaw is the angle (radians) about world +z, measured from +x towards +y.

The one definition of each: ``unit`` (unit vectors), ``rodrigues`` (axis + angle -> matrix),
``axis_angle_to_matrix`` / ``matrix_to_axis_angle`` (rotation vectors), ``yaw_matrix`` (rotation
about +z) and ``fit_yaw`` (best planar turn between two point sets).
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

__all__ = ["Y_UP_TO_Z_UP", 
    "matrix_to_6d",
    "sixd_to_matrix",
    "matrix_to_quat",
    "quat_to_matrix",
    "least_rotation",
    "matrix_to_axis_angle",
    "axis_angle_to_matrix",
    "euler_to_matrix",
    "yaw_matrix",
    "fit_yaw",
    "unit",
    "skew",
    "rodrigues",
]

# The one y-up <-> z-up turn of the project (mesh import, BVH and GLB export, TRUMANS-release import):
# +90 deg about x, y-up (x, y, z) -> z-up (x, -z, y); det = +1. Its transpose takes our z-up world to
# the y-up files (x, y, z) -> (x, z, -y), which Blender's and three.js' importers turn back exactly.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


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


def unit(v: np.ndarray | torch.Tensor, eps: float = 1e-9) -> np.ndarray | torch.Tensor:
    """(..., 3) vectors -> unit vectors along them; a vector shorter than ``eps`` is divided by
    ``eps`` instead (so a zero vector stays zero)."""
    if isinstance(v, torch.Tensor):
        return v / v.norm(dim=-1, keepdim=True).clamp_min(eps)
    v = np.asarray(v, dtype=np.float64)
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), eps)


def skew(v: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """(..., 3) -> (..., 3, 3) cross-product matrices: ``skew(v) @ x == cross(v, x)``."""
    if isinstance(v, torch.Tensor):
        K = torch.zeros(*v.shape[:-1], 3, 3, dtype=v.dtype, device=v.device)
    else:
        v = np.asarray(v, dtype=np.float64)
        K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def rodrigues(axis: np.ndarray | torch.Tensor, angle: np.ndarray | torch.Tensor | float) -> np.ndarray | torch.Tensor:
    """Rotation by ``angle`` (...,) radians about ``axis`` (..., 3) (normalised here; a zero axis
    gives the identity) -> (..., 3, 3), by Rodrigues' formula ``R = c I + s [k]x + (1 - c) k k^T``.
    Leading shapes broadcast; torch in -> torch out (differentiable), numpy in -> numpy out."""
    if axis.shape[-1] != 3:
        raise ValueError(f"axis must be (..., 3), got {tuple(axis.shape)}")
    if isinstance(axis, torch.Tensor):
        k = unit(axis, 1e-12)
        ang = torch.as_tensor(angle, dtype=axis.dtype, device=axis.device)
        k, ang = torch.broadcast_tensors(k, ang[..., None])
        s, c = torch.sin(ang[..., 0])[..., None, None], torch.cos(ang[..., 0])[..., None, None]
        K = skew(k)
        eye = torch.eye(3, dtype=k.dtype, device=k.device).expand_as(K)
        return eye + s * K + (1 - c) * (K @ K)
    axis = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    k, ang = np.broadcast_arrays(axis / np.maximum(n, 1e-12), np.where(n > 0, np.asarray(angle, dtype=np.float64)[..., None], 0.0))
    ang = ang[..., 0]  # zero axis: angle 0 (the form below needs k k^T = I + [k]x^2)
    s, c = np.sin(ang), np.cos(ang)
    R = (1 - c)[..., None, None] * (k[..., :, None] * k[..., None, :])
    R[..., 0, 0] += c
    R[..., 1, 1] += c
    R[..., 2, 2] += c
    sk = s[..., None] * k
    R[..., 0, 1] -= sk[..., 2]
    R[..., 0, 2] += sk[..., 1]
    R[..., 1, 0] += sk[..., 2]
    R[..., 1, 2] -= sk[..., 0]
    R[..., 2, 0] -= sk[..., 1]
    R[..., 2, 1] += sk[..., 0]
    return R


def least_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the least rotation turning direction a (..., 3) into direction b (..., 3).

    Parallel directions or a zero vector give the identity; opposite directions a half turn about
    an axis perpendicular to a."""
    a, b = np.broadcast_arrays(np.asarray(a), np.asarray(b))
    degenerate = (np.linalg.norm(a, axis=-1) < 1e-9) | (np.linalg.norm(b, axis=-1) < 1e-9)
    a, b = unit(a), unit(b)
    c = np.cross(a, b)
    cos = (a * b).sum(-1)
    R = rodrigues(c, np.arctan2(np.linalg.norm(c, axis=-1), cos))
    anti = (cos < -1.0 + 1e-9) & ~degenerate
    if anti.any():  # half turn about any axis n perpendicular to a: R = 2 n n^T - I
        aa = a[anti]
        helper = np.where(np.abs(aa[:, :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        n = unit(np.cross(aa, helper))
        R[anti] = 2 * n[:, :, None] * n[:, None, :] - np.eye(3)
    R[degenerate] = np.eye(3)
    return R


def matrix_to_axis_angle(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 3) rotation vectors (radians, angle in [0, pi]).

    Closed form from the trace and the skew part; within 1e-3 rad of a half turn (where that is
    ill-conditioned) scipy's quaternion route is used."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must be (..., 3, 3), got {R.shape}")
    tr = np.trace(R, axis1=-2, axis2=-1)
    ang = np.arccos(np.clip((tr - 1) / 2, -1.0, 1.0))
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    s = np.sin(ang)
    out = w * np.where(s > 1e-9, ang / np.maximum(2 * s, 1e-12), 0.5)[..., None]
    near_pi = ang > np.pi - 1e-3
    if near_pi.any():
        out[near_pi] = Rotation.from_matrix(R[near_pi]).as_rotvec()
    return out


def axis_angle_to_matrix(v: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """(..., 3) rotation vectors -> (..., 3, 3) (``rodrigues``; differentiable in torch)."""
    if v.shape[-1] != 3:
        raise ValueError(f"axis-angle must be (..., 3), got {tuple(v.shape)}")
    if isinstance(v, torch.Tensor):
        return rodrigues(v, v.norm(dim=-1))
    v = np.asarray(v, dtype=np.float64)
    return rodrigues(v, np.linalg.norm(v, axis=-1))


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


def fit_yaw(a: np.ndarray, b: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Yaw (radians) of the turn about +z that best maps the centred points ``a`` onto ``b`` in the
    ground plane (weighted least squares, Kabsch in 2D): a, b (..., N, 3) or (..., N, 2) with
    centroids already removed; w (..., N) weights (default 1) -> (...,)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.shape[-1] not in (2, 3):
        raise ValueError(f"a and b must both be (..., N, 2 or 3), got {a.shape} and {b.shape}")
    w = np.ones(a.shape[:-1]) if w is None else np.asarray(w, dtype=np.float64)
    cross = (w * (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])).sum(-1)
    dot = (w * (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1])).sum(-1)
    return np.arctan2(cross, dot)
