"""Batched local occupancy grids around floor points, rotated to a heading (the scene perceiver input).

A local grid is floor-anchored and body-aligned (TRUMANS §4.3 "Local Scene Perceiver": the
global occupancy queried on a grid around the episode subgoal, vertically from the floor,
oriented by the pelvis yaw at the episode start): axis 0 points along the heading (forward, local x),
axis 1 to the left (local y), axis 2 up (world z). Cell (i, j, k) samples the world point

    x = cx + cos(yaw) * u_i - sin(yaw) * v_j,    u_i = -ex/2 + (i + 1/2) ex/n
    y = cy + sin(yaw) * u_i + cos(yaw) * v_j,    v_j = -ey/2 + (j + 1/2) ey/n
    z = z_floor + w_k,                           w_k = (k + 1/2) ez/n

with the nearest voxel of the scene grid; points outside the scene grid are occupied.
"""
from __future__ import annotations

import numpy as np

from trumans.scenes.occupancy import OccupancyGrid

__all__ = ["local_grids", "local_points"]


def _check(centers: np.ndarray, yaw: np.ndarray, n: int, extent) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = np.asarray(centers, dtype=np.float32)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"centers must be (B, 3) floor points (x, y, z_floor), got shape {c.shape}")
    y = np.asarray(yaw, dtype=np.float32).reshape(-1)
    if y.shape[0] != c.shape[0]:
        raise ValueError(f"yaw must be (B,) = ({c.shape[0]},), got shape {np.shape(yaw)}")
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n}")
    e = np.asarray(extent, dtype=np.float32).reshape(-1)
    if e.shape != (3,) or np.any(e <= 0):
        raise ValueError(f"extent must be 3 positive lengths in m, got {extent}")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(y))):
        raise ValueError("centers / yaw contain NaN or inf")
    return c, y, e


def _axes(n: int, e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = (np.arange(n, dtype=np.float32) + 0.5) / n  # (n,) cell centres in [0, 1]
    return (t - 0.5) * e[0], (t - 0.5) * e[1], t * e[2]


def _cell_coords(c: np.ndarray, y: np.ndarray, n: int, e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World x (B, n, n), y (B, n, n) and z (B, n) of the cells of the grids at floor points c
    (B, 3) turned by yaw y (B,): the turn is about z, so x, y depend on (b, i, j) and z on (b, k)."""
    u, v, w = _axes(n, e)
    cos, sin = np.cos(y)[:, None, None], np.sin(y)[:, None, None]
    x = c[:, 0, None, None] + cos * u[None, :, None] - sin * v[None, None, :]
    yy = c[:, 1, None, None] + sin * u[None, :, None] + cos * v[None, None, :]
    return x, yy, c[:, 2, None] + w[None]


def local_points(
    centers: np.ndarray, yaw: np.ndarray, n: int = 32, extent: tuple[float, float, float] = (1.2, 1.2, 1.2)
) -> np.ndarray:
    """World positions of the local grid cells: (B, n, n, n, 3) float32 (reference/visualisation)."""
    c, y, e = _check(centers, yaw, n, extent)
    x, yy, z = _cell_coords(c, y, n, e)
    B = len(c)
    return np.stack(np.broadcast_arrays(x[..., None], yy[..., None], z[:, None, None, :]), -1).reshape(B, n, n, n, 3)


def local_grids(
    occ: OccupancyGrid,
    centers: np.ndarray,
    yaw: np.ndarray,
    n: int = 32,
    extent: tuple[float, float, float] = (1.2, 1.2, 1.2),
) -> np.ndarray:
    """Local occupancy grids: (B, n, n, n) bool, True = occupied, axes (forward, left, up).

    centers: (B, 3) float, world m, floor points (x, y, z_floor); yaw: (B,) rad heading from +x;
    extent: (ex, ey, ez) m spanned by the grid ([-ex/2, ex/2] x [-ey/2, ey/2] x [0, ez] above
    the floor point). Vectorised, float32 math: the rotation is about z, so the x/y voxel index
    depends only on (b, i, j) and the z index only on (b, k). If every query has the same z
    indices (one floor height, the usual case), those n layers are sliced once and whole
    n-byte columns are gathered. Otherwise each local column's z indices lie in a window of
    ``span`` consecutive scene voxels: one gather copies every window (B*n*n rows of ``span``
    bytes) and a ``take`` along the last axis per distinct z pattern picks the n samples. The
    scene grid is padded with a True border, so anything outside it reads as occupied.
    """
    c, y, e = _check(centers, yaw, n, extent)
    B = len(c)
    o = occ.origin.astype(np.float32)
    inv = np.float32(1.0 / occ.voxel)
    x, yy, z = _cell_coords(c, y, n, e)
    pad = occ.padded()  # (Nx+2, Ny+2, Nz+2), border True; padded index = voxel index + 1
    nx, ny, nz = pad.shape
    # nearest voxel index + 1, clipped into the padded grid: anything outside lands on the border
    ix = np.clip(np.floor((x - o[0]) * inv + np.float32(1.5)), 0, nx - 1).astype(np.int64)
    iy = np.clip(np.floor((yy - o[1]) * inv + np.float32(1.5)), 0, ny - 1).astype(np.int64)
    iz = np.clip(np.floor((z - o[2]) * inv + np.float32(1.5)), 0, nz - 1).astype(np.int64)
    out = np.empty((B, n, n, n), dtype=bool)
    if B == 0:
        return out
    if np.all(iz == iz[:1]):  # one floor height (the usual case): slice those n layers once
        x0, x1, y0, y1 = ix.min(), ix.max() + 1, iy.min(), iy.max() + 1
        sub = np.take(pad[x0:x1, y0:y1], iz[0], axis=2)  # (sx, sy, n) contiguous
        cols = sub.reshape(-1, n).view(np.dtype((np.void, n))).reshape(-1)  # one column = n bytes
        return np.take(cols, (ix - x0) * (y1 - y0) + (iy - y0)).view(bool).reshape(B, n, n, n)
    # window of span z voxels per query, shifted down so it never runs past the top of a column
    span = int((iz[:, -1] - iz[:, 0]).max()) + 1
    base = np.minimum(iz[:, 0], nz - span)  # (B,)
    rel = iz - base[:, None]  # (B, n) in [0, span)
    flat = pad.reshape(-1)
    # zero-copy view: element s is the span bytes flat[s : s + span]
    windows = np.ndarray((flat.size - span + 1,), dtype=np.dtype((np.void, span)), buffer=flat, strides=(1,))
    start = (ix * ny + iy) * nz + base[:, None, None]  # (B, n, n)
    win = windows[start].view(bool).reshape(B, n, n, span)
    patterns, group = np.unique(rel, axis=0, return_inverse=True)
    if len(patterns) == 1:
        return np.take(win, patterns[0], axis=-1)
    group = group.reshape(-1)
    for g, pat in enumerate(patterns):
        bs = np.flatnonzero(group == g)
        out[bs] = np.take(win[bs], pat, axis=-1)
    return out
