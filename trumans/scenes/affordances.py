"""Seats, beds and tables found in a raw mesh from its geometry (a scan or a room model without names).

What is found (``find_affordances``), in a z-up mesh in metres with the floor at z = 0:

- **support surfaces**: one vertical ray per ``cell`` floor column lists every surface it crosses
  (open3d ``list_intersections``); a *top* is a horizontal crossing (normal within 20 degrees of
  +z; of +-z when the mesh is not a closed, consistently wound solid, as scans are) whose **clearance**
  (the free height up to the next crossing above) is enough for the use: ``seat_clear`` for a seat
  (a sitting person's head), ``bed_clear`` for a bed, ``table_clear`` for a table top. Tops of
  neighbouring columns whose heights differ by at most ``flat_tol`` join into one flat patch
  (scipy connected components); a patch's size is its minimum-area rectangle
  (``trimesh.bounds.oriented_bounds_2D``), its height the median of its tops;
- **seats** (category ``chair`` with a backrest, ``stool`` without, ``sofa`` when longer than
  ``sofa_min_length``): patches at ``seat_z``, or small ones (at most ``high_seat_max`` across) at
  ``high_seat_z`` (bar stools); **beds**: at ``bed_z`` and at least ``bed_min`` (long x short side);
  **tables**: at ``table_z``, at least ``table_min_side`` across and not a high stool;
- **facing**: horizontal rays from above the surface (0.2 and 0.4 m up) tell on which sides
  something stands within ``back_m`` of the edge (a backrest, a headboard or a wall: the *back*);
  the free floor is the walkable map of the same columns (nothing between 0.1 and 1.8 m, a body of
  ``body_radius`` fits: ``trumans.scenes.walkability``'s rule), restricted to its largest connected
  region. A seat faces away from its back, towards the side with free floor to approach from (a
  sofa from one of its long sides); a bed's head is at its back end and it is sat on from its free
  long side; a table is used from the side with the most free floor. A surface with no free floor
  beside it is dropped (nobody can reach it).

Each find becomes a static ``SceneObject`` in the contract of ``trumans.scenes.furniture`` (local
+x = front, origin at the surface's centre on the floor, meta in the local frame, m / rad), named
``seat_K`` (chairs, stools, sofas), ``bed_K`` and ``table_K`` in the order of their centres (x,
then y); its mesh is the part of the input mesh over its footprint (the input stays the scene's
static mesh). Named parts (``named_parts``: OBJ ``o``/``g`` groups, GLB/glTF nodes or their
parents whose name starts with the word chair, sofa, stool, bed, table or desk: ``Chair.001``, ``bed_2``,
not ``bedside``) are honoured:
the part's own largest flat top at a plausible height for its category gives the object, named as
in the file, and geometric finds on its footprint are dropped.

Frame checks (``check_room_frame``, ValueError naming the fix): a mesh spanning more than
``MAX_SPAN_M`` is taken to be in centimetres or millimetres; a mesh whose large horizontal floor is
not at z = 0, or that has no horizontal floor but a large floor across y, is refused (translate
it, or read it with ``up='y'``). Everything is deterministic (fixed ray grid, sorted output).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from trumans.rotations import Y_UP_TO_Z_UP
from trumans.scenes._open3d import open3d_module
from trumans.scenes.raycast import bodies_inside, check_mesh, nthreads, split_bodies, to_o3d_scene
from trumans.scenes.scene import SceneObject
from trumans.scenes.walkability import WalkMap

__all__ = ["AffordanceConfig", "find_affordances", "named_parts", "mesh_affordances", "check_room_frame",
           "describe", "NAMED_PREFIXES", "MAX_SPAN_M", "SEAT_CATEGORIES"]

#: object-name prefixes of a mesh file's parts that are honoured, and the category each gives
NAMED_PREFIXES: dict[str, str] = {"chair": "chair", "sofa": "sofa", "stool": "stool", "bed": "bed", "table": "table",
                                  "desk": "desk"}
#: categories named seat_K (what ``--sit-on`` takes)
SEAT_CATEGORIES: tuple[str, ...] = ("chair", "stool", "sofa")
MAX_SPAN_M = 60.0  # a room or a flat larger than this is taken to be in cm / mm
SQUARE_RATIO = 1.2  # a patch squarer than this whose world-aligned box is about as small is aligned with the world (rooms are)
FLOOR_MIN_M2 = 2.0  # a horizontal layer this large (and >= 30 % of the footprint) is a room's floor
_COS_HORIZONTAL = np.cos(np.radians(20.0))
_MERGE_M = 0.002  # crossings closer than this along one ray are one surface (touching parts)
_LAYERS = 3  # tops per column kept per pass (a seat under a table top under a lamp ...)
_SIDES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))  # (rectangle axis, sign)


@dataclass(frozen=True)
class AffordanceConfig:
    """Thresholds of ``find_affordances`` (m). Heights are of the support surface above the floor."""

    cell: float = 0.03  # column spacing
    flat_tol: float = 0.02  # height step between neighbouring columns of one patch
    seat_z: tuple[float, float] = (0.33, 0.62)
    high_seat_z: tuple[float, float] = (0.62, 0.80)  # bar stools: only patches at most high_seat_max across
    high_seat_max: float = 0.45
    seat_min_side: float = 0.25
    sofa_min_length: float = 0.95  # a seat patch longer than this is a sofa (several places)
    bed_z: tuple[float, float] = (0.25, 0.75)
    bed_min: tuple[float, float] = (1.6, 0.8)  # long side, short side
    table_z: tuple[float, float] = (0.62, 1.00)
    table_min_side: float = 0.35
    max_length: float = 3.5  # longer flat tops (platforms, counters) are not furniture
    min_fill: float = 0.6  # patch area / its rectangle's area (round seats 0.79)
    seat_clear: float = 0.9
    bed_clear: float = 0.75
    table_clear: float = 0.3
    back_m: float = 0.25  # something this close behind an edge, 0.2-0.4 m above the surface, is a back
    body_radius: float = 0.25  # the walk map's body radius
    approach_m: tuple[float, float] = (0.2, 0.8)  # where the approach point may lie beyond the front edge
    max_columns: int = 1_500_000

    def __post_init__(self) -> None:
        for name in ("cell", "flat_tol", "seat_min_side", "table_min_side", "seat_clear", "bed_clear",
                     "table_clear", "back_m", "high_seat_max", "max_length", "sofa_min_length"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"AffordanceConfig.{name} must be a positive length in m, got {v}")
        for name in ("seat_z", "high_seat_z", "bed_z", "table_z", "approach_m"):
            lo, hi = getattr(self, name)
            if not 0 <= lo < hi:
                raise ValueError(f"AffordanceConfig.{name} must be (low, high) m with 0 <= low < high, got {(lo, hi)}")


# ----------------------------------------------------------------------------- columns


@dataclass
class _Columns:
    """Crossings of the vertical rays, top to bottom per ray. ray/z/top/clear/part: (H,) each."""

    lo: np.ndarray  # (2,) world xy of column (0, 0)
    shape: tuple[int, int]
    cell: float
    ray: np.ndarray
    z: np.ndarray
    top: np.ndarray  # horizontal crossing that may be a support top
    clear: np.ndarray  # free height above, m (inf for the highest)
    xy: np.ndarray = field(default=None)  # (N, 2) column centres


def _cast_columns(rc: "open3d.t.geometry.RaycastingScene", normals: np.ndarray, trust: bool, lo: np.ndarray,
                  shape: tuple[int, int], cell: float, z_top: float) -> _Columns:
    nx, ny = shape
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    xy = lo + cell * np.stack([ii, jj], -1).reshape(-1, 2)
    rays = np.zeros((len(xy), 6), np.float32)
    rays[:, :2], rays[:, 2], rays[:, 5] = xy, z_top, -1.0
    res = rc.list_intersections(open3d_module().core.Tensor(rays), nthreads=nthreads())
    splits = res["ray_splits"].numpy().astype(np.int64)
    t = res["t_hit"].numpy().astype(np.float64)
    prim = res["primitive_ids"].numpy().astype(np.int64)
    ray = np.repeat(np.arange(len(xy)), np.diff(splits))
    order = np.lexsort((t, ray))
    ray, z, nz = ray[order], z_top - t[order], normals[prim[order], 2]
    horiz = np.abs(nz) >= _COS_HORIZONTAL
    up = horiz & (nz > 0) if trust else horiz
    start = np.ones(len(z), bool)  # a new surface: another ray or more than _MERGE_M below the last one
    start[1:] = (ray[1:] != ray[:-1]) | (z[:-1] - z[1:] > _MERGE_M)
    first = np.flatnonzero(start)
    if len(first):
        top = np.logical_or.reduceat(up, first)
        ray, z = ray[first], z[first]
    else:
        top = np.zeros(0, bool)
    clear = np.full(len(z), np.inf)
    same = ray[1:] == ray[:-1]
    clear[1:][same] = z[:-1][same] - z[1:][same]
    return _Columns(lo, shape, cell, ray, z, top, clear, xy)


def _walk_map(cols: _Columns, mesh: trimesh.Trimesh, body_radius: float) -> tuple[WalkMap, np.ndarray]:
    """The columns' walk map (trumans.scenes.walkability's rule: blocked if anything is between 0.1
    and 1.8 m, or the band lies inside a solid; walkable iff no blocked centre within the body
    radius) and the mask of its largest 8-connected walkable region, (Nx, Ny) each."""
    nx, ny = cols.shape
    blocked = np.zeros(nx * ny, bool)
    blocked[cols.ray[(cols.z > 0.1) & (cols.z < 1.8)]] = True
    rest = np.flatnonzero(~blocked)
    if len(rest):  # a solid through the whole band (a wall) has no crossing in it
        pts = np.concatenate([cols.xy[rest], np.full((len(rest), 1), 0.95)], 1)
        blocked[rest[bodies_inside(split_bodies(mesh), pts)]] = True
    padded = np.pad(blocked.reshape(nx, ny), 1, constant_values=True)
    walkable = (ndimage.distance_transform_edt(~padded) * cols.cell > body_radius + 1e-9)[1:-1, 1:-1]
    labels, n = ndimage.label(walkable, structure=np.ones((3, 3)))
    main = np.zeros_like(walkable)
    if n:
        sizes = ndimage.sum_labels(walkable, labels, index=np.arange(1, n + 1))
        main = labels == 1 + int(np.argmax(sizes))
    return WalkMap(walkable, cols.lo.copy(), cols.cell), main


# ----------------------------------------------------------------------------- patches


@dataclass
class _Patch:
    """A flat top: centre (2,) world xy, axes (2, 2) rows = unit rectangle axes, ext (2,) m along
    them, height m, fill (area / rectangle area), cells (C,) column ids."""

    centre: np.ndarray
    axes: np.ndarray
    ext: np.ndarray
    height: float
    fill: float
    cells: np.ndarray

    @property
    def long(self) -> float:
        return float(self.ext.max())

    @property
    def short(self) -> float:
        return float(self.ext.min())

    def contains(self, p: np.ndarray, margin: float = 0.0) -> bool:
        d = self.axes @ (np.asarray(p, np.float64)[:2] - self.centre)
        return bool(np.all(np.abs(d) <= self.ext / 2 + margin))


def _patches(cols: _Columns, sel: np.ndarray, tol: float, min_cells: int) -> list[_Patch]:
    """Flat patches of the selected tops ``sel`` (H,) bool: 8-neighbour columns whose tops differ by
    at most ``tol`` m join (at most _LAYERS tops per column, the highest)."""
    idx = np.flatnonzero(sel)
    if len(idx) == 0:
        return []
    ray = cols.ray[idx]
    first = np.ones(len(idx), bool)
    first[1:] = ray[1:] != ray[:-1]
    starts = np.flatnonzero(first)
    layer = np.arange(len(idx)) - np.repeat(starts, np.diff(np.append(starts, len(idx))))
    keep = layer < _LAYERS
    idx, ray, layer = idx[keep], ray[keep], layer[keep]
    nx, ny = cols.shape
    node = np.full((nx * ny, _LAYERS), -1, np.int64)
    node[ray, layer] = np.arange(len(idx))
    zz = np.full((nx * ny, _LAYERS), np.nan)
    zz[ray, layer] = cols.z[idx]
    node, zz = node.reshape(nx, ny, _LAYERS), zz.reshape(nx, ny, _LAYERS)
    rows, colsl = [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        a = (slice(0, nx - di), slice(max(0, -dj), ny - max(0, dj)))
        b = (slice(di, nx), slice(max(0, dj), ny + min(0, dj)))
        for ka in range(_LAYERS):
            for kb in range(_LAYERS):
                na, nb = node[a][..., ka], node[b][..., kb]
                ok = (na >= 0) & (nb >= 0) & (np.abs(zz[a][..., ka] - zz[b][..., kb]) <= tol)
                rows.append(na[ok])
                colsl.append(nb[ok])
    r, c = np.concatenate(rows), np.concatenate(colsl)
    graph = coo_matrix((np.ones(len(r)), (r, c)), shape=(len(idx), len(idx)))
    _, label = connected_components(graph, directed=False)
    out = []
    for lab in np.unique(label):
        members = np.flatnonzero(label == lab)
        if len(members) < min_cells:
            continue
        cells = ray[members]
        pts = cols.xy[cells]
        T, rect = trimesh.bounds.oriented_bounds_2D(pts)
        inv = np.linalg.inv(T)
        axes = inv[:2, :2].T  # rows: the rectangle's axes in world xy
        ext = np.asarray(rect, np.float64) + cols.cell
        world_ext = np.ptp(pts, axis=0) + cols.cell
        if ext.max() < SQUARE_RATIO * ext.min() and np.prod(world_ext) < SQUARE_RATIO * np.prod(ext):
            # round (or square and aligned with the world): the rectangle's axes say nothing, take the world's
            axes, ext = np.eye(2), world_ext
            inv[:2, 2] = 0.5 * (pts.min(0) + pts.max(0))
        order = np.argsort(-ext, kind="stable")  # axis 0 = the long side
        axes, ext = axes[order], ext[order]
        axes = axes * np.where(axes[:, :1] + 1e-9 * axes[:, 1:] >= 0, 1.0, -1.0)  # deterministic signs
        fill = len(cells) * cols.cell ** 2 / float(np.prod(ext))
        out.append(_Patch(inv[:2, 2].copy(), axes, ext, float(np.median(cols.z[idx[members]])), fill, cells))
    return out


# ----------------------------------------------------------------------------- sides


@dataclass
class _Side:
    """One edge of a patch: outward unit ``normal`` (2,), ``back`` fraction of rays blocked within
    back_m beyond it, ``back_m`` median distance beyond the edge of the blocked rays (inf: none),
    ``free`` fraction of main-floor points 0.3-0.6 m beyond it, ``approach`` floor point or None."""

    normal: np.ndarray
    back: float
    back_m: float
    free: float
    approach: np.ndarray | None
    beyond: float  # approach distance beyond the edge, m


def _sides(p: _Patch, rc, wm: WalkMap, main: np.ndarray, cfg: AffordanceConfig) -> list[_Side]:
    out = []
    for ax, sign in _SIDES:
        n = sign * p.axes[ax]
        lat = p.axes[1 - ax]
        half, halfw = p.ext[ax] / 2, p.ext[1 - ax] / 2
        offs = np.array([-0.6, 0.0, 0.6]) * halfw
        origins = np.array([[*(p.centre + o * lat), p.height + dz] for dz in (0.2, 0.4) for o in offs])
        rays = np.concatenate([origins, np.tile([n[0], n[1], 0.0], (len(origins), 1))], 1).astype(np.float32)
        t = rc.cast_rays(open3d_module().core.Tensor(rays), nthreads=nthreads())["t_hit"].numpy().astype(np.float64)
        beyond = t - half
        hit = beyond <= cfg.back_m
        back_m = float(np.median(beyond[hit])) if hit.any() else np.inf
        ds = np.array([0.3, 0.45, 0.6])
        pts = (p.centre + n * half)[None, None] + ds[:, None, None] * n + np.linspace(-0.8, 0.8, 5)[None, :, None] \
            * halfw * lat
        free = float(_on_main(wm, main, pts.reshape(-1, 2)).mean())
        approach, dist = None, float(cfg.approach_m[0])
        for d in np.arange(cfg.approach_m[0], cfg.approach_m[1] + 1e-9, 0.05):
            q = p.centre + n * (half + d)
            if _on_main(wm, main, q[None])[0]:
                approach, dist = q, float(d)
                break
        out.append(_Side(n, float(hit.mean()), back_m, free, approach, dist))
    return out


def _on_main(wm: WalkMap, main: np.ndarray, pts: np.ndarray) -> np.ndarray:
    idx = wm.index(pts)
    n = np.asarray(main.shape)
    inside = np.all((idx >= 0) & (idx < n), axis=-1)
    c = np.clip(idx, 0, n - 1)
    return inside & main[c[..., 0], c[..., 1]]


def _front(sides: list[_Side], allowed: tuple[int, ...]) -> int | None:
    """The side a seat / table is used from, among ``allowed`` sides without a back: the one opposite a
    back (a backrest, headboard or wall) if any, preferring one with an approach point; else the one
    with an approach point and the most free floor (the first in ties); None when no side qualifies.
    A side opposite a back without an approach point keeps ``approach`` None (the caller stands the
    person ``approach_m[0]`` beyond the edge; the controller moves that onto the nearest walkable floor)."""
    opposite = {0: 1, 1: 0, 2: 3, 3: 2}
    ok = [k for k in allowed if sides[k].back < 0.5]
    facing_away = [k for k in ok if sides[opposite[k]].back >= 0.5]
    if facing_away:
        return max(facing_away, key=lambda k: (sides[k].approach is not None, sides[k].free, -k))
    reachable = [k for k in ok if sides[k].approach is not None]
    if not reachable:
        return None
    return max(reachable, key=lambda k: (sides[k].free, -k))


# ----------------------------------------------------------------------------- objects


def _f(v) -> float | list:
    a = np.asarray(v, dtype=np.float64)
    return float(round(float(a), 4)) if a.ndim == 0 else np.round(a, 4).tolist()


def _pose(centre: np.ndarray, front: np.ndarray) -> np.ndarray:
    """(4, 4) world-from-object: origin at ``centre`` (2,) on the floor, local +x along ``front``."""
    yaw = float(np.arctan2(front[1], front[0]))
    T = np.eye(4)
    T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    T[:2, 3] = centre
    return T


def _local(T: np.ndarray, p2: np.ndarray) -> np.ndarray:
    return T[:2, :2].T @ (np.asarray(p2, np.float64) - T[:2, 3])


def _crop(mesh: trimesh.Trimesh, T: np.ndarray, half: np.ndarray, z_max: float, back: float) -> trimesh.Trimesh:
    """The faces of ``mesh`` whose centroid lies over the local box |y| <= half[1] + 0.1,
    -half[0] - back <= x <= half[0] + 0.1, 5 mm <= z <= z_max, in the object frame."""
    inv = np.linalg.inv(T)
    c = mesh.triangles_center @ inv[:3, :3].T + inv[:3, 3]
    m = (c[:, 0] >= -half[0] - back) & (c[:, 0] <= half[0] + 0.1) & (np.abs(c[:, 1]) <= half[1] + 0.1) \
        & (c[:, 2] >= 0.005) & (c[:, 2] <= z_max)
    if not m.any():
        return trimesh.creation.box(bounds=[[-half[0], -half[1], 0.0], [half[0], half[1], 0.01]])
    faces = np.asarray(mesh.faces)[m]
    used, inverse = np.unique(faces, return_inverse=True)
    v = np.asarray(mesh.vertices)[used] @ inv[:3, :3].T + inv[:3, 3]
    return trimesh.Trimesh(v, inverse.reshape(-1, 3), process=False)


def _seat_object(p: _Patch, sides: list[_Side], mesh, cfg: AffordanceConfig, category: str | None,
                 name: str, rc) -> SceneObject | None:
    """A chair / stool / sofa (``category`` None: decided from the patch) facing its front side."""
    sofa = category == "sofa" or (category is None and p.long > cfg.sofa_min_length)
    k = _front(sides, (2, 3) if sofa else (0, 1, 2, 3))
    if k is None:
        return None
    s = sides[k]
    T = _pose(p.centre, s.normal)
    ax = _SIDES[k][0]
    depth, width = p.ext[ax], p.ext[1 - ax]
    back = sides[{0: 1, 1: 0, 2: 3, 3: 2}[k]]
    if category is None:
        category = "sofa" if sofa else ("chair" if back.back >= 0.5 and _own_back(p, back, rc) else "stool")
    h = p.height
    x = max(0.0, depth / 2 - 0.24)  # upright: the thighs end at the front edge (furniture.sofa)
    meta = {"approach": _f([depth / 2 + s.beyond, 0.0]), "approach_yaw": 0.0, "seat_height": _f(h),
            "seat_center": _f([x, 0.0, h]), "sit_yaw": 0.0}
    if sofa:
        n_places = max(2, int(width // 0.6))
        ys = (np.arange(n_places) + 0.5) / n_places * width - width / 2
        meta["seat_centers"] = _f([[x, y, h] for y in ys])
        meta.update(lie_center=_f([0.0, 0.0, h]), lie_yaw=_f(np.pi / 2), lie_length=_f(width))
    obj_mesh = _crop(mesh, T, np.array([depth / 2, width / 2]), h + 0.9, 0.35)
    meta = {"size": _f(obj_mesh.extents), **meta, "found_by": "geometry"}
    return SceneObject(name, category, obj_mesh, pose=T, dof="static", dynamic=False, meta=meta)


def _own_back(p: _Patch, back: _Side, rc) -> bool:
    """True when the back ends with the seat (a backrest), False when it also stands beside it (a wall):
    a ray 0.3 m up, 0.1 m beyond one side of the seat, meets nothing within 2.5 cm behind the back."""
    n = back.normal
    k = int(np.argmax(np.abs(p.axes @ n)))
    lat, half, halfw = p.axes[1 - k], p.ext[k] / 2, p.ext[1 - k] / 2
    origins = np.array([[*(p.centre + s * (halfw + 0.1) * lat), p.height + 0.3] for s in (-1.0, 1.0)])
    rays = np.concatenate([origins, np.tile([n[0], n[1], 0.0], (2, 1))], 1).astype(np.float32)
    t = rc.cast_rays(open3d_module().core.Tensor(rays), nthreads=nthreads())["t_hit"].numpy().astype(np.float64)
    return bool(np.any(t - half > back.back_m + 0.025))  # any: a chair in a corner has a wall on one side


def _bed_object(p: _Patch, sides: list[_Side], mesh, name: str, category: str = "bed") -> SceneObject | None:
    """A bed: head at the end with a back (headboard / wall), sat on from its free long side."""
    ends = (0, 1)
    head = max(ends, key=lambda k: (sides[k].back, -sides[k].back_m, k))  # ties: the second end (-axis)
    foot = 1 - head
    x_dir = sides[foot].normal  # local +x: towards the feet
    T = _pose(p.centre, x_dir)
    L, W, h = p.ext[0], p.ext[1], p.height
    meta = {"lie_center": _f([0.0, 0.0, h]), "lie_yaw": _f(np.pi), "lie_length": _f(L), "seat_height": _f(h)}
    longs = [k for k in (2, 3) if sides[k].approach is not None]
    if longs:
        k = max(longs, key=lambda j: (sides[j].free, -j))
        side = 1.0 if float(np.dot(_local(T, p.centre + sides[k].normal) , [0.0, 1.0])) > 0 else -1.0
        sit_x = 0.1
        meta.update(approach=_f([sit_x, side * (W / 2 + sides[k].beyond)]), approach_yaw=_f(side * np.pi / 2),
                    seat_center=_f([sit_x, side * (W / 2 - 0.2), h]), sit_yaw=_f(side * np.pi / 2), side=side)
    elif sides[foot].approach is not None:
        meta.update(approach=_f([L / 2 + sides[foot].beyond, 0.0]), approach_yaw=_f(np.pi))
        del meta["seat_height"]
    else:
        return None
    obj_mesh = _crop(mesh, T, np.array([L / 2, W / 2]), h + 0.8, 0.15)
    meta = {"size": _f(obj_mesh.extents), **meta, "found_by": "geometry"}
    return SceneObject(name, category, obj_mesh, pose=T, dof="static", dynamic=False, meta=meta)


def _table_object(p: _Patch, sides: list[_Side], mesh, name: str, category: str = "table") -> SceneObject | None:
    """A table (or desk): used from the side with the most free floor (local +x)."""
    k = _front(sides, (0, 1, 2, 3))
    if k is None:
        return None
    s = sides[k]
    T = _pose(p.centre, s.normal)
    ax = _SIDES[k][0]
    sx, sy, h = p.ext[ax], p.ext[1 - ax], p.height
    obj_mesh = _crop(mesh, T, np.array([sx / 2, sy / 2]), h + 0.05, 0.0)
    meta = {"size": _f(obj_mesh.extents), "approach": _f([sx / 2 + s.beyond, 0.0]), "approach_yaw": _f(np.pi),
            "surface_height": _f(h), "surface_center": _f([0.0, 0.0, h]), "surface_size": _f([sx, sy]),
            "found_by": "geometry"}
    return SceneObject(name, category, obj_mesh, pose=T, dof="static", dynamic=False, meta=meta)


# ----------------------------------------------------------------------------- entry points


def check_room_frame(mesh: trimesh.Trimesh, where: str = "mesh") -> None:
    """Raise ValueError when ``mesh`` is clearly not z-up metres with the floor at z = 0: it spans
    more than MAX_SPAN_M (centimetres / millimetres), its large horizontal floor (>= 30 % of its
    footprint and >= FLOOR_MIN_M2, within its lowest 0.3 m) lies more than 5 cm off z = 0 (the message also
    suggests up='y' when such a floor lies across y at y = 0: a y-up file read as z-up), or it has no floor
    at all but one across y at y = 0. Meshes without a large floor pass."""
    check_mesh(mesh, where)
    ext = mesh.extents
    if float(ext.max()) > MAX_SPAN_M:
        raise ValueError(f"{where} spans {ext.round(1).tolist()} units; trumans reads metres: is it in centimetres "
                         f"or millimetres? rescale it (x0.01 / x0.001) before use")
    fz = _floor_level(mesh, 2)
    if fz is not None and abs(fz) <= 0.05:
        return
    y_up = (fy := _floor_level(mesh, 1)) is not None and abs(fy) <= 0.05
    if fz is not None:
        hint = "; or, as it has a floor across y at y = 0, it may be y-up: read it with --up y (up='y')" if y_up else ""
        raise ValueError(f"{where}: its floor is at z = {fz:.2f} m, trumans needs the floor at z = 0: translate "
                         f"the mesh by {-fz:.2f} m in z{hint}")
    if y_up:
        raise ValueError(f"{where} has no floor at z = 0 but one across y at y = 0: it looks y-up; read it with "
                         f"--up y (up='y')")


def _floor_level(mesh: trimesh.Trimesh, axis: int) -> float | None:
    """The level (m along ``axis``) of the highest 1 cm layer within the mesh's lowest 0.3 m whose faces
    normal to ``axis`` cover >= 30 % of the mesh's footprint across ``axis`` and FLOOR_MIN_M2; None if none does."""
    n = mesh.face_normals[:, axis]
    c = mesh.triangles_center[:, axis]
    lo = float(mesh.bounds[0, axis])
    others = [a for a in range(3) if a != axis]
    foot = float(np.prod(mesh.extents[others]))
    m = (np.abs(n) >= _COS_HORIZONTAL) & (c <= lo + 0.3)
    if foot <= 0 or not m.any():
        return None
    bins = np.clip(np.floor((c[m] - lo) / 0.01), 0, None).astype(np.int64)
    area = np.bincount(bins, weights=mesh.area_faces[m])
    big = np.flatnonzero((area >= 0.3 * foot) & (area >= FLOOR_MIN_M2))
    if len(big) == 0:
        return None
    level = np.bincount(bins, weights=mesh.area_faces[m] * c[m])[big.max()] / area[big.max()]  # its mean level
    return float(level)


