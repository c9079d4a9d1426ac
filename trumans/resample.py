"""Time resampling of sequences (e.g. 30 fps capture -> the generator's 10 fps).

``resample_sequence``: joints and root positions interpolate linearly, rotations by slerp (via
scipy), labels and contacts take the nearest source frame. The new clip spans the same duration:
frame i is at time i / fps.

``resample_smooth``: raw capture keys (24 fps FBX keys, 120 fps BVH frames) to a sequence rate in
one step: a zero-phase low-pass (4th-order Butterworth, forward and backward) that removes the
keys' broadband marker noise and anti-aliases, then a C2 cubic spline through the filtered keys
(no kink, so no jerk spike, at a key). The default cutoff, 6 Hz, is the usual one for human
movement marker data (Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., §2.2:
residual analysis puts walking's signal below 6 Hz).
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation, Slerp

from .limits import check_fps, check_frames
from .rotations import matrix_to_6d, sixd_to_matrix
from .sequence import ObjectTrack, Sequence

__all__ = ["resample_times", "resample_sequence", "resample_smooth", "resample_joints_smooth", "interp_rotations",
           "HUMAN_MOTION_CUTOFF_HZ"]

HUMAN_MOTION_CUTOFF_HZ = 6.0  # low-pass cutoff of raw capture keys (Winter, see the module doc)


def resample_times(num_frames: int, fps_in: float, fps_out: float) -> np.ndarray:
    """Source-frame coordinates (float) of the output frames: (T_out,)."""
    check_fps(fps_in, "the source frame rate")
    check_fps(fps_out, "the target frame rate")
    duration = (num_frames - 1) / fps_in
    n_out = check_frames(np.floor(duration * fps_out + 1e-9) + 1, f"resampling {num_frames} frames to {fps_out:g} fps")
    t_out = np.arange(n_out) / fps_out
    return t_out * fps_in


def resample_smooth(keys: np.ndarray, fps_in: float, fps_out: float,
                    cutoff_hz: float = HUMAN_MOTION_CUTOFF_HZ) -> np.ndarray:
    """Raw keys (T, ...) float (positions, any unit) at ``fps_in`` -> (T_out, ...) float64 at ``fps_out``,
    same duration (``resample_times``): zero-phase 4th-order Butterworth low-pass at
    min(``cutoff_hz``, 0.4 fps_out, 0.4 fps_in) Hz, then a cubic spline through the filtered keys
    (see the module doc). Clips shorter than the filter's padding are only splined."""
    x = np.asarray(keys, np.float64)
    if x.ndim < 1 or len(x) < 2 or not np.isfinite(x).all():
        raise ValueError(f"keys must be finite with at least 2 frames, got shape {x.shape}")
    if not cutoff_hz > 0:
        raise ValueError(f"cutoff_hz must be > 0, got {cutoff_hz}")
    t_out = resample_times(len(x), fps_in, fps_out)
    fc = min(cutoff_hz, 0.4 * fps_out, 0.4 * fps_in)
    sos = butter(4, fc, fs=fps_in, output="sos")
    pad = min(len(x) - 1, int(np.ceil(fps_in / fc)) * 3)  # ~3 periods of the cutoff, odd extension
    if pad >= 6:
        x = sosfiltfilt(sos, x, axis=0, padtype="odd", padlen=pad)
    return CubicSpline(np.arange(len(x)), x, axis=0)(t_out)


