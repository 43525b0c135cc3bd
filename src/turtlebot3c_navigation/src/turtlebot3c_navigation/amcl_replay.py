"""Offline localisation: run a ROS 1 bag's scans and odometry through AMCL against a map. No rospy.

What the live amcl node does, without a ROS master: the same particle filter (amcl.py), the
same inputs, the pose per scan. Reads the bag with `rosbags` (no ROS installation needed):
- scans: sensor_msgs/LaserScan on `scan_topic`;
- odometry at each scan's time: the odom -> base transforms on /tf when the bag has them (what
  the live node looks up), else the nav_msgs/Odometry on `odom_topic`; interpolated like tf
  (linear position, shortest-way yaw) between the two poses around the scan; a scan with a
  time_increment is deskewed (scan_deskew) over its revolution with that odometry, as the node
  does;
- the LIDAR's planar pose on the base: the base -> scan frame chain from /tf_static (or /tf),
  or one given.
Scans outside the odometry's time span are skipped and counted. The filter starts as the node
does: from an initial pose with its covariance (amcl's default: 0, 0, 0), or spread over the
whole free space (global localisation).
"""
import math
import time
from typing import List, NamedTuple, Optional, Tuple

import numpy as np

from turtlebot3c_common.bag_inputs import BagError, frame_in_base, odometry_series
from turtlebot3c_common.scan_deskew import beam_motion, deskew_ranges, reference_time, time_increment
from turtlebot3c_common.se2 import compose

from .navigation_stack import Localizer, MapLayers, make_filter, scan_angles


def sensor_offset_in_tree(tree, base_frame, scan_frame):
    """(x, y, yaw) of scan_frame in base_frame through the bag's transforms (planar, as the amcl node
    takes the sensor's offset), or None when the chain does not reach the base."""
    return frame_in_base(tree, base_frame, scan_frame, (0.0, 0.0, 0.0), compose)


class Start(NamedTuple):
    """How the filter starts: at `pose` with `covariance` (3 x 3 over x, y, yaw), or, when pose is
    None, spread over the map's free space (global localisation)."""

    pose: Optional[Tuple[float, float, float]] = (0.0, 0.0, 0.0)
    covariance: Optional[np.ndarray] = None  # None: the parameters' initial_cov_*


class LocalizeResult(NamedTuple):
    trajectory: List[Tuple[float, float, float, float]]  # (stamp, x, y, yaw) in the map frame, per scan
    processed: int
    skipped: int            # scans outside the odometry's time span
    updates: int            # filter updates (the robot had moved update_min_d / update_min_a)
    converged: bool         # the filter's own view at the end: one tight cluster holds the weight
    spread: float           # m, position standard deviation of the estimate's cluster at the end
    seconds: float          # CPU seconds of this process in the replay
    duration: float         # s the bag covers
    odometry_source: str    # "tf" or the odometry topic


AMCL_DEFAULT_START = Start()  # amcl's: 0, 0, 0 with the parameters' initial covariance


def replay(inputs, layers: MapLayers, params, start: Start = AMCL_DEFAULT_START, base_frame="base_footprint",
           odometry_source="auto", sensor_offset=None, odom_topic="/odom", seed=None) -> LocalizeResult:
    """Localise every scan of `inputs` on the map `layers` with a new particle filter."""
    series, source = odometry_series(inputs, odometry_source, base_frame, odom_topic)
    localizer = Localizer(make_filter(layers, params, seed=seed))
    trajectory, offsets = [], {}
    skipped = updates = 0
    started = time.process_time()
    for stamp, scan in sorted(inputs.scans, key=lambda item: item[0]):
        frame = scan.header.frame_id
        if frame not in offsets:
            offsets[frame] = sensor_offset if sensor_offset is not None else \
                sensor_offset_in_tree(inputs.tree, base_frame, frame)
            if offsets[frame] is None:
                raise BagError(f"bag has no transform from {base_frame} to the scan frame {frame} on /tf_static "
                               "or /tf; give the mount (--scan-mount X,Y,YAW)")
        count, increment = len(scan.ranges), time_increment(scan)
        reference = reference_time(stamp, count, increment)
        odom = series.at(reference)
        if odom is None or series.at(min(stamp, stamp + (count - 1) * increment)) is None:
            skipped += 1
            continue
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan_angles(scan)
        ranges, angles = deskew_ranges(ranges, angles, offsets[frame],
                                       beam_motion(stamp, count, increment, series.at))
        if not localizer.filter.initialized:
            if start.pose is None:
                localizer.global_localization()
            else:
                localizer.set_pose(start.pose, odom, start.covariance)
        updates += localizer.update(odom, ranges, angles, scan.range_min, offsets[frame], scan.range_max)
        trajectory.append((reference,) + tuple(localizer.pose(odom)))
    seconds = time.process_time() - started
    estimate = localizer.filter.estimate
    spread = math.sqrt(max(0.0, estimate.covariance[0, 0] + estimate.covariance[1, 1])) if estimate else math.inf
    return LocalizeResult(trajectory, len(trajectory), skipped, updates, localizer.filter.converged(), spread,
                          seconds, inputs.duration, source)
