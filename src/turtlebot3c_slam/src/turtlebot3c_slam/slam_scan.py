"""A LaserScan's rays in the robot frame, for any scan geometry. Pure numpy; no rospy.

Each range is classified as a LaserScan consumer should read it:
- a *hit*: finite, at least range_min and below range_max (and below the usable range);
- *no return*: +inf, or at/above range_max -- nothing was in reach, so the ray is free
  space up to the usable range but ends at no obstacle;
- *invalid*: NaN, -inf, 0 or below range_min (many drivers report 0 for "no measurement");
  it tells nothing and is dropped.
Hits beyond `usable_range` are cut there and count as free rays, as gmapping's maxUrange
does: far returns of long-range LIDARs are too inaccurate in angle to draw walls with.
"""
import math

import numpy as np

from turtlebot3c_common.message_fields import scan_range_limits
from turtlebot3c_common.scan_deskew import deskew_points


class ScanGeometry:
    """The fixed part of a LaserScan plus where the LIDAR sits on the robot.

    `mount` is (x, y, yaw) of the scan frame in the robot's base frame; `upside_down`
    when the scan frame's z axis points down (beam angles then run clockwise).
    """

    def __init__(self, angle_min, angle_increment, count, range_min, range_max, mount=(0.0, 0.0, 0.0),
                 upside_down=False):
        if count <= 0:
            raise ValueError("a scan needs at least one beam")
        if not (math.isfinite(angle_min) and math.isfinite(angle_increment)):
            raise ValueError("scan angles must be finite")
        self.angle_min = float(angle_min)
        self.angle_increment = float(angle_increment)
        self.count = int(count)
        self.range_min, self.range_max = scan_range_limits(range_min, range_max)
        self.mount = tuple(float(v) for v in mount)
        self.upside_down = bool(upside_down)
        sign = -1.0 if upside_down else 1.0
        angles = self.mount[2] + sign * (self.angle_min + np.arange(self.count) * self.angle_increment)
        self.directions = np.column_stack((np.cos(angles), np.sin(angles)))
        self.origin = np.array(self.mount[:2])

    def key(self):
        return (self.angle_min, self.angle_increment, self.count, self.range_min, self.range_max, self.mount,
                self.upside_down)

    def __eq__(self, other):
        return isinstance(other, ScanGeometry) and self.key() == other.key()

    def __hash__(self):
        return hash(self.key())


class ScanRays:
    """One scan's usable rays in the robot frame: hit endpoints, and free rays without a hit."""

    def __init__(self, geometry, hits, free_ends):
        self.geometry = geometry
        self.origin = geometry.origin
        self.hits = hits            # (N, 2) endpoints that are obstacles
        self.free_ends = free_ends  # (M, 2) endpoints of rays that saw nothing up to there


def scan_rays(geometry, ranges, usable_range, motion=None):
    """Classify `ranges` (sequence of float) and return the rays in the robot frame.

    `motion` (count, 3), from scan_deskew.beam_motion, is where the robot was at each beam's time
    relative to where it is at the scan's reference time: end points are deskewed to that time.
    Rays are still traced from the sensor's one origin: it moves a few centimetres in a scan at
    most, which shifts free cells, not the end points that make walls.
    """
    ranges = np.asarray(ranges, dtype=np.float64)
    if ranges.shape != (geometry.count,):
        raise ValueError(f"scan has {ranges.size} ranges, its geometry {geometry.count}")
    limit = min(usable_range, geometry.range_max)
    with np.errstate(invalid="ignore"):
        # 0 is "no measurement" even from a scan that declares no range_min: never a wall at the sensor.
        valid = (ranges >= geometry.range_min) & (ranges > 0.0) & ~np.isnan(ranges)
        hit = valid & (ranges < geometry.range_max) & (ranges <= usable_range)
    free = valid & ~hit
    hit_points = geometry.origin + geometry.directions[hit] * ranges[hit, None]
    free_points = geometry.origin + geometry.directions[free] * limit if math.isfinite(limit) else np.empty((0, 2))
    if motion is not None:
        motion = np.asarray(motion, dtype=np.float64)
        hit_points = deskew_points(hit_points, motion[hit])
        if len(free_points):
            free_points = deskew_points(free_points, motion[free])
    return ScanRays(geometry, hit_points, free_points)


def voxel_filter(points, cell):
    """One point per `cell`-sized square (the first one seen), order kept."""
    if len(points) == 0:
        return points
    keys = np.floor(points / cell).astype(np.int64)
    _, first = np.unique(keys[:, 0] * 2000003 + keys[:, 1], return_index=True)
    return points[np.sort(first)]
