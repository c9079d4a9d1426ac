"""Hinged objects (doors): one turning axis through one fixed point, fitted to the whole sequence.

iReplica (§4.3, supp. §10 C) drives a hinged object within its degree of freedom: it only turns
about its hinge, so its translation follows from its rotation. Here the hinge is not given (no
scene scan): it is estimated from the tracked sequence itself. The filtered rotations R(t) (after
rest pooling) are reduced to one degree of freedom, R_h(t) = Rot(a, θ(t)) R̄, with R̄ their chordal
mean and a the principal direction of the rotation vectors of R(t) R̄ᵀ; the hinge is the point u in
the object's frame that stays at one world point c, so the object's translation is
p(t) = c − R_h(t) u, with c and u the least-squares fit to every observed tracked translation (u
with a small ridge: its component along the axis only trades with c). The tracker's drift of the
object then averages over the whole sequence instead of over each rest, and the moves take the
shape the rotation gives them.

Which categories are hinged is a fact of the data world (``HINGED_CATEGORIES``: ``trumans.scenes.furniture``
builds doors with dof "hinge"); the post-step fits the hinge for ``HingeConfig.categories`` (default
those), and ``trumans refine --hinge`` / ``--no-hinge`` overrides it (``any_category`` / ``enabled``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from trumans.refine.frame import FRAME_DIM, OBJ_R, OBJ_T
from trumans.rotations import matrix_to_6d, sixd_to_matrix

__all__ = ["HINGED_CATEGORIES", "HingeConfig", "fit_hinge"]

HINGED_CATEGORIES: tuple[str, ...] = ("door",)  # the data world's dof == "hinge" objects (trumans.scenes.furniture.door)


@dataclass(frozen=True)
class HingeConfig:
    """enabled: whether the post-step runs (``trumans.refine.post_steps``); it then runs for objects
    of ``categories`` (default ``HINGED_CATEGORIES``), or for every object with ``any_category``.
    min_turn_deg: below this turn from the mean rotation the hinge point is not identifiable and the
    input is returned as it is; ridge: the prior on u (module doc), per observed frame."""

    enabled: bool = True
    categories: tuple[str, ...] = HINGED_CATEGORIES
    any_category: bool = False
    min_turn_deg: float = 10.0
    ridge: float = 1e-3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.min_turn_deg) and 0 <= self.min_turn_deg <= 180):
            raise ValueError(f"hinge min_turn_deg must be in [0, 180], got {self.min_turn_deg}")
        if not (np.isfinite(self.ridge) and self.ridge > 0):
            raise ValueError(f"hinge ridge must be a positive number, got {self.ridge}")

    def applies_to(self, category: str) -> bool:
        """Whether the hinge is fitted for an object of ``category`` (``enabled`` aside)."""
        return self.any_category or category in self.categories


def fit_hinge(filtered: np.ndarray, tracked: np.ndarray, config: HingeConfig = HingeConfig()) -> np.ndarray:
    """filtered: (T, 235) the filter's output (rests pooled), tracked: (T, 235) its input on the same
    frames (NaN = missing) -> (T, 235) a copy whose object turns about one fitted hinge (module doc).
    Unchanged when the object turns by less than ``config.min_turn_deg`` from its mean rotation or
    fewer than 3 tracked translations are observed. Whatever the category: which objects get a hinge
    is the caller's (``HingeConfig.applies_to``)."""
    out = np.array(filtered, dtype=np.float64, copy=True)
    tr = np.asarray(tracked, dtype=np.float64)
    if out.ndim != 2 or out.shape[1] != FRAME_DIM or tr.shape != out.shape:
        raise ValueError(f"filtered and tracked must both be (T, {FRAME_DIM}), got {out.shape} and {tr.shape}")
    if not np.isfinite(out[:, OBJ_R]).all():
        raise ValueError("the filtered object rotations must be finite (the filter's output)")
    seen = np.isfinite(tr[:, OBJ_T]).all(-1)
    if seen.sum() < 3:
        return out.astype(filtered.dtype)
    rots = Rotation.from_matrix(sixd_to_matrix(out[:, OBJ_R]))
    mean = rots.mean()
    rv = (rots * mean.inv()).as_rotvec()  # (T, 3) world-frame turns from the mean
    if np.degrees(np.linalg.norm(rv, axis=1).max()) < config.min_turn_deg:
        return out.astype(filtered.dtype)
    axis = np.linalg.eigh(rv.T @ rv)[1][:, -1]
    Rh = (Rotation.from_rotvec((rv @ axis)[:, None] * axis[None]) * mean).as_matrix()  # (T, 3, 3), one dof
    n = int(seen.sum())
    # unknowns [c, u]: rows c - R_h(t) u = tracked(t) for observed t, then sqrt(ridge n) u = 0
    A = np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -Rh[seen]], axis=2).reshape(-1, 6)
    A = np.concatenate([A, np.sqrt(config.ridge * n) * np.hstack([np.zeros((3, 3)), np.eye(3)])])
    y = np.concatenate([tr[seen][:, OBJ_T].reshape(-1), np.zeros(3)])
    c_u = np.linalg.lstsq(A, y, rcond=None)[0]
    out[:, OBJ_T] = c_u[None, :3] - Rh @ c_u[3:]
    out[:, OBJ_R] = matrix_to_6d(Rh)
    return out.astype(filtered.dtype)
