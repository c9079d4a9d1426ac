"""Footsteps: per-take gait style, the stances the swings leave, and the ankle / foot tracks of
each swing (toe-off over the planted toe, flight, heel strike over the heel)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from trumans.rotations import euler_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX
from .gait_plan import Timeline
from .legs import foot_places, rest_ankle_rel, wrap_angle
from .poses import ease

__all__ = ["Style", "stance_plan", "foot_tracks", "SWING_PIVOT", "SWING_LAND"]

@dataclass
class Style:
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
    def draw(rng: np.random.Generator) -> "Style":
        u = rng.uniform
        return Style(arm_swing=u(0.2, 0.38), elbow=u(0.05, 0.25), lean=u(0.02, 0.08), twist=u(0.04, 0.09),
                     width=u(0.75, 1.0), toe_out=u(0.0, 0.12), lift=u(0.05, 0.08), head=u(-0.05, 0.08))


def stance_plan(tl: Timeline, offsets: np.ndarray, style: Style, rng: np.random.Generator):
    """Per foot: list of stances (t_on, t_off, ankle xy (2,), foot yaw) from the swings."""
    xy = np.concatenate(tl.xy)
    yaw = np.concatenate(tl.yaw)
    T = len(xy)
    fps = tl.fps
    t_end = (T - 1) / fps
    rel = rest_ankle_rel(offsets)
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
SWING_PIVOT = 0.30
SWING_LAND = 0.88
_TOE_OFF_PITCH = 0.60  # rad, foot pitch (toe down) when the toe leaves the floor
_PEAK_PITCH = 0.85  # rad, the largest pitch, reached _PEAK_AFTER (swing fraction) after toe-off: the
_PEAK_AFTER = 0.20  # foot keeps rotating through toe-off, so the heel rise lifts the ankle steadily
_HEEL_ON_PITCH = 0.20  # rad, foot pitch (toe up) when the heel touches down
_MIN_TOE_LIFT = 0.04  # m, least toe clearance of a swing (clears the 2 cm contact band early)
_TOE_RISE = 0.35  # fraction of the flight over which the toe's vertical speed eases in (and out at landing)
_GLIDE_DELAY = 0.12  # fraction of the flight before the toe starts to travel horizontally
_GLIDE_RAMP = 0.35  # fraction of the toe's travel time spent speeding up (and slowing down)


def _glide(x: np.ndarray, ramp: float = _GLIDE_RAMP) -> np.ndarray:
    """Progress (0 -> 1) at x in [0, 1] of a travel whose speed rises smoothly (quintic ease) over
    the first ``ramp`` of the time, stays constant, and falls over the last ``ramp``: zero speed and
    acceleration at both ends, peak speed ~1 / (1 - ramp) of the mean (1.875 for ``ease``)."""
    g = np.linspace(0.0, 1.0, 401)
    v = ease(g / ramp) * ease((1.0 - g) / ramp)
    c = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]))])
    return np.interp(np.clip(x, 0.0, 1.0), g, c / c[-1])


def _swing_pitch(s: np.ndarray) -> np.ndarray:
    """Foot pitch (rad, toe down > 0) at swing phases s (n,): one C2 curve (clamped cubic spline)
    from flat (0) through _TOE_OFF_PITCH at SWING_PIVOT and its peak _PEAK_PITCH shortly after to
    -_HEEL_ON_PITCH at SWING_LAND, so the foot keeps rotating through the toe-off -> flight change (no
    stop-and-go jerk; the ankle keeps rising, so the trailing knee bends on without straightening
    again in the heel rise), then an eased roll flat."""
    s = np.clip(s, 0.0, 1.0)
    knots = np.array([0.0, SWING_PIVOT, SWING_PIVOT + _PEAK_AFTER, SWING_LAND])
    vals = np.array([0.0, _TOE_OFF_PITCH, _PEAK_PITCH, -_HEEL_ON_PITCH])
    flight = CubicSpline(knots, vals, bc_type="clamped")(np.minimum(s, SWING_LAND))
    # Heel strike: the foot rolls flat from a standstill about the heel (eased).
    return np.where(s < SWING_LAND, flight, -_HEEL_ON_PITCH * (1.0 - ease((s - SWING_LAND) / (1.0 - SWING_LAND))))


def _swing(s: np.ndarray, place0: np.ndarray, yaw0: float, place1: np.ndarray, yaw1: float, z0: float,
           foot_off: np.ndarray, heel_off: np.ndarray, lift: float) -> tuple[np.ndarray, np.ndarray]:
    """Ankle targets (n, 3) and foot rotations (n, 3, 3) of one swing at phases s (n,) in (0, 1), from
    the flat stance at ankle xy ``place0`` / foot yaw ``yaw0`` to the one at ``place1`` / ``yaw1``.

    Toe-off: the foot pitches toe-down about the toe joint, which stays where it was (no slide);
    flight: the toe rises ``lift`` m (at least _MIN_TOE_LIFT) before it travels (and the foot turns)
    to where the heel lands with the toe up, the foot pitching about it on its way (the toe does not
    slide while still near the floor); heel strike: the foot pitches flat about the heel point
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
    toe_land = heel1 + R(np.array(yaw1), np.array(-_HEEL_ON_PITCH)) @ (foot_off - heel_off)
    ank = np.empty((len(s), 3))
    frot = np.empty((len(s), 3, 3))
    # toe-off: roll over the toe
    pitch = _swing_pitch(s)
    m = s < SWING_PIVOT
    if m.any():
        frot[m] = R(np.full(m.sum(), yaw0), pitch[m])
        ank[m] = toe0 - frot[m] @ foot_off
    # flight: the toe rises, then travels (slow start, so it barely moves while low), the foot turns on the way
    m = (s >= SWING_PIVOT) & (s < SWING_LAND)
    if m.any():
        u = (s[m] - SWING_PIVOT) / (SWING_LAND - SWING_PIVOT)
        w = _glide((u - _GLIDE_DELAY) / (1.0 - _GLIDE_DELAY))
        e = ease(u)
        # The toe rises by about the lift: a sin bump whose ends are eased in, so the toe leaves and
        # meets the floor with zero vertical speed and acceleration (no velocity jump).
        bump = np.sin(np.pi * u) * ease(u / _TOE_RISE) * ease((1.0 - u) / _TOE_RISE)
        toe = toe0 + w[:, None] * (toe_land - toe0)
        toe[:, 2] = toe0[2] + e * (toe_land[2] - toe0[2]) + max(lift, _MIN_TOE_LIFT) * bump
        frot[m] = R(yaw0 + w * dyaw, pitch[m])
        ank[m] = toe - frot[m] @ foot_off
    # heel strike: roll down over the heel
    m = s >= SWING_LAND
    if m.any():
        v = (s[m] - SWING_LAND) / (1.0 - SWING_LAND)
        frot[m] = R(np.full(m.sum(), yaw1), pitch[m])
        ank[m] = heel1 - frot[m] @ heel_off
    return ank, frot


def foot_tracks(stances, offsets: np.ndarray, T: int, fps: float, style: Style):
    """Ankle targets (T, 2, 3), foot rotations (T, 2, 3, 3), flat contact (T, 2) bool."""
    t = np.arange(T) / fps
    ank = np.zeros((T, 2, 3))
    frot = np.zeros((T, 2, 3, 3))
    contact = np.zeros((T, 2), dtype=bool)
    rel = rest_ankle_rel(offsets)
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
