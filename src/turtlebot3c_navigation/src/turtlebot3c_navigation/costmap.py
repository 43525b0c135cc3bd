"""Costmaps for planning and control, with costmap_2d's cost values.

A cell's cost comes from its distance d to the nearest obstacle (static map or laser):
LETHAL where the obstacle is, INSCRIBED where the robot's centre there would make the
robot (a circle of robot_radius) touch it, then an exponential decay
252·exp(-cost_scaling_factor·(d − robot_radius)) out to inflation_radius, 0 beyond.

The obstacle layer is marked by laser end points within obstacle_range and cleared
along each beam up to its end (or raytrace_range for beams with no return), so obstacles
that appear are seen and obstacles that leave are forgotten.
"""
import math
from typing import Optional, Tuple

import numpy as np

from turtlebot3c_common.message_fields import scan_range_limits

from .grid_info import GridInfo
from .likelihood_field import distance_transform

FREE = 0
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255


def footprint_radii(footprint) -> Tuple[float, float]:
    """(inscribed, circumscribed) radius of a footprint polygon around the origin."""
    points = np.asarray(footprint, dtype=float)
    circumscribed = float(np.hypot(points[:, 0], points[:, 1]).max())
    inscribed = math.inf
    for a, b in zip(points, np.roll(points, -1, axis=0)):
        edge = b - a
        t = np.clip(-(a @ edge) / (edge @ edge), 0.0, 1.0)
        inscribed = min(inscribed, float(np.hypot(*(a + t * edge))))
    return inscribed, circumscribed


def inflate(distances, robot_radius, inflation_radius, cost_scaling_factor):
    """Cost (uint8) of each cell from its distance (m) to the nearest obstacle."""
    decay = 252.0 * np.exp(-cost_scaling_factor * np.maximum(distances - robot_radius, 0.0))
    costs = np.where(distances <= inflation_radius, np.floor(decay), 0.0).astype(np.uint8)
    costs[distances <= robot_radius] = INSCRIBED
    costs[distances <= 0.0] = LETHAL
    return costs


def beam_end_points(pose, ranges, angles, sensor_offset=(0.0, 0.0, 0.0)):
    """Sensor origin (x, y) and end points (N x 2) of beams, in the frame of `pose`."""
    x, y, yaw = pose
    sx, sy, syaw = sensor_offset
    origin = (x + math.cos(yaw) * sx - math.sin(yaw) * sy, y + math.sin(yaw) * sx + math.cos(yaw) * sy)
    directions = yaw + syaw + np.asarray(angles, dtype=float)
    ranges = np.asarray(ranges, dtype=float)
    ends = np.column_stack([origin[0] + ranges * np.cos(directions), origin[1] + ranges * np.sin(directions)])
    return origin, ends


