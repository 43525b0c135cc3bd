"""Offline re-mapping: run a ROS 1 bag's scans and odometry through the SLAM core. No rospy.

Reads the bag with `rosbags` (no ROS installation needed). Inputs, as the live node takes them:
- scans: sensor_msgs/LaserScan on `scan_topic`;
- odometry at each scan's time: the odom -> base transforms on /tf when the bag has them (what the
  live node looks up), else the nav_msgs/Odometry on `odom_topic`; interpolated like tf
  (linear position, shortest-way yaw) between the two messages around the scan; a scan with a
  time_increment is deskewed (scan_deskew) with that odometry over its revolution;
- the LIDAR mount: the base -> scan frame chain from /tf_static (or /tf), or one given.
Scans outside the odometry's time span are skipped and counted.
"""
import bisect
import math
import time

import numpy as np

from turtlebot3c_common.message_fields import pose_from_transform
from turtlebot3c_common.scan_deskew import beam_motion, reference_time

from .slam import Slam
from .slam_messages import (
    ScanGeometries,
    interpolate_pose,
    mount_from_transform,
    pose_from_odometry,
    stamp_seconds,
)

TF_TOPICS = ("/tf", "/tf_static")


class BagError(ValueError):
    """A bag that cannot be re-mapped; the message says what is missing."""


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


class BagInputs:
    """What a bag holds for SLAM: scans (stamp, message), odometry series, frame tree."""

    def __init__(self):
        self.scans = []
        self.tf_odometry = ([], [])      # (stamps, poses) of odom -> base on /tf
        self.topic_odometry = ([], [])   # (stamps, poses) from the odometry topic
        self.tree = {}                   # child frame -> (parent frame, Transform3D), latest
        self.duration = 0.0


def read_bag(path, scan_topic="/scan", odom_topic="/odom", odom_frame="odom", base_frame="base_footprint"):
    """Collect BagInputs from a ROS 1 bag file."""
    from rosbags.rosbag1 import Reader, ReaderError
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC)
    inputs = BagInputs()
    wanted = {scan_topic, odom_topic} | set(TF_TOPICS)
    try:
        with Reader(str(path)) as reader:
            topics = {connection.topic for connection in reader.connections}
            if scan_topic not in topics:
                raise BagError("bag {} has no {} topic (its topics: {})".format(
                    path, scan_topic, ", ".join(sorted(topics)) or "none"))
            connections = [c for c in reader.connections if c.topic in wanted]
            for connection in connections:  # types the store lacks (tf2_msgs) come with the bag
                # rosbags >= 0.10 wraps the definition text; 0.9 (the last for Python 3.8) gives it plain.
                definition = getattr(connection.msgdef, "data", connection.msgdef)
                if connection.msgtype not in typestore.types and definition:
                    typestore.register(get_types_from_msg(definition, connection.msgtype))
            inputs.duration = (reader.end_time - reader.start_time) * 1e-9 if reader.message_count else 0.0
            for connection, _, raw in reader.messages(connections=connections):
                message = typestore.deserialize_ros1(raw, connection.msgtype)
                _collect(inputs, connection.topic, message, scan_topic, odom_topic, odom_frame, base_frame)
    except ReaderError as error:
        raise BagError(f"cannot read bag {path}: {error}") from error
    except FileNotFoundError as error:
        raise BagError(f"cannot read bag {path}: no such file") from error
    return inputs


def _collect(inputs, topic, message, scan_topic, odom_topic, odom_frame, base_frame):
    if topic == scan_topic:
        inputs.scans.append((stamp_seconds(message.header), message))
    elif topic == odom_topic:
        inputs.topic_odometry[0].append(stamp_seconds(message.header))
        inputs.topic_odometry[1].append(pose_from_odometry(message))
    if topic in TF_TOPICS:
        for transform in message.transforms:
            parent, child = transform.header.frame_id.lstrip("/"), transform.child_frame_id.lstrip("/")
            if parent == odom_frame and child == base_frame:
                inputs.tf_odometry[0].append(stamp_seconds(transform.header))
                inputs.tf_odometry[1].append(pose_from_transform(transform.transform))
            else:
                inputs.tree[child] = (parent, Transform3D.of(transform.transform))


