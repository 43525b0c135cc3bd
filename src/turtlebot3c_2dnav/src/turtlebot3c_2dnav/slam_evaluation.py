"""Measuring a SLAM run against ground truth: map agreement, trajectory error, a route driver.

Used by the SLAM benchmark (scripts/bench_slam) and tests. Pure numpy; no rospy. The
simulator is passed in (any object with `pose`, `set_command`, `step`, `time`), so this
module does not depend on the simulator package.
"""
import math

import numpy as np

from .slam_se2 import wrap_angle


def ground_truth_window(occupancy_map):
    """(origin_xy, width, height) of the grid cells of an OccupancyMap, for World.rasterize;
    a map turned by its origin's yaw is refused (its cells are compared one to one with an
    unrotated rasterisation)."""
    yaw = occupancy_map.origin[2]
    if abs(math.atan2(math.sin(yaw), math.cos(yaw))) > 1e-9:
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
