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
import bisect
import math
import time
from typing import List, NamedTuple, Optional, Tuple

import numpy as np

from turtlebot3c_common.message_fields import pose_from_msg, pose_from_transform
from turtlebot3c_common.scan_deskew import beam_motion, deskew_ranges, reference_time
from turtlebot3c_common.se2 import compose, wrap_angle

from .navigation_stack import Localizer, MapLayers, make_filter

TF_TOPICS = ("/tf", "/tf_static")


class BagError(ValueError):
    """A bag that cannot be replayed; the message says what is missing."""


class BagInputs:
    """What a bag holds for localisation: scans (stamp, message), odometry series, frame tree."""

    def __init__(self):
        self.scans = []
        self.tf_odometry = ([], [])      # (stamps, poses) of odom -> base on /tf
        self.topic_odometry = ([], [])   # (stamps, poses) from the odometry topic
        self.tree = {}                   # child frame -> (parent frame, planar pose (x, y, yaw)), latest
        self.duration = 0.0


def stamp_seconds(header):
    """A header's stamp in seconds, for rospy-style (secs, nsecs) and rosbags-style (sec, nanosec) stamps."""
    stamp = header.stamp
    seconds = stamp.secs if hasattr(stamp, "secs") else stamp.sec
    nanoseconds = stamp.nsecs if hasattr(stamp, "nsecs") else stamp.nanosec
    return seconds + nanoseconds * 1e-9


def read_bag(path, scan_topic="/scan", odom_topic="/odom", odom_frame="odom", base_frame="base_footprint"):
    """Collect BagInputs from a ROS 1 bag file; BagError when it cannot be read or has no scan topic."""
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
    except IsADirectoryError as error:
        raise BagError(f"cannot read bag {path}: it is a directory") from error
    return inputs


def _collect(inputs, topic, message, scan_topic, odom_topic, odom_frame, base_frame):
    if topic == scan_topic:
        inputs.scans.append((stamp_seconds(message.header), message))
    elif topic == odom_topic:
        inputs.topic_odometry[0].append(stamp_seconds(message.header))
        inputs.topic_odometry[1].append(pose_from_msg(message.pose.pose))
    if topic in TF_TOPICS:
        for transform in message.transforms:
            parent, child = transform.header.frame_id.lstrip("/"), transform.child_frame_id.lstrip("/")
            if parent == odom_frame and child == base_frame:
                inputs.tf_odometry[0].append(stamp_seconds(transform.header))
                inputs.tf_odometry[1].append(pose_from_transform(transform.transform))
            else:
                inputs.tree[child] = (parent, pose_from_transform(transform.transform))


def sensor_offset_in_tree(tree, base_frame, scan_frame):
    """(x, y, yaw) of scan_frame in base_frame through the bag's transforms (planar, as the amcl node
    takes the sensor's offset), or None when the chain does not reach the base."""
    frame, chain = scan_frame.lstrip("/"), []
    while frame != base_frame:
        if frame not in tree or len(chain) > 64:
            return None
        parent, pose = tree[frame]
        chain.append(pose)
        frame = parent
    offset = (0.0, 0.0, 0.0)
    for pose in reversed(chain):
        offset = compose(offset, pose)
    return offset


class OdometrySeries:
    """Poses at sorted stamps, interpolated at any time within them (as tf: linear, yaw the short way)."""

    def __init__(self, stamps, poses):
        order = np.argsort(np.asarray(stamps, dtype=float), kind="stable")
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
        before, after = self.poses[index - 1], self.poses[index]
        fraction = (stamp - self.stamps[index - 1]) / (self.stamps[index] - self.stamps[index - 1])
        return (before[0] + (after[0] - before[0]) * fraction, before[1] + (after[1] - before[1]) * fraction,
                wrap_angle(before[2] + wrap_angle(after[2] - before[2]) * fraction))


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
    if odometry_source not in ("auto", "tf", "topic"):
        raise ValueError(f"odometry source must be auto, tf or topic, got {odometry_source!r}")
    use_tf = odometry_source == "tf" or (odometry_source == "auto" and bool(inputs.tf_odometry[0]))
    series = OdometrySeries(*(inputs.tf_odometry if use_tf else inputs.topic_odometry))
    if not len(series):
        raise BagError(f"bag has no odometry: no odom -> {base_frame} transforms on /tf and no messages on "
                       f"{odom_topic}")
    if not inputs.scans:
        raise BagError("bag has no scans")
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
        count, increment = len(scan.ranges), scan.time_increment
        reference = reference_time(stamp, count, increment)
        odom = series.at(reference)
        if odom is None or series.at(min(stamp, stamp + (count - 1) * increment)) is None:
            skipped += 1
            continue
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan.angle_min + np.arange(count) * scan.angle_increment
        ranges, angles = deskew_ranges(ranges, angles, offsets[frame],
                                       beam_motion(stamp, count, increment, series.at))
        if not localizer.filter.initialized:
            if start.pose is None:
                localizer.global_localization()
            else:
                localizer.set_pose(start.pose, odom, start.covariance)
        updates += localizer.update(odom, ranges, angles, scan.range_min, offsets[frame])
        trajectory.append((reference,) + tuple(localizer.pose(odom)))
    seconds = time.process_time() - started
    estimate = localizer.filter.estimate
    spread = math.sqrt(max(0.0, estimate.covariance[0, 0] + estimate.covariance[1, 1])) if estimate else math.inf
    return LocalizeResult(trajectory, len(trajectory), skipped, updates, localizer.filter.converged(), spread,
                          seconds, inputs.duration, "tf" if use_tf else odom_topic)


def write_trajectory(path, trajectory):
    """One line per scan: stamp x y yaw (s, m, m, rad), the format remap_bag writes."""
    with open(path, "w") as stream:
        stream.write("# stamp x y yaw  (map frame; s, m, m, rad)\n")
        for stamp, x, y, yaw in trajectory:
            stream.write(f"{stamp:.9f} {x:.6f} {y:.6f} {yaw:.6f}\n")


def read_trajectory(path):
    rows = [line.split() for line in open(path) if line.strip() and not line.startswith("#")]
    return [tuple(float(v) for v in row) for row in rows]


def parse_pose(text, what="pose"):
    """'X,Y,YAW' (metres, radians) -> (x, y, yaw); ValueError naming `what` otherwise."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be X,Y,YAW (metres, radians), got {text!r}")
    return (values[0], values[1], values[2])