def mount_in_tree(tree, base_frame, scan_frame):
    """(x, y, yaw, upside_down) of scan_frame in base_frame from the bag's transforms, or None."""
    scan_frame, chain = scan_frame.lstrip("/"), []
    frame = scan_frame
    while frame != base_frame:
        if frame not in tree or len(chain) > 64:
            return None
        parent, transform = tree[frame]
        chain.append(transform)
        frame = parent
    total = Transform3D((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    for transform in reversed(chain):
        total = total.then(transform)
    return mount_from_transform(total)


class OdometrySeries:
    """Poses at sorted stamps, interpolated at any time within them."""

    def __init__(self, stamps, poses):
        order = np.argsort(np.asarray(stamps), kind="stable")
        self.stamps = [stamps[i] for i in order]
        self.poses = [poses[i] for i in order]

    def __len__(self):
        return len(self.stamps)

    def at(self, stamp):
        if not self.stamps or stamp < self.stamps[0] or stamp > self.stamps[-1]:
            return None
        index = bisect.bisect_left(self.stamps, stamp)
        if self.stamps[index] == stamp:
            return self.poses[index]
        before, after = index - 1, index
        span = self.stamps[after] - self.stamps[before]
        return interpolate_pose(self.poses[before], self.poses[after], (stamp - self.stamps[before]) / span)


class ReplayResult:
    def __init__(self, slam, processed, skipped, seconds, duration, odometry_source):
        self.slam = slam
        self.processed = processed
        self.skipped = skipped
        self.seconds = seconds                  # processing time (CPU of this process)
        self.duration = duration                # time span the bag covers
        self.odometry_source = odometry_source  # "tf" or the odometry topic


def replay(inputs, config, base_frame="base_footprint", odometry_source="auto", scan_mount=None,
           odom_topic="/odom"):
    """Run the bag's scans through a new Slam; returns a ReplayResult."""
    if odometry_source not in ("auto", "tf", "topic"):
        raise ValueError(f"odometry source must be auto, tf or topic, got {odometry_source!r}")
    use_tf = odometry_source == "tf" or (odometry_source == "auto" and inputs.tf_odometry[0])
    series = OdometrySeries(*(inputs.tf_odometry if use_tf else inputs.topic_odometry))
    source = "tf" if use_tf else odom_topic
    if not len(series):
        raise BagError(f"bag has no odometry: no odom -> {base_frame} transforms on /tf and no messages on "
                       f"{odom_topic}")
    if not inputs.scans:
        raise BagError("bag has no scans")
    slam, geometries, mounts = Slam(config), ScanGeometries(), {}
    processed = skipped = 0
    started = time.process_time()
    for stamp, scan in sorted(inputs.scans, key=lambda item: item[0]):
        frame = scan.header.frame_id
        if frame not in mounts:
            mounts[frame] = scan_mount if scan_mount is not None else mount_in_tree(inputs.tree, base_frame, frame)
            if mounts[frame] is None:
                raise BagError(f"bag has no transform from {base_frame} to the scan frame {frame} on /tf_static "
                               "or /tf; give the mount (--scan-mount X,Y,YAW)")
        # As the live node: a scan measured over a revolution is deskewed to its latest beam.
        count, increment = len(scan.ranges), scan.time_increment
        reference = reference_time(stamp, count, increment)
        first_beam = min(stamp, stamp + (count - 1) * increment)
        odometry = series.at(reference)
        if odometry is None or series.at(first_beam) is None:
            skipped += 1
            continue
        motion = beam_motion(stamp, count, increment, series.at)
        slam.add_scan(reference, np.asarray(scan.ranges, dtype=np.float64), geometries.get(scan, mounts[frame]),
                      odometry, motion)
        processed += 1
    return ReplayResult(slam, processed, skipped, time.process_time() - started, inputs.duration, source)


def write_trajectory(path, trajectory):
    """One line per scan: stamp x y yaw (s, m, m, rad)."""
    with open(path, "w") as stream:
        stream.write("# stamp x y yaw  (map frame; s, m, m, rad)\n")
        for stamp, x, y, yaw in trajectory:
            stream.write(f"{stamp:.9f} {x:.6f} {y:.6f} {yaw:.6f}\n")


def read_trajectory(path):
    rows = [line.split() for line in open(path) if line.strip() and not line.startswith("#")]
    return [tuple(float(v) for v in row) for row in rows]


def parse_mount(text):
    """'X,Y,YAW' -> (x, y, yaw, False)."""
    parts = text.split(",")
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"scan mount must be X,Y,YAW (metres, radians), got {text!r}")
    return (values[0], values[1], values[2], False)
