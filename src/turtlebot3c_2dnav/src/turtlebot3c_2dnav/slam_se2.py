"""Rigid motions in the plane (x, y, yaw), as SLAM composes them. Pure Python; no rospy."""
import math

import numpy as np


def wrap_angle(angle):
    """The same angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def compose(a, b):
    """The pose b, given relative to pose a, in a's parent frame (a ⊕ b)."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(at + bt))


def inverse(a):
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-c * ax - s * ay, s * ax - c * ay, wrap_angle(-at))


def between(a, b):
    """The pose b relative to pose a (a⁻¹ ⊕ b)."""
    return compose(inverse(a), b)


def transform_points(pose, points):
    """Points (N, 2) given in the frame at `pose`, expressed in that pose's parent frame."""
    x, y, t = pose
    c, s = math.cos(t), math.sin(t)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return np.column_stack((x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]))


def distance(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1])


def yaw_from_quaternion(x, y, z, w):
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw):
    """(x, y, z, w) of a rotation by yaw about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
