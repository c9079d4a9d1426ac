"""Point-to-scene distances (unsigned and signed) with open3d ray casting.

Sign convention (owned here): ``signed`` is negative inside a solid, positive outside, in metres.
``normal`` is the unit normal of the closest triangle, following its winding (outward for a
correctly oriented closed mesh). Inside-ness is computed per body and OR-ed (see
``trumans.scenes.raycast``), so overlapping meshes do not cancel each other.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from trumans.scenes._open3d import open3d_module

from trumans.scenes.raycast import Body, Watertight, bodies_inside, check_mesh, nthreads, split_bodies, to_o3d_scene

__all__ = ["DistanceResult", "SceneDistance"]


@dataclass
class DistanceResult:
    """Per-query-point results; ``...`` is the batch shape of the query points."""

    dist: np.ndarray  # (...,) float32, m, unsigned distance to the nearest surface
    signed: np.ndarray  # (...,) float32, m, negative inside a solid
    closest: np.ndarray  # (..., 3) float32, world, closest surface point
    normal: np.ndarray  # (..., 3) float32, unit normal of the closest triangle (outward)
    mesh_index: np.ndarray  # (...,) int64, index into ``names`` of the closest mesh
    names: list[str]  # mesh names in index order
    inside: np.ndarray  # (...,) bool, True inside any solid


def _as_points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points)
    if p.ndim < 1 or p.shape[-1] != 3:
        raise ValueError(f"points must be (..., 3), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or inf; pass finite coordinates in metres")
    return p


class SceneDistance:
    """Distance queries against a set of named world-frame meshes.

    meshes: name -> Trimesh in world coordinates (metres, z up). One RaycastingScene holds every
    mesh (geometry id = position in ``names``) for closest-point queries; inside tests use one
    scene per connected body.
    """

    def __init__(self, meshes: dict[str, trimesh.Trimesh], watertight: Watertight = "auto",
                 build_scene: bool = True) -> None:
        """build_scene=False defers the closest-point scene to the first ``query`` (inside tests
        alone never build it)."""
        if not isinstance(meshes, dict) or not meshes:
            raise ValueError("meshes must be a non-empty dict name -> trimesh.Trimesh")
        for name, m in meshes.items():
            check_mesh(m, f"mesh {name!r}")
        self.names: list[str] = list(meshes)
        self.meshes = dict(meshes)
        self.watertight = watertight
        self._scene = None
        if build_scene:
            self._build_scene()
        self._bodies: dict[str, list[Body]] = {}
        self._single: dict[str, SceneDistance] = {}

    def _build_scene(self) -> None:
        self._scene, ids = to_o3d_scene(*self.meshes.values())
        self._id_to_index = np.full(max(ids) + 1, -1, dtype=np.int64)
        self._id_to_index[ids] = np.arange(len(ids))

    def _bodies_of(self, name: str) -> list[Body]:
        if name not in self._bodies:
            self._bodies[name] = split_bodies(self.meshes[name], self.watertight)
        return self._bodies[name]

    def inside_per_mesh(self, points: np.ndarray) -> np.ndarray:
        """points: (..., 3) -> (..., M) bool, True if inside mesh m (order of ``names``)."""
        p = _as_points(points)
        flat = p.reshape(-1, 3).astype(np.float64)
        out = np.stack([bodies_inside(self._bodies_of(n), flat) for n in self.names], axis=-1)
        return out.reshape(p.shape[:-1] + (len(self.names),))

    def query(self, points: np.ndarray) -> DistanceResult:
        """points: (..., 3) float, world metres -> DistanceResult with batch shape ``...``."""
        p = _as_points(points)
        batch = p.shape[:-1]
        flat = np.ascontiguousarray(p.reshape(-1, 3), dtype=np.float32)
        if len(flat) == 0:
            z = np.zeros(batch, np.float32)
            return DistanceResult(z, z.copy(), np.zeros(batch + (3,), np.float32),
                                  np.zeros(batch + (3,), np.float32), np.zeros(batch, np.int64),
                                  list(self.names), np.zeros(batch, bool))
        if self._scene is None:
            self._build_scene()
        res = self._scene.compute_closest_points(open3d_module().core.Tensor(flat), nthreads=nthreads())
        closest = res["points"].numpy()
        normal = res["primitive_normals"].numpy()
        normal = normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
        gid = res["geometry_ids"].numpy().astype(np.int64)
        dist = np.linalg.norm(flat - closest, axis=-1).astype(np.float32)
        inside = np.zeros(len(flat), dtype=bool)
        for n in self.names:
            inside |= bodies_inside(self._bodies_of(n), flat.astype(np.float64))
        signed = np.where(inside, -dist, dist).astype(np.float32)
        return DistanceResult(
            dist=dist.reshape(batch),
            signed=signed.reshape(batch),
            closest=closest.reshape(batch + (3,)),
            normal=normal.astype(np.float32).reshape(batch + (3,)),
            mesh_index=self._id_to_index[gid].reshape(batch),
            names=list(self.names),
            inside=inside.reshape(batch),
        )

    def query_mesh(self, points: np.ndarray, name: str) -> DistanceResult:
        """Like ``query`` but against the single mesh ``name`` (``names == [name]``, index 0)."""
        if name not in self.meshes:
            raise KeyError(f"no mesh named {name!r}; meshes are {self.names}")
        if name not in self._single:
            single = SceneDistance({name: self.meshes[name]}, self.watertight)
            single._bodies[name] = self._bodies_of(name)
            self._single[name] = single
        return self._single[name].query(points)
