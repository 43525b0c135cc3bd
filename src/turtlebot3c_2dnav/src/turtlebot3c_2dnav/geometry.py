"""Planar poses (x, y, yaw): angle wrapping, composition, quaternions, grids.

Poses are plain (x, y, yaw) tuples or numpy arrays whose last axis is (x, y, yaw),
so the particle filter can apply the same functions to thousands of poses at once.
"""
import math
from typing import NamedTuple, Tuple

import numpy as np


def wrap_angle(angle):
    """Angle(s) in [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def wrap(angle: float) -> float:
    """A single angle in [-pi, pi), as a float."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def compose(a, b) -> Tuple[float, float, float]:
    """Pose b expressed in a's frame, returned in a's parent frame (a ⊕ b)."""
    ax, ay, ayaw = a
    bx, by, byaw = b
    c, s = math.cos(ayaw), math.sin(ayaw)
    return (ax + c * bx - s * by, ay + s * bx + c * by, wrap(ayaw + byaw))


def inverse(a) -> Tuple[float, float, float]:
    """The pose whose composition with a is the identity."""
    ax, ay, ayaw = a
    c, s = math.cos(ayaw), math.sin(ayaw)
    return (-c * ax - s * ay, s * ax - c * ay, wrap(-ayaw))


def relative(a, b) -> Tuple[float, float, float]:
    """Pose b seen from pose a (a⁻¹ ⊕ b)."""
    return compose(inverse(a), b)


def yaw_to_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by yaw about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw of a quaternion (rotation about z; roll and pitch ignored)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


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
