"""What a ROS 1 bag holds for replaying a scan-driven node offline (remap_bag, localize_bag). No rospy.

Reads the bag with `rosbags` (imported only when a bag is read, so nodes that never read one do
not need it): the sensor_msgs/LaserScan on the scan topic, the odometry (odom -> base on /tf,
and the nav_msgs/Odometry topic) and the other transforms, the frame tree the LIDAR's mount is
found in. OdometrySeries interpolates odometry at any time within it, as tf does.
"""
import bisect
import functools
import math
import struct

import numpy as np

from .message_fields import pose_from_msg, pose_from_transform
from .se2 import compose, interpolate_pose, inverse, relative

TF_TOPICS = ("/tf", "/tf_static")
# Faster than this between two odometry samples (taken at least MIN_STEP_TIME apart), the
# odometry jumped: no robot this stack maps with is that fast (the Radish logs' robots step
# 1-4 m between samples 1 s apart).
MAX_SPEED = 10.0          # m/s
MAX_TURN_RATE = 10.0      # rad/s
MIN_STEP_TIME = 0.1       # s
# s: odometry that stays where it jumped to for this long was reset; back sooner, it glitched.
JUMP_CONFIRM_TIME = 1.0
IDENTITY = (0.0, 0.0, 0.0)


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


def frame_in_base(tree, base_frame, frame, identity, then):
    """`frame`'s transform in `base_frame` through the tree's chain of frame values, each combined
    with the next by then(parent_side, child_side) from `identity`; None when the chain does not
    reach the base (or loops)."""
    frame, chain = frame.lstrip("/"), []
    while frame != base_frame:
        if frame not in tree or len(chain) > len(tree):
            return None
        frame, value = tree[frame]
        chain.append(value)
    return functools.reduce(then, reversed(chain), identity)


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
    return series, ("tf" if use_tf else odom_topic) + series.repairs()


class OdometrySeries:
    """Poses at sorted stamps, interpolated at any time within them (as tf: linear, yaw the short way).

    A sample that is not a number is left out. A step no robot makes (faster than MAX_SPEED or
    MAX_TURN_RATE) is the odometry's own: samples off the path that it then comes back to (a
    glitch) are left out; odometry that stays where it jumped to for JUMP_CONFIRM_TIME (a board
    reset) continues from the sample before the jump, as the wheel odometry's driver does. Taken
    as a motion, one sample 10^12 m off made remap_bag grow its map until the kernel killed it,
    and AMCL's particles never came back."""

    def __init__(self, stamps, poses):
        order = np.argsort(np.asarray(stamps, dtype=float), kind="stable")
        self.stamps, self.poses = [], []
        self.not_numbers = self.off_path = self.jumps = 0
        numbers = []
        for index in order:
            stamp, pose = float(stamps[index]), tuple(float(value) for value in poses[index])
            if all(math.isfinite(value) for value in (stamp,) + pose):
                numbers.append((stamp, pose))
            else:
                self.not_numbers += 1
        self._mend(numbers)

    def _mend(self, samples):
        offset = IDENTITY  # what the jumps so far moved the odometry by, undone
        kept = None        # the last sample kept, as read
        suspects = []      # the samples since one jumped from it, as read
        for stamp, pose in samples:
            # Odometry that goes on from where it jumped to stays there, even once the time since
            # the sample before the jump would allow the step back.
            if suspects and not _jumped(suspects[-1], (stamp, pose)):
                suspects.append((stamp, pose))
                if stamp - suspects[0][0] >= JUMP_CONFIRM_TIME:
                    offset = self._continue_after_jump(suspects)
                    suspects, kept = [], suspects[-1]
            elif kept is None or not _jumped(kept, (stamp, pose)):
                self.off_path += len(suspects)
                suspects, kept = [], (stamp, pose)
                self._append(stamp, compose(offset, pose) if offset != IDENTITY else pose)
            else:
                self.off_path += len(suspects)
                suspects = [(stamp, pose)]
        if suspects:  # the odometry ends where it jumped to: it stayed there
            self._continue_after_jump(suspects)

    def _continue_after_jump(self, samples):
        """Append `samples` (as read, the first one jumped) continuing from the last sample
        appended; returns the offset that takes odometry as read there."""
        self.jumps += 1
        offset = compose(self.poses[-1], inverse(samples[0][1]))
        # The first as it is: through the offset, a far sample's rounding would stay in the rest.
        self._append(samples[0][0], self.poses[-1])
        for stamp, pose in samples[1:]:
            self._append(stamp, compose(offset, pose))
        return offset

    def _append(self, stamp, pose):
        self.stamps.append(stamp)
        self.poses.append(pose)

    def repairs(self):
        """What was mended, for a summary line ("" when nothing was)."""
        notes = [f"{_counted(self.jumps, 'jump')} taken as no motion"] if self.jumps else []
        if self.off_path:
            notes.append(f"{_counted(self.off_path, 'sample')} off the path left out")
        if self.not_numbers:
            notes.append(f"{_counted(self.not_numbers, 'sample')} that {'is' if self.not_numbers == 1 else 'are'} "
                         "not a number left out")
        return f" ({', '.join(notes)})" if notes else ""

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


def _counted(count, noun):
    return f"{count} {noun}" + ("" if count == 1 else "s")


def _jumped(sample, later):
    """Whether odometry went from `sample` to `later` (stamp, pose) faster than any robot moves."""
    step, reckoned = relative(sample[1], later[1]), max(later[0] - sample[0], MIN_STEP_TIME)
    return math.hypot(step[0], step[1]) > MAX_SPEED * reckoned or abs(step[2]) > MAX_TURN_RATE * reckoned


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
