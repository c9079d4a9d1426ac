"""Procedural locomotion: walking along a path, turning in place and idle standing.

Every motion starts and ends in the *canonical standing state* of ``standing_state`` (pose 'stand',
pelvis at the actor's rest height, feet at their rest places, legs solved by IK), so primitives
concatenate without jumps. Feet are planted by leg IK: during a (flat-foot) stance the ankle target
is fixed in the world and the foot keeps its world orientation, so planted joints do not slide.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from trumans.actions import ActionInterval
from trumans.rotations import euler_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX, forward_kinematics
from trumans.ik.limb import limb_reach, set_global_rotation, solve_limb
from .motion import Motion
from .poses import POSES, ease, pose

__all__ = [
    "pelvis_height_limit", "stand_height", "standing_state", "foot_places", "walk", "turn", "stand",
    "solve_legs", "wrap_angle",
]

_ANKLES = (JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"])
_HIPS = (JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"])
_LEGS = ("left_leg", "right_leg")


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap radians to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def _rest_ankle_rel(offsets: np.ndarray) -> np.ndarray:
    """(2, 3) left/right ankle positions relative to the pelvis in the rest pose (body frame)."""
    rot = np.tile(np.eye(3), (1, 24, 1, 1))
    P, _ = forward_kinematics(rot, np.zeros((1, 3)), offsets)
    return P[0, list(_ANKLES)]


def stand_height(offsets: np.ndarray) -> float:
    """Pelvis height (m) of the canonical standing state: the rest height with the knees softened by
    4 mm (scaled by the leg length) so the legs are not at full extension."""
    leg = min(limb_reach(offsets, "left_leg")[1], limb_reach(offsets, "right_leg")[1])
    return float(offsets[0, 2] - 0.004 * leg / 0.784)


def foot_places(offsets: np.ndarray, pos: np.ndarray, yaw: float) -> np.ndarray:
    """(2, 3) world ankle positions (left, right) of the canonical stance at pelvis xy ``pos`` (2,), ``yaw``."""
    rel = _rest_ankle_rel(offsets)
    out = (yaw_matrix(yaw) @ rel.T).T
    out[:, :2] += np.asarray(pos, dtype=np.float64)[:2]
    out[:, 2] = offsets[0, 2] + rel[:, 2]
    return out


def solve_legs(
    rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, ankle_targets: np.ndarray,
    foot_rot: np.ndarray | None = None, pole_dir: np.ndarray | None = None,
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Both legs to world ankle targets (T, 2, 3); ``foot_rot`` (T, 2, 3, 3) sets the ankles' global
    rotations (default: keep them); ``pole_dir`` (T, 3) world knee direction (default: pelvis forward).
    Returns (rot (T, 24, 3, 3), reached (T, 2) bool)."""
    reached = np.ones((rot.shape[0], 2), dtype=bool)
    for i, limb in enumerate(_LEGS):
        pole = None
        if pole_dir is not None:
            P, _ = forward_kinematics(rot, root, offsets)
            pole = P[:, _HIPS[i]] + pole_dir
        rot, reached[:, i] = solve_limb(rot, root, offsets, limb, ankle_targets[:, i], pole=pole, mask=mask)
        if foot_rot is not None:
            rot = set_global_rotation(rot, root, offsets, _ANKLES[i], foot_rot[:, i])
    return rot, reached


def pelvis_height_limit(rot: np.ndarray, root_xy: np.ndarray, offsets: np.ndarray, ankle_targets: np.ndarray,
                        reach_frac: float = 0.999) -> np.ndarray:
    """Highest pelvis z (T,) (m) at which both legs still reach their ankle targets (T, 2, 3), given
    the local rotations rot (T, 24, 3, 3) (root orientation included) and pelvis xy (T, 2)."""
    T = rot.shape[0]
    P0, _ = forward_kinematics(rot, np.column_stack([root_xy, np.zeros(T)]), offsets)
    h_lim = np.full(T, np.inf)
    for f in range(2):
        reach = limb_reach(offsets, _LEGS[f])[1] * reach_frac
        hip = P0[:, _HIPS[f]]
        dh2 = ((ankle_targets[:, f, :2] - hip[:, :2]) ** 2).sum(1)
        h_lim = np.minimum(h_lim, ankle_targets[:, f, 2] + np.sqrt(np.maximum(reach**2 - dh2, 0.0)) - hip[:, 2])
    return h_lim


