"""Between ROS messages and the SLAM core: scan geometry, sensor mounts, odometry.

No rospy. These functions only read message attributes, so they serve rospy messages (live
node) and rosbags messages (offline re-mapping) alike. The map messages the node publishes
are built by turtlebot3c_maps.map_messages, as map_server's are.
"""
import math

from turtlebot3c_common.message_fields import pose_from_msg

from .slam_scan import ScanGeometry


def mount_from_transform(transform):
    """(x, y, yaw, upside_down) of a sensor frame in the base frame, from a geometry_msgs/Transform.

    upside_down when the sensor's z axis points down (its beams then turn clockwise in the base frame).
    """
    t, q = transform.translation, transform.rotation
    # First column of the rotation matrix: the sensor's x axis in the base frame.
    x_axis = (1.0 - 2.0 * (q.y * q.y + q.z * q.z), 2.0 * (q.x * q.y + q.z * q.w))
    z_axis_z = 1.0 - 2.0 * (q.x * q.x + q.y * q.y)
    return (float(t.x), float(t.y), math.atan2(x_axis[1], x_axis[0]), z_axis_z < 0.0)


def pose_from_odometry(odometry):
    """(x, y, yaw) of a nav_msgs/Odometry's pose."""
    return pose_from_msg(odometry.pose.pose)


class ScanGeometries:
    """ScanGeometry per distinct scan layout and mount (cached: building one costs a few trig arrays)."""

    def __init__(self):
        self._cache = {}

    def get(self, scan, mount):
        x, y, yaw, upside_down = mount
        key = (scan.angle_min, scan.angle_increment, len(scan.ranges), scan.range_min, scan.range_max,
               x, y, yaw, upside_down)
        geometry = self._cache.get(key)
        if geometry is None:
            if len(self._cache) > 16:
                self._cache.clear()
            geometry = ScanGeometry(scan.angle_min, scan.angle_increment, len(scan.ranges), scan.range_min,
                                    scan.range_max, (x, y, yaw), upside_down)
            self._cache[key] = geometry
        return geometry

