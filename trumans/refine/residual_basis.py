"""Where the filter's slow error lives: a joint-space subspace for the input residual (data of the
``residual`` post-step; our addition, not I'm-HOI's).

The residual step (``residual.py``) adds back G_sigma(r), r = tracked - filtered. Under tracker
jitter most of what is left after it is the input's own white noise that the Gaussian passes
(12 mm per axis x 0.33 at sigma 3), while the filter's slow error it is there to correct is not
white across joints: in the body's heading frame it is mostly a few whole-body patterns (a pose
held a little off, a limb chain offset together). With an orthonormal basis V (k, 72) of those
patterns, fitted once per filter on its low-passed errors on training clips, the step keeps

    low = R_yaw( V^T V R_yaw^-1 G_sigma(r) ) + G_tail((I - R_yaw V^T V R_yaw^-1) r),

the projection passing only k/72 of the white noise's energy, and the part outside the subspace
still coming back, more smoothly (``ResidualConfig.tail_sigma_frames``). R_yaw turns the horizontal
plane by each frame's heading (the filtered hips' left-right axis), so one basis serves every
direction the body faces. Chosen on corpus train clips, then the held-out families (docs/results.md):
k = 24 of 72, fitted under the training corruption, sigma 2 frames inside the subspace (the noise
cut, the Gaussian can be narrower than the plain step's 3), tail sigma 8 frames.

The basis is part of the filter checkpoint (``extra['residual_basis']``, fitted at export by
``scripts/ship_refine.py``); a checkpoint without one keeps the plain Gaussian. Units: metres;
joints (T, 24, 3) z-up world; frames at the filter's rate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.skeleton import JOINT_INDEX, NUM_JOINTS

__all__ = ["ResidualBasis", "heading_yaw", "to_heading_frame", "fit_residual_basis", "BASIS_KEY"]

BASIS_KEY = "residual_basis"  # the filter checkpoint's extra
_D = 3 * NUM_JOINTS
_LH, _RH = JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]


def heading_yaw(joints: np.ndarray) -> np.ndarray:
    """(T, 24, 3) joints (m) -> (T,) rad: the angle of the hips' right-to-left axis in the horizontal
    plane (0 for hips that coincide)."""
    a = joints[:, _LH, :2] - joints[:, _RH, :2]
    return np.arctan2(a[:, 1], a[:, 0])


def to_heading_frame(v: np.ndarray, yaw: np.ndarray, inverse: bool = False) -> np.ndarray:
    """(T, 24, 3) vectors turned about z by -yaw per frame (into the heading frame), or by +yaw with
    ``inverse`` (back to the world)."""
    ang = yaw if inverse else -yaw
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    out = v.copy()
    out[..., 0] = c * v[..., 0] - s * v[..., 1]
    out[..., 1] = s * v[..., 0] + c * v[..., 1]
    return out


@dataclass(frozen=True)
class ResidualBasis:
    """vectors: (k, 72) orthonormal rows in the heading frame (joint-major x, y, z); sigma_frames:
    the Gaussian of the errors it was fitted on (frames at the filter's rate)."""

    vectors: np.ndarray
    sigma_frames: float

    def __post_init__(self) -> None:
        V = np.asarray(self.vectors, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != _D or not 1 <= V.shape[0] <= _D:
            raise ValueError(f"a residual basis is (k, {_D}) with 1 <= k <= {_D}, got {V.shape}; the checkpoint is "
                             f"inconsistent - re-export it with scripts/ship_refine.py")
        if not np.isfinite(V).all() or not (np.isfinite(self.sigma_frames) and self.sigma_frames > 0):
            raise ValueError("the residual basis or its sigma is not finite; the checkpoint is corrupt - re-export it")
        if np.abs(V @ V.T - np.eye(len(V))).max() > 1e-3:
            raise ValueError("the residual basis' rows are not orthonormal; the checkpoint is corrupt - re-export it")
        object.__setattr__(self, "vectors", V)

    @property
    def rank(self) -> int:
        return len(self.vectors)

    def project(self, v: np.ndarray, yaw: np.ndarray) -> np.ndarray:
        """(T, 24, 3) world vectors -> their projection on the subspace, (T, 24, 3) world."""
        T = len(v)
        h = to_heading_frame(v, yaw).reshape(T, _D)
        return to_heading_frame(((h @ self.vectors.T) @ self.vectors).reshape(T, NUM_JOINTS, 3), yaw, inverse=True)

    def to_extra(self) -> dict:
        """Plain data for a checkpoint's ``extra`` (a float32 array and a float)."""
        import torch

        return {"vectors": torch.from_numpy(self.vectors.astype(np.float32)), "sigma_frames": float(self.sigma_frames)}

    @classmethod
    def from_extra(cls, d: dict) -> ResidualBasis:
        if not isinstance(d, dict) or set(d) != {"vectors", "sigma_frames"}:
            raise ValueError(f"extra['{BASIS_KEY}'] must hold vectors and sigma_frames, got {d!r:.80}; re-export "
                             f"the checkpoint with scripts/ship_refine.py")
        v = d["vectors"]
        v = v.detach().cpu().numpy() if hasattr(v, "detach") else np.asarray(v)
        return cls(v.astype(np.float64), float(d["sigma_frames"]))


def fit_residual_basis(filtered: list[np.ndarray], clean: list[np.ndarray], rank: int = 24,
                       sigma_frames: float = 3.0) -> ResidualBasis:
    """The ``rank`` leading principal directions (no centring: an offset is a pattern too) of the
    filter's low-passed errors G_sigma(clean - filtered) in the heading frame, over every frame of
    every clip. filtered, clean: lists of (T_i, 24, 3) m, finite, one shape per pair."""
    if not filtered or len(filtered) != len(clean):
        raise ValueError(f"need one clean clip per filtered clip (and at least one), got {len(filtered)} / {len(clean)}")
    if not 1 <= rank <= _D:
        raise ValueError(f"rank must be in 1..{_D}, got {rank}")
    rows = []
    for F, G in zip(filtered, clean):
        F, G = np.asarray(F, np.float64), np.asarray(G, np.float64)
        if F.shape != G.shape or F.ndim != 3 or F.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"filtered and clean clips must both be (T, {NUM_JOINTS}, 3), got {F.shape} / {G.shape}")
        if not (np.isfinite(F).all() and np.isfinite(G).all()):
            raise ValueError("fit_residual_basis needs finite joints")
        e = gaussian_filter1d(G - F, sigma_frames, axis=0, mode="nearest")
        rows.append(to_heading_frame(e, heading_yaw(F)).reshape(len(F), _D))
    E = np.concatenate(rows)
    if len(E) < rank:
        raise ValueError(f"{len(E)} frames cannot fit a basis of rank {rank}")
    _, _, Vt = np.linalg.svd(E, full_matrices=False)
    return ResidualBasis(Vt[:rank], sigma_frames)
