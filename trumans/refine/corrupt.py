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

The wider family (issue 36, "trained for the real world"); every kind is off at its default, so
``CorruptionConfig()`` draws exactly what it drew before these options existed (the kinds below
draw from a child generator taken from the caller's only when one of them is on):

- ``walk_m_per_sqrt_s`` (default 0: off): drift as a random walk of the whole body, Gaussian
  steps of ``walk_m_per_sqrt_s`` per axis per square-root second, the vertical at
  ``walk_vertical`` (default 0.3) of that; it starts at 0 on the window's first frame;
- ``height_m`` (default (0, 0): off): a constant vertical offset of the body per window,
  uniform in [lo, hi] m in magnitude, either sign;
- ``extremity_jitter`` (default 1: off): the jitter of wrists, index1, ankles and toe bases times
  this factor (trackers see the extremities worst);
- ``p_held`` (default 0: off), ``held_frames`` (default (3, 15)): silent freezes: per frame, the
  probability that a run of held output starts for one of five parts (an arm from the elbow, a
  leg from the knee, or the whole body, each with ``p_held`` / 5); the part's joints and local
  rotations repeat their last output bit for bit, with no missing flag;
- ``p_swap`` (default 0: off), ``swap_frames`` (default (3, 12)): the left and right legs (hip,
  knee, ankle, toe base: positions and local rotations) exchanged for a run;
- ``p_burst`` (default 0: off), ``burst_frames`` (default (3, 10)), ``burst_m`` (default 0.04):
  runs where every joint gets extra white noise of ``burst_m`` per axis (motion blur, a lost and
  re-found track);
- ``p_clean`` (default 0: off): the share of windows whose body is handed over clean (joints and
  rotations exact and complete, except where the rotation block is missing): the filter learns to
  leave clean input alone. ``position_scale = [lo, hi]`` with a small lo gives lightly jittered
  windows (jitter levels);
- ``leg_scale`` / ``spine_scale`` (default (1, 1): off): skeleton variation, applied to the
  *clean* windows before the corruption by ``vary_skeleton`` (the target changes with it): one
  factor per window, uniform in [lo, hi], on every leg bone (hip to knee, knee to ankle, ankle to
  toe base) and on every spine bone (pelvis to spine1 up to spine3), each joint at its parent plus
  its own bone vector times its factor (the local rotations stay exact), the window's lowest foot
  height kept; the rest offsets are scaled the same way.

Dropouts (``p_dropout``, ``dropout_frames``) are the flagged kind above. ``dropout_frames`` and
the per-window severity ``position_scale`` widen the existing kinds.

Presets: ``CorruptionConfig()`` is the training model of the filter shipped before issue 36 (a
video / marker-less tracker with an object IMU); ``CorruptionConfig.real_world()`` is the wider
family the "real world" filter config trains on (``trumans/train/configs/filter/real.toml``; bursts
held out); ``CorruptionConfig.drift()`` is a drift-dominated, IMU-like model the filter is not
trained on.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import JOINT_INDEX, NUM_JOINTS, PARENTS

from trumans.refine.frame import FRAME_DIM, IMU_A, IMU_FLAG, IMU_R, JOINTS, OBJ_R, OBJ_T, ROTATIONS

__all__ = ["CorruptionConfig", "simulate_imu_acc", "add_clean_imu", "corrupt", "vary_skeleton", "WIDER_KINDS"]

IMU_SMOOTHING = 4  # eq. 16's n ("smoothing factor")
_ARMS = [JOINT_INDEX[n] for n in ("left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_index1", "right_index1")]
_EXTREMITIES = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("wrist", "index1", "ankle", "foot")]
_LEGS = [[JOINT_INDEX[f"{s}_{n}"] for n in ("hip", "knee", "ankle", "foot")] for s in ("left", "right")]
_HELD_PARTS = [[JOINT_INDEX[f"{s}_{n}"] for n in names] for s in ("left", "right")
               for names in (("elbow", "wrist", "index1"), ("knee", "ankle", "foot"))] + [list(range(NUM_JOINTS))]
