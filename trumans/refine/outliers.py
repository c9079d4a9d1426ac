"""Tracking failures that can be recognised before filtering, then treated as missing.

Frozen frames: a tracker that loses its target repeats its last output; a frame whose joints equal
the previous frame's bit for bit is such a repeat (a body measured by any sensor never does this),
so its human and object entries are set to NaN and interpolated across (``frozen_frame_mask``).
Flipped object rotations:

Marker-less and symmetric-object trackers sometimes report an object turned by about π about one
of its own axes for a run of frames (I'm-HOI §3.2 names such flips among the tracking errors the
filter must undo). A rigid object in a hand does not turn by more than ``max_angle_deg`` and back
within ``window_s``: a frame whose rotation is more than that away from most of the observed frames
within ``window_s`` of it is an outlier. Its rotation is set to NaN, so the filter sees it as missing
and its condition interpolates across it (``trumans.refine.frame.fill_missing``); the translation is kept.
Not in the paper (which leaves flips to the network); measured in the README's filter section.

A run of flips longer than ``window_s``, or flips dense enough to outvote the true rotation there,
escape that vote. ``object_flip_labels`` therefore first reads the flips from the whole sequence: a
flip about one of the object's own axes (what symmetric-object trackers report) is a right
multiplication by one of S_x, S_y, S_z = diag(1,-1,-1), diag(-1,1,-1), diag(-1,-1,1), which with I
form a group (S_x S_y = S_z). Between two consecutive observed frames a rigid object turns far less
than 90°, so the member that best explains their relative rotation is the change of flip state; its
running product gives every frame's state relative to the first, and the state shared by most
frames is taken as the unflipped one (flips are the exception over a sequence, wherever they fall).
Frames read as flipped are turned back (``unflip_object``), so they keep their information; a pair
that no member explains within ``max_step_deg`` (a flip about another axis, a turn across a long
gap) cuts the chain, and each piece votes on its own.
"""
from __future__ import annotations

import numpy as np

from trumans.refine.frame import FRAME_DIM, IMU_R, JOINTS, OBJ_R
from trumans.rotations import matrix_to_6d, sixd_to_matrix

__all__ = ["object_flip_labels", "unflip_object", "object_flip_mask", "drop_object_flips", "frozen_frame_mask",
           "drop_frozen_frames", "frozen_joint_mask", "drop_frozen_joints"]

# the flips about the object's own x, y, z axes; label k means R_tracked = R_true @ _FLIPS[k]
_FLIPS = np.array([np.diag(d) for d in ((1.0, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1))])


def object_flip_mask(obj6: np.ndarray, fps: float, window_s: float = 1.0, max_angle_deg: float = 150.0) -> np.ndarray:
    """obj6: (T, 6) object rotations (6D, NaN = missing) at ``fps`` -> (T,) bool, True where the
    rotation is more than ``max_angle_deg`` from at least half of the other observed rotations within
    ``window_s`` (s) of it. Missing frames are never outliers. A run of flipped frames shorter than
    ``window_s`` is outvoted by the frames around it."""
    r = np.asarray(obj6, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] != 6:
        raise ValueError(f"object rotations must be (T, 6) 6D, got {r.shape}")
    if not fps > 0 or not window_s > 0 or not 0 < max_angle_deg < 180:
        raise ValueError(f"need fps > 0, window_s > 0 and 0 < max_angle_deg < 180, got {fps}, {window_s}, {max_angle_deg}")
    T = len(r)
    seen = np.isfinite(r).all(-1)
    R = np.zeros((T, 3, 3))
    R[seen] = sixd_to_matrix(r[seen])
    h = max(1, int(round(window_s * fps)))
    cos_max = np.cos(np.radians(max_angle_deg))
    agree = np.zeros(T)
    votes = np.zeros(T)
    for k in range(1, min(h, T - 1) + 1):  # offsets (not frames): 2h vectorised comparisons
        both = seen[:-k] & seen[k:]
        # cos of the relative angle: (trace(R_a^T R_b) - 1) / 2
        cos = (np.einsum("tij,tij->t", R[:-k], R[k:]) - 1.0) / 2.0
        ok = both & (cos > cos_max)
        for sl in (slice(None, -k), slice(k, None)):
            votes[sl] += both
            agree[sl] += ok
    return seen & (votes > 0) & (agree < 0.5 * votes)


