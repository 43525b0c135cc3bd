"""Measuring mapping against the simulated world's truth: maps, trajectories, and a route driver.

The one scorer of maps against the world, for the SLAM benchmark (benchmarks/bench_slam), the
demo and the tests. Two views of a map:
- cell by cell against the world rasterised on the map's own grid (cell_agreement,
  occupied_precision), when the map frame is the world frame, as in the benchmark;
- through the map frame's pose in the world, against the world's geometry (score_map), as the
  demo needs: SLAM's map frame is the odometry frame at its first scan, learnt from one
  simultaneous pair of poses (frame_in_world).
Pure numpy; no rospy. The simulator is passed in (any object with `pose`, `set_command`,
`step`, `time`), so drive_route does not depend on the simulation module.
"""
import math
from typing import NamedTuple

import numpy as np

from turtlebot3c_common.se2 import compose, inverse, relative, transform_points, wrap_angle

UNKNOWN, FREE_MAX, OCCUPIED_MIN = -1, 25, 65


def ground_truth_window(occupancy_map):
    """(origin_xy, width, height) of the grid cells of an OccupancyMap, for World.rasterize;
    a map turned by its origin's yaw is refused (its cells are compared one to one with an
    unrotated rasterisation)."""
    yaw = occupancy_map.origin[2]
    if abs(wrap_angle(yaw)) > 1e-9:
        raise ValueError(f"map origin yaw {yaw:.3f} rad: the SLAM evaluation compares unrotated grids only "
                         "(our SLAM saves maps with yaw 0)")
    return (occupancy_map.origin[0], occupancy_map.origin[1]), occupancy_map.width, occupancy_map.height


def cell_agreement(cells, truth_occupied):
    """Fraction of known cells (not -1) whose occupied/free state equals the ground truth's."""
    known = cells >= 0
    if not known.any():
        return 0.0
    return float(((cells[known] == 100) == truth_occupied[known]).mean())


def occupied_precision(cells, truth_occupied, tolerance_cells=1):
    """Fraction of occupied map cells within `tolerance_cells` of a truly occupied cell (a doubled wall lowers it)."""
    occupied = cells == 100
    if not occupied.any():
        return 0.0
    near = _dilate(truth_occupied, tolerance_cells)
    return float(near[occupied].mean())


def _dilate(mask, radius):
    result = mask.copy()
    height, width = mask.shape
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            shifted = np.zeros_like(mask)
            shifted[max(dy, 0):height + min(dy, 0), max(dx, 0):width + min(dx, 0)] = \
                mask[max(-dy, 0):height + min(-dy, 0), max(-dx, 0):width + min(-dx, 0)]
            result |= shifted
    return result


def absolute_trajectory_error(estimated, truth):
    """RMS position error (m) and RMS heading error (rad) between matching pose lists (x, y, yaw)."""
    estimated = np.asarray(estimated, dtype=np.float64)[:, :3]
    truth = np.asarray(truth, dtype=np.float64)[:, :3]
    position = np.hypot(estimated[:, 0] - truth[:, 0], estimated[:, 1] - truth[:, 1])
    heading = np.array([wrap_angle(a - b) for a, b in zip(estimated[:, 2], truth[:, 2])])
    return float(np.sqrt(np.mean(position ** 2))), float(np.sqrt(np.mean(heading ** 2)))


def frame_in_world(pose_in_world, pose_in_frame):
    """Where a frame lies in the world, from one pose known in both."""
    return compose(pose_in_world, inverse(pose_in_frame))


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


def drive_route(sim, waypoints, scan_period, on_scan, max_linear=0.2, max_angular=1.5, step=0.05,
                tolerance=0.1, timeout=None):
    """Drive `sim` through waypoints (x, y) with a simple heading controller on the true pose.

    Calls on_scan(sim) every scan_period seconds of simulated time. Returns False on a
    collision or timeout, True when the last waypoint was reached.
    """
    next_scan = sim.time
    deadline = None if timeout is None else sim.time + timeout
    for target in waypoints:
        while True:
            x, y, yaw = sim.pose
            gap = math.hypot(target[0] - x, target[1] - y)
            if gap < tolerance:
                break
            error = wrap_angle(math.atan2(target[1] - y, target[0] - x) - yaw)
            angular = max(-max_angular, min(max_angular, 2.5 * error))
            linear = 0.0 if abs(error) > 0.6 else max_linear * math.cos(error) * min(1.0, gap / 0.3 + 0.3)
            sim.set_command(linear, angular)
            sim.step(step)
            if sim.time + 1e-9 >= next_scan:
                on_scan(sim)
                next_scan += scan_period
            if getattr(sim, "collided", False) or (deadline is not None and sim.time > deadline):
                sim.set_command(0.0, 0.0)
                return False
    sim.set_command(0.0, 0.0)
    return True