_LEG_BONES = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("knee", "ankle", "foot")]  # bone ends
_SPINE_BONES = [JOINT_INDEX[n] for n in ("spine1", "spine2", "spine3")]
_FEET = [JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("ankle", "foot")]
# the wider family's switches (name -> its "off" value); any one on draws from a child generator
WIDER_KINDS: dict[str, object] = {"walk_m_per_sqrt_s": 0.0, "height_m": (0.0, 0.0), "extremity_jitter": 1.0,
                                  "p_held": 0.0, "p_swap": 0.0, "p_burst": 0.0, "p_clean": 0.0}
_RANGES = ("position_scale", "height_m", "leg_scale", "spine_scale")  # (lo, hi) real-valued, lo <= hi


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
    # the wider family (issue 36; module docstring): every default is "off"
    walk_m_per_sqrt_s: float = 0.0
    walk_vertical: float = 0.3
    height_m: tuple[float, float] = (0.0, 0.0)
    extremity_jitter: float = 1.0
    p_held: float = 0.0
    held_frames: tuple[int, int] = (3, 15)
    p_swap: float = 0.0
    swap_frames: tuple[int, int] = (3, 12)
    p_burst: float = 0.0
    burst_frames: tuple[int, int] = (3, 10)
    burst_m: float = 0.04
    p_clean: float = 0.0  # per window
    leg_scale: tuple[float, float] = (1.0, 1.0)  # per window, on the clean window (vary_skeleton)
    spine_scale: tuple[float, float] = (1.0, 1.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, tuple) else (v,)
            if any(isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) for x in vals):
                raise ValueError(f"corruption {f.name} must be a number (or a [min, max] pair), got {v!r}")
            if any(not np.isfinite(x) or x < 0 for x in vals):
                raise ValueError(f"corruption {f.name} must be finite and >= 0, got {v}")
            if f.name.startswith("p_") and v > 1:
                raise ValueError(f"corruption {f.name} is a probability, got {v}")
            if f.name in _RANGES:
                if len(v) != 2 or not v[0] <= v[1]:
                    raise ValueError(f"corruption {f.name} must be (min, max) with 0 <= min <= max, got {v}")
                if f.name in ("leg_scale", "spine_scale") and v[0] <= 0:
                    raise ValueError(f"corruption {f.name} must be (min, max) factors with 0 < min <= max, got {v}")
            elif isinstance(v, tuple) and (len(v) != 2 or not 1 <= v[0] <= v[1]):
                raise ValueError(f"corruption {f.name} must be (min, max) frames with 1 <= min <= max, got {v}")
        if self.drift_frames < 1:
            raise ValueError(f"drift_frames must be >= 1, got {self.drift_frames}")

    @property
    def wider(self) -> bool:
        """Whether any kind of the wider family (``WIDER_KINDS``) is on."""
        return any(getattr(self, k) != off for k, off in WIDER_KINDS.items())

    @property
    def varies_skeleton(self) -> bool:
        """Whether ``vary_skeleton`` changes the clean windows (a bone scale range other than (1, 1))."""
        return self.leg_scale != (1.0, 1.0) or self.spine_scale != (1.0, 1.0)

    @classmethod
    def real_world(cls) -> "CorruptionConfig":
        """The wider family the "real world" filter trains on (``configs/filter/real.toml`` of
        ``trumans.train``, which spells the same values): jitter levels 0.1-2x per window with the
        extremities at 1.5x, a random-walk drift (1.5 cm/sqrt(s)), height offsets up to 8 cm, silent
        limb / body freezes, leg swaps, longer dropouts, 10 % clean windows, legs x0.85-1.15 and
        spine x0.9-1.15. Bursts are held out (``p_burst`` = 0): the evaluation's unseen kind."""
        return cls(position_scale=(0.1, 2.0), dropout_frames=(1, 15), walk_m_per_sqrt_s=0.015, height_m=(0.0, 0.08),
                   extremity_jitter=1.5, p_held=0.006, p_swap=0.004, p_clean=0.1, leg_scale=(0.85, 1.15),
                   spine_scale=(0.9, 1.15))

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


