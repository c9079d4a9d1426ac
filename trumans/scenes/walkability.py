"""Walkable floor maps from occupancy grids and grid path planning.

Convention (owned here): ``walkable[i, j] == True`` means a body of radius ``body_radius`` can
stand with its centre at cell (i, j); cell (i, j) has centre ``origin + cell * (i, j)`` (world x,
y, metres). Points outside the map are not walkable.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from trumans.scenes.occupancy import OccupancyGrid

__all__ = ["WalkMap", "NoPathError", "walkable_map", "plan_path", "nearest_walkable"]


class NoPathError(ValueError):
    """No walkable path between the requested start and goal."""


@dataclass(eq=False)
class WalkMap:
    """walkable: (Nx, Ny) bool; origin: (2,) world xy of cell (0, 0)'s centre, m; cell: size, m."""

    walkable: np.ndarray
    origin: np.ndarray
    cell: float

    def __post_init__(self) -> None:
        self.walkable = np.asarray(self.walkable, dtype=bool)
        if self.walkable.ndim != 2:
            raise ValueError(f"walkable must be (Nx, Ny), got shape {self.walkable.shape}")
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(2)
        self.cell = float(self.cell)
        if not self.cell > 0:
            raise ValueError(f"cell must be > 0 m, got {self.cell}")

    def index(self, points: np.ndarray) -> np.ndarray:
        """points: (..., 2) world xy m -> (..., 2) int64 nearest cell (may lie outside the map)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim < 1 or p.shape[-1] != 2:
            raise ValueError(f"points must be (..., 2) world xy, got shape {p.shape}")
        return np.floor((p - self.origin) / self.cell + 0.5).astype(np.int64)

    def centers(self, idx: np.ndarray) -> np.ndarray:
        """idx: (..., 2) int cell indices -> (..., 2) world xy of the cell centres, m."""
        return self.origin + self.cell * np.asarray(idx, dtype=np.float64)

    def query(self, points: np.ndarray) -> np.ndarray:
        """points: (..., 2) world xy m -> (...,) bool, True walkable; outside the map is False."""
        idx = self.index(points)
        n = np.asarray(self.walkable.shape)
        inside = np.all((idx >= 0) & (idx < n), axis=-1)
        c = np.clip(idx, 0, n - 1)
        return inside & self.walkable[c[..., 0], c[..., 1]]


def walkable_map(occ: OccupancyGrid, z_min: float = 0.1, z_max: float = 1.8, body_radius: float = 0.25) -> WalkMap:
    """Floor cells where a standing body fits: (Nx, Ny) map on the occupancy grid's xy cells.

    A column is blocked if any voxel whose centre lies between ``z_min`` (ankle) and ``z_max``
    (head) m is occupied (heights above the grid count as occupied: outside = occupied). Blocked
    cells, and the area outside the grid, are inflated by ``body_radius`` m with a Euclidean
    distance transform: a cell is walkable iff no blocked cell centre lies within the radius.
    """
    if not z_max > z_min:
        raise ValueError(f"need z_max > z_min, got z_min={z_min}, z_max={z_max}")
    if body_radius < 0:
        raise ValueError(f"body_radius must be >= 0 m, got {body_radius}")
    nz = occ.grid.shape[2]
    zc = occ.origin[2] + occ.voxel * np.arange(nz)
    band = (zc >= z_min) & (zc <= z_max)
    blocked = occ.grid[:, :, band].any(axis=2)
    top = occ.origin[2] + occ.voxel * (nz - 0.5)
    if top < z_max or not band.any():
        blocked[:] = True  # the body sticks out of the grid, which counts as occupied
    padded = np.pad(blocked, 1, constant_values=True)  # outside the grid is blocked
    dist = ndimage.distance_transform_edt(~padded) * occ.voxel  # m to the nearest blocked centre
    walkable = (dist > body_radius + 1e-9)[1:-1, 1:-1]
    return WalkMap(walkable, occ.origin[:2].copy(), occ.voxel)


def nearest_walkable(wm: WalkMap, point: np.ndarray) -> np.ndarray:
    """point: (2,) or (N, 2) world xy m -> same shape, centre of the nearest walkable cell, m."""
    p = np.asarray(point, dtype=np.float64)
    if p.shape[-1:] != (2,) or p.ndim > 2:
        raise ValueError(f"point must be (2,) or (N, 2) world xy, got shape {p.shape}")
    cells = np.argwhere(wm.walkable)
    if len(cells) == 0:
        raise NoPathError("the walk map has no walkable cell; check the occupancy grid and body_radius")
    from scipy.spatial import cKDTree

    _, k = cKDTree(wm.centers(cells)).query(p.reshape(-1, 2))
    return wm.centers(cells[k]).reshape(p.shape)


def _graph(wm: WalkMap):
    """Sparse 8-connected graph over walkable cells (diagonals need both side cells walkable)."""
    w = wm.walkable
    nx, ny = w.shape
    ids = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, costs = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        a = (slice(0, nx - di), slice(max(0, -dj), ny - max(0, dj)))
        b = (slice(di, nx), slice(max(0, dj), ny + min(0, dj)))
        ok = w[a] & w[b]
        if di and dj:  # no corner cutting
            ok &= w[(slice(di, nx), a[1])] & w[(a[0], b[1])]
        rows.append(ids[a][ok])
        cols.append(ids[b][ok])
        costs.append(np.full(int(ok.sum()), np.hypot(di, dj) * wm.cell))
    r, c, d = np.concatenate(rows), np.concatenate(cols), np.concatenate(costs)
    return coo_matrix((d, (r, c)), shape=(nx * ny, nx * ny)).tocsr()


def _line_of_sight(wm: WalkMap, a: np.ndarray, bs: np.ndarray) -> np.ndarray:
    """a: (2,) world xy, bs: (M, 2) -> (M,) bool, segment a->b stays on walkable cells."""
    length = np.linalg.norm(bs - a, axis=1)
    m = int(np.ceil(length.max() / (0.25 * wm.cell))) + 2 if len(bs) else 2
    t = np.linspace(0.0, 1.0, m)
    pts = a + (bs - a)[:, None, :] * t[None, :, None]  # (M, m, 2)
    return wm.query(pts).all(axis=1)


def _resample(poly: np.ndarray, spacing: float) -> np.ndarray:
    """Split each segment of ``poly`` (V, 2) into equal steps of about ``spacing``; corners kept."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    k = np.maximum(1, np.round(seg / spacing).astype(np.int64))  # steps per segment
    seg_of = np.repeat(np.arange(len(seg)), k)
    t = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)  # in [0, 1)
    out = poly[seg_of] + (poly[seg_of + 1] - poly[seg_of]) * t[:, None]
    return np.concatenate([out, poly[-1:]], axis=0)