def find_affordances(mesh: trimesh.Trimesh, parts: dict[str, trimesh.Trimesh] | None = None,
                     config: AffordanceConfig | None = None, notes: list[str] | None = None) -> list[SceneObject]:
    """Seats, beds and tables of ``mesh`` (z-up, metres, floor at z = 0; module doc): static
    SceneObjects named seat_K / bed_K / table_K (and the names of ``parts``: name -> world-frame
    mesh of a named chair / sofa / stool / bed / table / desk), sorted by category then centre.
    A named part without a usable top or free floor beside it is skipped, with a line in ``notes``.
    Raises ValueError for an empty mesh or one in the wrong frame (``check_room_frame``)."""
    cfg = config or AffordanceConfig()
    check_room_frame(mesh)
    parts = dict(parts or {})
    b = mesh.bounds
    cell = cfg.cell
    span = b[1, :2] - b[0, :2]
    if np.prod(np.ceil(span / cell) + 1) > cfg.max_columns:
        cell = float(np.sqrt(np.prod(span + cell) / cfg.max_columns))
    shape = tuple(int(v) for v in np.ceil(span / cell).astype(np.int64) + 1)
    lo = b[0, :2] + 0.5 * (span - cell * (np.asarray(shape) - 1)) + 0.0137 * cell  # off the axes of boxes
    normals = np.asarray(mesh.face_normals)
    trust = bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)
    rc, _ = to_o3d_scene(mesh)
    z_top = float(b[1, 2]) + 1.0
    cols = _cast_columns(rc, normals, trust, lo, shape, cell, z_top)
    wm, main = _walk_map(cols, mesh, cfg.body_radius)
    min_cells = max(4, int(np.ceil(0.04 / cell ** 2)))

    found: list[tuple[str, SceneObject]] = []  # (kind, object) kind: seat / bed / table
    taken: list[_Patch] = []

    # named parts first: each part's own largest flat top at a plausible height for its category
    for pname in sorted(parts):
        cat = _prefix_category(pname)
        pm = parts[pname]
        if cat is None or len(pm.faces) == 0:
            continue
        prc, _ = to_o3d_scene(pm)
        pcols = _cast_columns(prc, np.asarray(pm.face_normals), False, lo, shape, cell, z_top)
        pcols.clear = _clearance_in(cols, pcols)
        zr = {"bed": (0.15, 0.9), "table": (0.4, 1.3), "desk": (0.4, 1.3)}.get(cat, (0.2, 0.95))
        need = {"bed": 0.5, "table": 0.2, "desk": 0.2}.get(cat, 0.5)
        sel = pcols.top & (pcols.z >= zr[0]) & (pcols.z <= zr[1]) & (pcols.clear >= need)
        cands = _patches(pcols, sel, cfg.flat_tol, min_cells)
        if not cands:
            _note(notes, f"named part {pname!r} skipped: it has no flat top {zr[0]}-{zr[1]} m high with {need} m free "
                         f"above it (a {cat} needs one; rename parts that are not furniture)")
            continue
        p = max(cands, key=lambda q: (len(q.cells), q.height))
        sides = _sides(p, rc, wm, main, cfg)
        obj_name = _safe_name(pname)
        if cat == "bed":
            obj = _bed_object(p, sides, mesh, obj_name)
        elif cat in ("table", "desk"):
            obj = _table_object(p, sides, mesh, obj_name, cat)
        else:
            obj = _seat_object(p, sides, mesh, cfg, cat, obj_name, rc)
        if obj is None:
            _note(notes, f"named part {pname!r} skipped: no free floor beside it to approach from")
            continue
        obj.mesh = _part_local(pm, obj.pose)
        obj.meta["size"] = _f(obj.mesh.extents)
        obj.meta["found_by"] = "name"
        found.append(({"bed": "bed", "table": "table", "desk": "table"}.get(cat, "seat"), obj))
        taken.append(p)

    def free_patch(p: _Patch) -> bool:
        return not any(t.contains(p.centre, 0.05) or p.contains(t.centre, 0.05) for t in taken)

    top = cols.top
    beds = [p for p in _patches(cols, top & _between(cols.z, cfg.bed_z) & (cols.clear >= cfg.bed_clear), cfg.flat_tol,
                                min_cells)
            if cfg.bed_min[0] <= p.long <= cfg.max_length and p.short >= cfg.bed_min[1] and p.fill >= cfg.min_fill]
    for p in beds:
        if free_patch(p):
            obj = _bed_object(p, _sides(p, rc, wm, main, cfg), mesh, "bed")
            if obj is not None:
                found.append(("bed", obj))
                taken.append(p)
    seat_sel = top & (cols.clear >= cfg.seat_clear) & (_between(cols.z, cfg.seat_z) | _between(cols.z, cfg.high_seat_z))
    for p in _patches(cols, seat_sel, cfg.flat_tol, min_cells):
        high = p.height > cfg.seat_z[1]
        if high and p.long > cfg.high_seat_max:
            continue
        if p.short < cfg.seat_min_side or p.fill < cfg.min_fill or p.long > cfg.max_length:
            continue
        if p.long > cfg.sofa_min_length and p.short >= cfg.bed_min[1]:
            continue  # bed-sized: the bed pass's
        if not free_patch(p):
            continue
        obj = _seat_object(p, _sides(p, rc, wm, main, cfg), mesh, cfg, None, "seat", rc)
        if obj is not None:
            found.append(("seat", obj))
            taken.append(p)
    table_sel = top & _between(cols.z, cfg.table_z) & (cols.clear >= cfg.table_clear)
    for p in _patches(cols, table_sel, cfg.flat_tol, min_cells):
        if p.short < cfg.table_min_side or p.fill < cfg.min_fill or p.long > cfg.max_length:
            continue
        if p.height <= cfg.high_seat_z[1] and p.long <= cfg.high_seat_max:
            continue  # a bar stool
        if not free_patch(p):
            continue
        obj = _table_object(p, _sides(p, rc, wm, main, cfg), mesh, "table")
        if obj is not None:
            found.append(("table", obj))
            taken.append(p)
    return _named(found)