def resample_joints_smooth(keys: np.ndarray, fps_in: float, fps_out: float,
                           cutoff_hz: float = HUMAN_MOTION_CUTOFF_HZ) -> np.ndarray:
    """Raw joint keys (T, 24, 3) m at ``fps_in`` -> (T_out, 24, 3) float64 at ``fps_out``: every joint
    through ``resample_smooth``, then the bones put back to their lengths (the keys' per-frame
    lengths, resampled the same way), from the root down along the filtered bone directions. A
    low-pass of positions alone shortens fast-turning bones (a toe in its swing, ~1 cm); the bone
    lengths of the keys are kept (a rigid rig's stay constant)."""
    from .skeleton import NUM_JOINTS, PARENTS

    x = np.asarray(keys, np.float64)
    if x.ndim != 3 or x.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"keys must be (T, {NUM_JOINTS}, 3) joints, got {x.shape}")
    par = np.asarray(PARENTS)
    f = resample_smooth(x, fps_in, fps_out, cutoff_hz)
    lengths = resample_smooth(np.linalg.norm(x[:, 1:] - x[:, par[1:]], axis=-1), fps_in, fps_out, cutoff_hz)
    out = f.copy()
    for j in range(1, NUM_JOINTS):  # parents come first
        d = f[:, j] - f[:, par[j]]
        out[:, j] = out[:, par[j]] + lengths[:, j - 1, None] * d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
    return out


def _lerp(x: np.ndarray, src: np.ndarray) -> np.ndarray:
    i0 = np.clip(np.floor(src).astype(int), 0, len(x) - 1)
    i1 = np.clip(i0 + 1, 0, len(x) - 1)
    w = (src - i0).reshape(-1, *([1] * (x.ndim - 1)))
    return (1 - w) * x[i0] + w * x[i1]


def interp_rotations(R: np.ndarray, src: np.ndarray) -> np.ndarray:
    """Slerp rotation matrices R (T, ..., 3, 3) at fractional frames src (T_out,) -> (T_out, ..., 3, 3)."""
    T = R.shape[0]
    lead = R.shape[1:-2]
    flat = R.reshape(T, -1, 3, 3)
    out = np.empty((len(src), flat.shape[1], 3, 3))
    times = np.arange(T)
    s = np.clip(src, 0, T - 1)
    for j in range(flat.shape[1]):  # loop over joints only; frames are vectorised inside Slerp
        if T == 1:
            out[:, j] = flat[0, j]
        else:
            out[:, j] = Slerp(times, Rotation.from_matrix(flat[:, j]))(s).as_matrix()
    return out.reshape(len(src), *lead, 3, 3)


def resample_sequence(seq: Sequence, fps: float) -> Sequence:
    """A copy of ``seq`` at ``fps`` Hz (same duration)."""
    if abs(seq.fps - fps) < 1e-9:
        return seq
    src = resample_times(seq.num_frames, seq.fps, fps)
    near = np.clip(np.rint(src).astype(int), 0, seq.num_frames - 1)
    rot = None
    if seq.rotations is not None:
        rot = matrix_to_6d(interp_rotations(sixd_to_matrix(np.asarray(seq.rotations, np.float64)), src)).astype(np.float32)
    objects = {}
    for name, ob in seq.objects.items():
        pose = np.tile(np.eye(4), (len(src), 1, 1))
        pose[:, :3, :3] = interp_rotations(np.asarray(ob.pose[:, :3, :3], np.float64), src)
        pose[:, :3, 3] = _lerp(np.asarray(ob.pose[:, :3, 3], np.float64), src)
        objects[name] = ObjectTrack(
            pose=pose.astype(np.float32), category=ob.category,
            imu_rot=None if ob.imu_rot is None else matrix_to_6d(
                interp_rotations(sixd_to_matrix(np.asarray(ob.imu_rot, np.float64)), src)).astype(np.float32),
            imu_acc=None if ob.imu_acc is None else _lerp(np.asarray(ob.imu_acc), src).astype(np.float32),
        )
    return Sequence(
        joints=_lerp(seq.joints.astype(np.float64), src).astype(np.float32),
        fps=float(fps),
        rotations=rot,
        root_pos=None if seq.root_pos is None else _lerp(np.asarray(seq.root_pos, np.float64), src).astype(np.float32),
        actions=None if seq.actions is None else np.asarray(seq.actions)[near],
        action_names=list(seq.action_names),
        contacts=None if seq.contacts is None else np.asarray(seq.contacts)[near],
        scene=seq.scene,
        objects=objects,
        extra={},
    )
