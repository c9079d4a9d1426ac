"""The over-parameterised HOI frame vector of the interaction filter (I'm-HOI §3.2 "Interaction
Representation") and its round trip with ``Sequence``.

Per frame, ``FRAME_DIM = 235`` float features, in this order (owned here):

==========  =====  ==========================================================================
slice       width  content
==========  =====  ==========================================================================
JOINTS      72     24 joint positions (m), x/y/z interleaved, joint order of ``skeleton``
ROTATIONS   144    24 local joint rotations, 6D (first two columns), root first
OBJ_T       3      object translation (m): the origin of ``objects/<name>/pose``
OBJ_R       6      object rotation, 6D
IMU_R       6      object IMU rotation, 6D (world-calibrated orientation)
IMU_A       3      object IMU free acceleration (m/s², gravity removed, world axes)
IMU_FLAG    1      1 where the IMU is present, 0 where not (then IMU_R and IMU_A are 0)
==========  =====  ==========================================================================

The paper uses SMPL-H (52 joints, x ∈ R^486); ours is the 24-joint skeleton. NaN marks a missing
measurement (dropped frame, occluded joint); ``condition_features`` turns tracked frame vectors
into the filter's per-frame condition: missing values interpolated in time, plus observed flags
(24 joints, rotations, object).

Frames move between the world and a window's canonical frame (``to_frame`` / ``from_frame``):
``p' = R_z(-yaw)(p - origin)`` for positions, ``R' = R_z(-yaw) R`` for the root, object and IMU
rotations, ``a' = R_z(-yaw) a`` for the acceleration.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.rotations import matrix_to_6d, sixd_to_matrix, yaw_matrix
from trumans.sequence import ObjectTrack, Sequence
from trumans.skeleton import NUM_JOINTS, heading

__all__ = [
    "JOINTS", "ROTATIONS", "OBJ_T", "OBJ_R", "IMU_R", "IMU_A", "IMU_FLAG", "FRAME_DIM", "COND_DIM",
    "HOIFrames", "pack_frames", "unpack_frames", "frames_from_sequence", "sequence_from_frames",
    "condition_features", "fill_missing", "window_frame", "to_frame", "from_frame", "orthonormalize_6d", "resample_frames",
]

JOINTS = slice(0, 72)
ROTATIONS = slice(72, 216)
OBJ_T = slice(216, 219)
OBJ_R = slice(219, 225)
IMU_R = slice(225, 231)
IMU_A = slice(231, 234)
IMU_FLAG = 234
FRAME_DIM = 235
# condition = frame vector with NaN -> 0, then observed flags: 24 joints, rotations, object
COND_DIM = FRAME_DIM + NUM_JOINTS + 2
assert OBJ_R.stop == IMU_R.start and ROTATIONS.stop - ROTATIONS.start == 6 * NUM_JOINTS  # orthonormalize_6d's runs of 6D blocks


@dataclass
class HOIFrames:
    """A frame vector unpacked: joints (T, 24, 3) m, rotations (T, 24, 6), obj_pose (T, 4, 4),
    imu_rot (T, 6), imu_acc (T, 3) m/s², imu_present (T,) bool. NaN = missing."""

    joints: np.ndarray
    rotations: np.ndarray
    obj_pose: np.ndarray
    imu_rot: np.ndarray
    imu_acc: np.ndarray
    imu_present: np.ndarray


def pack_frames(joints: np.ndarray, rotations: np.ndarray | None, obj_pose: np.ndarray,
                imu_rot: np.ndarray | None = None, imu_acc: np.ndarray | None = None) -> np.ndarray:
    """Build frame vectors (T, 235) float32. rotations None -> NaN (missing); no IMU (both None)
    -> zeros with IMU_FLAG 0. A frame whose IMU rotation is NaN counts as having no IMU."""
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {joints.shape}")
    T = joints.shape[0]
    out = np.zeros((T, FRAME_DIM), dtype=np.float64)
    out[:, JOINTS] = joints.reshape(T, -1)
    if rotations is None:
        out[:, ROTATIONS] = np.nan
    else:
        if np.shape(rotations) != (T, NUM_JOINTS, 6):
            raise ValueError(f"rotations must be ({T}, 24, 6), got {np.shape(rotations)}")
        out[:, ROTATIONS] = np.asarray(rotations, dtype=np.float64).reshape(T, -1)
    obj_pose = np.asarray(obj_pose, dtype=np.float64)
    if obj_pose.shape != (T, 4, 4):
        raise ValueError(f"object pose must be ({T}, 4, 4), got {obj_pose.shape}")
    out[:, OBJ_T] = obj_pose[:, :3, 3]
    out[:, OBJ_R] = matrix_to_6d(obj_pose[:, :3, :3])
    if (imu_rot is None) != (imu_acc is None):
        raise ValueError("give both imu_rot (T, 6) and imu_acc (T, 3), or neither")
    if imu_rot is not None:
        if np.shape(imu_rot) != (T, 6) or np.shape(imu_acc) != (T, 3):
            raise ValueError(f"imu_rot must be ({T}, 6) and imu_acc ({T}, 3), got {np.shape(imu_rot)}, {np.shape(imu_acc)}")
        present = np.isfinite(imu_rot).all(-1) & np.isfinite(imu_acc).all(-1)
        out[:, IMU_R] = np.where(present[:, None], imu_rot, 0.0)
        out[:, IMU_A] = np.where(present[:, None], imu_acc, 0.0)
        out[:, IMU_FLAG] = present
    return out.astype(np.float32)


def unpack_frames(frames: np.ndarray) -> HOIFrames:
    """frames (T, 235) -> ``HOIFrames`` (object rotation re-orthonormalised; NaN stays NaN)."""
    f = np.asarray(frames, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
    T = f.shape[0]
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3] = sixd_to_matrix(f[:, OBJ_R])
    pose[:, :3, 3] = f[:, OBJ_T]
    return HOIFrames(joints=f[:, JOINTS].reshape(T, NUM_JOINTS, 3), rotations=f[:, ROTATIONS].reshape(T, NUM_JOINTS, 6),
                     obj_pose=pose, imu_rot=f[:, IMU_R], imu_acc=f[:, IMU_A], imu_present=f[:, IMU_FLAG] > 0.5)


def _object_name(seq: Sequence, name: str | None) -> str:
    if not seq.objects:
        raise ValueError("the sequence has no object track (objects/<name>/pose); the HOI filter refines "
                         "a human together with one object")
    if name is None:
        if len(seq.objects) == 1:
            return next(iter(seq.objects))
        moved = {n: np.nan_to_num(np.ptp(np.asarray(o.pose[:, :3, 3], np.float64), axis=0)).sum() for n, o in seq.objects.items()}
        return max(moved, key=moved.get)  # the object that moves most
    if name not in seq.objects:
        raise ValueError(f"object {name!r} is not in the sequence; it has {sorted(seq.objects)}")
    return name


def frames_from_sequence(seq: Sequence, object_name: str | None = None) -> tuple[np.ndarray, str]:
    """(frames (T, 235) float32, object name) of ``seq`` with one object (default: the only one,
    else the one whose translation spans most). NaN entries of a tracked sequence stay NaN."""
    name = _object_name(seq, object_name)
    ob = seq.objects[name]
    return pack_frames(seq.joints, seq.rotations, ob.pose, ob.imu_rot, ob.imu_acc), name


def sequence_from_frames(frames: np.ndarray, fps: float, object_name: str, category: str,
                         template: Sequence | None = None, imu: bool = True) -> Sequence:
    """A ``Sequence`` from frame vectors: joints, rotations, root_pos (= pelvis), the object's pose
    and (``imu`` and flag set on every frame) its IMU. Other fields and objects come from
    ``template`` (same length) when given."""
    h = unpack_frames(frames)
    T = h.joints.shape[0]
    if template is not None and template.num_frames != T:
        raise ValueError(f"template has {template.num_frames} frames, the frame vectors {T}")
    rot = None if np.isnan(h.rotations).all() else matrix_to_6d(sixd_to_matrix(h.rotations)).astype(np.float32)
    has_imu = imu and bool(h.imu_present.all())
    track = ObjectTrack(pose=h.obj_pose.astype(np.float32), category=category,
                        imu_rot=h.imu_rot.astype(np.float32) if has_imu else None,
                        imu_acc=h.imu_acc.astype(np.float32) if has_imu else None)
    t = template
    objects = dict(t.objects) if t is not None else {}
    objects[object_name] = track
    missing = bool(np.isnan(frames).any())
    return Sequence(
        joints=h.joints.astype(np.float32), fps=float(fps), rotations=rot,
        root_pos=h.joints[:, 0].astype(np.float32),
        actions=None if t is None else t.actions, action_names=[] if t is None else list(t.action_names),
        contacts=None if t is None else t.contacts, scene="" if t is None else t.scene,
        objects=objects, extra={} if t is None else dict(t.extra), allow_missing=missing)


def fill_missing(frames: np.ndarray) -> np.ndarray:
    """Fill NaN entries (..., L, D) along the time axis (-2) by linear interpolation between the
    nearest observed frames of the same column, holding the first / last observed value at the
    ends; a column with no observed frame becomes 0."""
    f = np.asarray(frames, dtype=np.float64)
    L = f.shape[-2]
    cols = np.moveaxis(f, -2, 0).reshape(L, -1)  # (L, n): every column of every leading index
    ok = np.isfinite(cols)
    out = np.where(ok, cols, 0.0)  # complete columns as they are, unobserved ones 0
    gap = np.flatnonzero(ok.any(0) & ~ok.all(0))  # only the columns with a gap are interpolated
    if len(gap):
        g, okg = cols[:, gap], ok[:, gap]
        t = np.arange(L).reshape(L, 1)
        prev = np.maximum.accumulate(np.where(okg, t, -1), axis=0)
        nxt = np.flip(np.minimum.accumulate(np.flip(np.where(okg, t, L), 0), axis=0), 0)
        has_p, has_n = prev >= 0, nxt < L
        vp = np.take_along_axis(g, np.clip(prev, 0, L - 1), 0)
        vn = np.take_along_axis(g, np.clip(nxt, 0, L - 1), 0)
        w = np.where(has_p & has_n, (t - prev) / np.maximum(nxt - prev, 1), 0.0)
        filled = np.where(has_p & has_n, (1 - w) * vp + w * vn, np.where(has_p, vp, vn))
        out[:, gap] = np.where(okg, g, filled)
    return np.moveaxis(out.reshape((L,) + f.shape[:-2] + f.shape[-1:]), 0, -2).astype(np.float32)


def fill_missing_joints(joints: np.ndarray) -> np.ndarray:
    """Joints (T, 24, 3) m with NaN = missing -> (T, 24, 3) float64, each coordinate's gaps filled
    by ``fill_missing`` (linear in time, ends held)."""
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, {NUM_JOINTS}, 3), got {J.shape}")
    return fill_missing(J.reshape(len(J), -1)).reshape(J.shape).astype(np.float64)


def condition_features(frames: np.ndarray, filled: np.ndarray | None = None) -> np.ndarray:
    """Tracked frame vectors (..., L, 235) with NaN = missing -> the filter's condition (..., L, 261):
    the values with missing entries filled (``filled``, e.g. gaps filled over a whole sequence before
    it was cut into windows; default ``fill_missing(frames)``: linear in time, 0 where a column has
    no observation), then observed flags (24 joints, rotations, object) in {0, 1}."""
    f = np.asarray(frames, dtype=np.float32)
    if f.ndim < 2 or f.shape[-1] != FRAME_DIM:
        raise ValueError(f"frame vectors must be (..., L, {FRAME_DIM}), got {f.shape}")
    joints = f[..., JOINTS].reshape(*f.shape[:-1], NUM_JOINTS, 3)
    seen_j = np.isfinite(joints).all(-1)
    seen_r = np.isfinite(f[..., ROTATIONS]).all(-1, keepdims=True)
    seen_o = (np.isfinite(f[..., OBJ_T]).all(-1) & np.isfinite(f[..., OBJ_R]).all(-1))[..., None]
    flags = np.concatenate([seen_j, seen_r, seen_o], -1).astype(np.float32)
    if filled is None:
        filled = fill_missing(f)
    elif np.shape(filled) != f.shape or not np.isfinite(filled).all():
        raise ValueError(f"filled must be finite and shaped like frames {f.shape}, got {np.shape(filled)}")
    return np.concatenate([np.asarray(filled, np.float32), flags], -1)


def window_frame(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical frame of windows from (possibly noisy, partly missing) tracked frame vectors:
    frames (..., L, 235) -> origin (..., 3) (mean observed pelvis, z = 0), yaw (...,) (heading of
    the mean observed hip line). A window with no observed pelvis/hips gets origin 0, yaw 0."""
    f = np.asarray(frames, dtype=np.float64)
    J = f[..., JOINTS].reshape(*f.shape[:-1], NUM_JOINTS, 3)
    ok = np.isfinite(J[..., [0, 1, 2], :]).all((-1, -2))  # (..., L)
    w = ok.astype(np.float64)[..., None, None]
    n = np.maximum(w.sum(-3), 1.0)
    mean = (np.nan_to_num(J) * w).sum(-3) / n  # (..., 24, 3): only joints 0-2 are used
    origin = mean[..., 0, :].copy()
    origin[..., 2] = 0.0
    yaw = heading(mean)
    none = ~ok.any(-1)
    origin[none], yaw = 0.0, np.where(none, 0.0, yaw)
    return origin, yaw