ROUTES = {
    # Around the nine pillars inside the hexagonal wall, then through the middle corridors.
    "turtlebot3_world": [(-1.6, -1.55), (0.0, -1.6), (1.6, -1.55), (1.6, 0.0), (1.6, 1.55), (0.0, 1.6),
                         (-1.6, 1.55), (-1.6, 0.0), (-1.6, -1.55), (-0.55, -1.6), (-0.55, 0.0),
                         (-0.55, 1.6), (0.55, 1.6), (0.55, 0.0), (0.55, -1.6), (1.6, -1.55)],
    # Kitchen -> hall -> living room -> bedroom -> kitchen (the loop through the four doors), then
    # into the hall again, so the loop must close.
    "house": [(-1.0, -2.0), (0.0, -2.0), (1.0, -2.0), (2.3, -1.3), (3.0, -0.6), (3.0, 0.4), (2.2, 0.9),
              (1.2, 2.0), (0.0, 2.0), (-1.2, 1.8), (-2.4, 1.5), (-3.0, 0.9), (-3.0, 0.0), (-3.0, -0.9),
              (-2.5, -2.0), (-1.0, -2.2), (0.0, -2.0), (1.0, -1.8), (2.0, -1.0)],
}


class RelativeError(NamedTuple):
    translation: float   # m, mean over the pairs
    rotation: float      # rad, mean over the pairs
    pairs: int


def relative_pose_errors(estimated, reference, travel, min_travel=1.0, max_travel=10.0):
    """Mean error of the motion between every pair of poses `min_travel`..`max_travel` m of path apart.

    The relations metric of Kümmerle et al. (2009): for each pair, how far the estimated pose
    of the later one, seen from the earlier one, lies from the reference's; a trajectory that
    is right locally scores well wherever its map frame lies. `travel` (N,) is the reference
    path length to each pose.
    """
    estimated = np.asarray(estimated, dtype=np.float64)[:, :3]
    reference = np.asarray(reference, dtype=np.float64)[:, :3]
    travel = np.asarray(travel, dtype=np.float64)
    first, last = [], []
    for index in range(len(travel)):
        start = np.searchsorted(travel, travel[index] + min_travel, side="left")
        stop = np.searchsorted(travel, travel[index] + max_travel, side="right")
        first.append(np.full(max(stop - start, 0), index))
        last.append(np.arange(start, stop))
    first, last = np.concatenate(first).astype(int), np.concatenate(last).astype(int)
    if len(first) == 0:
        return RelativeError(math.nan, math.nan, 0)
    error_xy, error_theta = relation_errors(estimated, reference, first, last)
    return RelativeError(float(error_xy.mean()), float(error_theta.mean()), len(first))


def relation_errors(estimated, reference, first, last):
    """(m, rad) per pair: how far the motion from pose first[k] to pose last[k] of `estimated`
    (N x 3 arrays) lies from the reference's."""
    def motion(poses):
        dx, dy = poses[last, 0] - poses[first, 0], poses[last, 1] - poses[first, 1]
        cos, sin = np.cos(poses[first, 2]), np.sin(poses[first, 2])
        return cos * dx + sin * dy, -sin * dx + cos * dy, poses[last, 2] - poses[first, 2]
    ex, ey, et = motion(estimated)
    rx, ry, rt = motion(reference)
    return np.hypot(ex - rx, ey - ry), np.abs(wrap_angle(et - rt))


def aligned_trajectory_error(estimated, reference):
    """RMS position error (m) after the rigid motion that best lays `estimated` on `reference` (Horn)."""
    estimated = np.asarray(estimated, dtype=np.float64)[:, :2]
    reference = np.asarray(reference, dtype=np.float64)[:, :2]
    mean_estimated, mean_reference = estimated.mean(axis=0), reference.mean(axis=0)
    a, b = estimated - mean_estimated, reference - mean_reference
    angle = math.atan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    cos, sin = math.cos(angle), math.sin(angle)
    turned = np.column_stack((cos * a[:, 0] - sin * a[:, 1], sin * a[:, 0] + cos * a[:, 1]))
    return float(np.sqrt(np.mean(np.sum((turned - b) ** 2, axis=1))))


def false_relations(pairs, reference, tolerance_xy=0.2, tolerance_theta=0.035):
    """How many of `pairs` [(i, j, (x, y, yaw))] -- a claimed pose of scan j seen from scan i, such
    as a loop closure -- contradict the reference by more than the tolerances (m, rad: 2 degrees)."""
    return sum(contradicts(tuple(claimed), relative(tuple(reference[i]), tuple(reference[j])), tolerance_xy,
                           tolerance_theta) for i, j, claimed in pairs)


def contradicts(claimed, expected, tolerance_xy=0.2, tolerance_theta=0.035):
    """Whether a claimed relative pose misses the expected one by more than the tolerances (m, rad)."""
    error = relative(expected, claimed)
    return math.hypot(error[0], error[1]) > tolerance_xy or abs(error[2]) > tolerance_theta
