"""Scene safety of a motion: what a body must never do in a scene, as pure functions of arrays.

Joints are ``(T, 24, 3)`` float, world m, z up; ``sdf`` is a ``trumans.scenes.sdf.SceneSDF`` of
the scene (floor excluded; the functions use its ``enclosed`` form, where the outside of a closed
room is solid, so a body that has passed a wall is deep in it, not in free space). Definitions:

- **crossing** (``swept_dips``, ``crossings``): joint j between frames t-1 and t moves along the
  segment a -> b; the field is sampled along it every ``step`` m (half a voxel). The segment
  crosses a solid when it dips deeper than ``depth`` below both its ends and the surface:
  ``min_s sdf(s) < min(sdf(a), sdf(b), 0) - depth``. A hand that jumps through a 12 cm wall in one
  frame (both ends in free space, the middle 6 cm inside) crosses; a body walking along the wall,
  or a shin sliding along a mattress it is in, does not. Per-frame penetration undercounts the
  first case: after the jump the hand is inside nothing. A joint can also pass a wall over several
  frames, each entering it a little further: a joint that is inside a solid (sdf < -``depth``) for
  a run of frames and leaves it on the other side (the field's gradient where it leaves points
  against the gradient where it entered, cosine < -0.5) crosses at the frame it leaves. A knee that
  dips into a mattress and comes back up does not.
- **exit** (``room_exits``): the pelvis stands on a floor column outside the room
  (``trumans.scenes.sdf.outside_columns``: joined to the grid's border through free space) or
  beyond the field's grid. An open scene has no outside: only leaving the grid counts.
- **depth** (``core_depths``): ``max(0, r_j - sdf(x_j))`` per joint in the enclosed field, ``r_j``
  the body's core radius (``trumans.contacts.rule.JOINT_CORE_RADIUS``): a body outside the room
  is as deep as it is far from the room. (The mesh-exact contact-rule penetration of the synthesis
  figures, ``trumans.eval.synthesis_metrics.penetration_cm``, is the other half of the benchmark's
  penetration figure.)
- **contact depth** (``contact_depths``): that contact-rule penetration measured in the enclosed
  field instead of the meshes: ``max(0, r_eff - sdf(x_j))`` with ``r_eff`` the contact radius
  (``JOINT_RADIUS``) where the field's descent direction (``-gradient``, toward the nearest
  surface) lies within 60 deg of one of the joint's outward directions
  (``trumans.contacts.rule.outward_directions``: a heel, a seat, a lying back) or the joint is
  inside a solid, else the core radius (``trumans.contacts.rule.body_penetration``). Never below
  the core depth; within about 2 cm of the mesh-exact figure where the field sees the surface (a
  part thinner than a voxel may be missing from it: a cabinet's drawer front).
- **floating** / **sinking** frames: on frames the feet carry (``upright``), the lowest foot joint
  more than ``FLOAT_M`` above its resting height (``trumans.skeleton.FOOT_REST_HEIGHT``); on any
  frame, more than ``SINK_M`` below it.
- **feet off** frames: frames that are not lying (``not_lying``) whose two feet each have every
  foot joint more than ``FEET_OFF_M`` above its resting height (the stool perch with both feet in
  the air).
- **seat error** (``seat_errors``): on seated frames, |pelvis height - (seat height + sit offset)|.
- **lying legs** (``lying_leg_depths``): on lying frames, for each leg joint (hips, knees, ankles,
  toes) over the lying surface, how far its skin (``trumans.contacts.rule.JOINT_RADIUS`` below the
  joint) is under the surface: ``max(0, h + r_j - z_j)``.
"""
from __future__ import annotations

import numpy as np
import torch

from trumans.contacts.rule import FACING_COS, JOINT_CORE_RADIUS, JOINT_RADIUS, body_penetration, outward_directions
from trumans.scenes.sdf import SceneSDF
from trumans.skeleton import ANKLES, FEET, FOOT_REST_HEIGHT, HIPS, JOINT_INDEX, KNEES

__all__ = ["CROSS_DEPTH", "FLOAT_M", "SINK_M", "FEET_OFF_M", "LEG_JOINTS", "swept_dips", "crossings",
           "room_exits", "core_depths", "contact_depths", "floating_frames", "sinking_frames", "feet_off_frames", "seat_errors",
           "lying_leg_depths"]