# the 3-vectors a rigid transform turns: 24 joints, the root rotation's two 6D columns, the object
# translation, the object and IMU rotations' columns, the IMU acceleration (column starts)
_TURNED = np.concatenate([np.arange(JOINTS.start, JOINTS.stop, 3), [72, 75, OBJ_T.start, OBJ_R.start, OBJ_R.start + 3,
                                                                   IMU_R.start, IMU_R.start + 3, IMU_A.start]])
_TURNED_COLS = (_TURNED[:, None] + np.arange(3)).ravel()  # (96,)
_SHIFTED = np.r_[np.arange(NUM_JOINTS), 26]  # of those, the positions (joints, object translation)


def _apply(frames: np.ndarray, R: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """p -> R p + shift on positions, R X on root/object/IMU rotations, R a on accelerations.
    frames (..., L, 235); R (..., 3, 3); shift (..., 3). All 32 turned 3-vectors of all frames in
    one matrix product."""
    f = np.asarray(frames)
    lead, L = f.shape[:-2], f.shape[-2]
    out = f.astype(np.float32)  # a copy: the columns not turned as they are
    v = np.take(f, _TURNED_COLS, axis=-1).astype(np.float64).reshape(*lead, L * len(_TURNED), 3) @ np.swapaxes(R, -1, -2)
    v = v.reshape(*lead, L, len(_TURNED), 3)
    v[..., _SHIFTED, :] += shift[..., None, None, :]
    out[..., _TURNED_COLS] = v.reshape(*lead, L, -1)  # computed in float64, stored in float32
    # a missing IMU is 0 and stays 0 (rotating zeros); the flag is untouched
    return out


def to_frame(frames: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World -> canonical: frames (..., L, 235), origin (..., 3), yaw (...,) rad."""
    Rinv = np.swapaxes(yaw_matrix(yaw), -1, -2)
    return _apply(frames, Rinv, -(Rinv @ np.asarray(origin, np.float64)[..., None])[..., 0])


def from_frame(frames: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Canonical -> world, the inverse of ``to_frame``."""
    return _apply(frames, yaw_matrix(yaw), np.asarray(origin, np.float64))


def orthonormalize_6d(frames: np.ndarray) -> np.ndarray:
    """Frame vectors with every 6D block (joint, object, IMU rotations) made a proper rotation
    (Gram-Schmidt); a missing IMU (flag 0) keeps its zeros."""
    f = np.asarray(frames, dtype=np.float64).copy()
    for sl in (ROTATIONS, slice(OBJ_R.start, IMU_R.stop)):  # every 6D block of a run at once: (..., n, 6)
        r6 = f[..., sl].reshape(*f.shape[:-1], -1, 6)
        f[..., sl] = matrix_to_6d(sixd_to_matrix(r6)).reshape(*f.shape[:-1], -1)
    f[..., IMU_R] *= f[..., IMU_FLAG:IMU_FLAG + 1] > 0.5
    return f.astype(np.float32)


def resample_frames(frames: np.ndarray, fps_in: float, fps_out: float, num_out: int | None = None) -> np.ndarray:
    """Frame vectors (T, 235) at ``fps_in`` -> (T_out, 235) at ``fps_out``: over the same duration
    (``trumans.resample.resample_times``), or ``num_out`` frames from time 0 (a last frame past the
    input's end is extrapolated linearly from its last two frames). Linear interpolation, 6D blocks
    re-orthonormalised, NaN (missing) spreading to the output frames it touches."""
    from trumans.resample import resample_times

    f = np.asarray(frames, dtype=np.float64)
    T = f.shape[0]
    if abs(fps_in - fps_out) < 1e-9 and (num_out is None or num_out == T):
        return f.astype(np.float32)
    src = resample_times(T, fps_in, fps_out) if num_out is None else np.arange(num_out) * (fps_in / fps_out)
    i0 = np.clip(np.floor(src).astype(int), 0, max(T - 2, 0))
    i1 = np.minimum(i0 + 1, T - 1)
    w = (src - i0)[:, None]
    out = (1 - w) * f[i0] + w * f[i1]
    out = np.where(w == 0, f[i0], np.where(w == 1, f[i1], out))  # an exact source frame ignores a NaN neighbour
    out[:, IMU_FLAG] = np.where(w[:, 0] == 0, f[i0, IMU_FLAG], np.where(w[:, 0] == 1, f[i1, IMU_FLAG],
                                                                         np.minimum(f[i0, IMU_FLAG], f[i1, IMU_FLAG])))
    return orthonormalize_6d(out)
