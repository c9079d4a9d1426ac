"""Where a let-go object comes to rest: the support under it (not in iReplica; its objects slide
on the floor or turn on hinges, so none is ever let go in the air).

A carried (free) object that the hands let go comes down onto the surface under it: the floor,
a table top, another object. ``SupportQuery.support_height`` casts rays straight down from just
above the object's bottom at the centre of its footprint (world bounding box) and near its four
corners (``footprint_points``) and returns the height of the first surface each meets (static
meshes, static objects, other dynamic objects at their current poses); ``gaps`` is the object's
bottom height above the highest of them (m, negative when it sinks in: an object whose footprint
is partly over a table edge stays on the table, which a localisation error of a few cm must not
push off); ``rest_pose`` sets the object upright (its yaw kept, footprint centre kept) with its
bottom on that surface. Units: metres, z up, poses (4, 4) world-from-object (``docs/conventions.md``).
"""
from __future__ import annotations

import numpy as np

from trumans.scenes.scene import Scene

__all__ = ["SupportQuery", "upright_pose", "footprint_points", "ABOVE_M", "FOOTPRINT_SHARE"]

ABOVE_M = 0.03  # m, the rays start this far above the object's bottom (an object sunk into a table by less rests on it)
FOOTPRINT_SHARE = 0.8  # the rays under the footprint's corners start this share of the way out from its centre
_DOWN = np.array([0.0, 0.0, -1.0])


def footprint_points(lo: np.ndarray, hi: np.ndarray, share: float = FOOTPRINT_SHARE) -> np.ndarray:
    """Ray origins (n, 5, 3) under objects with world bounding boxes lo, hi (n, 3): the footprint's
    centre and four points ``share`` of the way to its corners, ``ABOVE_M`` above the bottom."""
    c = 0.5 * (lo + hi)
    h = 0.5 * share * (hi - lo)
    sx = np.array([0.0, 1.0, 1.0, -1.0, -1.0])
    sy = np.array([0.0, 1.0, -1.0, 1.0, -1.0])
    x, y = c[:, None, 0] + sx * h[:, None, 0], c[:, None, 1] + sy * h[:, None, 1]
    return np.stack([x, y, np.broadcast_to((lo[:, 2] + ABOVE_M)[:, None], x.shape)], -1)


def upright_pose(vertices: np.ndarray, pose: np.ndarray, bottom_z: float | None = None) -> np.ndarray:
    """``pose`` (4, 4) turned upright: the rotation replaced by its yaw (of the object's x axis, or
    of its y axis when x points up or down), the footprint centre (xy of the world bounding box)
    kept, and the lowest vertex at ``bottom_z`` (m; None keeps the lowest point's height).
    vertices: (V, 3) object frame."""
    v = np.asarray(vertices, np.float64)
    R = np.asarray(pose, np.float64)[:3, :3]
    world = v @ R.T + pose[:3, 3]
    use_x = np.linalg.norm(R[:2, 0]) > 0.3
    axis = R[:, 0] if use_x else R[:, 1]
    yaw = float(np.arctan2(axis[1], axis[0])) - (0.0 if use_x else np.pi / 2)
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    up = v @ out[:3, :3].T
    centre = 0.5 * (world[:, :2].min(0) + world[:, :2].max(0))
    out[:2, 3] = centre - 0.5 * (up[:, :2].min(0) + up[:, :2].max(0))
    out[2, 3] = (world[:, 2].min() if bottom_z is None else bottom_z) - up[:, 2].min()
    return out


