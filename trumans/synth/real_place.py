"""Place a real mocap clip in a procedural room whose furniture leaves its walked path free.

The clip is turned by a yaw and moved on the floor; the room is made around it (a procedural
room of ``trumans.scenes.procedural.make_room`` whose size holds the clip's pelvis path plus
``BODY_RADIUS`` and its fitted seats / beds, ``trumans.scene_fit``). A placement is accepted when
every pelvis position keeps ``BODY_RADIUS`` and every joint ``LIMB_CLEARANCE`` from the walls and
from every procedural floor footprint, and the fitted furniture keeps ``MARGIN`` from the procedural footprints and
``BODY_RADIUS`` from the door's approach point. Of ``ATTEMPTS`` seeded (room, yaw, offset)
draws, the first one with no blocking piece is taken; if every draw is blocked, the draw with the
fewest blocking pieces is taken and those pieces are removed from the room (with the objects
standing on them). Clips too large for a 20 m room fit no room. ``extra`` objects fitted to the clip
beforehand (``real_objects``: picked-up objects and their supports, in the clip's frame) move with
the clip and count as fitted; ``free`` footprints (the places a carried object passes or is put)
are kept free like fitted ones.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from trumans.scenes.procedural import approach_points, floor_footprints, make_room
from trumans.scenes.scene import Scene, SceneObject

from trumans.rotations import yaw_matrix
from trumans.scene_fit import fit_scene
from trumans.skeleton import JOINT_INDEX

__all__ = ["BODY_RADIUS", "MARGIN", "ATTEMPTS", "Placement", "place_clip", "quad_distance", "footprint_quad",
           "turn_and_move", "remove_objects"]

BODY_RADIUS = 0.25  # m, the pelvis path's clearance from walls and procedural furniture
LIMB_CLEARANCE = 0.05  # m, every joint's clearance from walls and procedural furniture
MARGIN = 0.08  # m, clearance between a fitted and a procedural footprint (trumans.scenes.procedural.MARGIN)
ATTEMPTS = 6
MAX_ROOM_SIDE = 20.0  # m, make_room's largest side
SAMPLE_M = 0.05  # m, spacing of the points that sample a fitted footprint


@dataclass
class Placement:
    """A clip in its room: ``scene`` (procedural room + fitted objects, named ``fit_*``),
    ``joints`` (T, 24, 3) m moved into the room, the applied ``yaw`` (rad, about z through the
    pelvis path's bbox centre) and ``shift`` (2,) m, the draw ``attempt`` taken, the procedural
    objects ``removed`` to free the path, the ``fitted`` object names and the rigid ``transform``
    (4, 4) from the clip's frame into the room's (p' = R(yaw) p + shift)."""

    scene: Scene
    joints: np.ndarray
    yaw: float
    shift: np.ndarray
    attempt: int
    removed: list[str]
    fitted: list[str]
    transform: np.ndarray


def turn_and_move(joints: np.ndarray, yaw: float, shift: np.ndarray) -> np.ndarray:
    """(T, 24, 3) joints turned by ``yaw`` (rad) about the z axis through the origin, then moved by ``shift`` (2,) m."""
    return np.asarray(joints, np.float64) @ yaw_matrix(yaw).T + np.array([shift[0], shift[1], 0.0])


def quad_distance(points: np.ndarray, quad: np.ndarray) -> np.ndarray:
    """Distance (N,) m from points (N, 2) to the convex quad (4, 2) (0 inside)."""
    p = np.asarray(points, np.float64)[:, None, :]  # (N, 1, 2)
    a = np.asarray(quad, np.float64)[None]  # (1, 4, 2)
    e = np.roll(a, -1, axis=1) - a
    t = np.clip(((p - a) * e).sum(-1) / np.maximum((e * e).sum(-1), 1e-18), 0.0, 1.0)
    seg = np.linalg.norm(p - (a + t[..., None] * e), axis=-1).min(axis=1)
    cross = e[..., 0] * (p[..., 1] - a[..., 1]) - e[..., 1] * (p[..., 0] - a[..., 0])  # (N, 4)
    inside = np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)
    return np.where(inside, 0.0, seg)


def footprint_quad(obj: SceneObject) -> np.ndarray:
    """(4, 2) world corners of an object's mesh bounds rectangle (its floor footprint), m."""
    lo, hi = obj.mesh.bounds[0, :2], obj.mesh.bounds[1, :2]
    c = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return c @ obj.pose[:2, :2].T + obj.pose[:2, 3]


def _quad_samples(quad: np.ndarray) -> np.ndarray:
    """Points (N, 2) covering a rectangle quad (4, 2) every ``SAMPLE_M`` m, corners included."""
    u, v = quad[1] - quad[0], quad[3] - quad[0]
    nu = max(2, int(np.ceil(np.linalg.norm(u) / SAMPLE_M)) + 1)
    nv = max(2, int(np.ceil(np.linalg.norm(v) / SAMPLE_M)) + 1)
    a, b = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    return quad[0] + a.reshape(-1, 1) * u + b.reshape(-1, 1) * v


def _blockers(scene: Scene, joints: np.ndarray, fitted: list[np.ndarray]) -> list[str]:
    """Procedural floor objects within ``BODY_RADIUS`` of the pelvis path, ``LIMB_CLEARANCE`` of any
    joint (joints (T, 24, 3) m) or ``MARGIN`` of a fitted footprint."""
    samples = np.concatenate([_quad_samples(q) for q in fitted]) if fitted else np.zeros((0, 2))
    pelvis = joints[:, JOINT_INDEX["pelvis"], :2]
    body = joints[:, :, :2].reshape(-1, 2)
    out = []
    for name, quad in floor_footprints(scene).items():
        if quad_distance(pelvis, quad).min(initial=np.inf) < BODY_RADIUS or \
                quad_distance(body, quad).min(initial=np.inf) < LIMB_CLEARANCE or \
                (len(samples) and quad_distance(samples, quad).min() < MARGIN):
            out.append(name)
    return out


def remove_objects(scene: Scene, names: list[str]) -> list[str]:
    """Remove objects ``names`` and the objects supported by them or parts of them (a cabinet's
    drawers: meta "parent"), transitively; returns all removed names (sorted)."""
    gone = set(names)
    while True:
        more = {n for n, o in scene.objects.items() if n not in gone
                and (o.meta.get("support") in gone or o.meta.get("parent") in gone)}
        if not more:
            break
        gone |= more
    for n in gone:
        del scene.objects[n]
    return sorted(gone)


def place_clip(joints: np.ndarray, states: np.ndarray, seed: int, name: str, fps: float = 30.0,
               extra: Sequence[SceneObject] = (), free: Sequence[np.ndarray] = ()) -> Placement | None:
    """Place a clip (joints (T, 24, 3) m, per-frame ``states`` of ``trumans.motion_labels``) in a
    procedural room made for it; None when no room can hold it. ``extra``: objects already fitted to
    the clip (named ``fit_*``, poses in the clip's frame), added with it; ``free``: (4, 2) floor quads
    m in the clip's frame to keep free of procedural furniture. Deterministic in ``seed``."""
    j0 = np.asarray(joints, np.float64)
    pel = j0[:, JOINT_INDEX["pelvis"], :2]
    centre = (pel.min(0) + pel.max(0)) / 2
    best: tuple[int, int, Scene, np.ndarray, float, np.ndarray, list[SceneObject]] | None = None
    for attempt in range(ATTEMPTS):
        rng = np.random.default_rng([seed, attempt])
        yaw = float(rng.uniform(-np.pi, np.pi))
        J = turn_and_move(j0 - np.array([centre[0], centre[1], 0.0]), yaw, np.zeros(2))
        fitted = list(fit_scene(J, states, fps=fps).objects.values())
        M = np.eye(4)
        M[:3, :3] = yaw_matrix(yaw)
        M[:2, 3] = _centre_shift(centre, yaw)
        for o in fitted:
            o.name = f"fit_{o.name}"
        fitted += [replace(o, pose=M @ o.pose, meta=dict(o.meta)) for o in extra]
        quads = [footprint_quad(o) for o in fitted] + [np.asarray(q, np.float64) @ M[:2, :2].T + M[:2, 3] for q in free]
        p = J[:, JOINT_INDEX["pelvis"], :2]
        body = J[:, :, :2].reshape(-1, 2)
        pts = np.concatenate([p - BODY_RADIUS, p + BODY_RADIUS, body - LIMB_CLEARANCE, body + LIMB_CLEARANCE] + quads)
        lo, hi = pts.min(0), pts.max(0)
        size = np.maximum(rng.uniform(4.0, 7.0, 2), hi - lo + 0.02)
        if size.max() > MAX_ROOM_SIDE:
            return None  # no room holds this clip
        shift = -lo + 0.01 + rng.uniform(0.0, 1.0, 2) * (size - (hi - lo) - 0.02)
        J = J + np.array([shift[0], shift[1], 0.0])
        for o in fitted:
            o.pose = o.pose.copy()
            o.pose[:2, 3] += shift
        M[:2, 3] += shift
        quads = [q + shift for q in quads]
        scene = make_room(int(rng.integers(2**31)), size=(float(size[0]), float(size[1])))
        door = approach_points(scene).get(scene.meta["door"])
        if door is not None and any(quad_distance(door[None], q)[0] < BODY_RADIUS for q in quads):
            continue  # a fitted seat would block the door
        blocking = _blockers(scene, J, quads)
        if best is None or len(blocking) < best[0]:
            best = (len(blocking), attempt, scene, J, yaw, M[:2, 3].copy(), fitted)
            best_blocking = blocking
        if not blocking:
            break
    if best is None:
        return None
    _, attempt, scene, J, yaw, shift, fitted = best
    removed = remove_objects(scene, best_blocking) if best_blocking else []
    names = []
    for o in fitted:
        scene.objects[o.name] = o
        names.append(o.name)
    scene.meta = {**scene.meta, "real_clip": name, "placement": {"yaw": yaw, "shift": [float(v) for v in shift]},
                  "removed_for_path": removed, "fitted": names}
    transform = np.eye(4)
    transform[:3, :3] = yaw_matrix(yaw)
    transform[:2, 3] = shift
    return Placement(scene, J.astype(np.float32), yaw, shift, attempt, removed, names, transform)


def _centre_shift(centre: np.ndarray, yaw: float) -> np.ndarray:
    """The part of the total shift that undoes the centring: -R(yaw) centre (2,) m."""
    return -(yaw_matrix(yaw)[:2, :2] @ centre)