CROSS_DEPTH = 0.01  # m a segment must dip below its ends (and the surface) to cross a solid
FLOAT_M = 0.05  # m: the lowest foot joint this far above its rest on a frame the feet carry is floating
SINK_M = 0.03  # m: the lowest foot joint this far below its rest is sinking into the floor
FEET_OFF_M = 0.05  # m: a foot whose every joint is this far above its rest is off the floor
LEG_JOINTS: tuple[int, ...] = (*HIPS, *KNEES, *ANKLES, *FEET)
_PELVIS = JOINT_INDEX["pelvis"]
_FOOT_SIDES = ((ANKLES[0], FEET[0]), (ANKLES[1], FEET[1]))  # (ankle, toe base) of the left, right foot
_REST = {j: h for j, h in zip((*ANKLES, *FEET), FOOT_REST_HEIGHT)}


def _joints(joints: np.ndarray) -> np.ndarray:
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (24, 3) or not np.isfinite(J).all():
        raise ValueError(f"joints must be finite (T, 24, 3) world m, got shape {J.shape}")
    return J


def _field(sdf: SceneSDF, points: np.ndarray) -> np.ndarray:
    return sdf(torch.as_tensor(points, dtype=torch.float32)).numpy().astype(np.float64)


def swept_dips(joints: np.ndarray, sdf: SceneSDF, step: float | None = None) -> np.ndarray:
    """joints (T, 24, 3) -> (T, 24) m: how far each joint's segment from frame t-1 to t dips below
    ``min(sdf(a), sdf(b), 0)`` in ``sdf.enclosed()`` (0 at t = 0; module doc), sampled every
    ``step`` m (default half a voxel)."""
    J = _joints(joints)
    field = sdf.enclosed()
    step = 0.5 * field.voxel if step is None else float(step)
    if not step > 0:
        raise ValueError(f"step must be > 0 m, got {step}")
    T = len(J)
    out = np.zeros((T, 24))
    if T < 2:
        return out
    a, b = J[:-1], J[1:]  # (T - 1, 24, 3)
    n = max(2, int(np.ceil(np.linalg.norm(b - a, axis=-1).max() / step)) + 1)
    u = np.linspace(0.0, 1.0, n)
    d = np.empty((T - 1, 24, n))
    for i in range(0, T - 1, 64):  # chunks bound the memory of long motions
        pts = a[i:i + 64, :, None] + u[None, None, :, None] * (b[i:i + 64] - a[i:i + 64])[:, :, None]
        d[i:i + 64] = _field(field, pts)
    ends = np.minimum(np.minimum(d[..., 0], d[..., -1]), 0.0)
    out[1:] = np.maximum(ends - d.min(-1), 0.0)
    return out


def crossings(joints: np.ndarray, sdf: SceneSDF, depth: float = CROSS_DEPTH) -> np.ndarray:
    """(T, 24) bool: joint j crosses a solid between frames t-1 and t (``swept_dips`` > ``depth``),
    or leaves at frame t, through its other side, a solid it entered frames before (module doc)."""
    J = _joints(joints)
    out = swept_dips(J, sdf) > depth
    field = sdf.enclosed()
    d, g = field.value_and_gradient(torch.as_tensor(J, dtype=torch.float32))
    d, g = d.numpy().astype(np.float64), g.numpy().astype(np.float64)  # (T, 24), (T, 24, 3)
    inside = d < -depth
    for j in np.flatnonzero(inside.any(0)):
        t = 1
        while t < len(J):
            if inside[t, j] and not inside[t - 1, j]:  # enters at t; the last outside frame is t - 1
                e = t
                while t < len(J) and inside[t, j]:
                    t += 1
                if t < len(J):  # leaves at t
                    a, b = g[e - 1, j], g[t, j]
                    cos = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-9)
                    out[t, j] |= cos < -0.5
            t += 1
    return out


def room_exits(pelvis_xy: np.ndarray, sdf: SceneSDF) -> np.ndarray:
    """pelvis_xy (T, 2) world m -> (T,) bool: on an outside column of ``sdf.enclosed()`` or beyond
    its grid (module doc)."""
    p = np.asarray(pelvis_xy, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"pelvis_xy must be (T, 2) world m, got shape {p.shape}")
    field = sdf.enclosed()
    lo, vox = field.lo[:2].numpy().astype(np.float64), field.voxel
    shape = np.asarray(field.volume.shape[-1:-3:-1])  # (Nx, Ny)
    idx = np.floor((p - lo) / vox + 0.5).astype(np.int64)
    beyond = np.any((idx < 0) | (idx >= shape), axis=-1)
    if field.outside is None:
        return beyond
    c = np.clip(idx, 0, shape - 1)
    return beyond | field.outside[c[:, 0], c[:, 1]]