class SupportQuery:
    """Rays straight down onto a scene's static meshes and objects (vectorised point-in-triangle tests
    in the xy plane; each object's triangles moved to its pose on each query)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self._static = [np.asarray(m.triangles, np.float64) for m in scene.static.values()]
        self._objects: dict[str, np.ndarray] = {}

    @staticmethod
    def _hits(triangles: np.ndarray, origins: np.ndarray) -> np.ndarray:
        """Height (n,) m of the highest of ``triangles`` (m, 3, 3) world straight under each of
        ``origins`` (n, 3) world (at or below it); -inf where there is none. Vertical rays, so a
        point-in-triangle test in the xy plane and the plane's height there (barycentric)."""
        out = np.full(len(origins), -np.inf)
        if not len(triangles) or not len(origins):
            return out
        lo, hi = origins.min(0), origins.max(0)
        tlo, thi = triangles.min(1), triangles.max(1)
        keep = (thi[:, 0] >= lo[0]) & (tlo[:, 0] <= hi[0]) & (thi[:, 1] >= lo[1]) & (tlo[:, 1] <= hi[1]) \
            & (tlo[:, 2] <= hi[2])
        tri = triangles[keep]
        a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]  # (m, 3)
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        ok = np.abs(det) > 1e-12  # triangles seen edge-on from above hold nothing up
        a, e1, e2, det = a[ok], e1[ok], e2[ok], det[ok]
        if not len(a):
            return out
        step = max(1, 2_000_000 // len(a))
        for i in range(0, len(origins), step):
            o = origins[i:i + step]
            dx, dy = o[:, None, 0] - a[None, :, 0], o[:, None, 1] - a[None, :, 1]  # (k, m)
            u = (dx * e2[None, :, 1] - dy * e2[None, :, 0]) / det
            v = (e1[None, :, 0] * dy - e1[None, :, 1] * dx) / det
            z = a[None, :, 2] + u * e1[None, :, 2] + v * e2[None, :, 2]
            inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9) & (z <= o[:, None, 2])
            out[i:i + step] = np.where(inside, z, -np.inf).max(1)
        return out

    def support_height(self, origins: np.ndarray, exclude: str, poses: dict[str, np.ndarray]) -> np.ndarray:
        """Height (n,) m of the highest surface straight under each of ``origins`` (n, 3) world: static
        meshes, static objects at their scene pose and the dynamic objects at ``poses`` {name: (4, 4)}
        (their scene pose when absent; ``exclude`` left out); 0 (the floor plane) where a ray meets nothing."""
        origins = np.asarray(origins, np.float64).reshape(-1, 3)
        best = np.full(len(origins), -np.inf)
        for triangles in self._static:
            best = np.maximum(best, self._hits(triangles, origins))
        for name, obj in self.scene.objects.items():
            if name == exclude:
                continue
            if name not in self._objects:
                self._objects[name] = np.asarray(obj.mesh.triangles, np.float64)
            pose = np.asarray(poses.get(name, obj.pose) if obj.dof != "static" else obj.pose, np.float64)
            best = np.maximum(best, self._hits(self._objects[name] @ pose[:3, :3].T + pose[:3, 3], origins))
        return np.where(np.isfinite(best), best, 0.0)

    def gaps(self, name: str, poses_of: np.ndarray, others: dict[str, np.ndarray]) -> np.ndarray:
        """Bottom heights (n,) m of object ``name`` at poses (n, 4, 4) above the highest surface under its
        footprint (``footprint_points``; negative: sunk in; at most ``ABOVE_M`` is looked into); the
        other objects at ``others`` {name: (4, 4)}."""
        P = np.asarray(poses_of, np.float64).reshape(-1, 4, 4)
        world = np.einsum("nij,vj->nvi", P[:, :3, :3], np.asarray(self.scene.objects[name].mesh.vertices, np.float64)) \
            + P[:, None, :3, 3]
        lo, hi = world.min(1), world.max(1)  # (n, 3)
        origins = footprint_points(lo, hi)  # (n, 5, 3)
        top = self.support_height(origins.reshape(-1, 3), name, others).reshape(len(P), -1).max(1)
        return lo[:, 2] - top

    def gap(self, name: str, pose: np.ndarray, poses: dict[str, np.ndarray]) -> float:
        """Bottom height (m) of object ``name`` at ``pose`` (4, 4) above the surface under its footprint's
        centre (negative: sunk in by that much; at most ``ABOVE_M`` is looked into)."""
        return float(self.gaps(name, pose[None], poses)[0])

    def rest_pose(self, name: str, pose: np.ndarray, poses: dict[str, np.ndarray]) -> np.ndarray:
        """Where object ``name`` let go at ``pose`` (4, 4) comes to rest: upright (``upright_pose``) on the
        highest surface under its footprint (``poses``: the other objects' current poses)."""
        vertices = self.scene.objects[name].mesh.vertices
        up = upright_pose(vertices, pose)
        world = np.asarray(vertices, np.float64) @ up[:3, :3].T + up[:3, 3]
        origins = footprint_points(world.min(0)[None], world.max(0)[None])[0]
        return upright_pose(vertices, up, float(self.support_height(origins, name, poses).max()))
