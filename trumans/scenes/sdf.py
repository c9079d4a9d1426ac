"""The scene's signed distance field as a differentiable torch volume (a scene query like
``distance``): the generator's penetration guidance and its push-outs and foot cleanup after the
network read it (``trumans.sample.guidance``, ``trumans.sample.cleanup``).

The field: Euclidean distance transforms of the occupied and free voxels (scipy.ndimage),
positive outside, negative inside, m; floor voxels (centre below ``floor_z``) count as free, the
floor being left to whoever handles feet (the generator's foot cleanup).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage

from trumans.scenes.occupancy import OccupancyGrid

__all__ = ["SceneSDF"]


class SceneSDF:
    """Signed distance (m) of an occupancy grid as a torch volume; ``__call__`` samples it."""

    def __init__(self, occ: OccupancyGrid, floor_z: float = 0.01) -> None:
        grid = np.asarray(occ.grid, dtype=bool).copy()
        z = occ.origin[2] + occ.voxel * np.arange(grid.shape[2])
        grid[:, :, z < floor_z] = False
        if grid.any():  # the two transforms release the GIL: side by side on torch's thread budget
            with ThreadPoolExecutor(max_workers=max(1, min(2, torch.get_num_threads()))) as pool:
                outside, inside = pool.map(ndimage.distance_transform_edt, (~grid, grid))
        else:
            outside, inside = np.full(grid.shape, 1e3), np.zeros(grid.shape)
        sdf = (outside - inside) * occ.voxel  # voxel centres: + outside, - inside (half a voxel coarse)
        # grid_sample volume (1, 1, D=z, H=y, W=x)
        self.volume = torch.from_numpy(np.ascontiguousarray(np.transpose(sdf, (2, 1, 0)), dtype=np.float32))[None, None]
        self.lo = torch.as_tensor(occ.origin, dtype=torch.float32)
        self.hi = self.lo + occ.voxel * (torch.as_tensor(grid.shape, dtype=torch.float32) - 1)
        self.voxel = float(occ.voxel)
        self._with_gradient: torch.Tensor | None = None  # (1, 4, z, y, x): the field and its gradient, lazily

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        """points (..., 3) world m -> (...,) signed distance, m (outside the grid: the border value)."""
        u = 2.0 * (points - self.lo) / (self.hi - self.lo) - 1.0  # [-1, 1] per axis, x y z order
        flat = u.reshape(1, 1, 1, -1, 3)
        out = F.grid_sample(self.volume.to(points.device), flat, mode="bilinear", padding_mode="border",
                            align_corners=True)
        return out.reshape(points.shape[:-1])

    def value_and_gradient(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """points (..., 3) world m -> the signed distance (...,) m and its spatial gradient (..., 3)
        (central differences of the field at the voxel centres, interpolated trilinearly: smooth
        across cells, unlike the derivative of the trilinear field itself)."""
        if self._with_gradient is None:
            vol = self.volume[0, 0]  # (z, y, x)
            gz, gy, gx = torch.gradient(vol, spacing=self.voxel)
            self._with_gradient = torch.stack([vol, gx, gy, gz])[None]
        u = 2.0 * (points - self.lo) / (self.hi - self.lo) - 1.0
        out = F.grid_sample(self._with_gradient.to(points.device), u.reshape(1, 1, 1, -1, 3), mode="bilinear",
                            padding_mode="border", align_corners=True)[0, :, 0, 0]  # (4, N)
        return out[0].reshape(points.shape[:-1]), out[1:].T.reshape(points.shape)
