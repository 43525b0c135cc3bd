"""ROS messages built from simulation state, shared by the simulator and fake_robot nodes (no rospy)."""
from nav_msgs.msg import Odometry

from turtlebot3c_common.message_fields import covariance
from turtlebot3c_common.ros_messages import quaternion_msg

# Gazebo's diff drive plugin's odometry covariance (pose x, y, z, roll, pitch, yaw diagonal).
POSE_COVARIANCE_DIAGONAL = (1e-5, 1e-5, 1e12, 1e12, 1e12, 1e-3)
TWIST_COVARIANCE_DIAGONAL = (1e-5, 1e-5, 1e12, 1e12, 1e12, 1e-3)


def odometry_message(stamp, frame_id, child_frame_id, pose, velocity) -> Odometry:
    """Odometry of `child_frame_id` at pose (x, y, yaw) in `frame_id`, twist (linear, angular) in the child frame."""
    message = Odometry()
    message.header.stamp = stamp
    message.header.frame_id = frame_id
    message.child_frame_id = child_frame_id
    message.pose.pose.position.x, message.pose.pose.position.y = pose[0], pose[1]
    message.pose.pose.orientation = quaternion_msg(pose[2])
    message.pose.covariance = covariance(POSE_COVARIANCE_DIAGONAL)
    message.twist.twist.linear.x = velocity[0]
    message.twist.twist.angular.z = velocity[1]
    message.twist.covariance = covariance(TWIST_COVARIANCE_DIAGONAL)
    return message
