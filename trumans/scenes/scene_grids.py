"""Local grids with the dynamic objects placed where they are at each episode's start (TRUMANS §4.3).

A scene's cached ``occupancy.npz`` holds the dynamic objects (doors, drawers, chairs, carried
things) at their ``scene.json`` poses, but during a sequence they move. ``SceneGrids`` therefore
voxelises the scene WITHOUT its dynamic objects once (``trumans.scenes.occupancy.scene_occupancy``,
~1 s per room), voxelises each dynamic object once in its own frame (interior voxel centres),
and for every episode samples the static local grid (``trumans.scenes.local_grid.local_grids``) and
splats each dynamic object's points, posed by the sequence's object track at the episode's first
frame (or the scene pose when the sequence does not track it), into the local cells. Objects too
far from an episode's grid are skipped. A scene without dynamic objects (or without a
``scene.json``, e.g. imported grids) uses ``occupancy.npz`` directly.
"""
from __future__ import annotations

import hashlib

import numpy as np

from trumans.scenes.local_grid import local_grids
from trumans.scenes.occupancy import OccupancyGrid, compute_occupancy, scene_key, scene_occupancy

__all__ = ["SceneGrids"]


class SceneGrids:
    """Episode local grids of one scene. occ: its cached occupancy; scene: ``trumans.scenes.Scene`` or None."""

    def __init__(self, occ: OccupancyGrid | None, scene=None, voxel: float | None = None,
                 memo: dict | None = None) -> None:
        """occ: the scene's cached occupancy (may be None when ``scene`` is given: then only
        ``voxel`` m is needed); memo: a dict shared between scenes so that scene variations that
        differ in one object (augmented data) voxelise their common static part and each distinct
        object mesh once."""
        if occ is None and scene is None:
            raise ValueError("SceneGrids needs an occupancy grid or a scene")
        self.occ = occ
        self.points: dict[str, np.ndarray] = {}  # object name -> (P, 3) interior points, object frame, m
        self.scene_pose: dict[str, np.ndarray] = {}
        dyn = {} if scene is None else {k: o for k, o in scene.objects.items() if o.dynamic}
        v = float(voxel if voxel is not None else occ.voxel)
        if not dyn:
            self.static = occ if occ is not None else scene_occupancy(scene, None, voxel=v)
            return
        memo = {} if memo is None else memo
        key = ("static", scene_key(scene, v, include_dynamic=False))
        if key not in memo:
            memo[key] = scene_occupancy(scene, None, voxel=v, include_dynamic=False)
        self.static = memo[key]
        for name, o in dyn.items():
            okey = ("object", v, hashlib.sha256(np.ascontiguousarray(o.mesh.vertices, np.float32).tobytes()
                                                + np.ascontiguousarray(o.mesh.faces, np.int64).tobytes()).hexdigest())
            if okey not in memo:
                lo, hi = o.mesh.bounds
                g = compute_occupancy([o.mesh], np.stack([lo - v, hi + v]), v)
                pts = g.centers()[g.grid]
                if len(pts) == 0:  # thinner than a voxel: keep its surface samples
                    pts = np.asarray(o.mesh.vertices)
                memo[okey] = pts.astype(np.float32)
            self.points[name] = memo[okey]
            self.scene_pose[name] = np.asarray(o.pose, dtype=np.float64)

    def query(self, centers: np.ndarray, yaw: np.ndarray, object_poses: dict[str, np.ndarray] | None = None,
              n: int = 32, extent: tuple[float, float, float] = (1.2, 1.2, 1.2)) -> np.ndarray:
        """(B, n, n, n) bool local grids (axes forward, left, up; True = occupied).

        centers: (B, 3) floor points, world m; yaw: (B,) rad; object_poses: name -> (B, 4, 4)
        world-from-object pose per episode (objects not given sit at their scene pose)."""
        out = local_grids(self.static, centers, yaw, n=n, extent=extent)
        if not self.points:
            return out
        object_poses = object_poses or {}
        unknown = sorted(set(object_poses) - set(self.points))
        if unknown:
            raise ValueError(f"object tracks {unknown} have no dynamic object of that name in the scene "
                             f"(it has {sorted(self.points)}); fix the sequence's objects or the scene.json")
        c = np.asarray(centers, dtype=np.float64)
        yaw = np.asarray(yaw, dtype=np.float64)
        B = len(c)
        e = np.asarray(extent, dtype=np.float64)
        reach = 0.5 * np.hypot(e[0], e[1])
        cos, sin = np.cos(yaw), np.sin(yaw)
        flat = out.reshape(B, -1)
        for name, pts in self.points.items():
            pose = np.asarray(object_poses.get(name, np.broadcast_to(self.scene_pose[name], (B, 4, 4))), np.float64)
            if pose.shape != (B, 4, 4):
                raise ValueError(f"object_poses[{name!r}] must be ({B}, 4, 4), got {pose.shape}")
            radius = float(np.linalg.norm(pts, axis=1).max())
            near = np.flatnonzero(np.hypot(*(pose[:, :2, 3] - c[:, :2]).T) < radius + reach)
            if len(near) == 0:
                continue
            w = np.einsum("bij,pj->bpi", pose[near, :3, :3], pts) + pose[near, None, :3, 3]  # (b, P, 3) world
            d = w - c[near, None, :]
            u = cos[near, None] * d[..., 0] + sin[near, None] * d[..., 1]
            vv = -sin[near, None] * d[..., 0] + cos[near, None] * d[..., 1]
            i = np.floor((u / e[0] + 0.5) * n).astype(np.int64)
            j = np.floor((vv / e[1] + 0.5) * n).astype(np.int64)
            k = np.floor(d[..., 2] / e[2] * n).astype(np.int64)
            ok = (i >= 0) & (i < n) & (j >= 0) & (j < n) & (k >= 0) & (k < n)
            b = np.broadcast_to(near[:, None], ok.shape)[ok]
            flat[b, (i[ok] * n + j[ok]) * n + k[ok]] = True
        return out