class Costmap:
    """A grid with a static layer (fixed obstacles, unknown cells), an obstacle layer
    from the laser, and their inflation."""

    def __init__(self, info: GridInfo, static_occupied=None, unknown=None, robot_radius=0.105,
                 inflation_radius=1.0, cost_scaling_factor=3.0, obstacle_range=3.0, raytrace_range=3.5,
                 track_unknown=True, static_tolerance=0.1):
        self.info = info
        shape = (info.height, info.width)
        self.static = np.zeros(shape, bool) if static_occupied is None else np.asarray(static_occupied, bool)
        self.unknown = np.zeros(shape, bool) if unknown is None or not track_unknown else np.asarray(unknown, bool)
        self.obstacles = np.zeros(shape, bool)
        self.robot_radius = robot_radius
        self.inflation_radius = max(inflation_radius, robot_radius)
        self.cost_scaling_factor = cost_scaling_factor
        self.obstacle_range = obstacle_range
        self.raytrace_range = raytrace_range
        self._costs: Optional[np.ndarray] = None
        # Laser returns this close to a known obstacle are that obstacle, seen through range
        # noise and localisation error: marking them would narrow doors with phantoms.
        self.near_static = (distance_transform(self.static, info.resolution, static_tolerance + info.resolution)
                            <= static_tolerance) if self.static.any() else np.zeros(shape, bool)

    @property
    def costs(self) -> np.ndarray:
        """Inflated cost of every cell (uint8 grid, row = y index); NO_INFORMATION where unknown."""
        if self._costs is None:
            occupied = self.static | self.obstacles
            distances = distance_transform(occupied, self.info.resolution, self.inflation_radius + self.info.resolution)
            self._distances = distances
            costs = inflate(distances, self.robot_radius, self.inflation_radius, self.cost_scaling_factor)
            costs[self.unknown & ~occupied] = NO_INFORMATION
            self._costs = costs
        return self._costs

    def cost_at(self, x, y, outside=LETHAL):
        """Costs at world points; `outside` for points off the grid."""
        row, col = self.info.world_to_cell(x, y)
        inside = self.info.contains(row, col)
        result = np.full(np.shape(row), outside, dtype=np.uint8)
        result[inside] = self.costs[row[inside], col[inside]]
        return result

    def clearance_at(self, x, y, outside=0.0):
        """Distance (m) from points to the nearest obstacle (capped past inflation_radius)."""
        self.costs  # noqa: B018 -- brings the distances up to date
        row, col = self.info.world_to_cell(x, y)
        inside = self.info.contains(row, col)
        result = np.full(np.shape(row), outside, dtype=float)
        result[inside] = self._distances[row[inside], col[inside]]
        return result

    def clear_obstacles(self):
        """Forget everything the laser marked (a recovery behaviour)."""
        self.obstacles[:] = False
        self._costs = None

    def clear_obstacles_outside(self, x, y, radius):
        """Forget laser marks farther than radius from (x, y) (move_base's conservative reset)."""
        rows, cols = np.nonzero(self.obstacles)
        cx, cy = self.info.cell_to_world(rows, cols)
        far = np.hypot(cx - x, cy - y) > radius
        self.obstacles[rows[far], cols[far]] = False
        self._costs = None

    def update_from_scan(self, pose, ranges, angles, range_min=0.12, sensor_offset=(0.0, 0.0, 0.0),
                         range_max=math.inf):
        """Clear along every beam, then mark the end points of returns within obstacle_range.

        A beam with no return (inf, or range_max and beyond: each LIDAR says it its own way) clears
        up to raytrace_range and marks nothing; one that is no reading (NaN, 0, below range_min, or
        at an angle that is not a number) does neither."""
        range_min, range_max = scan_range_limits(range_min, range_max)
        ranges = np.asarray(ranges, dtype=float)
        angles = np.asarray(angles, dtype=float)
        with np.errstate(invalid="ignore"):
            valid = (ranges >= range_min) & (ranges > 0.0) & np.isfinite(angles)
        ranges, angles = ranges[valid], angles[valid]
        hit = (ranges < range_max) & (ranges <= self.raytrace_range)
        clear_lengths = np.where(hit, ranges, self.raytrace_range)
        origin, ends = beam_end_points(pose, clear_lengths, angles, sensor_offset)
        self._clear_rays(origin, ends)
        marking = hit & (ranges <= self.obstacle_range)
        self._mark(ends[marking])
        self._costs = None

    def _clear_rays(self, origin, ends):
        step = self.info.resolution * 0.5
        lengths = np.hypot(ends[:, 0] - origin[0], ends[:, 1] - origin[1])
        samples = int(math.ceil(lengths.max() / step)) if lengths.size else 0
        if samples == 0:
            return
        # Stop one cell short of each end point: that cell holds the obstacle.
        fractions = np.arange(samples) * step
        along = fractions[None, :] < (lengths[:, None] - self.info.resolution)
        unit = (ends - np.asarray(origin)) / np.maximum(lengths, 1e-9)[:, None]
        xs = origin[0] + unit[:, 0:1] * fractions[None, :]
        ys = origin[1] + unit[:, 1:2] * fractions[None, :]
        row, col = self.info.world_to_cell(xs[along], ys[along])
        inside = self.info.contains(row, col)
        self.obstacles[row[inside], col[inside]] = False

    def _mark(self, points):
        if len(points) == 0:
            return
        row, col = self.info.world_to_cell(points[:, 0], points[:, 1])
        inside = self.info.contains(row, col)
        row, col = row[inside], col[inside]
        # The static map already holds what it knows; the layer keeps only new obstacles.
        fresh = ~self.near_static[row, col]
        self.obstacles[row[fresh], col[fresh]] = True


class RollingCostmap(Costmap):
    """A square window of the obstacle layer that follows the robot (the local costmap)."""

    def __init__(self, size=3.0, resolution=0.05, **kwargs):
        cells = int(round(size / resolution))
        super().__init__(GridInfo(resolution, cells, cells, -size / 2.0, -size / 2.0), **kwargs)
        self.size = size

    def recenter(self, x, y):
        """Move the window so that (x, y) is at its centre, keeping marks that stay inside."""
        res = self.info.resolution
        half = self.info.width * res / 2.0
        new_origin_x = math.floor((x - half) / res) * res
        new_origin_y = math.floor((y - half) / res) * res
        shift_col = int(round((new_origin_x - self.info.origin_x) / res))
        shift_row = int(round((new_origin_y - self.info.origin_y) / res))
        if shift_col == 0 and shift_row == 0:
            return
        moved = np.zeros_like(self.obstacles)
        h, w = moved.shape
        if abs(shift_row) >= h or abs(shift_col) >= w:
            shift_row, shift_col = h, w  # jumped out of the window: nothing carries over
        src_rows = slice(max(0, shift_row), min(h, h + shift_row))
        dst_rows = slice(max(0, -shift_row), min(h, h - shift_row))
        src_cols = slice(max(0, shift_col), min(w, w + shift_col))
        dst_cols = slice(max(0, -shift_col), min(w, w - shift_col))
        if shift_row < h and shift_col < w:
            moved[dst_rows, dst_cols] = self.obstacles[src_rows, src_cols]
        self.obstacles = moved
        self.info = self.info._replace(origin_x=new_origin_x, origin_y=new_origin_y)
        self.static = np.zeros_like(self.obstacles)
        self.near_static = self.static
        self.unknown = np.zeros_like(self.obstacles)
        self._costs = None

    def cost_at(self, x, y, outside=FREE):
        # Beyond the window nothing is known locally: the global plan vouches for it.
        return super().cost_at(x, y, outside=outside)

    def clearance_at(self, x, y, outside=math.inf):
        return super().clearance_at(x, y, outside=outside)