def object_flip_labels(obj6: np.ndarray, max_step_deg: float = 60.0) -> np.ndarray:
    """obj6: (T, 6) object rotations (6D, NaN = missing) -> (T,) int8 flip labels (module doc): 0 = as
    tracked, k = 1, 2, 3 = turned by π about the object's own x, y, z axis (``R_tracked = R @
    _FLIPS[k]``), -1 = missing. Consecutive observed frames are chained where one member of {I, S_x,
    S_y, S_z} explains their relative rotation within ``max_step_deg``; in each chain the state most
    frames share is 0."""
    r = np.asarray(obj6, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] != 6:
        raise ValueError(f"object rotations must be (T, 6) 6D, got {r.shape}")
    if not 0 < max_step_deg < 90:
        raise ValueError(f"max_step_deg must be in (0, 90) (beyond it a flip and a turn look alike), got {max_step_deg}")
    labels = np.full(len(r), -1, dtype=np.int8)
    idx = np.flatnonzero(np.isfinite(r).all(-1))
    if len(idx) == 0:
        return labels
    R = sixd_to_matrix(r[idx])
    rel = np.einsum("tji,tjk->tik", R[:-1], R[1:])  # R_i^T R_j of consecutive observed frames
    # cos of the angle of rel @ S_k for each member k: (trace(rel S_k) - 1) / 2, S_k diagonal
    cos = (np.einsum("tii,ki->tk", rel, np.diagonal(_FLIPS, axis1=1, axis2=2)) - 1.0) / 2.0
    step = np.argmax(cos, axis=1)
    linked = cos[np.arange(len(step)), step] > np.cos(np.radians(max_step_deg))
    state = np.bitwise_xor.accumulate(np.r_[0, step]) # S_a S_b = S_(a xor b): the state relative to frame idx[0]
    chain = np.r_[0, np.cumsum(~linked)]
    for c in np.unique(chain):  # pieces cut by unexplained steps (rare): each takes its own majority
        part = chain == c
        labels[idx[part]] = state[part] ^ np.argmax(np.bincount(state[part], minlength=4))
    return labels


def unflip_object(frames: np.ndarray, max_step_deg: float = 60.0) -> np.ndarray:
    """Frame vectors (T, 235) -> a copy whose object rotations read as flipped (``object_flip_labels``)
    are turned back; everything else is unchanged."""
    f = np.array(frames, dtype=np.float32, copy=True)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    labels = object_flip_labels(f[:, OBJ_R], max_step_deg)
    fix = labels > 0
    if fix.any():
        R = sixd_to_matrix(f[fix][:, OBJ_R].astype(np.float64)) @ _FLIPS[labels[fix]]
        f[np.flatnonzero(fix)[:, None], np.arange(OBJ_R.start, OBJ_R.stop)[None]] = matrix_to_6d(R)
    return f


def drop_object_flips(frames: np.ndarray, fps: float, window_s: float = 1.0, max_angle_deg: float = 150.0) -> np.ndarray:
    """Frame vectors (T, 235) -> a copy whose flipped object rotations (``object_flip_mask``) are NaN."""
    f = np.array(frames, dtype=np.float32, copy=True)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    f[object_flip_mask(f[:, OBJ_R], fps, window_s, max_angle_deg), OBJ_R] = np.nan
    return f


def frozen_frame_mask(frames: np.ndarray) -> np.ndarray:
    """Frame vectors (T, 235) -> (T,) bool, True where every joint value equals the previous
    frame's exactly (a repeated tracker output; frames with missing joints are not compared)."""
    f = np.asarray(frames)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    J = f[:, JOINTS]
    same = np.isfinite(J[1:]).all(-1) & (J[1:] == J[:-1]).all(-1)
    return np.r_[False, same]


def drop_frozen_frames(frames: np.ndarray) -> np.ndarray:
    """Frame vectors (T, 235) -> a copy whose repeated frames (``frozen_frame_mask``) have NaN human
    and object entries (the IMU, a separate sensor, is kept)."""
    f = np.array(frames, dtype=np.float32, copy=True)
    f[frozen_frame_mask(f), :IMU_R.start] = np.nan
    return f


def frozen_joint_mask(frames: np.ndarray, min_repeats: int = 2) -> np.ndarray:
    """Frame vectors (T, 235) -> (T, 24) bool, True where a joint's position equals its previous
    frame's exactly for at least ``min_repeats`` frames in a row (a tracker that holds one limb's last
    output without flagging it; the earliest frame of the run, the last real reading, stays). A real
    joint at rest still moves by sensor noise, so at float precision two exact repeats in a row
    are a held output (the 0.1 mm-quantised corpus: 0.00-0.07 % of its entries)."""
    f = np.asarray(frames)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    if min_repeats < 1:
        raise ValueError(f"min_repeats must be >= 1, got {min_repeats}")
    J = f[:, JOINTS].reshape(len(f), -1, 3)
    same = np.r_[np.zeros((1, J.shape[1]), bool), np.isfinite(J[1:]).all(-1) & (J[1:] == J[:-1]).all(-1)]
    # the runs of repeats, joint by joint: starts and ends (exclusive) in time order per joint
    edge = np.diff(np.pad(same.T.astype(np.int8), ((0, 0), (1, 1))), axis=1)  # (24, T + 1)
    (jo, start), (_, end) = np.nonzero(edge == 1), np.nonzero(edge == -1)
    long = end - start >= min_repeats  # every frame of a run that reaches min_repeats
    mark = np.zeros((len(same) + 1, same.shape[1]), np.int64)
    np.add.at(mark, (start[long], jo[long]), 1)
    np.add.at(mark, (end[long], jo[long]), -1)
    return np.cumsum(mark[:-1], axis=0) > 0


def drop_frozen_joints(frames: np.ndarray, min_repeats: int = 2) -> np.ndarray:
    """Frame vectors (T, 235) -> a copy whose held joint positions (``frozen_joint_mask``) are NaN."""
    f = np.array(frames, dtype=np.float32, copy=True)
    m = frozen_joint_mask(f, min_repeats)
    J = f[:, JOINTS].reshape(len(f), -1, 3)
    J[m] = np.nan
    f[:, JOINTS] = J.reshape(len(f), -1)
    return f
