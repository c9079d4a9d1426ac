"""Simulated object IMU (I'm-HOI appendix B.2, eq. 16) and the seeded corruption model that turns
clean HOI frame vectors into tracked-like input for training and evaluating the filter.

Corruption (``CorruptionConfig``; every draw from the caller's ``numpy.random.Generator``):

- human: per-joint, per-frame Gaussian jitter (``jitter_m``) with rare outlier spikes
  (``p_spike``, ``spike_m``); slow drift = smooth noise with knots every ``drift_frames`` frames,
  shared by the body (``drift_m``) plus a smaller per-joint part (``joint_drift_m``); jitter, spikes and
  drifts of a window scaled by one factor drawn from ``position_scale`` (default 1: a fixed severity); local rotation
  noise (``rot_noise_rad``, axis-angle); occluded joints (runs of NaN per joint, mostly the arms);
  the whole rotation block missing with ``p_no_rotations`` (a joints-only tracker);
- dropouts: runs of missing frames (NaN) for the human and, separately, for the object
  (``p_dropout`` per frame to start a run of ``dropout_frames`` frames); frozen frames (the tracker
  repeats its last output) for runs of ``freeze_frames``;
- object: translation jitter + drift, rotation noise, and flips (a run where the pose is turned by
  π about one of its own axes, the classic symmetric-object ambiguity);
- IMU: with probability ``p_no_imu`` absent (zeros, flag 0), else rotation = true object rotation
  under a constant bias rotation + slowly drifting bias + noise, and acceleration = eq. 16 of the
  true translation + constant bias + noise. The IMU is never occluded.

Presets: ``CorruptionConfig()`` is the training model (a video / marker-less tracker with an object
IMU); ``CorruptionConfig.drift()`` is a drift-dominated, IMU-like model the filter is not trained on.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS

from trumans.refine.frame import FRAME_DIM, IMU_A, IMU_FLAG, IMU_R, JOINTS, OBJ_R, OBJ_T, ROTATIONS

__all__ = ["CorruptionConfig", "simulate_imu_acc", "add_clean_imu", "corrupt"]

IMU_SMOOTHING = 4  # eq. 16's n ("smoothing factor")
_ARMS = [JOINT_INDEX[n] for n in ("left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_index1", "right_index1")]


@dataclass(frozen=True)
class CorruptionConfig:
    """Magnitudes in metres / radians / m/s²; probabilities per frame unless said per window."""

    jitter_m: float = 0.015
    p_spike: float = 0.003
    spike_m: float = 0.10
    drift_m: float = 0.015
    joint_drift_m: float = 0.005
    drift_frames: int = 30
    rot_noise_rad: float = 0.06
    p_joint_occlusion: float = 0.002
    occlusion_frames: tuple[int, int] = (5, 20)
    p_no_rotations: float = 0.2  # per window
    p_dropout: float = 0.01
    dropout_frames: tuple[int, int] = (1, 12)
    p_freeze: float = 0.01
    freeze_frames: tuple[int, int] = (2, 8)
    obj_jitter_m: float = 0.02
    obj_drift_m: float = 0.03
    obj_rot_noise_rad: float = 0.08
    p_obj_dropout: float = 0.015
    p_flip: float = 0.003
    flip_frames: tuple[int, int] = (5, 30)
    p_no_imu: float = 0.3  # per window
    imu_bias_rad: float = 0.05
    imu_drift_rad: float = 0.03
    imu_rot_noise_rad: float = 0.01
    imu_acc_bias: float = 0.2
    imu_acc_noise: float = 0.5
    position_scale: tuple[float, float] = (1.0, 1.0)  # per window: factor on joint jitter, spikes and drifts


    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, tuple) else (v,)
            if any(not np.isfinite(x) or x < 0 for x in vals):
                raise ValueError(f"corruption {f.name} must be finite and >= 0, got {v}")
            if f.name.startswith("p_") and v > 1:
                raise ValueError(f"corruption {f.name} is a probability, got {v}")
            if f.name == "position_scale":
                if len(v) != 2 or not v[0] <= v[1]:
                    raise ValueError(f"corruption position_scale must be (min, max) with 0 <= min <= max, got {v}")
            elif isinstance(v, tuple) and (len(v) != 2 or not 1 <= v[0] <= v[1]):
                raise ValueError(f"corruption {f.name} must be (min, max) frames with 1 <= min <= max, got {v}")
        if self.drift_frames < 1:
            raise ValueError(f"drift_frames must be >= 1, got {self.drift_frames}")

    @classmethod
    def drift(cls) -> "CorruptionConfig":
        """Drift-dominated (IMU-like inertial body tracker): little jitter, large slow drift, no
        dropouts or flips, always an object IMU."""
        return cls(jitter_m=0.004, p_spike=0.0, drift_m=0.12, joint_drift_m=0.03, drift_frames=60,
                   rot_noise_rad=0.02, p_joint_occlusion=0.0, p_no_rotations=0.0, p_dropout=0.0, p_freeze=0.0,
                   obj_jitter_m=0.005, obj_drift_m=0.10, obj_rot_noise_rad=0.02, p_obj_dropout=0.0, p_flip=0.0,
                   p_no_imu=0.0, imu_drift_rad=0.08)

    def without_imu(self) -> "CorruptionConfig":
        return replace(self, p_no_imu=1.0)

    def to_dict(self) -> dict:
        return asdict(self)


def simulate_imu_acc(obj_t: np.ndarray, fps: float, n: int = IMU_SMOOTHING) -> np.ndarray:
    """Free acceleration (m/s²) from object translations by appendix eq. 16:
    ``a_t = (T_{t-n} + T_{t+n} - 2 T_t) / (n τ)²``, τ = 1 / fps; indices clamped at the ends.
    obj_t: (..., T, 3) m -> (..., T, 3)."""
    obj_t = np.asarray(obj_t, dtype=np.float64)
    T = obj_t.shape[-2]
    idx = np.arange(T)
    lo, hi = np.clip(idx - n, 0, T - 1), np.clip(idx + n, 0, T - 1)
    return (obj_t[..., lo, :] + obj_t[..., hi, :] - 2 * obj_t) / (n / fps) ** 2


def add_clean_imu(frames: np.ndarray, fps: float) -> np.ndarray:
    """Frame vectors (..., T, 235) with a perfect IMU: rotation = the object's, acceleration by
    eq. 16, flag 1."""
    f = np.asarray(frames, dtype=np.float32).copy()
    f[..., IMU_R] = f[..., OBJ_R]
    f[..., IMU_A] = simulate_imu_acc(f[..., OBJ_T], fps)
    f[..., IMU_FLAG] = 1.0
    return f


def _runs(rng: np.random.Generator, shape: tuple[int, ...], p: float | np.ndarray, frames: tuple[int, int]) -> np.ndarray:
    """Bool (..., L) marking runs that start with probability ``p`` (broadcast to ``shape``) per frame and last
    ``frames[0]..frames[1]`` frames (last axis = time)."""
    start = rng.random(shape) < p
    length = rng.integers(frames[0], frames[1] + 1, shape)
    t = np.arange(shape[-1])
    end = np.where(start, t + length, 0)
    return np.maximum.accumulate(end, axis=-1) > t


def _smooth(rng: np.random.Generator, shape: tuple[int, ...], sigma: float, every: int) -> np.ndarray:
    """Smooth Gaussian noise (B, L, *rest): N(0, σ²) knots every ``every`` frames, linearly
    interpolated (axis 1 = time)."""
    B, L, rest = shape[0], shape[1], shape[2:]
    K = L // every + 2
    knots = rng.normal(0.0, sigma, (B, K) + rest)
    s = np.arange(L) / every + rng.random((B, 1))  # random phase per window
    i0 = np.floor(s).astype(int)
    w = (s - i0).reshape(B, L, *([1] * len(rest)))
    take = lambda i: np.take_along_axis(knots, i.reshape(B, L, *([1] * len(rest))), axis=1)
    return (1 - w) * take(i0) + w * take(np.minimum(i0 + 1, K - 1))


def _rot_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma: float) -> np.ndarray:
    """Random rotations (*shape, 3, 3) with axis-angle components N(0, σ²)."""
    return axis_angle_to_matrix(rng.normal(0.0, sigma, shape + (3,)))


def _compose6d(R: np.ndarray, r6: np.ndarray, right: bool = False) -> np.ndarray:
    M = sixd_to_matrix(np.asarray(r6, np.float64))
    return matrix_to_6d(M @ R if right else R @ M)


def corrupt(frames: np.ndarray, fps: float, rng: np.random.Generator,
            cfg: CorruptionConfig = CorruptionConfig(), parts: dict | None = None) -> np.ndarray:
    """Clean frame vectors (B, L, 235) (world, IMU from ``add_clean_imu``) -> tracked-like frame
    vectors (B, L, 235) with NaN = missing, by the model in the module docstring. ``parts``: a dict
    to receive known components for diagnosis: ``body_drift`` (B, L, 3) m, the whole-body drift
    every joint got (severity-scaled). The result does not depend on it."""
    x = np.asarray(frames, dtype=np.float64)
    if x.ndim != 3 or x.shape[-1] != FRAME_DIM:
        raise ValueError(f"frames must be (B, L, {FRAME_DIM}), got {x.shape}")
    B, L, _ = x.shape
    out = x.copy()
    c = cfg
    # human positions: jitter, spikes, drift (body + per joint)
    J = x[..., JOINTS].reshape(B, L, NUM_JOINTS, 3)
    scale = 1.0 if c.position_scale == (1.0, 1.0) else rng.uniform(*c.position_scale, (B, 1, 1, 1))  # severity per window
    noise = rng.normal(0.0, c.jitter_m, J.shape)
    spikes = (rng.random((B, L, NUM_JOINTS, 1)) < c.p_spike) * rng.normal(0.0, c.spike_m, J.shape)
    body_drift = _smooth(rng, (B, L, 1, 3), c.drift_m, c.drift_frames)
    drift = body_drift + _smooth(rng, (B, L, NUM_JOINTS, 3), c.joint_drift_m, c.drift_frames)
    if parts is not None:
        parts["body_drift"] = (scale * body_drift)[:, :, 0]
    out[..., JOINTS] = (J + scale * (noise + spikes + drift)).reshape(B, L, -1)
    # rotations: axis-angle noise on every local rotation
    R6 = x[..., ROTATIONS].reshape(B, L, NUM_JOINTS, 6)
    out[..., ROTATIONS] = _compose6d(_rot_noise(rng, (B, L, NUM_JOINTS), c.rot_noise_rad), R6).reshape(B, L, -1)
    # object: translation jitter + drift, rotation noise, flips about a random own axis
    out[..., OBJ_T] = x[..., OBJ_T] + rng.normal(0.0, c.obj_jitter_m, (B, L, 3)) + _smooth(rng, (B, L, 3), c.obj_drift_m, c.drift_frames)
    obj6 = _compose6d(_rot_noise(rng, (B, L), c.obj_rot_noise_rad), x[..., OBJ_R])
    flip = _runs(rng, (B, L), c.p_flip, c.flip_frames)
    axis = np.eye(3)[rng.integers(0, 3, (B, 1))].repeat(L, 1)  # (B, L, 3)
    flipped = _compose6d(axis_angle_to_matrix(np.pi * axis), obj6, right=True)
    out[..., OBJ_R] = np.where(flip[..., None], flipped, obj6)
    # IMU: bias rotation (constant + slow drift) on the true rotation, noise; acceleration bias + noise
    bias = axis_angle_to_matrix(rng.normal(0.0, c.imu_bias_rad, (B, 1, 3)) + _smooth(rng, (B, L, 3), c.imu_drift_rad, 2 * c.drift_frames))
    imu = _compose6d(bias @ _rot_noise(rng, (B, L), c.imu_rot_noise_rad), x[..., OBJ_R])
    acc = x[..., IMU_A] + rng.normal(0.0, c.imu_acc_bias, (B, 1, 3)) + rng.normal(0.0, c.imu_acc_noise, (B, L, 3))
    has_imu = (rng.random((B, 1, 1)) >= c.p_no_imu) & (x[..., IMU_FLAG:IMU_FLAG + 1] > 0.5)
    out[..., IMU_R] = np.where(has_imu, imu, 0.0)
    out[..., IMU_A] = np.where(has_imu, acc, 0.0)
    out[..., IMU_FLAG] = has_imu[..., 0]
    # frozen frames: the tracker repeats its last output (human and object together; not the IMU)
    frozen = _runs(rng, (B, L), c.p_freeze, c.freeze_frames)
    frozen[:, 0] = False
    src = np.maximum.accumulate(np.where(frozen, 0, np.arange(L)), axis=1)
    held = np.take_along_axis(out, src[..., None], axis=1)
    vis = slice(0, IMU_R.start)
    out[..., vis] = held[..., vis]
    # missing: whole rotation block, occluded joints (mostly the arms), human / object dropouts
    out[rng.random(B) < c.p_no_rotations, :, ROTATIONS] = np.nan
    p_j = np.full(NUM_JOINTS, c.p_joint_occlusion)
    p_j[_ARMS] *= 5
    occl = np.swapaxes(_runs(rng, (B, NUM_JOINTS, L), p_j[None, :, None], c.occlusion_frames), 1, 2)  # (B, L, 24)
    Jo = out[..., JOINTS].reshape(B, L, NUM_JOINTS, 3)
    Jo[occl] = np.nan
    out[..., JOINTS] = Jo.reshape(B, L, -1)
    human_gone = _runs(rng, (B, L), c.p_dropout, c.dropout_frames)
    out[human_gone, JOINTS.start:ROTATIONS.stop] = np.nan
    obj_gone = _runs(rng, (B, L), c.p_obj_dropout, c.dropout_frames)
    out[obj_gone, OBJ_T.start:OBJ_R.stop] = np.nan
    return out.astype(np.float32)

