"""Fixtures shared across the test tree (plain helpers are in tests/helpers.py).

This is the rootdir conftest: pytest puts its folder (tests/) on sys.path, which is what lets test
modules in the subfolders import ``helpers``."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.scene import Scene
from trumans.scenes.walkability import walkable_map


@pytest.fixture(scope="module")
def open_room():
    """(scene, occupancy, walkable map) of an empty 2.4 m room: only a floor at z < 0, 2 cm voxels."""
    grid = np.zeros((120, 120, 120), dtype=bool)
    grid[:, :, :5] = True  # floor: z < 0
    occ = OccupancyGrid(grid, np.array([0.01, 0.01, -0.09]), 0.02)
    return Scene("open"), occ, walkable_map(occ)
