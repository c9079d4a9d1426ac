"""Voxel occupancy grids of scenes (open3d ray casting) and their cached ``occupancy.npz`` files.

Convention (owned here): ``grid[i, j, k] == True`` means the voxel is *occupied* (solid, not
walkable); every point outside the grid counts as occupied. ``origin`` is the world position of
the CENTRE of voxel (0, 0, 0); voxel (i, j, k) has centre ``origin + voxel * (i, j, k)``, and a
point belongs to its nearest voxel centre. Axes are world x, y, z (z up), metres.
"""
from __future__ import annotations

import hashlib
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import trimesh

from trumans.scenes.atomic import atomic_write
from trumans.scenes.raycast import Watertight, bodies_inside, check_mesh, split_bodies

if TYPE_CHECKING:
    from trumans.scenes.scene import Scene

__all__ = ["OccupancyGrid", "compute_occupancy", "scene_occupancy", "OCCUPANCY_FILE"]

OCCUPANCY_FILE = "occupancy.npz"
_CACHE_VERSION = "occ-v1"
DEFAULT_VOXEL = 0.02  # m, the voxel of cached scene grids (docs/conventions.md)
_CHUNK = 1 << 20  # voxel centres per ray-casting call (~12 MB of float32 points)


@dataclass(eq=False)
class OccupancyGrid:
    """grid: (Nx, Ny, Nz) bool, True = occupied; origin: (3,) world centre of voxel (0,0,0); voxel: m."""

    grid: np.ndarray
    origin: np.ndarray
    voxel: float

    def __post_init__(self) -> None:
        self.grid = np.asarray(self.grid)
        if self.grid.ndim != 3 or self.grid.dtype != bool:
            raise ValueError(f"grid must be a 3D bool array, got {self.grid.dtype} {self.grid.shape}")
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(-1)
        if self.origin.shape != (3,) or not np.all(np.isfinite(self.origin)):
            raise ValueError(f"origin must be 3 finite numbers, got {self.origin}")
        self.voxel = float(self.voxel)
        if not (self.voxel > 0 and np.isfinite(self.voxel)):
            raise ValueError(f"voxel must be a positive size in metres, got {self.voxel}")
        self._padded: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.grid.shape)  # type: ignore[return-value]

    def bounds(self) -> np.ndarray:
        """(2, 3) world extent of the grid (outer faces of the border voxels), m."""
        lo = self.origin - self.voxel / 2
        return np.stack([lo, lo + self.voxel * np.asarray(self.grid.shape)])

    def centers(self) -> np.ndarray:
        """(Nx, Ny, Nz, 3) float64 world voxel centres (memory: 24 bytes per voxel)."""
        axes = [self.origin[a] + self.voxel * np.arange(n) for a, n in enumerate(self.grid.shape)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    def padded(self) -> np.ndarray:
        """The grid with a one-voxel border of ``True`` (cached): index i + 1 of it is voxel i."""
        if self._padded is None or self._padded.shape != tuple(s + 2 for s in self.grid.shape):
            self._padded = np.pad(self.grid, 1, constant_values=True)
        return self._padded

    def index(self, points: np.ndarray) -> np.ndarray:
        """points: (..., 3) world m -> (..., 3) int64 nearest voxel index (may lie outside the grid)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim < 1 or p.shape[-1] != 3:
            raise ValueError(f"points must be (..., 3), got shape {p.shape}")
        return np.floor((p - self.origin) / self.voxel + 0.5).astype(np.int64)

    def query(self, points: np.ndarray) -> np.ndarray:
        """points: (..., 3) world m -> (...,) bool occupancy of the nearest voxel; outside = True."""
        idx = self.index(points)
        idx = np.clip(idx + 1, 0, np.asarray(self.grid.shape) + 1)  # out of range -> True border
        return self.padded()[idx[..., 0], idx[..., 1], idx[..., 2]]

    def save(self, path: str | Path, key: str | None = None) -> None:
        """Write ``grid``, ``origin``, ``voxel`` (and an optional cache ``key``) to .npz atomically."""
        arrays = {"grid": self.grid, "origin": self.origin, "voxel": np.asarray(self.voxel)}
        if key is not None:
            arrays["key"] = np.asarray(key)

        def write(tmp: str) -> None:
            with open(tmp, "wb") as f:
                np.savez_compressed(f, **arrays)

        atomic_write(path, write)

    @classmethod
    def load(cls, path: str | Path) -> "OccupancyGrid":
        """Read an occupancy .npz written by ``save``; clear errors for missing/corrupt files."""
        return _load(path)[0]


def _load(path: str | Path) -> tuple[OccupancyGrid, str | None]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"occupancy file {path} does not exist; compute it with scene_occupancy()")
    try:
        with np.load(path, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise ValueError("not an .npz archive")
            files = set(z.files)
            arrays = {k: z[k] for k in ("grid", "origin", "voxel", "key") if k in files}
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as e:
        why = "it holds Python objects; unpickling is refused" if "pickle" in str(e) else str(e)  # never advise unsafe loading
        raise ValueError(f"occupancy file {path} is corrupt ({why}); delete it and recompute") from e
    missing = {"grid", "origin", "voxel"} - set(arrays)
    if missing:
        raise ValueError(f"occupancy file {path} lacks {sorted(missing)}; delete it and recompute")
    grid, origin, voxel = arrays["grid"], arrays["origin"], arrays["voxel"]
    key = str(arrays["key"]) if "key" in arrays else None
    return OccupancyGrid(grid.astype(bool) if grid.dtype != bool else grid, origin, float(voxel)), key


def _as_mesh_list(meshes) -> list[trimesh.Trimesh]:
    items = list(meshes.items()) if isinstance(meshes, dict) else list(enumerate(meshes))
    if not items:
        raise ValueError("no meshes given; pass at least one non-empty trimesh.Trimesh")
    for name, m in items:
        check_mesh(m, f"mesh {name!r}")
    return [m for _, m in items]


def compute_occupancy(
    meshes: list[trimesh.Trimesh] | dict[str, trimesh.Trimesh],
    bounds: np.ndarray,
    voxel: float = 0.02,
    watertight: Watertight = "auto",
) -> OccupancyGrid:
    """Voxelise world-frame meshes over ``bounds`` (2, 3) m at ``voxel`` m; True = inside a solid.

    The grid's voxel centres are ``bounds[0] + voxel * (i + 1/2)``; it has
    ``ceil((bounds[1] - bounds[0]) / voxel)`` voxels per axis. Each mesh is split into connected
    bodies which are tested separately and OR-ed, so overlapping closed parts never cancel (ray
    parity). Only voxels inside a body's bounding box are ray-cast, in chunks of ~1M points.

    watertight: ``'auto'`` (per connected component: closed -> open3d ray parity,
    ``compute_occupancy(nsamples=3)``; open components (scans, holes) -> all open parts together,
    majority vote of the crossing parities of 15 rays in fixed directions spread over the sphere,
    see ``trumans.scenes.raycast``), ``True`` (trust every component to be closed) or ``False``
    (everything uses the vote). The vote misclassifies points close to a large opening; a mesh
    that bounds no solid at all (a single plane) gives no occupied voxels.
    """
    mesh_list = _as_mesh_list(meshes)
    b = np.asarray(bounds, dtype=np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"bounds must be (2, 3) [min, max] with max > min, got {b.tolist()}")
    voxel = float(voxel)
    if not voxel > 0:
        raise ValueError(f"voxel must be > 0 m, got {voxel}")
    shape = np.maximum(np.ceil((b[1] - b[0]) / voxel - 1e-9).astype(np.int64), 1)
    if np.prod(shape) > 2_000_000_000:
        raise ValueError(f"grid {shape.tolist()} at {voxel} m is too large; use a coarser voxel or smaller bounds")
    origin = b[0] + voxel / 2
    grid = np.zeros(tuple(shape), dtype=bool)
    for mesh in mesh_list:
        for body in split_bodies(mesh, watertight):
            lo = np.clip(np.floor((body.bounds[0] - origin) / voxel).astype(np.int64), 0, shape)
            hi = np.clip(np.ceil((body.bounds[1] - origin) / voxel).astype(np.int64) + 1, 0, shape)
            if np.any(hi <= lo):
                continue
            ys = origin[1] + voxel * np.arange(lo[1], hi[1])
            zs = origin[2] + voxel * np.arange(lo[2], hi[2])
            plane = np.stack(np.meshgrid(ys, zs, indexing="ij"), -1).reshape(-1, 2)  # (ny*nz, 2)
            step = max(1, _CHUNK // len(plane))
            for i0 in range(lo[0], hi[0], step):
                i1 = min(i0 + step, hi[0])
                xs = origin[0] + voxel * np.arange(i0, i1)
                pts = np.concatenate([np.repeat(xs, len(plane))[:, None], np.tile(plane, (len(xs), 1))], 1)
                occ = body.inside(pts).reshape(i1 - i0, hi[1] - lo[1], hi[2] - lo[2])
                grid[i0:i1, lo[1]:hi[1], lo[2]:hi[2]] |= occ
    return OccupancyGrid(grid, origin, voxel)


def scene_key(scene: "Scene", voxel: float, include_dynamic: bool) -> str:
    """SHA-256 of what determines the grid. Vertices are hashed as float32 (what PLY files keep),
    so a scene that went through save/load keeps its key; poses are hashed in float64."""
    h = hashlib.sha256(f"{_CACHE_VERSION}|{voxel!r}|{include_dynamic}".encode())

    def add(m: trimesh.Trimesh, pose: np.ndarray | None) -> None:
        h.update(np.ascontiguousarray(m.vertices, dtype=np.float32).tobytes())
        h.update(np.ascontiguousarray(m.faces, dtype=np.int64).tobytes())
        if pose is not None:
            h.update(np.ascontiguousarray(pose, dtype=np.float64).tobytes())
        h.update(b"|")

    for m in scene.static.values():
        add(m, None)
    for o in scene.objects.values():
        if include_dynamic or not o.dynamic:
            add(o.mesh, o.pose)
    return h.hexdigest()


def scene_occupancy(
    scene: "Scene",
    folder: str | Path | None = None,
    voxel: float = DEFAULT_VOXEL,
    include_dynamic: bool = True,
    min_height: float = 2.2,
) -> OccupancyGrid:
    """Occupancy of a whole scene at ``voxel`` m, cached as ``folder/occupancy.npz``.

    The grid covers the bounds of every scene mesh (dynamic ones too, so both settings share
    one frame) plus one voxel in x/y, and z from min(0, scene min z) to max(scene top,
    ``min_height``) plus one voxel (a room without a ceiling still has head room, since points
    outside the grid count as occupied). The z layers start at a multiple of ``voxel`` so that
    z = 0 is a voxel boundary. Everything below the floor (z < 0) is occupied: those voxels are
    set True, and points under the grid are outside, hence occupied. The cache stores a SHA-256
    key of every mesh and pose, ``voxel``, ``include_dynamic`` and ``min_height``; a changed
    scene or setting recomputes and overwrites it.
    """
    voxel = float(voxel)
    if not voxel > 0:
        raise ValueError(f"voxel must be > 0 m, got {voxel}")
    meshes = scene.world_meshes(include_dynamic)
    if not meshes:
        raise ValueError(f"scene {scene.name!r} has no meshes; add static meshes or objects first")
    key = scene_key(scene, float(voxel), include_dynamic) + f"|h{float(min_height)!r}"
    cache = Path(folder) / OCCUPANCY_FILE if folder is not None else None
    if cache is not None and cache.is_file():
        try:
            occ, old = _load(cache)
            if old == key:
                return occ
        except ValueError:
            pass  # corrupt cache: recompute and overwrite below
    mb = scene.bounds()
    z_lo = -np.ceil(max(0.0, -mb[0, 2]) / voxel - 1e-9) * voxel  # z = 0 falls on a voxel boundary
    lo = np.array([mb[0, 0] - voxel, mb[0, 1] - voxel, z_lo])
    hi = np.array([mb[1, 0] + voxel, mb[1, 1] + voxel, max(mb[1, 2], min_height, 0.0) + voxel])
    occ = compute_occupancy(meshes, np.stack([lo, hi]), voxel)
    zc = occ.origin[2] + voxel * np.arange(occ.grid.shape[2])
    occ.grid[:, :, zc < 0] = True  # below the floor is solid
    if cache is not None:
        occ.save(cache, key=key)
    return occ