def standing_state(
    offsets: np.ndarray, pos: np.ndarray, yaw: float, base_pose: str = "stand"
) -> tuple[np.ndarray, np.ndarray]:
    """Canonical standing state: (rot (24, 3, 3), root (3,)) with pelvis xy ``pos`` (2,) at the
    actor's rest height, heading ``yaw`` (rad), upper body ``base_pose``, feet at ``foot_places``."""
    rot = pose(base_pose, offsets)[None].copy()
    rot[0, 0] = yaw_matrix(yaw)
    root = np.array([[pos[0], pos[1], stand_height(offsets)]], dtype=np.float64)
    feet = foot_places(offsets, pos, yaw)[None]
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=np.broadcast_to(yaw_matrix(yaw), (1, 2, 3, 3)))
    return rot[0], root[0]


@dataclass
class _Style:
    """Per-take style parameters (drawn once per motion from the rng)."""

    arm_swing: float  # rad, shoulder swing amplitude at 1.2 m/s
    elbow: float  # rad, extra elbow flexion while walking
    lean: float  # rad, trunk forward lean at 1.2 m/s
    twist: float  # rad, pelvis yaw amplitude
    width: float  # scale of the step width
    toe_out: float  # rad, feet yaw outwards
    lift: float  # m, swing ankle lift
    head: float  # rad, head pitch

    @staticmethod
    def draw(rng: np.random.Generator) -> "_Style":
        u = rng.uniform
        return _Style(arm_swing=u(0.2, 0.38), elbow=u(0.05, 0.25), lean=u(0.02, 0.08), twist=u(0.04, 0.09),
                      width=u(0.75, 1.0), toe_out=u(0.0, 0.12), lift=u(0.05, 0.08), head=u(-0.05, 0.08))


def _smooth_path(path: np.ndarray, spacing: float = 0.02, sigma_m: float = 0.25) -> np.ndarray:
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