def _between(z: np.ndarray, r: tuple[float, float]) -> np.ndarray:
    return (z >= r[0]) & (z <= r[1])


def _clearance_in(full: _Columns, part: _Columns) -> np.ndarray:
    """(H_part,) free height above each crossing of ``part`` up to the next crossing of ``full`` (the
    whole mesh) in the same column, m."""
    key_full = full.ray * 1e4 - full.z  # ascending by (ray, -z)
    order = np.argsort(key_full, kind="stable")
    kf = key_full[order]
    # the nearest full crossing above: same ray, z > part z + merge
    q = part.ray * 1e4 - (part.z + _MERGE_M)
    i = np.searchsorted(kf, q, side="left") - 1
    ok = i >= 0
    j = order[np.clip(i, 0, None)]
    ok &= full.ray[j] == part.ray
    out = np.full(len(part.z), np.inf)
    out[ok] = full.z[j[ok]] - part.z[ok]
    return out


def _prefix_category(name: str) -> str | None:
    """The category of a part name that starts with a NAMED_PREFIXES word not followed by a letter
    ('Chair.001', 'bed_2', 'table' yes; 'bedside', 'stools_rack' no)."""
    m = _NAME_RE.match(name)
    return NAMED_PREFIXES[m.group(1).lower()] if m else None


