"""Where a 2D grid lies in the world: the cells of the costmaps and the likelihood field."""
from typing import NamedTuple

import numpy as np


class GridInfo(NamedTuple):
    """Placement of a 2D grid in the world: cell (row, col) covers
    [origin_x + col*res, +res) x [origin_y + row*res, +res); row 0 is the lowest y
    (as nav_msgs/OccupancyGrid and map_server)."""

    resolution: float
    width: int
    height: int
    origin_x: float
    origin_y: float

    def world_to_cell(self, x, y):
        """(row, col) arrays of the cells containing the points (may be outside the grid)."""
        col = np.floor((np.asarray(x) - self.origin_x) / self.resolution).astype(int)
        row = np.floor((np.asarray(y) - self.origin_y) / self.resolution).astype(int)
        return row, col

    def cell_to_world(self, row, col):
        """(x, y) of the centres of cells."""
        x = self.origin_x + (np.asarray(col) + 0.5) * self.resolution
        y = self.origin_y + (np.asarray(row) + 0.5) * self.resolution
        return x, y

    def contains(self, row, col):
        return (row >= 0) & (row < self.height) & (col >= 0) & (col < self.width)
