"""What a ROS 1 bag holds for replaying a scan-driven node offline (remap_bag, localize_bag). No rospy.

Reads the bag with `rosbags` (imported only when a bag is read, so nodes that never read one do
not need it): the sensor_msgs/LaserScan on the scan topic, the odometry (odom -> base on /tf,
and the nav_msgs/Odometry topic) and the other transforms, the frame tree the LIDAR's mount is
found in. OdometrySeries interpolates odometry at any time within it, as tf does.
"""
import bisect
import math
import struct

import numpy as np

from .message_fields import pose_from_msg, pose_from_transform
from .se2 import interpolate_pose

TF_TOPICS = ("/tf", "/tf_static")


class BagError(ValueError):
    """A bag that cannot be replayed; the message says what is missing."""


class BagInputs:
    """Scans (stamp, message), odometry series and frame tree of a bag."""

    def __init__(self):
        self.scans = []
        self.tf_odometry = ([], [])      # (stamps, poses) of odom -> base on /tf
        self.topic_odometry = ([], [])   # (stamps, poses) from the odometry topic
        self.tree = {}                   # child frame -> (parent frame, frame_value(transform)), latest
        self.duration = 0.0


def stamp_seconds(header):
    """A header's stamp in seconds, for rospy-style (secs, nsecs) and rosbags-style (sec, nanosec) stamps."""
    stamp = header.stamp
    seconds = stamp.secs if hasattr(stamp, "secs") else stamp.sec
    nanoseconds = stamp.nsecs if hasattr(stamp, "nsecs") else stamp.nanosec
    return seconds + nanoseconds * 1e-9


def read_bag(path, scan_topic="/scan", odom_topic="/odom", odom_frame="odom", base_frame="base_footprint",
             frame_value=pose_from_transform):
    """Collect BagInputs from a ROS 1 bag file; BagError when it cannot be read or has no scan topic.

    The frame tree keeps frame_value(transform) of each transform: a planar pose by default.
    """
    from rosbags.rosbag1 import Reader, ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

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
                _collect(inputs, connection.topic, message, (scan_topic, odom_topic, odom_frame, base_frame),
                         frame_value)
    except ReaderError as error:
        raise BagError(f"cannot read bag {path}: {error}") from error
    except FileNotFoundError as error:
        raise BagError(f"cannot read bag {path}: no such file") from error
    except IsADirectoryError as error:
        raise BagError(f"cannot read bag {path}: it is a directory") from error
    # rosbags trusts a bag's lengths, offsets and texts: a damaged one trips its parser wherever
    # the damage is (a missing chunk's KeyError, a short record's struct.error or AssertionError,
    # a text that is not UTF-8, a message or type definition that does not parse).
    except (SerdeError, TypesysError, AssertionError, KeyError, IndexError, struct.error, UnicodeDecodeError,
            EOFError) as error:
        reason = type(error).__name__ + (f": {str(error).splitlines()[0]}" if str(error) else "")
        raise BagError(f"cannot read bag {path}: it is damaged or not a ROS 1 bag ({reason})") from error
    return inputs


def _collect(inputs, topic, message, names, frame_value):
    scan_topic, odom_topic, odom_frame, base_frame = names
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
                inputs.tree[child] = (parent, frame_value(transform.transform))


def odometry_series(inputs, odometry_source, base_frame, odom_topic):
    """(OdometrySeries, source name) of the bag's odometry: /tf's odom -> base when `odometry_source`
    is "tf", or "auto" and the bag has it, else the odometry topic; BagError when there is none."""
    if odometry_source not in ("auto", "tf", "topic"):
        raise ValueError(f"odometry source must be auto, tf or topic, got {odometry_source!r}")
    use_tf = odometry_source == "tf" or (odometry_source == "auto" and bool(inputs.tf_odometry[0]))
    series = OdometrySeries(*(inputs.tf_odometry if use_tf else inputs.topic_odometry))
    if not len(series):
        raise BagError(f"bag has no odometry: no odom -> {base_frame} transforms on /tf and no messages on "
                       f"{odom_topic}")
    if not inputs.scans:
        raise BagError("bag has no scans")
    return series, "tf" if use_tf else odom_topic


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
        before, after = index - 1, index
        span = self.stamps[after] - self.stamps[before]
        return interpolate_pose(self.poses[before], self.poses[after], (stamp - self.stamps[before]) / span)


def write_trajectory(path, trajectory):
    """One line per scan: stamp x y yaw (s, m, m, rad)."""
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
