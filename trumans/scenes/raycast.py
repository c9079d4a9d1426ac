"""Inside/outside tests for triangle meshes with open3d ray casting, robust to overlapping bodies.

Convention (owned here): ``inside`` / occupancy ``True`` means the point lies in the solid.

open3d's ``RaycastingScene.compute_occupancy`` counts ray crossings (parity). When two closed
bodies overlap (e.g. furniture built by concatenating boxes), a point in the overlap crosses
both surfaces and the parities cancel. We therefore split every mesh into connected components
("bodies"), test each watertight body on its own scene and OR the results. Non-watertight
components (scans, meshes with holes) cannot be split meaningfully, so they are kept together as
one body and tested with a majority vote of the ray-crossing parities along ``NSAMPLES_OPEN``
fixed directions spread over the sphere (``RaycastingScene.count_intersections``): a point
inside a box with one face missing is still classified inside by most directions unless it is
close to the opening. (open3d's own ``compute_occupancy(nsamples=k)`` was checked and does not
help here: its sample rays are nearly parallel, so they all escape through the same hole.)
"""
from __future__ import annotations

import hashlib
import os
from collections import OrderedDict
from dataclasses import dataclass
from typing import Literal

import numpy as np
import trimesh

from trumans.scenes._open3d import open3d_module

__all__ = ["nthreads", "Watertight", "to_o3d_scene", "Body", "split_parts", "split_bodies", "bodies_inside", "check_mesh"]

Watertight = Literal["auto", True, False]

# Ray parity votes for bodies that are watertight (3 guards against rays grazing an edge) and
# for open bodies (majority vote over fixed spread directions; must be odd).
NSAMPLES_CLOSED = 3
NSAMPLES_OPEN = 15


def nthreads() -> int:
    """Threads for open3d ray casting: ``OMP_NUM_THREADS`` if set, else 0 (= all cores)."""
    try:
        return max(0, int(os.environ.get("OMP_NUM_THREADS", "0")))
    except ValueError:
        return 0