def _note(notes: list[str] | None, text: str) -> None:
    if notes is not None:
        notes.append(text)


def _safe_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name).strip(".") or "object"


def _part_local(part: trimesh.Trimesh, T: np.ndarray) -> trimesh.Trimesh:
    m = trimesh.Trimesh(np.asarray(part.vertices, np.float64), np.asarray(part.faces), process=False)
    m.apply_transform(np.linalg.inv(T))
    return m


def _named(found: list[tuple[str, SceneObject]]) -> list[SceneObject]:
    """Geometric finds renamed seat_K / bed_K / table_K by kind, then centre (x, y); named parts keep
    their names (a clash gets a suffix)."""
    out: list[SceneObject] = []
    used = {o.name for _, o in found if o.meta.get("found_by") == "name"}
    for kind in ("seat", "bed", "table"):
        group = [o for k, o in found if k == kind]
        geo = sorted((o for o in group if o.meta.get("found_by") != "name"),
                     key=lambda o: (round(float(o.pose[0, 3]), 2), round(float(o.pose[1, 3]), 2)))
        k = 0
        for o in geo:
            while f"{kind}_{k}" in used:
                k += 1
            o.name = f"{kind}_{k}"
            used.add(o.name)
            k += 1
        out += [o for o in group if o.meta.get("found_by") == "name"] + geo
    return out