def _arc_length(pts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def _speed_profile(pts: np.ndarray, speed: float, fps: float) -> np.ndarray:
    """Arc length s(t) (T,) along the smoothed path ``pts`` (N, 2): start from rest, cruise at
    ``speed`` m/s, slow down in tight turns (lateral acceleration <= 1 m/s^2, heading rate <= 1.8
    rad/s), stop at the end; accelerations <= ~0.9 m/s^2; ends exactly at the path length."""
    s_path = _arc_length(pts)
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


class _Timeline:
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
        self.labels.append(ActionInterval(label, self.T, self.T + len(xy) - 1))
        self.T += len(xy)

    def next_foot(self) -> int | None:
        return None if not self.swings else 1 - self.swings[-1][1]


def _turn_plan(xy: np.ndarray, y0: float, y1: float, fps: float, first_foot: int | None):
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


def _walk_plan(pts: np.ndarray, speed: float, step_len: float, fps: float, y_start: float, y_end: float,
               first_foot: int):
    s_path = _arc_length(pts)
    s = _speed_profile(pts, speed, fps)
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
    cadence = np.maximum(vel / step_len, 1.6)
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
            dur_i = min(1.15 / float(np.interp(c, t, cadence)), 0.6)
            swings.append((max(c, dur_i / 2 + 0.02), (first_foot + i) % 2, dur_i))
        swings += [(c_pen, (first_foot + n_reg) % 2, s_close), (c_last, (first_foot + n_reg + 1) % 2, s_close)]
    else:  # very short walk: two quick steps
        d2 = min(dur / 2.2, 0.5)
        swings = [(0.02 + d2 / 2, first_foot, d2), (dur - 0.02 - d2 / 2, 1 - first_foot, d2)]
    return xy, yaw, vel, swings


def _stance_plan(tl: _Timeline, offsets: np.ndarray, style: _Style, rng: np.random.Generator):
    """Per foot: list of stances (t_on, t_off, ankle xy (2,), foot yaw) from the swings."""
    xy = np.concatenate(tl.xy)
    yaw = np.concatenate(tl.yaw)
    T = len(xy)
    fps = tl.fps
    t_end = (T - 1) / fps
    rel = _rest_ankle_rel(offsets)
    stances: list[list[tuple[float, float, np.ndarray, float]]] = [[], []]
    final = foot_places(offsets, xy[-1], float(yaw[-1]))
    start = foot_places(offsets, xy[0], float(yaw[0]))
    for f in range(2):
        sw = sorted([(c - d / 2, c + d / 2) for c, ff, d in tl.swings if ff == f])
        ons = [0.0] + [b for _, b in sw]
        offs = [a for a, _ in sw] + [t_end]
        for k, (on, off) in enumerate(zip(ons, offs)):
            if k == 0:
                stances[f].append((on, off, start[f, :2], float(yaw[0])))
                continue
            if k == len(ons) - 1:
                stances[f].append((on, off, final[f, :2], float(yaw[-1])))
                continue
            m = 0.5 * (on + off)
            i = int(np.clip(round(m * fps), 0, T - 1))
            side = 1.0 if f == 0 else -1.0
            r = np.array([rel[f, 0] + 0.03, rel[f, 1] * style.width])
            Ry = yaw_matrix(yaw[i])[:2, :2]
            place = xy[i] + Ry @ r + rng.normal(0, 0.006, 2)
            stances[f].append((on, off, place, float(yaw[i]) + side * style.toe_out * min(1.0, k / 2)))
    return stances


# Swing phases (fractions of the swing time): the foot rolls over the planted toe until SWING_PIVOT
# (heel off, toe fixed), flies until SWING_LAND (the toe first rises clear of the floor, then moves),
# and rolls down over the planted heel until the swing ends (flat foot).
SWING_PIVOT = 0.20
SWING_LAND = 0.88
_TOE_OFF_PITCH = 0.45  # rad, foot pitch (toe down) when the toe leaves the floor
_HEEL_ON_PITCH = 0.20  # rad, foot pitch (toe up) when the heel touches down
_MIN_TOE_LIFT = 0.04  # m, least toe clearance of a swing (clears the 2 cm contact band early)
_TOE_RISE = 0.08  # fraction of the flight during which the toe rises before it moves horizontally
_GLIDE_RAMP = 0.35  # fraction of the toe's travel time spent speeding up (and slowing down)


def _glide(x: np.ndarray, ramp: float = _GLIDE_RAMP) -> np.ndarray:
    """Progress (0 -> 1) at x in [0, 1] of a travel whose speed rises smoothly (quintic ease) over
    the first ``ramp`` of the time, stays constant, and falls over the last ``ramp``: zero speed and
    acceleration at both ends, peak speed ~1 / (1 - ramp) of the mean (1.875 for ``ease``)."""
    g = np.linspace(0.0, 1.0, 401)
    v = ease(g / ramp) * ease((1.0 - g) / ramp)
    c = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]))])
    return np.interp(np.clip(x, 0.0, 1.0), g, c / c[-1])


