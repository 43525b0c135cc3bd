"""ROS messages of the navigation stack: costmaps and plans.

Message classes only (geometry_msgs, nav_msgs): no rospy, so the conversions are tested
without a ROS master. Times are passed in by the caller.
"""
import math

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Path

from turtlebot3c_common.ros_messages import pose_msg

from .costmap import INSCRIBED, LETHAL, NO_INFORMATION


def costs_to_occupancy(costs) -> np.ndarray:
    """costmap_2d's display mapping of costs to occupancy values: 0..252 scaled to 1..98,
    INSCRIBED 99, LETHAL 100, NO_INFORMATION -1, free 0."""
    costs = np.asarray(costs)
    values = np.where(costs == 0, 0, 1 + (97 * costs.astype(np.int32)) // 251).astype(np.int8)
    values[costs == INSCRIBED] = 99
    values[costs == LETHAL] = 100
    values[costs == NO_INFORMATION] = -1
    return values


def costmap_msg(costmap, frame_id, stamp) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = frame_id
    grid.header.stamp = stamp
    info = costmap.info
    grid.info = MapMetaData(map_load_time=stamp, resolution=info.resolution, width=info.width, height=info.height,
                            origin=pose_msg(info.origin_x, info.origin_y, 0.0))
    grid.data = costs_to_occupancy(costmap.costs).ravel().tolist()
    return grid


def path_msg(points, frame_id, stamp) -> Path:
    """A nav_msgs/Path through points (N x 2), each pose facing along the path."""
    path = Path()
    path.header.frame_id = frame_id
    path.header.stamp = stamp
    points = np.asarray(points, dtype=float)
    for index, (x, y) in enumerate(points):
        following = points[min(index + 1, len(points) - 1)]
        previous = points[max(index - 1, 0)]
        yaw = math.atan2(following[1] - previous[1], following[0] - previous[0]) if len(points) > 1 else 0.0
        stamped = PoseStamped()
        stamped.header = path.header
        stamped.pose = pose_msg(float(x), float(y), yaw)
        path.poses.append(stamped)
    return path
