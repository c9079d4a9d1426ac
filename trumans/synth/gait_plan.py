"""The root plan of locomotion: smoothed paths, speed profiles, walk and turn-in-place plans as
per-frame pelvis xy, heading and speed, with the foot swings (timing only) and action labels."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from trumans.actions import ActionInterval
from .legs import wrap_angle
from .poses import ease

__all__ = ["smooth_path", "arc_length", "speed_profile", "Timeline", "turn_plan", "walk_plan"]

def smooth_path(path: np.ndarray, spacing: float = 0.02, sigma_m: float = 0.25) -> np.ndarray:
    """Resample a polyline (K, 2) at ``spacing`` m and round its corners with a Gaussian of
    ``sigma_m`` m; odd reflection at the ends keeps both end points exactly."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    path = path[keep]
    if len(path) < 2:
        return np.repeat(path, 2, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    n = max(int(np.ceil(s[-1] / spacing)), 2) + 1
    u = np.linspace(0, s[-1], n)
    pts = np.stack([np.interp(u, s, path[:, 0]), np.interp(u, s, path[:, 1])], axis=1)
    sig = min(sigma_m / spacing, (n - 1) / 4.0)
    pad = min(int(4 * sig) + 1, n - 1)
    if sig < 0.5 or pad < 1:
        return pts
    ext = np.concatenate([2 * pts[0] - pts[1:pad + 1][::-1], pts, 2 * pts[-1] - pts[-pad - 1:-1][::-1]])
    sm = gaussian_filter1d(ext, sig, axis=0, mode="nearest")[pad:pad + n]
    sm[0], sm[-1] = pts[0], pts[-1]
    return sm


def arc_length(pts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def speed_profile(pts: np.ndarray, speed: float, fps: float) -> np.ndarray:
    """Arc length s(t) (T,) along the smoothed path ``pts`` (N, 2): start from rest, cruise at
    ``speed`` m/s, slow down in tight turns (lateral acceleration <= 1 m/s^2, heading rate <= 1.8
    rad/s), stop at the end; accelerations <= ~0.9 m/s^2; ends exactly at the path length."""
    s_path = arc_length(pts)
    length = float(s_path[-1])
    ds = np.diff(s_path)
    d1 = np.gradient(pts, s_path, axis=0)
    d2 = np.gradient(d1, s_path, axis=0)
    kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum((d1**2).sum(1) ** 1.5, 1e-9)
    kappa = maximum_filter1d(kappa, 9) if len(kappa) > 9 else kappa
    v_lim = np.minimum.reduce([np.full_like(kappa, speed), np.sqrt(1.0 / np.maximum(kappa, 1e-9)),
                               1.8 / np.maximum(kappa, 1e-9)])
    v_lim = np.maximum(v_lim, 0.3)
    a_max = 0.45 + 0.35 * speed
    v = v_lim.copy()
    v[0] = v[-1] = 0.0
    for k in range(1, len(v)):  # forward pass: accelerate at most a_max
        v[k] = min(v[k], np.sqrt(v[k - 1] ** 2 + 2 * a_max * ds[k - 1]))
    for k in range(len(v) - 2, -1, -1):  # backward pass: brake at most a_max
        v[k] = min(v[k], np.sqrt(v[k + 1] ** 2 + 2 * a_max * ds[k]))
    # Time along the path, then a smooth s(t) resampled at fps.
    v_mid = np.maximum(0.5 * (v[1:] + v[:-1]), 1e-3)
    t_path = np.concatenate([[0.0], np.cumsum(ds / v_mid)])
    total = float(t_path[-1])
    T = max(int(np.ceil(total * fps)) + 1, 2)
    t = np.linspace(0.0, total, T)
    s = np.interp(t, t_path, s_path)
    if T > 5:  # soften the acceleration corners, keep both ends
        sig = 0.12 * fps
        pad = int(4 * sig) + 1
        ext = np.concatenate([2 * s[0] - s[1:pad + 1][::-1], s, 2 * s[-1] - s[-pad - 1:-1][::-1]])
        s = gaussian_filter1d(ext, sig)[pad:pad + T]
        s = np.maximum.accumulate(np.clip(s, 0.0, length))
        s[0], s[-1] = 0.0, length
    return s


def _yaw_blend(y0: float, y1: np.ndarray, w: np.ndarray) -> np.ndarray:
    return y0 + w * wrap_angle(y1 - y0)


class Timeline:
    """Accumulates the root plan (pelvis xy, yaw, speed per frame), swings and labels."""

    def __init__(self, fps: float):
        self.fps = fps
        self.xy: list[np.ndarray] = []
        self.yaw: list[np.ndarray] = []
        self.speed: list[np.ndarray] = []
        self.swings: list[tuple[float, int, float]] = []  # (centre time s, foot 0/1, duration s)
        self.labels: list[ActionInterval] = []
        self.T = 0

    def add(self, xy: np.ndarray, yaw: np.ndarray, speed: np.ndarray, swings: list[tuple[float, int, float]],
            label: str) -> None:
        t0 = self.T / self.fps
        self.xy.append(xy)
        self.yaw.append(yaw)
        self.speed.append(speed)
        self.swings += [(t0 + c, f, d) for c, f, d in swings]
        self.labels.append(ActionInterval(label, self.T, self.T + len(xy)))
        self.T += len(xy)

    def next_foot(self) -> int | None:
        return None if not self.swings else 1 - self.swings[-1][1]


def turn_plan(xy: np.ndarray, y0: float, y1: float, fps: float, first_foot: int | None):
    """Turn in place from yaw y0 to y1: frames of (xy, yaw, speed) and swings."""
    d = float(wrap_angle(y1 - y0))
    dur = 0.5 + abs(d) / 2.2
    T = max(int(np.ceil(dur * fps)) + 1, 2)
    t = np.linspace(0.0, dur, T)
    yaw = y0 + d * ease(t / dur)
    n = int(np.ceil(abs(d) / np.radians(40))) + 1
    foot = (0 if d > 0 else 1) if first_foot is None else first_foot  # step first with the foot on the turn side
    period = dur / n
    swing = min(0.9 * period, 0.5)
    swings = [(period * (i + 0.5), (foot + i) % 2, swing) for i in range(n)]
    return np.repeat(np.asarray(xy, dtype=np.float64)[None, :2], T, axis=0), yaw, np.zeros(T), swings


def walk_plan(pts: np.ndarray, speed: float, step_len: float, fps: float, y_start: float, y_end: float,
              first_foot: int):
    s_path = arc_length(pts)
    s = speed_profile(pts, speed, fps)
    T = len(s)
    xy = np.stack([np.interp(s, s_path, pts[:, 0]), np.interp(s, s_path, pts[:, 1])], axis=1)
    tang = np.gradient(pts, axis=0)
    path_yaw = np.unwrap(np.arctan2(tang[:, 1], tang[:, 0]))
    yaw = np.interp(s, s_path, path_yaw)
    t = np.arange(T) / fps
    dur = t[-1]
    blend = min(0.6, dur / 3)  # absorb small start/end heading differences
    yaw = _yaw_blend(y_start, yaw, ease(t / blend)) if blend > 0 else yaw
    yaw = yaw + ease((t - (dur - blend)) / blend) * wrap_angle(y_end - yaw) if blend > 0 else yaw
    vel = np.gradient(s, t) if T > 1 else np.zeros(T)
    # Gait phase in steps: cadence follows the speed (step_len per step), with a floor for the
    # slow start and stop; step i swings around phase i + 1/2.
    cadence = np.maximum(vel / step_len, 1.25)
    phase = np.concatenate([[0.0], np.cumsum(0.5 * (cadence[1:] + cadence[:-1]) * np.diff(t))])
    # Each foot's last step goes to the final stance: the two closing steps end just before the stop
    # and the phase is rescaled a little so the regular steps lead into them without a pause.
    s_close = min(1.15 / float(cadence[-1]), 0.45, dur / 3)
    c_last = dur - 0.04 - s_close / 2
    c_pen = c_last - s_close
    phi_pen = float(np.interp(c_pen, t, phase))
    n_reg = int(np.ceil(phi_pen - 0.5 - 1e-6))  # ceil: steps only get shorter, never longer
    swings = []
    if c_pen - s_close / 2 > 0.02 and n_reg >= 0:
        phase = phase * ((n_reg + 0.5) / max(phi_pen, 1e-6))
        for i in range(n_reg):
            c = float(np.interp(i + 0.5, phase, t))
            dur_i = min(1.4 / float(np.interp(c, t, cadence)), 0.9)
            swings.append((max(c, dur_i / 2 + 0.02), (first_foot + i) % 2, dur_i))
        swings += [(c_pen, (first_foot + n_reg) % 2, s_close), (c_last, (first_foot + n_reg + 1) % 2, s_close)]
    else:  # very short walk: two quick steps
        d2 = min(dur / 2.2, 0.5)
        swings = [(0.02 + d2 / 2, first_foot, d2), (dur - 0.02 - d2 / 2, 1 - first_foot, d2)]
    return xy, yaw, vel, swings