def named_parts(path: str | Path, up: str = "z") -> dict[str, trimesh.Trimesh]:
    """World-frame meshes (z-up after ``up`` 'y', as ``trumans.scenes.io.import_mesh``) of the parts of a
    mesh file whose name starts with a NAMED_PREFIXES key (case-insensitive): OBJ ``o`` / ``g`` groups,
    glTF / GLB nodes (or a parent node so named: its whole subtree). {} for other formats or no names."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        parts = _obj_parts(path)
    elif suffix in (".glb", ".gltf"):
        parts = _gltf_parts(path)
    else:
        return {}
    if up == "y":
        T = np.eye(4)
        T[:3, :3] = Y_UP_TO_Z_UP
        for m in parts.values():
            m.apply_transform(T)
    return parts


_PREFIX_RE = re.compile(r"^\s*[og]\s+(" + "|".join(NAMED_PREFIXES) + r")(?![a-z])", re.IGNORECASE | re.MULTILINE)
_NAME_RE = re.compile(r"\s*(" + "|".join(NAMED_PREFIXES) + r")(?![a-z])", re.IGNORECASE)


def _obj_parts(path: Path) -> dict[str, trimesh.Trimesh]:
    """Named groups of an OBJ file (v and f records; polygons fanned into triangles)."""
    text = path.read_text(errors="replace")
    if not _PREFIX_RE.search(text):
        return {}
    verts: list[list[float]] = []
    faces: dict[str, list[list[int]]] = {}
    current = None
    for line in text.splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith(("o ", "g ")):
            name = line[2:].strip()
            current = name if _prefix_category(name) else None
        elif line.startswith("f ") and current is not None:
            idx = []
            for tok in line.split()[1:]:
                i = int(tok.split("/")[0])
                idx.append(i - 1 if i > 0 else len(verts) + i)
            faces.setdefault(current, []).extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    v = np.asarray(verts, np.float64).reshape(-1, 3)
    out = {}
    for name, f in faces.items():
        fa = np.asarray(f, np.int64)
        used, inv = np.unique(fa, return_inverse=True)
        out[name] = trimesh.Trimesh(v[used], inv.reshape(-1, 3), process=False)
    return out


def _gltf_parts(path: Path) -> dict[str, trimesh.Trimesh]:
    """Named nodes of a glTF / GLB file: a node so named, or below one, gives its world-frame geometry."""
    try:
        sc = trimesh.load_scene(path, process=False)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ValueError(f"cannot read mesh file {path}: {e}") from e
    parents = sc.graph.transforms.parents
    groups: dict[str, list[trimesh.Trimesh]] = {}
    for node in sc.graph.nodes_geometry:
        T, gname = sc.graph[node]
        chain, n = [node], node
        while n in parents:
            n = parents[n]
            chain.append(n)
        owner = next((c for c in chain if isinstance(c, str) and _prefix_category(c)), None)
        if owner is None and _prefix_category(str(gname)):
            owner = str(gname)
        geom = sc.geometry.get(gname)
        if owner is None or not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        m = trimesh.Trimesh(np.asarray(geom.vertices, np.float64), np.asarray(geom.faces), process=False)
        m.apply_transform(T)
        groups.setdefault(owner, []).append(m)
    return {k: trimesh.util.concatenate(v) for k, v in groups.items()}


def mesh_affordances(path: str | Path, mesh: trimesh.Trimesh, up: str = "z", config: AffordanceConfig | None = None,
                     notes: list[str] | None = None) -> list[SceneObject]:
    """``find_affordances`` of a mesh file's mesh (``import_mesh(path, up)``) with its named parts."""
    return find_affordances(mesh, named_parts(path, up), config, notes)


