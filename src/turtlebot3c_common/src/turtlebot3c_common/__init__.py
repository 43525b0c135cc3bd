"""What every turtlebot3c package shares: planar pose maths, ROS message helpers, backoff, and
the handling of a restarted ROS master.

The only package of ours that may import rospy outside `nodes/`; it depends on no other.
"""