def vary_skeleton(frames: np.ndarray, offsets: np.ndarray, rng: np.random.Generator,
                  cfg: CorruptionConfig) -> tuple[np.ndarray, np.ndarray]:
    """Skeleton variation of clean windows (module docstring): frames (B, L, 235) and rest offsets
    (B, 24, 3) m -> the same with each window's leg bones times one factor from ``cfg.leg_scale``
    and spine bones times one from ``cfg.spine_scale`` (joints rebuilt root first from their own
    bone vectors, so the local rotations stay exact; the window's lowest foot height kept). The
    rotations, object and IMU are unchanged. With both ranges (1, 1) the input is returned as it
    is and nothing is drawn."""
    x = np.asarray(frames)
    if x.ndim != 3 or x.shape[-1] != FRAME_DIM:
        raise ValueError(f"frames must be (B, L, {FRAME_DIM}), got {x.shape}")
    off = np.asarray(offsets)
    if off.shape != (x.shape[0], NUM_JOINTS, 3):
        raise ValueError(f"offsets must be ({x.shape[0]}, {NUM_JOINTS}, 3), got {off.shape}")
    if not cfg.varies_skeleton:
        return frames, offsets
    B, L, _ = x.shape
    scale = np.ones((B, NUM_JOINTS))
    scale[:, _LEG_BONES] = rng.uniform(*cfg.leg_scale, (B, 1))
    scale[:, _SPINE_BONES] = rng.uniform(*cfg.spine_scale, (B, 1))
    J = x[..., JOINTS].reshape(B, L, NUM_JOINTS, 3).astype(np.float64)
    out_j = J.copy()
    for j in range(1, NUM_JOINTS):  # PARENTS[j] < j: parents first
        p = PARENTS[j]
        out_j[:, :, j] = out_j[:, :, p] + scale[:, None, j, None] * (J[:, :, j] - J[:, :, p])
    low = lambda X: X[:, :, _FEET, 2].min(axis=(1, 2))  # (B,) the window's lowest foot height
    out_j[..., 2] += (low(J) - low(out_j))[:, None, None]
    out = np.array(x, copy=True)
    out[..., JOINTS] = out_j.reshape(B, L, -1).astype(out.dtype)
    return out, (off * scale[..., None]).astype(off.dtype)


def _part_src(held: np.ndarray) -> np.ndarray:
    """(..., L) bool runs of held frames -> (..., L) the frame each frame shows (its own, or the last
    one before the run); a run at frame 0 is dropped."""
    held = held.copy()
    held[..., 0] = False
    L = held.shape[-1]
    return np.maximum.accumulate(np.where(held, 0, np.arange(L)), axis=-1)


def _wider_body(J: np.ndarray, fps: float, rng: np.random.Generator, c: CorruptionConfig,
                scale: float | np.ndarray = 1.0) -> None:
    """The wider family's kinds that act on the tracked body itself, on J (B, L, 24, 3) in place: the
    random-walk drift, the height offset, the extremities' extra jitter (times ``scale``, the window's
    severity factor (B, 1, 1, 1) or 1, the one the jitter got) and bursts."""
    B, L = J.shape[:2]
    if c.walk_m_per_sqrt_s > 0:
        steps = rng.normal(0.0, c.walk_m_per_sqrt_s / np.sqrt(fps), (B, L, 3)) * np.array([1.0, 1.0, c.walk_vertical])
        walk = np.cumsum(steps, axis=1)
        J += (walk - walk[:, :1])[:, :, None]
    if c.height_m[1] > 0:
        J[..., 2] += (rng.uniform(*c.height_m, B) * rng.choice([-1.0, 1.0], B))[:, None, None]
    if c.extremity_jitter != 1.0:  # the extremities' total jitter: extremity_jitter x jitter_m (x the severity)
        extra = np.sqrt(max(c.extremity_jitter ** 2 - 1.0, 0.0)) * c.jitter_m
        J[:, :, _EXTREMITIES] += scale * rng.normal(0.0, extra, (B, L, len(_EXTREMITIES), 3))
    if c.p_burst > 0:
        burst = _runs(rng, (B, L), c.p_burst, c.burst_frames)
        J += burst[..., None, None] * rng.normal(0.0, c.burst_m, J.shape)


