"""The scene's signed distance field as a differentiable torch volume (a scene query like
``distance``): the generator's penetration guidance and its push-outs and foot cleanup after the
network read it (``trumans.sample.guidance``, ``trumans.sample.cleanup``).

The field: Euclidean distance transforms of the occupied and free voxels (scipy.ndimage),
positive outside, negative inside, m; floor voxels (centre below ``floor_z``) count as free, the
floor being left to whoever handles feet (the generator's foot cleanup).

A closed room's field says nothing about where the room is: a body that has passed a 12 cm wall
stands in free space again (positive distance; the field beyond the grid is its border value), and
a push-out along the gradient pushes it further out. ``SceneSDF.enclosed`` is the same field with
the room's outside made solid (``outside_columns``: the floor columns joined to the grid's border
through free space), so the depth of a body outside is its distance back into the room and the
gradient points there; in an open scene (the border reaches every free column) it is the field
itself. ``clearance_map`` is the field's minimum over a height band per floor column: how far a
standing body's axis there is from anything between ankle and head.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage

from trumans.scenes.occupancy import OccupancyGrid

__all__ = ["SceneSDF", "outside_columns"]

BAND = (0.1, 1.8)  # m: the heights a standing body occupies (ankle to head; the walk map's band)
ENCLOSE_PAD = 0.2  # m of free columns ``enclosed`` adds around the grid (it covers a body that far outside)


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
        self._device_copies: dict[tuple[str, str], torch.Tensor] = {}  # (name, device) -> a copy there
        self.floor_z = float(floor_z)
        self._enclosed: SceneSDF | None = None
        self._clearance: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
        self.outside: np.ndarray | None = None  # (Nx, Ny) bool: the columns ``enclosed`` made solid (its fields only)

    @property
    def occupied(self) -> np.ndarray:
        """(Nx, Ny, Nz) bool: the voxels inside (field < 0), floor excluded; x, y, z order."""
        return np.transpose(self.volume[0, 0].numpy() < 0.0, (2, 1, 0))

    def grid(self) -> OccupancyGrid:
        """The occupancy this field was built from (floor voxels free)."""
        return OccupancyGrid(self.occupied, self.lo.numpy().astype(np.float64), self.voxel)

    def enclosed(self) -> SceneSDF:
        """This field with the room's outside solid (module doc; built once, cached): the columns of
        ``outside_columns`` are occupied from ``floor_z`` up. Itself when the scene is open."""
        if self._enclosed is None:
            occ = self.grid()
            n = int(np.ceil(ENCLOSE_PAD / self.voxel))  # free columns around the grid: the outside reaches them
            grid = np.pad(occ.grid, ((n, n), (n, n), (0, 0)))
            origin = occ.origin - np.array([n, n, 0]) * self.voxel
            out = outside_columns(OccupancyGrid(grid, origin, self.voxel))
            if not out.any():
                self._enclosed = self
            else:
                z = origin[2] + self.voxel * np.arange(grid.shape[2])
                grid[out[:, :, None] & (z >= self.floor_z)[None, None]] = True
                self._enclosed = SceneSDF(OccupancyGrid(grid, origin, self.voxel), self.floor_z)
                self._enclosed._enclosed, self._enclosed.outside = self._enclosed, out
        return self._enclosed

    def clearance_map(self, band: tuple[float, float] = BAND) -> tuple[np.ndarray, np.ndarray]:
        """(map (Nx, Ny) m, origin (2,) world xy of cell (0, 0)): per floor column, the field's
        minimum over voxel centres with z in ``band`` m (how close the column comes to anything a
        standing body at that height could touch); the cells are the field's voxels. Cached."""
        key = (float(band[0]), float(band[1]))
        if key not in self._clearance:
            z = self.lo[2].item() + self.voxel * np.arange(self.volume.shape[2])
            sel = (z >= band[0]) & (z <= band[1])
            if not sel.any():
                raise ValueError(f"the field's grid has no voxel centre between {band[0]} and {band[1]} m")
            m = self.volume[0, 0].numpy()[sel].min(0).T  # (x, y)
            self._clearance[key] = (m.astype(np.float64), self.lo[:2].numpy().astype(np.float64))
        return self._clearance[key]

    def _on(self, name: str, tensor: torch.Tensor, device: torch.device) -> torch.Tensor:
        """``tensor`` on ``device``: itself on its own device, else a copy made once and kept."""
        if tensor.device == device:
            return tensor
        key = (name, str(device))
        if key not in self._device_copies:
            self._device_copies[key] = tensor.to(device)
        return self._device_copies[key]

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        """points (..., 3) world m -> (...,) signed distance, m (outside the grid: the border value)."""
        lo, hi = self._on("lo", self.lo, points.device), self._on("hi", self.hi, points.device)
        u = 2.0 * (points - lo) / (hi - lo) - 1.0  # [-1, 1] per axis, x y z order
        flat = u.reshape(1, 1, 1, -1, 3)
        out = F.grid_sample(self._on("volume", self.volume, points.device), flat, mode="bilinear", padding_mode="border",
                            align_corners=True)
        return out.reshape(points.shape[:-1])

    def gradient_volume(self) -> torch.Tensor:
        """(1, 4, Nz, Ny, Nx) float32: the field and its x, y, z gradient (central differences, m/m) at
        the voxel centres, what ``value_and_gradient`` samples; built on first use, cached."""
        if self._with_gradient is None:
            vol = self.volume[0, 0]  # (z, y, x)
            gz, gy, gx = torch.gradient(vol, spacing=self.voxel)
            self._with_gradient = torch.stack([vol, gx, gy, gz])[None]
        return self._with_gradient

    def value_and_gradient(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """points (..., 3) world m -> the signed distance (...,) m and its spatial gradient (..., 3)
        (central differences of the field at the voxel centres, interpolated trilinearly: smooth
        across cells, unlike the derivative of the trilinear field itself)."""
        lo, hi = self._on("lo", self.lo, points.device), self._on("hi", self.hi, points.device)
        u = 2.0 * (points - lo) / (hi - lo) - 1.0
        out = F.grid_sample(self._on("gradient", self.gradient_volume(), points.device), u.reshape(1, 1, 1, -1, 3), mode="bilinear",
                            padding_mode="border", align_corners=True)[0, :, 0, 0]  # (4, N)
        return out[0].reshape(points.shape[:-1]), out[1:].T.reshape(points.shape)


def outside_columns(occ: OccupancyGrid, band: tuple[float, float] = BAND, gap: float = 0.05) -> np.ndarray:
    """(Nx, Ny) bool: the floor columns outside a closed room. A column is blocked when a voxel
    centre in ``band`` (m) is occupied; blocked columns are widened by ``gap`` m (a crack between a
    door and its frame does not open the room); the free columns not connected (4-neighbours) to the
    grid's border there, widened back by ``gap``, are the room; every other free column is outside.
    A scene without such an enclosed column is open: all False."""
    from scipy import ndimage

    g = np.asarray(occ.grid, dtype=bool)
    z = occ.origin[2] + occ.voxel * np.arange(g.shape[2])
    sel = (z >= band[0]) & (z <= band[1])
    if not sel.any():
        return np.zeros(g.shape[:2], bool)
    raw = g[:, :, sel].any(2)
    r = int(np.ceil(gap / occ.voxel))
    disk = np.ones((2 * r + 1, 2 * r + 1), bool)
    blocked = ndimage.binary_dilation(raw, disk) if r > 0 else raw
    label, _ = ndimage.label(~blocked)
    border = np.unique(np.concatenate([label[0], label[-1], label[:, 0], label[:, -1]]))
    inside = (label > 0) & ~np.isin(label, border[border > 0])
    if not inside.any():  # no enclosed free column: an open scene
        return np.zeros(g.shape[:2], bool)
    # every free column but the enclosed ones and their rim (the room's own free cells within the gap)
    return ~raw & ~(ndimage.binary_dilation(inside, disk) if r > 0 else inside)
