"""Planar poses (x, y, yaw): angle wrapping, composition, quaternions. The one copy of this maths.

Poses are plain (x, y, yaw) tuples. `wrap_angle` also takes numpy arrays, so the particle
filter and the pose graph wrap thousands of angles at once with it.
"""
import math

import numpy as np


def wrap_angle(angle):
    """The same angle(s) in [-pi, pi): a float, or a numpy array element-wise."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def cos_sin(angles):
    """Cosines and sines of an array of angles, taken on a contiguous copy. NumPy's AVX-512 loops
    (NumPy 1.22 on) give a strided array, a column of poses, other last bits than a contiguous one,
    and which depends on where the array lies in memory: a SLAM run would then not repeat itself
    (a closure taken or not on a last bit). A contiguous array gets the same bits wherever it lies."""
    angles = np.ascontiguousarray(angles, dtype=np.float64)
    return np.cos(angles), np.sin(angles)


def compose(a, b):
    """Pose b, given in a's frame, expressed in a's parent frame (a ⊕ b)."""
    ax, ay, ayaw = a
    bx, by, byaw = b
    c, s = math.cos(ayaw), math.sin(ayaw)
    return (ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(ayaw + byaw))


def inverse(a):
    """The pose whose composition with a is the identity (a⁻¹)."""
    ax, ay, ayaw = a
    c, s = math.cos(ayaw), math.sin(ayaw)
    return (-c * ax - s * ay, s * ax - c * ay, wrap_angle(-ayaw))


def relative(a, b):
    """Pose b seen from pose a (a⁻¹ ⊕ b)."""
    return compose(inverse(a), b)


def moved_from(poses, i, pose):
    """Poses (N, 3) with pose i put at `pose` and every later one moved with it (a path bent at i)."""
    moved = np.array(poses, dtype=np.float64)[:, :3]
    correction = compose(tuple(pose), inverse(tuple(moved[i])))
    moved[i:] = [compose(correction, tuple(later)) for later in moved[i:]]
    return moved


def transform_points(pose, points):
    """Points (N, 2) given in the frame at `pose`, expressed in that pose's parent frame."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    rotation_transposed = np.array([[c, s], [-s, c]])
    return np.asarray(points, dtype=np.float64).reshape(-1, 2) @ rotation_transposed + (x, y)


def distance(a, b):
    """Distance between the positions of two poses (or points)."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def poses_within(a, b, xy, theta):
    """Whether poses `a` and `b` lie within `xy` m and `theta` rad of each other."""
    return distance(a, b) <= xy and abs(wrap_angle(a[2] - b[2])) <= theta


def yaw_to_quaternion(yaw):
    """(x, y, z, w) of a rotation by yaw about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x, y, z, w):
    """Yaw of a quaternion (the rotation about z; roll and pitch ignored)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def interpolate_pose(before, after, fraction):
    """Linear in position, shortest way in yaw (what tf does for planar motion)."""
    return (before[0] + (after[0] - before[0]) * fraction,
            before[1] + (after[1] - before[1]) * fraction,
            wrap_angle(before[2] + wrap_angle(after[2] - before[2]) * fraction))
