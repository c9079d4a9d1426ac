"""Which object the contacting hands touch (iReplica supp. §10.1), and where a grasp is aimed.

The paper's rule is the nearest object of the interaction's class within 0.5 m of the hands
(``object_candidates``; objects that declare a ``grasp_point`` are measured there). Under localisation error that rule cannot tell apart two objects of one
class closer together than the error (a pen beside a laptop on a desk, 13 cm drift: issue 12).
For free (carried) objects the release then decides: an object let go must rest on something, so
among the candidates near the best one the object whose centre, where the hand lets go, lies over a
surface wins (``release_support_gap``, ``choose_free_object``; not in the paper).
"""
from __future__ import annotations

import numpy as np

from trumans.scenes.distance import SceneDistance
from trumans.scenes.scene import Scene

__all__ = ["ObjectQueries", "grasp_targets", "two_hand_targets", "object_candidates", "release_support_gap",
           "choose_free_object"]


class ObjectQueries:
    """Closest points on scene objects posed anywhere (each mesh queried in its own frame) and on
    the static meshes (walls, floor)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self._sd: dict[str, SceneDistance] = {}
        self._static: SceneDistance | None = None

    def closest(self, name: str, pose: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """points (n, 3) world -> (closest (n, 3) world, distance (n,)) to object ``name`` at ``pose``."""
        closest, dist, _ = self.contact_target(name, pose, points, 0.0)
        return closest, dist

    def contact_target(self, name: str, pose: np.ndarray, points: np.ndarray,
                       gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest points (n, 3), unsigned distances (n,) and where each point should be to touch
        the object from outside at ``gap`` m (n, 3): off the closest point away from it, or along
        the outward normal for a point inside the object (all world, object at ``pose``)."""
        if name not in self._sd:
            self._sd[name] = SceneDistance({name: self.scene.objects[name].mesh})
        inv = np.linalg.inv(pose)
        local = points @ inv[:3, :3].T + inv[:3, 3]
        r = self._sd[name].query(local)
        closest = r.closest.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
        normal = r.normal.astype(np.float64) @ pose[:3, :3].T
        dist = r.dist.astype(np.float64)
        away = (points - closest) / np.maximum(dist, 1e-9)[:, None]
        out = np.where((r.signed < 0)[:, None] | (dist < 1e-9)[:, None], normal, away)
        return closest, dist, closest + gap * out

    def surface_distance(self, points: np.ndarray, poses: dict[str, np.ndarray]) -> np.ndarray:
        """points (T, k, 3) world -> (T, k) m, the distance to the nearest surface of the scene on each
        frame: the static meshes, static objects at their scene pose and the objects in ``poses``
        {name: (T, 4, 4)} (their scene pose when absent) at their pose on that frame."""
        pts = np.asarray(points, np.float64)
        T, k = pts.shape[:2]
        best = self.static_distance(pts.reshape(-1, 3)).reshape(T, k)
        for name, obj in self.scene.objects.items():
            P = np.asarray(poses[name], np.float64) if name in poses else np.broadcast_to(obj.pose, (T, 4, 4))
            if name not in self._sd:
                self._sd[name] = SceneDistance({name: obj.mesh})
            inv = np.linalg.inv(P)
            local = np.einsum("tij,tkj->tki", inv[:, :3, :3], pts) + inv[:, None, :3, 3]
            best = np.minimum(best, self._sd[name].query(local.reshape(-1, 3)).dist.astype(np.float64).reshape(T, k))
        return best

    def static_distance(self, points: np.ndarray) -> np.ndarray:
        """points (n, 3) world -> unsigned distance (n,) m to the static meshes (inf when none)."""
        if not self.scene.static:
            return np.full(len(points), np.inf)
        if self._static is None:
            self._static = SceneDistance(dict(self.scene.static))
        return self._static.query(points).dist.astype(np.float64)