def _swing(s: np.ndarray, place0: np.ndarray, yaw0: float, place1: np.ndarray, yaw1: float, z0: float,
           foot_off: np.ndarray, heel_off: np.ndarray, lift: float) -> tuple[np.ndarray, np.ndarray]:
    """Ankle targets (n, 3) and foot rotations (n, 3, 3) of one swing at phases s (n,) in (0, 1), from
    the flat stance at ankle xy ``place0`` / foot yaw ``yaw0`` to the one at ``place1`` / ``yaw1``.

    Toe-off: the foot pitches toe-down about the toe joint, which stays where it was (no slide);
    flight: the toe rises ``lift`` m (at least _MIN_TOE_LIFT) before the foot travels (its middle
    moves, the foot turns about it) to where the heel lands with the toe up; heel strike: the foot pitches flat about the heel point
    (``heel_off``, foot frame, on the floor). z0: ankle height of the flat foot; foot_off: the
    ankle -> toe (foot joint) offset in the foot frame."""
    def R(yaw, pitch):
        z = np.zeros_like(pitch)
        return yaw_matrix(yaw) @ euler_to_matrix(np.stack([z, pitch, z], -1), "ZYX")

    a0 = np.array([place0[0], place0[1], z0])
    a1 = np.array([place1[0], place1[1], z0])
    toe0 = a0 + yaw_matrix(yaw0) @ foot_off  # planted toe of the stance that ends
    heel1 = a1 + yaw_matrix(yaw1) @ heel_off  # where the heel lands (on the floor)
    dyaw = float(wrap_angle(yaw1 - yaw0))
    # In flight the foot moves its middle (half way from the ankle to the toe) and turns about it.
    mid = 0.5 * foot_off
    mid0 = toe0 + R(np.array(yaw0), np.array(_TOE_OFF_PITCH)) @ (mid - foot_off)
    mid_land = heel1 + R(np.array(yaw1), np.array(-_HEEL_ON_PITCH)) @ (mid - heel_off)
    toe_land = heel1 + R(np.array(yaw1), np.array(-_HEEL_ON_PITCH)) @ (foot_off - heel_off)
    ank = np.empty((len(s), 3))
    frot = np.empty((len(s), 3, 3))
    # toe-off: roll over the toe
    m = s < SWING_PIVOT
    if m.any():
        p = _TOE_OFF_PITCH * ease(s[m] / SWING_PIVOT)
        frot[m] = R(np.full(m.sum(), yaw0), p)
        ank[m] = toe0 - frot[m] @ foot_off
    # flight: the toe rises, then travels (slow start, so it barely moves while low), turns on the way
    m = (s >= SWING_PIVOT) & (s < SWING_LAND)
    if m.any():
        u = (s[m] - SWING_PIVOT) / (SWING_LAND - SWING_PIVOT)
        w = _glide((u - _TOE_RISE) / (1.0 - _TOE_RISE))
        e = ease(u)
        c = mid0 + w[:, None] * (mid_land - mid0)
        # The toe rises by about the lift (its height change from the pitch is added back).
        toe_z = toe0[2] + e * (toe_land[2] - toe0[2]) + max(lift, _MIN_TOE_LIFT) * np.sin(np.pi * u)
        frot[m] = R(yaw0 + e * dyaw, _TOE_OFF_PITCH + e * (-_HEEL_ON_PITCH - _TOE_OFF_PITCH))
        c[:, 2] = toe_z - (frot[m] @ (foot_off - mid))[:, 2]
        ank[m] = c - frot[m] @ mid
    # heel strike: roll down over the heel
    m = s >= SWING_LAND
    if m.any():
        v = (s[m] - SWING_LAND) / (1.0 - SWING_LAND)
        frot[m] = R(np.full(m.sum(), yaw1), -_HEEL_ON_PITCH * (1.0 - ease(v)))
        ank[m] = heel1 - frot[m] @ heel_off
    return ank, frot


def _foot_tracks(stances, offsets: np.ndarray, T: int, fps: float, style: _Style):
    """Ankle targets (T, 2, 3), foot rotations (T, 2, 3, 3), flat contact (T, 2) bool."""
    t = np.arange(T) / fps
    ank = np.zeros((T, 2, 3))
    frot = np.zeros((T, 2, 3, 3))
    contact = np.zeros((T, 2), dtype=bool)
    rel = _rest_ankle_rel(offsets)
    z0 = offsets[0, 2] + rel[0, 2]  # ankle height with the foot flat
    foot_off = offsets[JOINT_INDEX["left_foot"]]
    # Heel point in the foot frame: on the floor, a little behind the ankle.
    heel_off = np.array([-0.3 * foot_off[0], 0.0, -z0])
    for f in range(2):
        st = stances[f]
        for k, (on, off, place, fy) in enumerate(st):
            sel = (t >= on - 1e-9) & (t <= off + 1e-9)
            ank[sel, f, :2] = place
            ank[sel, f, 2] = z0
            frot[sel, f] = yaw_matrix(fy)
            contact[sel, f] = True
            if k + 1 < len(st):
                on2, _, place2, fy2 = st[k + 1]
                sel = (t > off + 1e-9) & (t < on2 - 1e-9)
                if not sel.any():
                    continue
                s = (t[sel] - off) / (on2 - off)
                dist = np.linalg.norm(place2 - place)
                lift = min(style.lift, 0.02 + 0.15 * dist)
                ank[sel, f], frot[sel, f] = _swing(s, place, fy, place2, fy2, z0, foot_off, heel_off, lift)
    return ank, frot, contact


