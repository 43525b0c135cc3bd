"""geometry_msgs built from planar poses: the builders every node shares.

Message classes only, no rospy; times are passed in by the caller.
"""
from geometry_msgs.msg import Point, Pose, Quaternion, TransformStamped

from .se2 import yaw_to_quaternion


def quaternion_msg(yaw) -> Quaternion:
    return Quaternion(*yaw_to_quaternion(yaw))


def pose_msg(x, y, yaw) -> Pose:
    return Pose(position=Point(x, y, 0.0), orientation=quaternion_msg(yaw))


def transform_msg(pose, parent, child, stamp) -> TransformStamped:
    """The transform from `parent` to `child`, whose origin is at `pose` (x, y, yaw) in `parent`."""
    message = TransformStamped()
    message.header.stamp = stamp
    message.header.frame_id = parent
    message.child_frame_id = child
    message.transform.translation.x, message.transform.translation.y = pose[0], pose[1]
    message.transform.rotation = quaternion_msg(pose[2])
    return message