def describe(obj: SceneObject) -> dict:
    """What ``trumans scene inspect`` prints of a seat / bed / table: name, category, centre (3,)
    world m (seat, else lying place, else surface centre; a bed: lying place), height m, facing (rad from world +x: where
    a seated person faces; the lying direction feet -> head for a bed; the side used for a table),
    approach (2,) world m, how it was found. A bed's centre is its lying place (the middle of the mattress)."""
    meta = obj.meta
    order = ("lie_center", "seat_center", "surface_center") if obj.category == "bed" else \
        ("seat_center", "lie_center", "surface_center")
    key = next((k for k in order if k in meta), None)
    R, t = obj.pose[:3, :3], obj.pose[:3, 3]
    yaw0 = float(np.arctan2(obj.pose[1, 0], obj.pose[0, 0]))
    centre = None if key is None else (R @ np.asarray(meta[key], np.float64) + t)
    if "sit_yaw" in meta and obj.category != "bed":
        facing = yaw0 + float(meta["sit_yaw"])
    elif "lie_yaw" in meta:
        facing = yaw0 + float(meta["lie_yaw"])
    else:
        facing = yaw0
    facing = float((facing + np.pi) % (2 * np.pi) - np.pi)
    height = meta.get("seat_height", meta.get("surface_height", None if centre is None else float(centre[2])))
    app = meta.get("approach")
    approach = None if app is None else (R[:2, :2] @ np.asarray(app, np.float64)[:2] + t[:2])
    return {"name": obj.name, "category": obj.category,
            "center": None if centre is None else np.round(centre, 3).tolist(),
            "height": None if height is None else round(float(height), 3),
            "facing_deg": round(float(np.degrees(facing)), 1),
            "approach": None if approach is None else np.round(approach, 3).tolist(),
            "lie": "lie_center" in meta, "found_by": meta.get("found_by", "scene.json")}
