"""Episodes: fixed-length motion windows in their canonical frame, the feature layout, normalisation.

TRUMANS §4.1: motion is generated in episodes of ``L_epi`` frames (10 fps, 16 frames by default).
Canonical frame (docs/conventions.md): the first frame's pelvis at x = y = 0 (height kept) and its heading
along +x. ``canonicalize`` / ``uncanonicalize`` are exact inverses.

Feature layout (owned here): per frame, the 24 joints' canonical positions ``(24 * 3)`` in joint
order, x/y/z interleaved, then optionally the 24 local rotations in 6D ``(24 * 6)`` whose root entry
is turned into the canonical frame. ``FeatureLayout.dim`` is the feature width ``F``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch

from trumans.rotations import matrix_to_6d, sixd_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS, heading

__all__ = [
    "FeatureLayout",
    "canonical_frame",
    "canonicalize",
    "uncanonicalize",
    "episode_starts",
    "Normalizer",
    "PELVIS",
]

PELVIS = JOINT_INDEX["pelvis"]


@dataclass(frozen=True)
class FeatureLayout:
    """Per-frame feature vector: ``positions`` (24 x 3, m, canonical) then ``rotations`` (24 x 6) if on."""

    rotations: bool = False

    @property
    def dim(self) -> int:
        return NUM_JOINTS * 3 + (NUM_JOINTS * 6 if self.rotations else 0)

    def position_index(self, joint: int | str, axes: tuple[int, ...] = (0, 1, 2)) -> list[int]:
        """Feature indices of ``joint``'s position coordinates ``axes`` (0 = x, 1 = y, 2 = z)."""
        j = JOINT_INDEX[joint] if isinstance(joint, str) else int(joint)
        if not 0 <= j < NUM_JOINTS:
            raise ValueError(f"joint must be 0..23 or a joint name, got {joint!r}")
        if any(a not in (0, 1, 2) for a in axes):
            raise ValueError(f"axes must be among 0, 1, 2, got {axes}")
        return [3 * j + a for a in axes]

    def to_dict(self) -> dict:
        return asdict(self)

    def pack(self, joints: np.ndarray, rotations: np.ndarray | None = None) -> np.ndarray:
        """joints (..., L, 24, 3) [+ rotations (..., L, 24, 6)] canonical -> features (..., L, F) float32."""
        joints = np.asarray(joints)
        if joints.shape[-2:] != (NUM_JOINTS, 3):
            raise ValueError(f"joints must be (..., 24, 3), got {joints.shape}")
        parts = [joints.reshape(*joints.shape[:-2], NUM_JOINTS * 3)]
        if self.rotations:
            if rotations is None or np.shape(rotations) != joints.shape[:-1] + (6,):
                raise ValueError(f"this layout needs rotations {joints.shape[:-1] + (6,)}, got "
                                 f"{None if rotations is None else np.shape(rotations)}")
            parts.append(np.asarray(rotations).reshape(*joints.shape[:-2], NUM_JOINTS * 6))
        return np.concatenate(parts, axis=-1).astype(np.float32)

    def unpack(self, features: np.ndarray | torch.Tensor):
        """features (..., F) -> (joints (..., 24, 3), rotations (..., 24, 6) or None)."""
        if features.shape[-1] != self.dim:
            raise ValueError(f"features must be (..., {self.dim}), got {tuple(features.shape)}")
        lead = tuple(features.shape[:-1])
        joints = features[..., : NUM_JOINTS * 3].reshape(*lead, NUM_JOINTS, 3)
        rot = features[..., NUM_JOINTS * 3:].reshape(*lead, NUM_JOINTS, 6) if self.rotations else None
        return joints, rot