def grasp_targets(targets: np.ndarray, hands: np.ndarray, mesh_vertices: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Where the contacting hands of a free (carried) object should be at the grasp (not in the
    paper, whose objects are large). targets: (k, 3) the side-contact targets (``hand_radius`` off
    the closest point); hands: (k, 3) the hand points; mesh_vertices: (V, 3) object frame; pose: (4, 4).
    A hand above the object's top takes it from above (a phone, a book, a pen): its closest point
    is straight below it wherever the drifted hand hovers over the footprint, so the closest point
    says nothing about the horizontal error; the hand then goes over the footprint's centre (xy of
    the world bounding box; z kept). Side grasps keep their targets. Returns (k, 3) world."""
    world = mesh_vertices @ pose[:3, :3].T + pose[:3, 3]
    lo, hi = world.min(0), world.max(0)
    out = np.array(targets, dtype=np.float64, copy=True)
    top = hands[:, 2] >= hi[2]
    out[top, :2] = 0.5 * (lo[:2] + hi[:2])
    return out


def two_hand_targets(targets: np.ndarray, hands: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Where two hands holding an object between them (``interactions.two_hand_take``) should be at
    the grasp (not in the paper, whose free objects ride on one hand). targets: (2, 3) the
    side-contact targets of the left and right hand points ``hands`` (2, 3); centre: (3,) the
    object's centre (world). The closest-point targets say little along the hands' line (a hand
    inside a box wider than the grip is sent to whichever face is nearer): along the horizontal
    line through the hands, the object's centre goes midway between them; across it, the mean
    side-contact correction stands. Both hands move by the same step (the body is rigid); returns
    (2, 3) world."""
    hands = np.asarray(hands, np.float64)
    u = hands[0, :2] - hands[1, :2]
    u = u / max(float(np.linalg.norm(u)), 1e-9)
    step = (np.asarray(targets, np.float64) - hands)[:, :2].mean(0)
    along = float((np.asarray(centre, np.float64)[:2] - hands[:, :2].mean(0)) @ u)
    out = hands.copy()
    out[:, :2] += step - (step @ u) * u + along * u
    return out


def object_candidates(queries: ObjectQueries, poses: dict[str, np.ndarray], frame: int, hands: np.ndarray,
                      dof: str, radius: float) -> list[tuple[str, float]]:
    """Objects of ``dof`` within ``radius`` of the contacting hands, nearest first (supp. §10.1:
    the nearest object of the interaction's class within ``radius``). hands: (n, k, 3) the k
    contacting hand points over the first n frames of the contact; objects at their ``poses`` at
    ``frame`` (at rest before the interaction). The closest approach over those frames, not the
    first frame's distance, counts (the hand reaches for the object during the first frames).
    An object that declares where it is held (meta ``grasp_point``, object frame) is ranked by the
    hands' approach to that point rather than to its nearest surface: a large object's surface
    (a laptop's) can come nearer a drifted hand than the small object beside it that the hand
    really took. Returns [(name, closest approach in m), ...] sorted by distance."""
    found = []
    for name, obj in queries.scene.objects.items():
        if obj.dof != dof or name not in poses:
            continue
        pose = poses[name][frame]
        _, dist = queries.closest(name, pose, hands.reshape(-1, 3))
        if float(dist.reshape(hands.shape[:2]).mean(1).min()) > radius:
            continue
        if "grasp_point" in obj.meta:
            grasp = pose[:3, :3] @ np.asarray(obj.meta["grasp_point"], np.float64).reshape(3) + pose[:3, 3]
            dist = np.linalg.norm(hands.reshape(-1, 3) - grasp, axis=-1)
        found.append((name, float(dist.reshape(hands.shape[:2]).mean(1).min())))
    return sorted(found, key=lambda c: c[1])


def release_support_gap(queries: ObjectQueries, name: str, pose: np.ndarray, others: dict[str, np.ndarray]) -> float:
    """How far (m) object ``name``, let go at world ``pose`` (4, 4), is from resting on something:
    the distance from the point 5 mm under the centre of its footprint (world bounding box) to the
    nearest static mesh or other object at its pose in ``others`` {name: (4, 4)}. About 5 mm for an
    object standing on a table; the overhang of its centre past the table's edge for one whose
    centre is not over a support (it would tip or fall)."""
    world = np.asarray(queries.scene.objects[name].mesh.vertices) @ pose[:3, :3].T + pose[:3, 3]
    lo, hi = world.min(0), world.max(0)
    probe = np.array([[0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2] - 0.005]])
    gap = float(queries.static_distance(probe)[0])
    for other, p in others.items():
        if other != name:
            gap = min(gap, float(queries.closest(other, p, probe)[1][0]))
    return gap


def choose_free_object(candidates: list[tuple[str, float]], release_gaps: dict[str, float],
                       ambiguity: float, support_tol: float = 0.02) -> str:
    """Pick the object a free-class contact carried. candidates: nearest first (``object_candidates``);
    release_gaps: ``release_support_gap`` of the candidates within ``ambiguity`` m of the nearest
    (those whose release was scored; a contact still held at the end has none). Among them the one
    whose release rests on a surface wins, unless the gaps differ by less than ``support_tol`` m,
    when the nearest is kept (the rule of the paper)."""
    if not candidates:
        raise ValueError("no candidate objects to choose from")
    best = candidates[0][0]
    close = [n for n, d in candidates if d <= candidates[0][1] + ambiguity and n in release_gaps]
    if best not in release_gaps or len(close) < 2:
        return best
    steady = min(close, key=lambda n: release_gaps[n])
    return steady if release_gaps[steady] < release_gaps[best] - support_tol else best