def _wider_output(out: np.ndarray, x: np.ndarray, rng: np.random.Generator, c: CorruptionConfig,
                  no_rot: np.ndarray) -> None:
    """The wider family's kinds that act on the tracker's output, on ``out`` (B, L, 235) in place:
    leg swaps, then silent held parts (bit-for-bit repeats, no missing flag); entries missing before
    stay missing; then the clean windows (``x``: the clean frames; ``no_rot`` (B,): windows
    without rotations)."""
    B, L, _ = out.shape
    J = out[..., JOINTS].reshape(B, L, NUM_JOINTS, 3).copy()
    R = out[..., ROTATIONS].reshape(B, L, NUM_JOINTS, 6).copy()
    missing, rot_missing = np.isnan(J), np.isnan(R)
    if c.p_swap > 0:
        swap = _runs(rng, (B, L), c.p_swap, c.swap_frames)[..., None, None]
        a, b = _LEGS
        for A in (J, R):
            left, right = A[:, :, a].copy(), A[:, :, b].copy()
            A[:, :, a] = np.where(swap, right, left)
            A[:, :, b] = np.where(swap, left, right)
    if c.p_held > 0:
        held = _runs(rng, (B, len(_HELD_PARTS), L), c.p_held / len(_HELD_PARTS), c.held_frames)
        for k, cols in enumerate(_HELD_PARTS):
            src = _part_src(held[:, k])[:, :, None, None]  # (B, L, 1, 1)
            for A in (J, R):
                A[:, :, cols] = np.take_along_axis(A[:, :, cols], src, axis=1)
    J[missing] = np.nan
    R[rot_missing] = np.nan
    out[..., JOINTS] = J.reshape(B, L, -1)
    out[..., ROTATIONS] = R.reshape(B, L, -1)
    if c.p_clean > 0:
        clean = rng.random(B) < c.p_clean
        out[clean, :, JOINTS] = x[clean][..., JOINTS]
        keep_rot = clean & ~no_rot
        out[keep_rot, :, ROTATIONS] = x[keep_rot][..., ROTATIONS]


def corrupt(frames: np.ndarray, fps: float, rng: np.random.Generator,
            cfg: CorruptionConfig = CorruptionConfig(), parts: dict | None = None) -> np.ndarray:
    """Clean frame vectors (B, L, 235) (world, IMU from ``add_clean_imu``) -> tracked-like frame
    vectors (B, L, 235) with NaN = missing, by the model in the module docstring. ``parts``: a dict
    to receive known components for diagnosis: ``body_drift`` (B, L, 3) m, the whole-body drift
    every joint got (severity-scaled; without the wider family's random walk and height). The result
    does not depend on it. Skeleton variation is not applied here (``vary_skeleton``: it changes
    the clean target too)."""
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
    Jt = J + scale * (noise + spikes + drift)
    wide = np.random.default_rng(rng.integers(0, 2 ** 63)) if c.wider else None  # drawn only when on
    if wide is not None:
        _wider_body(Jt, fps, wide, c, scale)
    out[..., JOINTS] = Jt.reshape(B, L, -1)
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
    no_rot = rng.random(B) < c.p_no_rotations
    out[no_rot, :, ROTATIONS] = np.nan
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
    if wide is not None:
        _wider_output(out, x, wide, c, no_rot)
    return out.astype(np.float32)