def canonical_frame(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical frame of episodes: joints (..., L, 24, 3) world m -> (origin (..., 3), yaw (...,)).

    origin = first frame's pelvis with z = 0 (height kept); yaw = first frame's heading (rad).
    """
    joints = np.asarray(joints)
    if joints.ndim < 3 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (..., L, 24, 3), got {joints.shape}")
    first = joints[..., 0, :, :]
    origin = first[..., PELVIS, :].astype(np.float64).copy()
    origin[..., 2] = 0.0
    return origin, heading(first).astype(np.float64)


def _check_frame(joints: np.ndarray, origin: np.ndarray, yaw: np.ndarray):
    joints = np.asarray(joints, dtype=np.float64)
    origin, yaw = np.asarray(origin, dtype=np.float64), np.asarray(yaw, dtype=np.float64)
    if joints.ndim < 3 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (..., L, 24, 3), got {joints.shape}")
    lead = joints.shape[:-3]
    if origin.shape != lead + (3,) or yaw.shape != lead:
        raise ValueError(f"origin must be {lead + (3,)} and yaw {lead} for joints {joints.shape}, "
                         f"got {origin.shape} and {yaw.shape}")
    return joints, origin, yaw


def canonicalize(joints: np.ndarray, origin: np.ndarray, yaw: np.ndarray,
                 rotations: np.ndarray | None = None):
    """World -> canonical: ``R_z(-yaw) (p - origin)``.

    joints (..., L, 24, 3) world m; origin (..., 3); yaw (...,) rad; rotations (..., L, 24, 6)
    local 6D (only the root's is turned). Returns joints (float32), or (joints, rotations) when
    rotations are given.
    """
    joints, origin, yaw = _check_frame(joints, origin, yaw)
    Rinv = np.swapaxes(yaw_matrix(yaw), -1, -2)[..., None, None, :, :]  # (..., 1, 1, 3, 3)
    out = (Rinv @ (joints - origin[..., None, None, :])[..., None])[..., 0].astype(np.float32)
    if rotations is None:
        return out
    return out, _turn_root(rotations, Rinv[..., 0, :, :])


def uncanonicalize(joints: np.ndarray, origin: np.ndarray, yaw: np.ndarray,
                   rotations: np.ndarray | None = None):
    """Canonical -> world, the exact inverse of ``canonicalize`` (same shapes)."""
    joints, origin, yaw = _check_frame(joints, origin, yaw)
    R = yaw_matrix(yaw)[..., None, None, :, :]
    out = ((R @ joints[..., None])[..., 0] + origin[..., None, None, :]).astype(np.float32)
    if rotations is None:
        return out
    return out, _turn_root(rotations, R[..., 0, :, :])


def _turn_root(rotations: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Left-multiply the root's local rotation by R (..., 1, 3, 3): rotations (..., L, 24, 6)."""
    rot = np.asarray(rotations, dtype=np.float64).copy()
    root = sixd_to_matrix(rot[..., PELVIS, :])  # (..., L, 3, 3)
    rot[..., PELVIS, :] = matrix_to_6d(R @ root)
    return rot.astype(np.float32)


def episode_starts(num_frames: int, length: int, stride: int) -> np.ndarray:
    """First frames of the windows ``[s, s + length)`` that fit in ``num_frames``, every ``stride`` frames."""
    if length < 1 or stride < 1:
        raise ValueError(f"length and stride must be >= 1, got {length}, {stride}")
    if num_frames < length:
        return np.zeros(0, dtype=np.int64)
    return np.arange(0, num_frames - length + 1, stride, dtype=np.int64)


@dataclass
class Normalizer:
    """Per-feature standardisation: ``(x - mean) / std``; mean, std: (F,) float32."""

    mean: np.ndarray
    std: np.ndarray

    def __post_init__(self) -> None:
        self.mean = np.asarray(self.mean, dtype=np.float32).reshape(-1)
        self.std = np.asarray(self.std, dtype=np.float32).reshape(-1)
        if self.mean.shape != self.std.shape or not np.all(self.std > 0):
            raise ValueError(f"mean/std must be (F,) with std > 0, got {self.mean.shape}, {self.std.shape}")

    @classmethod
    def fit(cls, features: np.ndarray, min_std: float = 1e-2) -> "Normalizer":
        """Statistics of features (..., F) over every leading axis; std floored at ``min_std``."""
        f = np.asarray(features, dtype=np.float64).reshape(-1, np.shape(features)[-1])
        if len(f) == 0:
            raise ValueError("cannot fit normalisation statistics on zero frames; the data has no episodes")
        return cls(f.mean(0), np.maximum(f.std(0), min_std))

    def normalize(self, x):
        """x (..., F) -> (x - mean) / std (numpy or torch, same type)."""
        m, s = self._like(x)
        return (x - m) / s

    def denormalize(self, x):
        """Inverse of ``normalize``."""
        m, s = self._like(x)
        return x * s + m

    def _like(self, x):
        if x.shape[-1] != self.mean.shape[0]:
            raise ValueError(f"features must be (..., {self.mean.shape[0]}), got {tuple(x.shape)}")
        if isinstance(x, torch.Tensor):
            return (torch.as_tensor(self.mean, dtype=x.dtype, device=x.device),
                    torch.as_tensor(self.std, dtype=x.dtype, device=x.device))
        return self.mean, self.std

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {"mean": torch.from_numpy(self.mean.copy()), "std": torch.from_numpy(self.std.copy())}

    @classmethod
    def from_state_dict(cls, d: dict) -> "Normalizer":
        return cls(np.asarray(d["mean"]), np.asarray(d["std"]))
