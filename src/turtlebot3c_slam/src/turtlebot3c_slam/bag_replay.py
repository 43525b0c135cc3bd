"""Offline re-mapping: run a ROS 1 bag's scans and odometry through the SLAM core. No rospy.

Reads the bag with `rosbags` (no ROS installation needed). Inputs, as the live node takes them:
- scans: sensor_msgs/LaserScan on `scan_topic`;
- odometry at each scan's time: the odom -> base transforms on /tf when the bag has them (what the
  live node looks up), else the nav_msgs/Odometry on `odom_topic`; interpolated like tf
  (linear position, shortest-way yaw) between the two messages around the scan; a scan with a
  time_increment is deskewed (scan_deskew) with that odometry over its revolution;
- the LIDAR mount: the base -> scan frame chain from /tf_static (or /tf), or one given.
Scans outside the odometry's time span are skipped and counted, and so are scans without beams
or with angles that are not numbers.
"""
import time

import numpy as np

from turtlebot3c_common import bag_inputs
from turtlebot3c_common.bag_inputs import BagError, odometry_series, parse_pose
from turtlebot3c_common.scan_deskew import beam_motion, reference_time, time_increment

from .slam import Slam
from .slam_messages import ScanGeometries, mount_from_transform


class Transform3D:
    """A rigid transform (translation, quaternion x y z w) with the attributes mount_from_transform reads."""

    class _Vector:
        def __init__(self, x, y, z, w=None):
            self.x, self.y, self.z, self.w = x, y, z, w

    def __init__(self, translation, rotation):
        self.t = np.asarray(translation, dtype=np.float64)
        self.q = np.asarray(rotation, dtype=np.float64)

    @classmethod
    def of(cls, transform):
        t, r = transform.translation, transform.rotation
        return cls((t.x, t.y, t.z), (r.x, r.y, r.z, r.w))

    def then(self, child):
        """This transform followed by `child` (parent <- self <- child)."""
        return Transform3D(self.t + _rotate(self.q, child.t), _multiply(self.q, child.q))

    @property
    def translation(self):
        return self._Vector(*self.t)

    @property
    def rotation(self):
        return self._Vector(*self.q)


def _multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def _rotate(q, v):
    qv = np.array([v[0], v[1], v[2], 0.0])
    conjugate = np.array([-q[0], -q[1], -q[2], q[3]])
    return _multiply(_multiply(q, qv), conjugate)[:3]


def read_bag(path, scan_topic="/scan", odom_topic="/odom", odom_frame="odom", base_frame="base_footprint"):
    """BagInputs of a bag whose frame tree keeps whole 3-D transforms (a LIDAR may be mounted upside down)."""
    return bag_inputs.read_bag(path, scan_topic, odom_topic, odom_frame, base_frame, frame_value=Transform3D.of)


def mount_in_tree(tree, base_frame, scan_frame):
    """(x, y, yaw, upside_down) of scan_frame in base_frame from the bag's transforms, or None."""
    identity = Transform3D((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    total = bag_inputs.frame_in_base(tree, base_frame, scan_frame, identity, Transform3D.then)
    return None if total is None else mount_from_transform(total)


class ReplayResult:
    def __init__(self, slam, processed, skipped, seconds, duration, odometry_source, unusable=0):
        self.slam = slam
        self.processed = processed
        self.skipped = skipped                  # scans outside the odometry's time span
        self.unusable = unusable                # scans without beams or with angles that are not numbers
        self.seconds = seconds                  # processing time (CPU of this process)
        self.duration = duration                # time span the bag covers
        self.odometry_source = odometry_source  # "tf" or the odometry topic, and what was mended in it


def replay(inputs, config, base_frame="base_footprint", odometry_source="auto", scan_mount=None,
           odom_topic="/odom"):
    """Run the bag's scans through a new Slam, refined at the end (Slam.refine); returns a ReplayResult."""
    series, source = odometry_series(inputs, odometry_source, base_frame, odom_topic)
    slam, geometries, mounts = Slam(config), ScanGeometries(), {}
    processed = skipped = unusable = 0
    started = time.process_time()
    for stamp, scan in sorted(inputs.scans, key=lambda item: item[0]):
        frame = scan.header.frame_id
        if frame not in mounts:
            mounts[frame] = scan_mount if scan_mount is not None else mount_in_tree(inputs.tree, base_frame, frame)
            if mounts[frame] is None:
                raise BagError(f"bag has no transform from {base_frame} to the scan frame {frame} on /tf_static "
                               "or /tf; give the mount (--scan-mount X,Y,YAW)")
        try:
            geometry = geometries.get(scan, mounts[frame])
        except ValueError:  # no beams, or angles that are not numbers: nothing to map, the rest still is
            unusable += 1
            continue
        # As the live node: a scan measured over a revolution is deskewed to its latest beam.
        count, increment = len(scan.ranges), time_increment(scan)
        reference = reference_time(stamp, count, increment)
        first_beam = min(stamp, stamp + (count - 1) * increment)
        odometry = series.at(reference)
        if odometry is None or series.at(first_beam) is None:
            skipped += 1
            continue
        motion = beam_motion(stamp, count, increment, series.at)
        slam.add_scan(reference, np.asarray(scan.ranges, dtype=np.float64), geometry, odometry, motion)
        processed += 1
    slam.refine()
    return ReplayResult(slam, processed, skipped, time.process_time() - started, inputs.duration, source, unusable)


def parse_mount(text):
    """'X,Y,YAW' -> (x, y, yaw, False)."""
    return parse_pose(text, "scan mount") + (False,)
