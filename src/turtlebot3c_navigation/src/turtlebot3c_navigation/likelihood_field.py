"""Distance to the nearest obstacle for every map cell, and the likelihood-field
sensor model built on it (Thrun, Burgard, Fox: Probabilistic Robotics, §6.4).

The distance transform is exact (Euclidean) up to a cap: a column pass finds the
vertical distance to the nearest obstacle in each column, then a row pass takes, for
each cell, the minimum over horizontal offsets within the cap. Both passes are numpy
loops over one axis only, so a 400 x 400 map takes a few tens of milliseconds.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import cos_sin

from .grid_info import GridInfo


def _column_distances(occupied, cap_cells):
    """Cells from each cell to the nearest occupied cell in its column (capped)."""
    height = occupied.shape[0]
    far = cap_cells + 1
    down = np.full(occupied.shape, far, dtype=np.int32)
    previous = np.full(occupied.shape[1], far, dtype=np.int32)
    for row in range(height):
        previous = np.where(occupied[row], 0, np.minimum(previous + 1, far))
        down[row] = previous
    previous = np.full(occupied.shape[1], far, dtype=np.int32)
    for row in range(height - 1, -1, -1):
        previous = np.where(occupied[row], 0, np.minimum(previous + 1, far))
        down[row] = np.minimum(down[row], previous)
    return down


def distance_transform(occupied, resolution, max_distance):
    """Euclidean distance (m) from each cell centre to the nearest occupied cell centre,
    capped at max_distance. `occupied` is a 2D bool array."""
    occupied = np.asarray(occupied, dtype=bool)
    cap = int(math.ceil(max_distance / resolution))
    vertical = _column_distances(occupied, cap).astype(np.float64)
    squared_vertical = vertical * vertical
    best = np.full(occupied.shape, float((cap + 1) ** 2))
    width = occupied.shape[1]
    for offset in range(-cap, cap + 1):
        if abs(offset) >= width:
            continue
        shifted = np.full(occupied.shape, np.inf)
        if offset >= 0:
            shifted[:, : width - offset] = squared_vertical[:, offset:]
        else:
            shifted[:, -offset:] = squared_vertical[:, : width + offset]
        np.minimum(best, shifted + offset * offset, out=best)
    return np.minimum(np.sqrt(best) * resolution, max_distance)


def obstacle_boundary(occupied):
    """Occupied cells with a non-occupied 4-neighbour: the surfaces a laser can hit.

    Scoring beam ends by their distance to these (not to any occupied cell) makes an end
    point deep inside a filled obstacle unlikely, as it should be: no beam gets there."""
    occupied = np.asarray(occupied, dtype=bool)
    padded = np.pad(occupied, 1, mode="constant", constant_values=False)
    interior = padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:]
    return occupied & ~interior


class LikelihoodField:
    """Scan likelihood against a map: each beam end point scores by its distance to the
    nearest obstacle (Gaussian of width sigma_hit, mixed with a uniform for random returns)."""

    def __init__(self, occupied, info: GridInfo, max_distance=2.0, sigma_hit=0.2, z_hit=0.5, z_rand=0.5,
                 max_range=3.5):
        self.info = info
        self.max_distance = max_distance
        self.distances = distance_transform(obstacle_boundary(occupied), info.resolution, max_distance)
        self.sigma_hit = sigma_hit
        self.z_hit = z_hit
        self.z_rand = z_rand
        self.max_range = max_range
        self._update_log_table()

    def use_max_range(self, max_range):
        """Score random returns as uniform over `max_range` (m) from now on: the scan's reach,
        once a scan tells it (the table is rebuilt only when it changes)."""
        if max_range != self.max_range:
            self.max_range = max_range
            self._update_log_table()

    def _update_log_table(self):
        probability = (self.z_hit * np.exp(-(self.distances ** 2) / (2.0 * self.sigma_hit ** 2))
                       + self.z_rand / self.max_range)
        self.log_probability = np.log(probability)
        far = self.z_hit * math.exp(-(self.max_distance ** 2) / (2.0 * self.sigma_hit ** 2))
        self.outside_log_probability = math.log(far + self.z_rand / self.max_range)

    def distance_at(self, x, y):
        """Distance (m) to the nearest obstacle at points; max_distance outside the map."""
        row, col = self.info.world_to_cell(x, y)
        inside = self.info.contains(row, col)
        result = np.full(np.shape(row), self.max_distance)
        result[inside] = self.distances[row[inside], col[inside]]
        return result

    def end_point_distances(self, pose, ranges, angles, sensor_offset=(0.0, 0.0, 0.0)):
        """Distance (m) from each beam's end point to the nearest obstacle, seen from one pose."""
        origin_x, origin_y, directions = _rays(*pose, angles, sensor_offset)
        return self.distance_at(origin_x + np.asarray(ranges) * np.cos(directions),
                                origin_y + np.asarray(ranges) * np.sin(directions))

    def passes_obstacle(self, pose, ranges, angles, margin, sensor_offset=(0.0, 0.0, 0.0)):
        """Whether each beam, seen from one pose, passes through an obstacle more than `margin` m
        before its end point: a reading through a wall, which nothing unmapped in front of the
        wall explains (a person, a chair: the beam ends short, in the open).

        Marches along every ray at once, each step as long as the ray's clearance from the
        nearest obstacle allows (less a cell and a half, as the clearance is a cell centre's),
        so open space costs a few steps per metre."""
        origin_x, origin_y, directions = _rays(*pose, angles, sensor_offset)
        cos, sin = np.cos(directions), np.sin(directions)
        resolution = self.info.resolution
        reach = np.asarray(ranges, dtype=float) - margin
        travelled = np.full(reach.shape, resolution)  # from the sensor's own cell on
        passes = np.zeros(reach.shape, dtype=bool)
        marching = np.nonzero(travelled < reach)[0]
        while marching.size:
            along = travelled[marching]
            clearance = self.distance_at(origin_x + along * cos[marching], origin_y + along * sin[marching])
            inside = clearance < resolution / 2.0  # in an obstacle's surface cell
            passes[marching[inside]] = True
            travelled[marching] = along + np.maximum(clearance - 1.5 * resolution, resolution / 2.0)
            marching = marching[~inside & (travelled[marching] < reach[marching])]
        return passes

    def log_likelihood(self, poses, ranges, angles, sensor_offset=(0.0, 0.0, 0.0)):
        """Sum over beams of log p(beam | pose) for each of N poses (N x 3 array).

        `ranges` and `angles` are the valid beams only (in the sensor frame);
        `sensor_offset` is the sensor's pose in the robot frame."""
        poses = np.atleast_2d(poses)
        sensor_x, sensor_y, beam_angles = _rays(
            poses[:, 0:1], poses[:, 1:2], poses[:, 2:3], np.asarray(angles)[None, :], sensor_offset)
        end_x = sensor_x + np.asarray(ranges)[None, :] * np.cos(beam_angles)
        end_y = sensor_y + np.asarray(ranges)[None, :] * np.sin(beam_angles)
        row, col = self.info.world_to_cell(end_x, end_y)
        inside = self.info.contains(row, col)
        log_p = np.full(end_x.shape, self.outside_log_probability)
        log_p[inside] = self.log_probability[row[inside], col[inside]]
        return log_p.sum(axis=1)


def _rays(x, y, yaw, angles, sensor_offset):
    """The sensor's position (x, y) and each beam's direction in the map frame, from the robot's
    pose: one pose, or a column of them (N x 1 arrays) against a row of angles."""
    sx, sy, syaw = sensor_offset
    cos, sin = cos_sin(yaw)
    return x + cos * sx - sin * sy, y + sin * sx + cos * sy, yaw + syaw + np.asarray(angles)