def _gait_motion(tl: _Timeline, offsets: np.ndarray, rng: np.random.Generator, base_pose: str) -> Motion:
    """Turn a root plan + swings into a full-body Motion (legs by IK to the foot tracks)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    style = _Style.draw(rng)
    fps = tl.fps
    xy = np.concatenate(tl.xy)
    yaw = np.concatenate(tl.yaw)
    speed = np.concatenate(tl.speed)
    T = len(xy)
    stances = _stance_plan(tl, offsets, style, rng)
    ank, frot, contact = _foot_tracks(stances, offsets, T, fps, style)

    # Gait phase signal: +1 when the left foot is ahead of the right one along the heading.
    fwd = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    leg_len = limb_reach(offsets, "left_leg")[1]
    d = np.clip(((ank[:, 0, :2] - ank[:, 1, :2]) * fwd).sum(1) / (0.8 * leg_len), -1, 1)
    vfac = np.clip(speed / 1.2, 0, 1.3)
    # Envelope that is 0 (with zero slope) at both ends so the motion starts/ends canonically.
    t = np.arange(T) / fps
    env = ease(t / 0.4) * ease((t[-1] - t) / 0.4) if T > 2 else np.zeros(T)

    # Lateral pelvis sway towards the stance foot, proportional to which foot is unloaded.
    lat = np.stack([-np.sin(yaw), np.cos(yaw)], axis=1)
    load = contact[:, 0].astype(float) - contact[:, 1].astype(float)
    load = gaussian_filter1d(load, 0.12 * fps) if T > 3 else load
    xy_root = xy + (0.018 * load * env)[:, None] * lat

    twist = -style.twist * d * np.minimum(vfac, 1.0) * env
    lean = style.lean * vfac * env
    R0 = yaw_matrix(yaw + twist) @ euler_to_matrix(np.stack([np.zeros(T), lean * 0.5, 0.03 * load * env], -1), "ZYX")

    rot = np.repeat(pose(base_pose, offsets)[None], T, axis=0)
    rot[:, 0] = R0
    carry_arms = base_pose != "stand"
    E = lambda z, y, x: euler_to_matrix(np.stack([z, y, x], -1), "ZYX")  # noqa: E731
    zero = np.zeros(T)
    # Counter-rotate the trunk against the pelvis and lean it a bit forward.
    rot[:, JOINT_INDEX["spine3"]] = E(-0.8 * twist, lean * 0.5, zero) @ rot[:, JOINT_INDEX["spine3"]]
    rot[:, JOINT_INDEX["head"]] = E(zero, style.head * env, zero) @ rot[:, JOINT_INDEX["head"]]
    if not carry_arms:  # arms swing opposite to the legs
        a = style.arm_swing * np.minimum(vfac, 1.2) * d * env
        rot[:, JOINT_INDEX["left_shoulder"]] = E(zero, a, zero) @ rot[:, JOINT_INDEX["left_shoulder"]]
        rot[:, JOINT_INDEX["right_shoulder"]] = E(zero, -a, zero) @ rot[:, JOINT_INDEX["right_shoulder"]]
        eb = style.elbow * np.minimum(vfac, 1.0) * env
        le, re = JOINT_INDEX["left_elbow"], JOINT_INDEX["right_elbow"]
        rot[:, le] = E(-eb - 0.3 * np.maximum(-a, 0), zero, zero) @ rot[:, le]
        rot[:, re] = E(eb + 0.3 * np.maximum(a, 0), zero, zero) @ rot[:, re]

    # Pelvis height: the rest height, lowered where an ankle target would be out of reach.
    h_lim = pelvis_height_limit(rot, xy_root, offsets, ank)
    h_rest = stand_height(offsets)
    h_nom = h_rest - 0.012 * np.minimum(vfac, 1.0) * env
    deficit = np.maximum(h_nom - (h_lim - 0.002), 0.0)
    if T > 3:  # spread the dips smoothly (a max-filter first so the smoothed dip covers the raw one)
        w = max(int(0.08 * fps), 1)
        deficit = gaussian_filter1d(maximum_filter1d(deficit, 2 * w + 1), 0.06 * fps, mode="constant")
    h = np.minimum(h_nom - deficit, h_lim - 0.001)
    root = np.column_stack([xy_root, h])

    knee_dir = np.stack([np.cos(yaw), np.sin(yaw), np.zeros(T)], axis=1)
    rot, _ = solve_legs(rot, root, offsets, ank, foot_rot=frot, pole_dir=knee_dir)
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=contact, actions=list(tl.labels))


def _check_common(offsets: np.ndarray, fps: float) -> np.ndarray:
    offsets = np.asarray(offsets, dtype=np.float64)
    if offsets.shape != (24, 3):
        raise ValueError(f"offsets must be (24, 3) (trumans.skeleton.rest_offsets(scale)), got {offsets.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return offsets


def _check_pose(base_pose: str) -> None:
    if base_pose not in POSES:
        raise ValueError(f"unknown base_pose {base_pose!r}; choose one of {sorted(POSES)}")


def walk(
    path: np.ndarray,
    offsets: np.ndarray,
    rng: np.random.Generator,
    speed: float = 1.2,
    fps: float = 30.0,
    start_yaw: float | None = None,
    end_yaw: float | None = None,
    base_pose: str = "stand",
    turn_threshold: float = np.radians(35),
    step_length: float | None = None,
) -> Motion:
    """Walk along world xy waypoints ``path`` (K, 2) m at cruise ``speed`` m/s, starting and stopping
    at rest in the canonical standing state (pelvis xy on the first/last waypoint).

    Heading follows the path tangent; if ``start_yaw``/``end_yaw`` (rad) differ from it by more
    than ``turn_threshold`` the walk begins/ends with a stepping turn in place (label 'turn'),
    smaller differences are blended into the walk. Labels: 'turn', 'walk'. ``foot_contact`` marks
    flat-foot stance frames, during which the ankle and foot joints are fixed in the world.
    ``base_pose`` names the upper-body pose (arms swing only for 'stand'). ``step_length`` (m):
    the cruise step length (default: from the leg length and the speed), e.g. short steps when
    handling something.
    """
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 2:
        raise ValueError(f"path must be (K >= 2, 2) world xy waypoints, got {path.shape}")
    if not 0.2 <= speed <= 2.5:
        raise ValueError(f"speed must be a walking speed in [0.2, 2.5] m/s, got {speed}")
    pts = _smooth_path(path)
    if _arc_length(pts)[-1] < 0.05:
        raise ValueError("path is shorter than 5 cm; use turn() or stand() instead")
    tang0, tang1 = pts[min(3, len(pts) - 1)] - pts[0], pts[-1] - pts[max(len(pts) - 4, 0)]
    y_path0, y_path1 = float(np.arctan2(tang0[1], tang0[0])), float(np.arctan2(tang1[1], tang1[0]))
    y0 = y_path0 if start_yaw is None else float(start_yaw)
    y1 = y_path1 if end_yaw is None else float(end_yaw)
    leg = limb_reach(offsets, "left_leg")[1]
    step_len = leg * (0.38 + 0.25 * min(speed, 1.8)) * rng.uniform(0.95, 1.05)
    if step_length is not None:
        if not 0.1 <= step_length <= 1.2:
            raise ValueError(f"step_length must be in [0.1, 1.2] m, got {step_length}")
        step_len = float(step_length)

    tl = _Timeline(fps)
    if abs(wrap_angle(y_path0 - y0)) > turn_threshold:
        tl.add(*_turn_plan(pts[0], y0, y_path0, fps, None), label="turn")
        y0 = y_path0
    ff = tl.next_foot()
    xy, yaw, vel, swings = _walk_plan(pts, speed, step_len, fps, y0,
                                      y_path1 if abs(wrap_angle(y_path1 - y1)) > turn_threshold else y1,
                                      int(rng.integers(2)) if ff is None else ff)
    if tl.T:  # the turn's last frame is the walk's first state: drop the duplicate
        xy, yaw, vel = xy[1:], yaw[1:], vel[1:]
        swings = [(c - 1 / fps, f, d) for c, f, d in swings]
    tl.add(xy, yaw, vel, swings, label="walk")
    if abs(wrap_angle(y_path1 - y1)) > turn_threshold:
        txy, tyaw, tv, tsw = _turn_plan(pts[-1], float(yaw[-1]), y1, fps, tl.next_foot())
        tl.add(txy[1:], tyaw[1:], tv[1:], [(c - 1 / fps, f, d) for c, f, d in tsw], label="turn")
    return _gait_motion(tl, offsets, rng, base_pose)


def turn(offsets: np.ndarray, pos: np.ndarray, yaw0: float, yaw1: float, rng: np.random.Generator,
         fps: float = 30.0, base_pose: str = "stand") -> Motion:
    """Stepping turn in place at pelvis xy ``pos`` (2,) from heading ``yaw0`` to ``yaw1`` (rad); label 'turn'."""
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    tl = _Timeline(fps)
    tl.add(*_turn_plan(np.asarray(pos, dtype=np.float64), float(yaw0), float(yaw1), fps, None), label="turn")
    return _gait_motion(tl, offsets, rng, base_pose)


def stand(offsets: np.ndarray, pos: np.ndarray, yaw: float, frames: int, rng: np.random.Generator,
          fps: float = 30.0, base_pose: str = "stand") -> Motion:
    """Idle standing for ``frames`` frames at pelvis xy ``pos`` (2,), heading ``yaw`` (rad): breathing,
    a slight sway, feet planted (contact on every frame); starts and ends in the canonical standing
    state. Label 'stand'."""
    offsets = _check_common(offsets, fps)
    _check_pose(base_pose)
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    rot0, root0 = standing_state(offsets, np.asarray(pos, dtype=np.float64), float(yaw), base_pose)
    T = int(frames)
    t = np.arange(T) / fps
    env = ease(t / 0.6) * ease((t[-1] - t) / 0.6) if T > 2 else np.zeros(T)
    f_b = rng.uniform(0.2, 0.3)  # breathing, Hz
    ph = rng.uniform(0, 2 * np.pi, 4)
    breath = np.sin(2 * np.pi * f_b * t + ph[0]) * env
    sway = np.stack([np.sin(2 * np.pi * 0.11 * t + ph[1]), np.sin(2 * np.pi * 0.07 * t + ph[2])], 1)
    sway = sway * rng.uniform(0.004, 0.01) * env[:, None]
    rot = np.repeat(rot0[None], T, axis=0)
    E = lambda z, y, x: euler_to_matrix(np.stack([z, y, x], -1), "ZYX")  # noqa: E731
    zero = np.zeros(T)
    rot[:, JOINT_INDEX["spine2"]] = E(zero, -0.015 * breath, zero) @ rot[:, JOINT_INDEX["spine2"]]
    rot[:, JOINT_INDEX["spine3"]] = E(zero, -0.015 * breath, zero) @ rot[:, JOINT_INDEX["spine3"]]
    rot[:, JOINT_INDEX["head"]] = E(0.05 * np.sin(2 * np.pi * 0.05 * t + ph[3]) * env, 0.01 * breath, zero) \
        @ rot[:, JOINT_INDEX["head"]]
    for side, sgn in (("left", -1.0), ("right", 1.0)):
        j = JOINT_INDEX[f"{side}_shoulder"]
        rot[:, j] = E(zero, zero, sgn * 0.02 * breath) @ rot[:, j]
    root = np.repeat(root0[None], T, axis=0)
    root[:, :2] += (yaw_matrix(yaw)[:2, :2] @ sway.T).T
    root[:, 2] -= 0.01 * env  # soften the knees a little while swaying
    feet = np.repeat(foot_places(offsets, pos, yaw)[None], T, axis=0)
    frot = np.broadcast_to(yaw_matrix(yaw), (T, 2, 3, 3))
    rot, _ = solve_legs(rot, root, offsets, feet, foot_rot=frot)
    return Motion(rot=rot, root=root, offsets=offsets, fps=fps, foot_contact=np.ones((T, 2), dtype=bool),
                  actions=[ActionInterval("stand", 0, T - 1)])
