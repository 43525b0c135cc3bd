"""A laser scan taken while the robot moves, brought to one instant ("deskewing"). Pure numpy; no rospy.

A spinning LIDAR measures its beams one after another: sensor_msgs/LaserScan says beam i
was measured at `header.stamp + i * time_increment`. The TurtleBot3 LDS take 0.2 s a
revolution; a robot turning at 0.6 rad/s turns 0.12 rad meanwhile, so a scan drawn from
one robot pose puts a pillar 2 m away up to 24 cm off, and the two ends of the revolution
(the same pillar seen at its start and its end) disagree: doubled pillars, phantom
obstacles. Deskewing expresses every beam's end point in the robot frame at one
reference time, the scan's latest beam, from the robot's poses (odometry) over the scan's
time span; the consumer then uses its pose at that reference time, as for an
instantaneous scan.

A scan with time_increment 0 (a simulator's instantaneous scan) is left untouched: the
functions return None for its motion, and None motion changes nothing.

    motion = beam_motion(stamp, len(ranges), time_increment, pose_at)   # pose_at(t) -> odom pose
    ranges, angles = deskew_ranges(ranges, angles, sensor_offset, motion)
    # then use the robot's pose at reference_time(stamp, len(ranges), time_increment)
"""
import math

import numpy as np

from .se2 import cos_sin

SAMPLE_STEP = 0.02  # s between the odometry poses sampled over a scan (odometry comes at 30-50 Hz)


def time_increment(scan):
    """A LaserScan's time between beams; 0 (beams at one time, no deskewing) when it is not a
    number, as another driver or a damaged recording may give."""
    return scan.time_increment if math.isfinite(scan.time_increment) else 0.0


def beam_times(stamp, count, time_increment):
    """When each of `count` beams was measured (s)."""
    return stamp + np.arange(count, dtype=np.float64) * time_increment


def reference_time(stamp, count, time_increment):
    """The time a deskewed scan is expressed at: its latest beam's (the stamp when the beams run
    backwards in time or are simultaneous)."""
    return stamp + max(0.0, (count - 1) * time_increment)


def sample_times(stamp, count, time_increment, step=SAMPLE_STEP):
    """Times spanning the scan from its earliest to its latest beam, at most `step` apart."""
    first, last = sorted((stamp, stamp + (count - 1) * time_increment))
    samples = max(2, int(math.ceil((last - first) / step)) + 1)
    return np.linspace(first, last, samples)


def relative_motion(times, poses, at_times, reference):
    """The robot's pose at each of `at_times` (N,) in the robot frame at time `reference`, (N, 3).

    `poses` (M, 3) are the robot's poses (x, y, yaw) in a fixed frame at the sorted `times`
    (M,); poses in between are interpolated linearly, yaw the short way round (as tf does).
    """
    times = np.asarray(times, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    yaw = np.unwrap(poses[:, 2])
    at_times = np.asarray(at_times, dtype=np.float64)

    def at(t):
        return np.interp(t, times, poses[:, 0]), np.interp(t, times, poses[:, 1]), np.interp(t, times, yaw)

    x, y, theta = at(at_times)
    rx, ry, rtheta = at(reference)
    c, s = math.cos(rtheta), math.sin(rtheta)
    dx, dy = x - rx, y - ry
    return np.column_stack((c * dx + s * dy, -s * dx + c * dy, theta - rtheta))


def beam_motion(stamp, count, time_increment, pose_at, step=SAMPLE_STEP):
    """Each beam's robot pose relative to the robot at reference_time(), (count, 3); None for an
    instantaneous scan. `pose_at(t)` gives the robot's (x, y, yaw) in a fixed frame at time t (s)."""
    if not time_increment or count < 2:
        return None
    times = sample_times(stamp, count, time_increment, step)
    poses = [pose_at(float(t)) for t in times]
    return relative_motion(times, poses, beam_times(stamp, count, time_increment),
                           reference_time(stamp, count, time_increment))


def deskew_points(points, motion):
    """Points (N, 2), each in the robot frame at its own beam's time, in the robot frame at the
    reference time; `motion` (N, 3) is each point's beam pose from beam_motion (None: unchanged)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if motion is None:
        return points
    motion = np.asarray(motion, dtype=np.float64).reshape(-1, 3)
    c, s = cos_sin(motion[:, 2])
    return np.column_stack((motion[:, 0] + c * points[:, 0] - s * points[:, 1],
                            motion[:, 1] + s * points[:, 0] + c * points[:, 1]))


def deskew_ranges(ranges, angles, sensor_offset, motion):
    """(ranges, angles) of the scan as the sensor would have measured it all at once at the reference
    time, from where it was then. Beams that returned nothing (not finite, or not above 0) keep their
    range and angle: deskewing moves end points, and they have none. `sensor_offset` is the sensor's
    (x, y, yaw) on the robot; `motion` from beam_motion (None: both returned unchanged)."""
    ranges = np.asarray(ranges, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)
    if motion is None:
        return ranges, angles
    sx, sy, syaw = sensor_offset
    with np.errstate(invalid="ignore"):
        returned = np.isfinite(ranges) & (ranges > 0.0)
    directions = syaw + angles[returned]
    ends = np.column_stack((sx + ranges[returned] * np.cos(directions), sy + ranges[returned] * np.sin(directions)))
    moved = deskew_points(ends, np.asarray(motion, dtype=np.float64)[returned]) - (sx, sy)
    moved_x, moved_y = np.ascontiguousarray(moved.T)  # for arctan2, as se2.cos_sin says
    new_ranges, new_angles = ranges.copy(), angles.copy()
    new_ranges[returned] = np.hypot(moved_x, moved_y)
    new_angles[returned] = np.arctan2(moved_y, moved_x) - syaw
    return new_ranges, new_angles
