"""Message fields to and from plain values: planar poses (x, y, yaw), covariance matrices and a
LaserScan's range limits.

Attribute reads only, no ROS import: rospy's messages (the nodes) and rosbags' (offline
re-mapping) serve alike, and so does any test double.
"""
import math

from .se2 import quaternion_to_yaw


def pose_from_transform(transform):
    """(x, y, yaw) of a geometry_msgs/Transform (its 2-D part)."""
    t, q = transform.translation, transform.rotation
    return (float(t.x), float(t.y), quaternion_to_yaw(q.x, q.y, q.z, q.w))


def pose_from_msg(pose):
    """(x, y, yaw) of a geometry_msgs/Pose."""
    p, q = pose.position, pose.orientation
    return (float(p.x), float(p.y), quaternion_to_yaw(q.x, q.y, q.z, q.w))


def scan_range_limits(range_min, range_max):
    """A LaserScan's range_min and range_max as the limits its readings are held to: each where it
    is a positive number, else none (0 m, infinity). Some drivers leave them 0; a damaged scan may
    carry NaN, which would otherwise make every comparison false."""
    low = float(range_min) if 0.0 < range_min < math.inf else 0.0
    high = float(range_max) if range_max > 0.0 else math.inf
    return low, high


def covariance(variances):
    """The row-major square matrix with `variances` on its diagonal, as ROS messages carry covariances."""
    size = len(variances)
    matrix = [0.0] * size * size
    for index, value in enumerate(variances):
        matrix[index * size + index] = value
    return matrix