def sphere_directions(k: int) -> np.ndarray:
    """(k, 3) float32 unit vectors on a Fibonacci sphere, tilted off the axes (no grazing rays)."""
    i = np.arange(k) + 0.5
    z = 1 - 2 * i / k
    r = np.sqrt(1 - z**2)
    phi = i * np.pi * (3 - np.sqrt(5)) + 0.1234
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    d = d @ trimesh.transformations.euler_matrix(0.0123, 0.0456, 0.0789)[:3, :3].T
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def check_mesh(mesh: trimesh.Trimesh, name: str = "mesh") -> None:
    """Raise ValueError if ``mesh`` is not a Trimesh with at least one face and finite vertices."""
    if not isinstance(mesh, trimesh.Trimesh):
        raise ValueError(f"{name} must be a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise ValueError(f"{name} is empty (no faces); give a mesh with at least one triangle")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"{name} has non-finite vertices; clean the mesh before using it")
    if not float(mesh.area) > 1e-10:
        raise ValueError(f"{name} is degenerate (its {len(mesh.faces)} faces have zero area), so nothing can touch "
                         f"it; fix or remove the mesh")


def to_o3d_scene(*meshes: trimesh.Trimesh | tuple[np.ndarray, np.ndarray]
                 ) -> tuple["open3d.t.geometry.RaycastingScene", list[int]]:
    """A RaycastingScene with one geometry per mesh (a Trimesh or a (vertices (V, 3) m, faces (F, 3)
    int) pair); returns (scene, geometry ids in order)."""
    o3d = open3d_module()
    scene = o3d.t.geometry.RaycastingScene()
    ids = []
    for m in meshes:
        vert, face = (m.vertices, m.faces) if isinstance(m, trimesh.Trimesh) else m
        v = o3d.core.Tensor(np.ascontiguousarray(vert, dtype=np.float32))
        f = o3d.core.Tensor(np.ascontiguousarray(face, dtype=np.uint32))
        ids.append(int(scene.add_triangles(v, f)))
    return scene, ids


@dataclass
class Body:
    """One solid tested on its own: a ray-casting scene, its AABB (2, 3), vote count, closed flag."""

    scene: "open3d.t.geometry.RaycastingScene"
    bounds: np.ndarray  # (2, 3) world, m
    nsamples: int
    closed: bool

    def inside(self, points: np.ndarray) -> np.ndarray:
        """points: (N, 3) float -> (N,) bool, True inside. Points outside the AABB skip ray casting."""
        out = np.zeros(len(points), dtype=bool)
        eps = 1e-6
        m = np.all((points >= self.bounds[0] - eps) & (points <= self.bounds[1] + eps), axis=1)
        if m.any():
            q = np.ascontiguousarray(points[m], dtype=np.float32)
            if self.closed:
                t = open3d_module().core.Tensor(q)
                occ = self.scene.compute_occupancy(t, nthreads=nthreads(), nsamples=self.nsamples).numpy()
                out[m] = occ > 0.5
            else:  # majority vote of crossing parities over fixed spread directions
                out[m] = self._vote(q)
        return out


    def _vote(self, q: np.ndarray, chunk: int = 1 << 16) -> np.ndarray:
        d = sphere_directions(self.nsamples)
        votes = np.empty(len(q), dtype=bool)
        for i in range(0, len(q), chunk):  # chunked: rays take 24 * nsamples bytes per point
            qc = q[i:i + chunk]
            rays = np.concatenate(np.broadcast_arrays(qc[:, None, :], d[None]), axis=-1)  # (n, k, 6)
            hits = self.scene.count_intersections(open3d_module().core.Tensor(np.ascontiguousarray(rays)), nthreads=nthreads())
            votes[i:i + chunk] = ((hits.numpy() % 2) == 1).sum(axis=1) * 2 > self.nsamples
        return votes


# split_bodies' parts per mesh topology (see ``split_parts``), least recently used dropped first
SPLIT_PARTS_CACHE: OrderedDict[tuple, list[tuple[np.ndarray, np.ndarray, bool]]] = OrderedDict()
SPLIT_PARTS_CACHE_SIZE = 256


def split_parts(merged: trimesh.Trimesh, watertight: Watertight) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    """The bodies of a merged mesh as (vertices (V, 3), faces (F, 3), closed) parts.

    trimesh's split (face adjacency, its hole filling) and the watertight test read only the faces
    of the merged mesh, never the vertex positions, so the parts of a mesh are those of any mesh
    with the same merged faces, with its own vertices: a moved, scaled or copied object (most
    penetration checks of ``trumans eval augment``) reuses them. Parts are therefore cached as
    rows of ``merged.vertices`` by the merged faces (a miss costs a trimesh split, about 5 ms for
    a 6-box chair; a hit about 0.3 ms)."""
    faces = np.ascontiguousarray(merged.faces, dtype=np.int64)
    verts = np.asarray(merged.vertices, dtype=np.float64)
    key = (watertight, len(verts), faces.shape, hashlib.blake2b(faces.tobytes(), digest_size=16).digest())
    hit = SPLIT_PARTS_CACHE.get(key)
    if hit is not None:
        SPLIT_PARTS_CACHE.move_to_end(key)
        return [(verts[rows], f, closed) for rows, f, closed in hit]
    comps = merged.split(only_watertight=False) if merged.body_count > 1 else [merged]
    if watertight is True:
        parts_closed, parts_open = list(comps), []
    else:
        parts_closed = [c for c in comps if c.is_watertight]
        parts_open = [c for c in comps if not c.is_watertight]
        if parts_open:
            parts_open = [trimesh.util.concatenate(parts_open)]
    parts = [(np.array(p.vertices, dtype=np.float64), np.array(p.faces, dtype=np.int64), closed)
             for p, closed in [(p, True) for p in parts_closed] + [(p, False) for p in parts_open]]
    # the parts' vertices are copies of rows of merged.vertices; cache them as row indices
    table = np.ascontiguousarray(np.concatenate([verts] + [v for v, _, _ in parts]))
    rows = table.view(np.dtype((np.void, table.dtype.itemsize * 3))).ravel()
    _, first, inv = np.unique(rows, return_index=True, return_inverse=True)
    idx = first[inv.ravel()]
    if len(first) == len(verts) and (idx < len(verts)).all():  # merged rows are distinct; all found
        cut = np.cumsum([len(verts)] + [len(v) for v, _, _ in parts])
        SPLIT_PARTS_CACHE[key] = [(idx[a:b], f, closed) for a, b, (_, f, closed) in zip(cut[:-1], cut[1:], parts)]
        while len(SPLIT_PARTS_CACHE) > SPLIT_PARTS_CACHE_SIZE:
            SPLIT_PARTS_CACHE.popitem(last=False)
    return parts


def split_bodies(mesh: trimesh.Trimesh, watertight: Watertight = "auto") -> list[Body]:
    """Split ``mesh`` into bodies tested separately (see module doc).

    watertight: ``'auto'`` checks each connected component; ``True`` trusts every component to be
    closed (single-ray-family parity); ``False`` treats the whole mesh as open (majority vote).
    """
    check_mesh(mesh)
    if watertight is False:
        parts = [(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces), False)]
    else:
        # A fresh processed copy merges duplicate vertices, so faces that share positions connect.
        merged = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=True)
        parts = split_parts(merged, watertight)
    bodies = []
    for verts, faces, closed in parts:
        if len(faces) == 0:
            continue
        scene, _ = to_o3d_scene((verts, faces))
        ns = NSAMPLES_CLOSED if closed else NSAMPLES_OPEN
        used = verts[np.asarray(faces).ravel()]  # the bounds of the faces (trimesh's ``bounds``)
        bodies.append(Body(scene, np.array([used.min(0), used.max(0)], dtype=np.float64), ns, closed))
    return bodies


def bodies_inside(bodies: list[Body], points: np.ndarray) -> np.ndarray:
    """points: (N, 3) -> (N,) bool, True if inside any body (OR over bodies, no parity cancelling)."""
    out = np.zeros(len(points), dtype=bool)
    for b in bodies:
        out |= b.inside(points)
    return out
