"""A saved map against the simulator world's true geometry, and the poses between frames.

SLAM's map frame is the odometry frame at its first scan, not the world's frame; the
demo learns the map frame's pose in the world from one simultaneous pair of poses
(ground truth and SLAM's estimate) and compares cells through it.
"""
import math
from typing import NamedTuple

import numpy as np

UNKNOWN, FREE_MAX, OCCUPIED_MIN = -1, 25, 65


def compose(a, b):
    """Pose b (x, y, yaw) given in frame a, expressed in a's parent frame."""
    cos_a, sin_a = math.cos(a[2]), math.sin(a[2])
    return (a[0] + cos_a * b[0] - sin_a * b[1], a[1] + sin_a * b[0] + cos_a * b[1], wrap(a[2] + b[2]))


def inverse(a):
    cos_a, sin_a = math.cos(a[2]), math.sin(a[2])
    return (-cos_a * a[0] - sin_a * a[1], sin_a * a[0] - cos_a * a[1], -a[2])


def frame_in_world(pose_in_world, pose_in_frame):
    """Where a frame lies in the world, from one pose known in both."""
    return compose(pose_in_world, inverse(pose_in_frame))


def transform_points(frame, points):
    """Points (N x 2) given in `frame` (a pose in the parent frame), in the parent frame."""
    points = np.asarray(points, float).reshape(-1, 2)
    cos_f, sin_f = math.cos(frame[2]), math.sin(frame[2])
    return np.column_stack([frame[0] + cos_f * points[:, 0] - sin_f * points[:, 1],
                            frame[1] + sin_f * points[:, 0] + cos_f * points[:, 1]])


class MapScore(NamedTuple):
    known_cells: int
    agreement: float       # known cells whose state matches the world, within one cell
    coverage: float        # the world's reachable free area the map knows as free
    occupied_cells: int


def score_map(data, resolution, origin, world, map_in_world, start_xy):
    """Compare an occupancy grid (rows = y, values -1 / 0..100) with the world.

    A known cell agrees when an occupied cell lies within 1.5 cells of an obstacle's
    boundary or inside it, and a free cell lies outside every obstacle by more than half
    a cell. Coverage counts the world's free cells reachable from `start_xy` (world frame)
    whose map cell is known free.
    """
    data = np.asarray(data)
    height, width = data.shape
    rows, cols = np.nonzero(data != UNKNOWN)
    centres = np.column_stack([origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution])
    in_world = transform_points(map_in_world, centres)
    values = data[rows, cols]
    occupied = values >= OCCUPIED_MIN
    free = values <= FREE_MAX
    inside = world.contains(in_world)
    boundary = world.distance_to_boundary(in_world)
    agrees = np.where(occupied, inside | (boundary <= 1.5 * resolution),
                      np.where(free, ~inside & (boundary > 0.5 * resolution), True))

    reachable = reachable_free_points(world, start_xy, resolution)
    in_map = transform_points(inverse(map_in_world), reachable)
    map_cols = np.floor((in_map[:, 0] - origin[0]) / resolution).astype(int)
    map_rows = np.floor((in_map[:, 1] - origin[1]) / resolution).astype(int)
    on_grid = (map_rows >= 0) & (map_rows < height) & (map_cols >= 0) & (map_cols < width)
    known_free = np.zeros(len(reachable), bool)
    known_free[on_grid] = (data[map_rows[on_grid], map_cols[on_grid]] >= 0) & \
        (data[map_rows[on_grid], map_cols[on_grid]] <= FREE_MAX)
    return MapScore(known_cells=int(len(values)), agreement=float(agrees.mean()) if len(values) else 0.0,
                    coverage=float(known_free.mean()) if len(reachable) else 0.0,
                    occupied_cells=int(occupied.sum()))


def reachable_free_points(world, start_xy, resolution):
    """Centres of the world's free cells (clear of obstacles by half a cell) connected to start_xy."""
    xmin, ymin, xmax, ymax = world.bounds
    width, height = int(math.ceil((xmax - xmin) / resolution)), int(math.ceil((ymax - ymin) / resolution))
    free = ~world.rasterize(resolution, (xmin, ymin), width, height)
    seed_row, seed_col = int((start_xy[1] - ymin) / resolution), int((start_xy[0] - xmin) / resolution)
    reached = np.zeros_like(free)
    reached[seed_row, seed_col] = free[seed_row, seed_col]
    while True:
        grown = reached.copy()
        grown[1:, :] |= reached[:-1, :]
        grown[:-1, :] |= reached[1:, :]
        grown[:, 1:] |= reached[:, :-1]
        grown[:, :-1] |= reached[:, 1:]
        grown &= free
        if (grown == reached).all():
            break
        reached = grown
    rows, cols = np.nonzero(reached)
    return np.column_stack([xmin + (cols + 0.5) * resolution, ymin + (rows + 0.5) * resolution])


def path_length(points):
    points = np.asarray(points, float).reshape(-1, 2)
    return float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 0.0


def wrap(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi
