"""ROS messages built from simulation state, shared by the simulator and fake_robot nodes (no rospy)."""
import math

from geometry_msgs.msg import Quaternion
from nav_msgs.msg import Odometry

# Gazebo's diff drive plugin's odometry covariance (pose x, y, z, roll, pitch, yaw diagonal).
POSE_COVARIANCE_DIAGONAL = (1e-5, 1e-5, 1e12, 1e12, 1e12, 1e-3)
TWIST_COVARIANCE_DIAGONAL = (1e-5, 1e-5, 1e12, 1e12, 1e12, 1e-3)


def yaw_quaternion(yaw: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def diagonal(values):
    matrix = [0.0] * 36
    for index, value in enumerate(values):
        matrix[index * 7] = value
    return matrix


def odometry_message(stamp, frame_id, child_frame_id, pose, velocity) -> Odometry:
    """Odometry of `child_frame_id` at pose (x, y, yaw) in `frame_id`, twist (linear, angular) in the child frame."""
    message = Odometry()
    message.header.stamp = stamp
    message.header.frame_id = frame_id
    message.child_frame_id = child_frame_id
    message.pose.pose.position.x, message.pose.pose.position.y = pose[0], pose[1]
    message.pose.pose.orientation = yaw_quaternion(pose[2])
    message.pose.covariance = diagonal(POSE_COVARIANCE_DIAGONAL)
    message.twist.twist.linear.x = velocity[0]
    message.twist.twist.angular.z = velocity[1]
    message.twist.covariance = diagonal(TWIST_COVARIANCE_DIAGONAL)
    return message