def core_depths(joints: np.ndarray, sdf: SceneSDF) -> np.ndarray:
    """(T, 24) m: ``max(0, core radius - sdf)`` per joint in ``sdf.enclosed()``."""
    J = _joints(joints)
    return np.maximum(JOINT_CORE_RADIUS[None] - _field(sdf.enclosed(), J), 0.0)


def contact_depths(joints: np.ndarray, sdf: SceneSDF) -> np.ndarray:
    """(T, 24) m: the contact-rule penetration of each joint's body in ``sdf.enclosed()`` (module doc:
    the contact radius where the nearest surface faces an outward direction or the joint is inside,
    else the core radius); >= ``core_depths``."""
    J = _joints(joints)
    d, g = sdf.enclosed().value_and_gradient(torch.as_tensor(J, dtype=torch.float32))
    d, g = d.numpy().astype(np.float64), g.numpy().astype(np.float64)
    toward = -g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-9)  # (T, 24, 3) to the surface
    cos = np.einsum("tjkc,tjc->tjk", outward_directions(J), toward).max(-1)
    return np.maximum(body_penetration(d, cos > FACING_COS), core_depths(J, sdf))


def _mask(mask: np.ndarray, T: int, what: str) -> np.ndarray:
    m = np.asarray(mask, dtype=bool)
    if m.shape != (T,):
        raise ValueError(f"{what} must be a (T,) = ({T},) bool mask, got shape {m.shape}")
    return m


def _foot_heights(J: np.ndarray) -> np.ndarray:
    """(T, 2): per foot (left, right) the height of its lowest joint above its rest, m."""
    return np.stack([np.minimum(J[:, a, 2] - _REST[a], J[:, f, 2] - _REST[f]) for a, f in _FOOT_SIDES], -1)


def floating_frames(joints: np.ndarray, upright: np.ndarray, height: float = FLOAT_M) -> np.ndarray:
    """(T,) bool: frames the feet carry (``upright`` (T,) bool) whose lowest foot joint is more
    than ``height`` m above its rest."""
    J = _joints(joints)
    return _mask(upright, len(J), "upright") & (_foot_heights(J).min(-1) > height)


def sinking_frames(joints: np.ndarray, depth: float = SINK_M) -> np.ndarray:
    """(T,) bool: frames whose lowest foot joint is more than ``depth`` m below its rest."""
    return _foot_heights(_joints(joints)).min(-1) < -depth


def feet_off_frames(joints: np.ndarray, not_lying: np.ndarray, height: float = FEET_OFF_M) -> np.ndarray:
    """(T,) bool: frames of ``not_lying`` (T,) bool with both feet more than ``height`` m off the floor."""
    J = _joints(joints)
    return _mask(not_lying, len(J), "not_lying") & (_foot_heights(J) > height).all(-1)


def seat_errors(joints: np.ndarray, seat_height: np.ndarray, offset: float) -> np.ndarray:
    """seat_height (T,) m (NaN where not seated) -> (n,) m: |pelvis z - (seat height + ``offset``)|
    on the seated frames (``offset``: the body's pelvis height above a seat, ``trumans.body.sit_offset``)."""
    J = _joints(joints)
    h = np.asarray(seat_height, dtype=np.float64)
    if h.shape != (len(J),):
        raise ValueError(f"seat_height must be (T,) = ({len(J)},) m, got shape {h.shape}")
    sel = np.isfinite(h)
    return np.abs(J[sel, _PELVIS, 2] - (h[sel] + float(offset)))


def lying_leg_depths(joints: np.ndarray, surface_height: np.ndarray, over: np.ndarray) -> np.ndarray:
    """surface_height (T,) m (NaN where not lying); over (T, len(LEG_JOINTS)) bool: the leg joint
    lies above the surface's footprint -> (n,) m, per (lying frame, leg joint over the surface):
    how far the joint's skin is under the surface, ``max(0, h + JOINT_RADIUS - z)``."""
    J = _joints(joints)
    h = np.asarray(surface_height, dtype=np.float64)
    o = np.asarray(over, dtype=bool)
    if h.shape != (len(J),) or o.shape != (len(J), len(LEG_JOINTS)):
        raise ValueError(f"need surface_height (T,) and over (T, {len(LEG_JOINTS)}) for T = {len(J)}, got "
                         f"{h.shape} and {o.shape}")
    legs = list(LEG_JOINTS)
    depth = np.maximum(h[:, None] + JOINT_RADIUS[legs][None] - J[:, legs, 2], 0.0)
    return depth[np.isfinite(h)[:, None] & o]