def plan_path(wm: WalkMap, start: np.ndarray, goal: np.ndarray, spacing: float = 0.6) -> np.ndarray:
    """Shortest walkable path from ``start`` to ``goal`` (world xy, m): (K, 2) float64 waypoints.

    Shortest path on the 8-connected grid of walkable cells (edge cost = step length; no corner
    cutting), computed with scipy's compiled Dijkstra (same optimum as A* with an admissible
    heuristic), then greedy line-of-sight smoothing (each vertex links to the farthest later
    vertex it can see), then each straight segment is cut into round(length / spacing) equal
    steps, i.e. about ``spacing`` m (at most 1.5x; shorter only for segments shorter than
    ``spacing``). Corners are kept, so the waypoint polyline itself stays walkable.
    First waypoint = start, last = goal. Raises NoPathError when start or
    goal is not walkable (says which) or they are disconnected.
    """
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0 m, got {spacing}")
    pts = {}
    for name, p in (("start", start), ("goal", goal)):
        p = np.asarray(p, dtype=np.float64)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ValueError(f"{name} must be a finite (2,) world xy point in m, got {p}")
        if not wm.query(p):
            raise NoPathError(f"{name} {p.tolist()} is not walkable (blocked, too close to an obstacle "
                              "or outside the map); move it, e.g. with nearest_walkable()")
        pts[name] = p
    s_idx, g_idx = wm.index(pts["start"]), wm.index(pts["goal"])
    ny = wm.walkable.shape[1]
    s_id, g_id = int(s_idx[0] * ny + s_idx[1]), int(g_idx[0] * ny + g_idx[1])
    if s_id == g_id:
        return _resample(np.stack([pts["start"], pts["goal"]]), spacing)
    dist, pred = dijkstra(_graph(wm), directed=False, indices=s_id, return_predecessors=True)
    if not np.isfinite(dist[g_id]):
        raise NoPathError(f"goal {pts['goal'].tolist()} is not reachable from start {pts['start'].tolist()}: "
                          "they lie in disconnected walkable regions")
    chain = [g_id]
    while chain[-1] != s_id:
        chain.append(int(pred[chain[-1]]))
    ids = np.asarray(chain[::-1])
    path = wm.centers(np.stack([ids // ny, ids % ny], axis=1))
    path[0], path[-1] = pts["start"], pts["goal"]
    # greedy line-of-sight smoothing
    keep = [0]
    i = 0
    while i < len(path) - 1:
        vis = _line_of_sight(wm, path[i], path[i + 1:])
        j = i + 1 + int(np.flatnonzero(vis).max()) if vis.any() else i + 1
        keep.append(j)
        i = j
    return _resample(path[keep], spacing)
