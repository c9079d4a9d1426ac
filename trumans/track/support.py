"""Where a let-go object comes to rest: the support under it (not in iReplica; its objects slide
on the floor or turn on hinges, so none is ever let go in the air).

A carried (free) object that the hands let go falls onto the surface under its centre: the floor,
a table top, another object. ``SupportQuery.support_height`` casts a ray straight down from just
above the object's bottom at the centre of its footprint (world bounding box) and returns the
height of the first surface it meets (static meshes, static objects, other dynamic objects at
their current poses); ``gap`` is the object's bottom height above it (m, negative when it sinks
in); ``rest_pose`` sets the object upright (its yaw kept, footprint centre kept) with its bottom
on that surface. Units: metres, z up, poses (4, 4) world-from-object (``docs/conventions.md``).
"""
from __future__ import annotations

import numpy as np
import trimesh
from trimesh.ray.ray_triangle import RayMeshIntersector

from trumans.scenes.scene import Scene

__all__ = ["SupportQuery", "upright_pose", "ABOVE_M"]

ABOVE_M = 0.03  # m, the ray starts this far above the object's bottom (an object sunk into a table by less rests on it)
_DOWN = np.array([0.0, 0.0, -1.0])


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
    """Ray casts straight down onto a scene's static meshes and objects (each object's mesh in its
    own frame, so an object at any pose is queried without rebuilding)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        static = list(scene.static.values())
        self._static = RayMeshIntersector(trimesh.util.concatenate(static)) if static else None
        self._objects: dict[str, RayMeshIntersector] = {}

    def _hit(self, name: str, pose: np.ndarray, origin: np.ndarray) -> float:
        """Height (m) of the first surface of object ``name`` at ``pose`` straight under ``origin`` (3,); -inf if none."""
        if name not in self._objects:
            self._objects[name] = RayMeshIntersector(self.scene.objects[name].mesh)
        inv = np.linalg.inv(pose)
        o = inv[:3, :3] @ origin + inv[:3, 3]
        d = inv[:3, :3] @ _DOWN
        loc, _, _ = self._objects[name].intersects_location(o[None], d[None])
        if not len(loc):
            return -np.inf
        return float((loc @ pose[:3, :3].T + pose[:3, 3])[:, 2].max())

    def support_height(self, origin: np.ndarray, exclude: str, poses: dict[str, np.ndarray]) -> float:
        """Height (m) of the highest surface straight under ``origin`` (3,) world: static meshes, static
        objects at their scene pose and the objects in ``poses`` {name: (4, 4)} (``exclude`` left out);
        0 (the floor plane) when the ray meets nothing."""
        best = -np.inf
        if self._static is not None:
            loc, _, _ = self._static.intersects_location(np.asarray(origin, np.float64)[None], _DOWN[None])
            if len(loc):
                best = float(loc[:, 2].max())
        for name, obj in self.scene.objects.items():
            if name == exclude:
                continue
            pose = poses.get(name, obj.pose) if obj.dof != "static" else obj.pose
            best = max(best, self._hit(name, np.asarray(pose, np.float64), origin))
        return best if np.isfinite(best) else 0.0

    def gap(self, name: str, pose: np.ndarray, poses: dict[str, np.ndarray]) -> float:
        """Bottom height (m) of object ``name`` at ``pose`` (4, 4) above the surface under its footprint's
        centre (negative: sunk in by that much; at most ``ABOVE_M`` is looked into)."""
        world = np.asarray(self.scene.objects[name].mesh.vertices, np.float64) @ pose[:3, :3].T + pose[:3, 3]
        lo, hi = world.min(0), world.max(0)
        origin = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2] + ABOVE_M])
        return float(lo[2] - self.support_height(origin, name, poses))

    def rest_pose(self, name: str, pose: np.ndarray, poses: dict[str, np.ndarray]) -> np.ndarray:
        """Where object ``name`` let go at ``pose`` (4, 4) comes to rest: upright (``upright_pose``) on the
        surface under its footprint's centre (``poses``: the other objects' current poses)."""
        vertices = self.scene.objects[name].mesh.vertices
        up = upright_pose(vertices, pose)
        world = np.asarray(vertices, np.float64) @ up[:3, :3].T + up[:3, 3]
        lo, hi = world.min(0), world.max(0)
        origin = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2] + ABOVE_M])
        return upright_pose(vertices, up, self.support_height(origin, name, poses))
